//! `host-bench replay`: run odometry estimators over a recorded or generated tick stream and
//! score them against the stream's ground-truth rows.
//!
//! `exact` runs in tick-timestamp mode: every tick instant is an update, at which the wheels
//! that did not tick are interpolated from their own last tick interval
//! ([`robot_math::ticks::TickTracker`]), and the fixed-point integrator
//! ([`robot_math::exact::ExactOdometry`]) moves the pose. Truth rows are scored at their own
//! instants, with every wheel interpolated to that instant.

use anyhow::{bail, Context, Result};
use robot_math::exact::{ExactOdometry, ExactParams, FixedPose, MAX_ENCODERS};
use robot_math::se2::wrap_angle;
use robot_math::ticks::TickTracker;
use robot_math::wheelset::WheelSolver;
use robot_math::Pose2;
use serde::Serialize;

use crate::robot::Robot;
use crate::tickstream::{Event, TickStream};

/// The estimators `replay` knows, in report order.
pub const ALGORITHMS: &[&str] = &["exact"];

/// How one estimator did on one stream.
#[derive(Clone, Debug, Serialize)]
pub struct Score {
    pub name: String,
    pub final_error_m: f64,
    pub max_error_m: f64,
    pub final_heading_error_rad: f64,
    pub path_length_m: f64,
    /// Truth rows scored.
    pub truth_rows: usize,
    /// The estimate at every truth row: (t s, x m, y m, θ rad).
    #[serde(skip)]
    pub track: Vec<(f64, Pose2)>,
}

/// Run `algorithm` over `stream` for `robot`.
pub fn replay(robot: &Robot, stream: &TickStream, algorithm: &str) -> Result<Score> {
    match algorithm {
        "exact" => replay_exact(robot, stream),
        other => bail!(
            "unknown algorithm {other:?}; available: {}, or all",
            ALGORITHMS.join(", ")
        ),
    }
}

fn replay_exact(robot: &Robot, stream: &TickStream) -> Result<Score> {
    if robot.carriage.is_some() {
        bail!(
            "robot {}: `exact` replay of a swivel-carriage robot (seed 004 layout) is not built yet",
            robot.name
        );
    }
    let n = robot.encoders.len();
    if n > MAX_ENCODERS {
        bail!(
            "robot {}: `exact` takes at most {MAX_ENCODERS} encoders, the robot has {n}",
            robot.name
        );
    }
    let solver = WheelSolver::new(&robot.encoder_wheels()).map_err(|e| {
        anyhow::anyhow!(
            "robot {}: encoders cannot determine the motion: {e:?}",
            robot.name
        )
    })?;
    let k: Vec<f64> = robot.encoders.iter().map(|e| e.metres_per_count).collect();
    let params = ExactParams::new(&solver, &k).map_err(|e| {
        anyhow::anyhow!(
            "robot {}: geometry out of fixed-point range: {e:?}",
            robot.name
        )
    })?;

    let start = stream
        .events
        .iter()
        .find_map(|e| match *e {
            Event::Truth {
                x_m,
                y_m,
                theta_rad,
                ..
            } => Some(Pose2::new(x_m, y_m, theta_rad)),
            _ => None,
        })
        .unwrap_or_default();
    let mut odo = ExactOdometry::new(params, FixedPose::from_pose2(start), &[0; MAX_ENCODERS]);
    let mut wheels = [TickTracker::new(); MAX_ENCODERS];
    let positions = |wheels: &[TickTracker; MAX_ENCODERS], t: u64| -> [i64; MAX_ENCODERS] {
        core::array::from_fn(|j| if j < n { wheels[j].position_q16(t) } else { 0 })
    };

    let mut score = Scorer::default();
    let events = &stream.events;
    let mut i = 0;
    while i < events.len() {
        let t = events[i].t_ns();
        // Everything at one instant first: ticks together, then the truth at that instant.
        let mut j = i;
        let mut ticked = false;
        while j < events.len() && events[j].t_ns() == t {
            if let Event::Tick { encoder, step, .. } = events[j] {
                let e = encoder as usize;
                if e >= n {
                    bail!(
                        "tick for encoder {e} at t = {t} ns, but robot {} has {n} encoders",
                        robot.name
                    );
                }
                wheels[e].tick(t, step);
                ticked = true;
            }
            j += 1;
        }
        let has_truth = events[i..j]
            .iter()
            .any(|e| matches!(e, Event::Truth { .. }));
        if ticked || has_truth {
            odo.update_q16(&positions(&wheels, t));
        }
        for e in &events[i..j] {
            if let Event::Truth {
                x_m,
                y_m,
                theta_rad,
                ..
            } = *e
            {
                score.add(t, odo.pose().to_pose2(), Pose2::new(x_m, y_m, theta_rad));
            }
        }
        i = j;
    }
    score.finish("exact")
}

#[derive(Default)]
struct Scorer {
    last_truth: Option<Pose2>,
    path: f64,
    max: f64,
    last: Option<(Pose2, Pose2)>,
    track: Vec<(f64, Pose2)>,
}

impl Scorer {
    fn add(&mut self, t_ns: u64, estimate: Pose2, truth: Pose2) {
        if let Some(prev) = self.last_truth {
            self.path += prev.distance_to(truth);
        }
        self.last_truth = Some(truth);
        self.max = self.max.max(estimate.distance_to(truth));
        self.last = Some((estimate, truth));
        self.track.push((t_ns as f64 / 1e9, estimate));
    }

    fn finish(self, name: &str) -> Result<Score> {
        let (estimate, truth) = self
            .last
            .context("the stream has no truth rows: nothing to score against")?;
        Ok(Score {
            name: name.into(),
            final_error_m: estimate.distance_to(truth),
            max_error_m: self.max,
            final_heading_error_rad: wrap_angle(estimate.theta - truth.theta),
            path_length_m: self.path,
            truth_rows: self.track.len(),
            track: self.track,
        })
    }
}
