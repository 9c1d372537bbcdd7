//! `host-bench replay`: run odometry estimators over a recorded or generated tick stream and
//! score them against the stream's ground-truth rows.
//!
//! The baselines: `arc` (seed 004) works on whole counts at every update; `lut` (seed 001)
//! tick by tick; `timing` (seed 000) needs every tick's time stamp. `exact` runs in either
//! sensor mode of the slave:
//! * [`Mode::Timestamps`] (edge interrupts / input capture): every tick instant is an update,
//!   at which the wheels that did not tick are interpolated from their own last tick interval
//!   ([`robot_math::ticks::TickTracker`]); truth rows are scored at their own instants, with
//!   every wheel interpolated to that instant.
//! * [`Mode::Counts`] (hardware quadrature counters read at a fixed rate): whole counts sampled
//!   every period; truth rows are scored with one extra sample at their instant (on the
//!   sampling grid, as the generator's truth rows are, that is the regular sample itself).
//!
//! Either way the fixed-point integrator ([`robot_math::exact::ExactOdometry`]) moves the pose.

use anyhow::{bail, Context, Result};
use robot_math::arc::ArcOdometry;
use robot_math::exact::{ExactOdometry, ExactParams, FixedPose, MAX_ENCODERS};
use robot_math::lut::{LutN, LutOdometry};
use robot_math::se2::wrap_angle;
use robot_math::ticks::{counts_as_ticks, TickTracker};
use robot_math::timing::TimingOdometry;
use robot_math::wheelset::WheelSolver;
use robot_math::Pose2;
use serde::Serialize;

use crate::formats::robot::Robot;
use crate::formats::tickstream::{Event, TickStream};

/// The estimators `replay` knows, in report order.
pub const ALGORITHMS: &[&str] = &["arc", "lut", "timing", "exact"];

/// Also accepted by [`replay`]: `exact`'s f64 twin, fed the same (interpolated) counts, for
/// checking the fixed-point version against it.
pub const ORACLE: &str = "exact-f64";

/// How the estimator sees the encoders.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Mode {
    /// Every tick with its time stamp.
    Timestamps,
    /// Whole counts sampled at a fixed rate.
    Counts { rate_hz: f64 },
}

impl std::fmt::Display for Mode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Mode::Timestamps => f.write_str("timestamps"),
            Mode::Counts { rate_hz } => write!(f, "counts@{rate_hz}Hz"),
        }
    }
}

/// How one estimator did on one stream.
#[derive(Clone, Debug, Serialize)]
pub struct Score {
    pub name: String,
    pub final_error_m: f64,
    pub max_error_m: f64,
    pub final_heading_error_rad: f64,
    pub path_length_m: f64,
    /// Median position error over the truth rows: the error while moving, which start-up and
    /// standstill quantisation (the maximum and often the final error) do not dominate.
    pub median_error_m: f64,
    /// Truth rows scored.
    pub truth_rows: usize,
    /// Every truth row scored: (t s, estimate, truth).
    #[serde(skip)]
    pub track: Vec<(f64, Pose2, Pose2)>,
}

impl Score {
    /// Write the track as CSV (t, truth, estimate, position error), atomically.
    pub fn write_track(&self, path: &std::path::Path) -> Result<()> {
        crate::formats::atomic::write_atomically(path, |file| {
            let mut w = csv::Writer::from_writer(file);
            w.write_record([
                "t_s",
                "true_x_m",
                "true_y_m",
                "true_theta_rad",
                "x_m",
                "y_m",
                "theta_rad",
                "error_m",
            ])?;
            for (t, e, tr) in &self.track {
                w.write_record(
                    [
                        t,
                        &tr.x,
                        &tr.y,
                        &tr.theta,
                        &e.x,
                        &e.y,
                        &e.theta,
                        &e.distance_to(*tr),
                    ]
                    .map(|v| v.to_string()),
                )?;
            }
            w.flush()?;
            Ok(())
        })
    }
}

/// What the replay driver tells an estimator. The trackers hold every tick up to `t_ns`.
trait Estimator {
    /// A single tick, as it happens (for estimators that use individual tick times).
    fn tick(&mut self, _t_ns: u64, _encoder: usize, _step: i8) {}
    /// An update at `t_ns`. `interpolate` is true in tick-timestamp mode (the estimator may
    /// place wheels between their ticks), false when it sees whole sampled counts.
    fn update(
        &mut self,
        t_ns: u64,
        wheels: &[TickTracker; MAX_ENCODERS],
        interpolate: bool,
    ) -> Pose2;
}

struct Exact {
    odo: ExactOdometry,
    n: usize,
}

impl Estimator for Exact {
    fn update(
        &mut self,
        t_ns: u64,
        wheels: &[TickTracker; MAX_ENCODERS],
        interpolate: bool,
    ) -> Pose2 {
        self.odo
            .update_q16(&positions_q16(wheels, self.n, t_ns, interpolate))
            .to_pose2()
    }
}

/// What `exact` (and its f64 twin: the same inputs, so the comparison is of the arithmetic
/// alone) sees of each wheel, in Q16 counts: interpolated between ticks with time stamps,
/// whole counts otherwise; unused slots zero.
fn positions_q16(
    wheels: &[TickTracker; MAX_ENCODERS],
    n: usize,
    t_ns: u64,
    interpolate: bool,
) -> [i64; MAX_ENCODERS] {
    core::array::from_fn(|j| match (j < n, interpolate) {
        (false, _) => 0,
        (true, true) => wheels[j].position_q16(t_ns),
        (true, false) => wheels[j].count() << 16,
    })
}

struct ExactF64 {
    odo: robot_math::exact::ExactOracle,
    n: usize,
}

impl Estimator for ExactF64 {
    fn update(
        &mut self,
        t_ns: u64,
        wheels: &[TickTracker; MAX_ENCODERS],
        interpolate: bool,
    ) -> Pose2 {
        let q = positions_q16(wheels, self.n, t_ns, interpolate);
        let c = q.map(|v| v as f64 / 65536.0);
        self.odo.update(&c[..self.n])
    }
}

struct Arc {
    odo: ArcOdometry,
    n: usize,
}

impl Estimator for Arc {
    fn update(
        &mut self,
        _t_ns: u64,
        wheels: &[TickTracker; MAX_ENCODERS],
        _interpolate: bool,
    ) -> Pose2 {
        // The arc algorithm works on whole counts, in either mode (seed 004 samples counters).
        let c: [f64; MAX_ENCODERS] = core::array::from_fn(|j| {
            if j < self.n {
                wheels[j].count() as f64
            } else {
                0.0
            }
        });
        self.odo.update(&c[..self.n])
    }
}

/// Methods that work tick by tick (seed 001's tables: that is their point).
trait TickByTick {
    fn tick(&mut self, wheel: usize, step: i8);
    fn pose(&self) -> Pose2;
}

impl TickByTick for LutOdometry {
    fn tick(&mut self, wheel: usize, step: i8) {
        LutOdometry::tick(self, wheel as u8, step);
    }
    fn pose(&self) -> Pose2 {
        LutOdometry::pose(self)
    }
}

impl TickByTick for LutN {
    fn tick(&mut self, wheel: usize, step: i8) {
        LutN::tick(self, wheel, step);
    }
    fn pose(&self) -> Pose2 {
        LutN::pose(self)
    }
}

/// A tick-by-tick method. With time stamps it sees every tick as it happens; reading sampled
/// counts, it gets each sample's count changes as ticks, the wheels interleaved.
struct PerTick<T> {
    odo: T,
    per_tick: bool,
    applied: [i64; MAX_ENCODERS],
}

impl<T: TickByTick> Estimator for PerTick<T> {
    fn tick(&mut self, _t_ns: u64, encoder: usize, step: i8) {
        if self.per_tick {
            self.odo.tick(encoder, step);
            self.applied[encoder] += step as i64;
        }
    }

    fn update(
        &mut self,
        _t_ns: u64,
        wheels: &[TickTracker; MAX_ENCODERS],
        _interpolate: bool,
    ) -> Pose2 {
        if !self.per_tick {
            let counts: [i64; MAX_ENCODERS] = core::array::from_fn(|j| wheels[j].count());
            counts_as_ticks(&mut self.applied, &counts, |j, step| self.odo.tick(j, step));
        }
        self.odo.pose()
    }
}

/// Seed 000's timing method: every tick with its time.
struct Timing {
    odo: TimingOdometry,
}

impl Estimator for Timing {
    fn tick(&mut self, t_ns: u64, encoder: usize, step: i8) {
        self.odo.tick(t_ns, encoder, step);
    }

    fn update(
        &mut self,
        t_ns: u64,
        _wheels: &[TickTracker; MAX_ENCODERS],
        _interpolate: bool,
    ) -> Pose2 {
        self.odo.update(t_ns)
    }
}

/// Origin of seed 001's unsigned coordinate square (in its 10^-8 m units) that keeps the
/// stream's truth rows, with a 1 m margin, inside the representable range.
fn lut_origin(stream: &TickStream) -> (u32, u32) {
    let (mut min_x, mut min_y) = (0.0f64, 0.0f64);
    for e in &stream.events {
        if let Event::Truth { x_m, y_m, .. } = *e {
            min_x = min_x.min(x_m);
            min_y = min_y.min(y_m);
        }
    }
    let lsb = |m: f64| ((1.0 - m) * 1e8).clamp(0.0, u32::MAX as f64) as u32;
    (lsb(min_x), lsb(min_y))
}

/// Whether the robot is a differential drive as seed 001's method assumes: two encoders on
/// one axle through the reference point, left (+y) then right (-y), both rolling forward,
/// with the same travel per count. Returns (travel per count, track).
fn seed001_layout(robot: &Robot) -> Option<(f64, f64)> {
    let [l, r] = robot.encoders.as_slice() else {
        return None;
    };
    let (wl, wr) = (l.wheel, r.wheel);
    let forward = |w: robot_math::wheel::Wheel| {
        (w.ux - 1.0).abs() < 1e-9 && w.uy.abs() < 1e-9 && w.x.abs() < 1e-9
    };
    let same = (l.metres_per_count - r.metres_per_count).abs() <= 1e-12 * l.metres_per_count;
    (forward(wl) && forward(wr) && same && wl.y > 0.0 && (wl.y + wr.y).abs() < 1e-9)
        .then_some((l.metres_per_count, wl.y - wr.y))
}

/// Run `algorithm` over `stream` for `robot`, seeing the encoders as `mode` says.
pub fn replay(robot: &Robot, stream: &TickStream, algorithm: &str, mode: Mode) -> Result<Score> {
    if let Mode::Counts { rate_hz } = mode {
        if !(rate_hz.is_finite() && rate_hz > 0.0 && rate_hz <= 1e9) {
            bail!("counts sampling rate must be a positive number of Hz up to 1e9, got {rate_hz}");
        }
    }
    if robot.carriage.is_some() {
        bail!(
            "robot {}: replay of a swivel-carriage robot (seed 004 layout) is not built yet; \
             `host-bench emulate` runs that layout",
            robot.name
        );
    }
    let n = robot.encoders.len();
    if n > MAX_ENCODERS {
        bail!(
            "robot {}: replay takes at most {MAX_ENCODERS} encoders, the robot has {n}",
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
    let mut estimator: Box<dyn Estimator> = match algorithm {
        "exact" => {
            let params = ExactParams::new(&solver, &k).map_err(|e| {
                anyhow::anyhow!(
                    "robot {}: geometry out of fixed-point range: {e:?}",
                    robot.name
                )
            })?;
            Box::new(Exact {
                odo: ExactOdometry::new(params, FixedPose::from_pose2(start), &[0; MAX_ENCODERS]),
                n,
            })
        }
        ORACLE => Box::new(ExactF64 {
            odo: robot_math::exact::ExactOracle::new(solver, &k, start, &vec![0.0; n]),
            n,
        }),
        "arc" => Box::new(Arc {
            odo: ArcOdometry::new(solver, &k, start, &vec![0.0; n]),
            n,
        }),
        "lut" => {
            // Seed 001 keeps coordinates unsigned (about 42.9 m of range at 10^-8 m): like the
            // paper, put the field origin so the whole run stays positive, 1 m inside the square.
            let origin = lut_origin(stream);
            match seed001_layout(robot) {
                // The paper's own method, for its differential drive.
                Some((step, track)) => Box::new(PerTick {
                    odo: LutOdometry::with_origin_offset(step, track, start, origin),
                    per_tick: mode == Mode::Timestamps,
                    applied: [0; MAX_ENCODERS],
                }),
                // Its ideas on other layouts whose wheels turn the body by equal steps.
                None => {
                    let odo = LutN::new(&solver, &k, start, origin).map_err(|e| {
                        anyhow::anyhow!(
                            "robot {}: `lut` (seed 001) needs a differential drive, or wheels that \
                             all turn the body by the same angle per tick ({e:?})",
                            robot.name
                        )
                    })?;
                    Box::new(PerTick {
                        odo,
                        per_tick: mode == Mode::Timestamps,
                        applied: [0; MAX_ENCODERS],
                    })
                }
            }
        }
        "timing" => {
            if mode != Mode::Timestamps {
                bail!("`timing` (seed 000) needs every tick's time stamp; it cannot run on sampled counts");
            }
            Box::new(Timing {
                odo: TimingOdometry::from_wheels(&robot.encoder_wheels(), &k, start)
                    .map_err(|e| anyhow::anyhow!("robot {}: {e:?}", robot.name))?,
            })
        }
        other => bail!(
            "unknown algorithm {other:?}; available: {}, or all",
            ALGORITHMS.join(", ")
        ),
    };
    drive(robot, stream, mode, n, estimator.as_mut())?.finish(algorithm)
}

/// Walk the stream in time order: ticks into the trackers (and the estimator), updates at
/// every tick instant (time stamps) or every sample (counts), scores at every truth row.
fn drive(
    robot: &Robot,
    stream: &TickStream,
    mode: Mode,
    n: usize,
    est: &mut dyn Estimator,
) -> Result<Scorer> {
    let mut wheels = [TickTracker::new(); MAX_ENCODERS];
    let period_ns = match mode {
        Mode::Counts { rate_hz } => Some(((1e9 / rate_hz).round() as u64).max(1)),
        Mode::Timestamps => None,
    };
    let interpolate = period_ns.is_none();
    let mut next_sample = period_ns.map(|p| stream.events.first().map_or(0, |e| e.t_ns()) + p);
    let mut pose = None;
    let mut score = Scorer::default();
    let events = &stream.events;
    let mut i = 0;
    while i < events.len() {
        let t = events[i].t_ns();
        // Fixed-rate samples strictly before this instant see the counts as they were.
        if let (Some(p), Some(next)) = (period_ns, next_sample.as_mut()) {
            while *next < t {
                pose = Some(est.update(*next, &wheels, false));
                *next += p;
            }
        }
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
                est.tick(t, e, step);
                ticked = true;
            }
            j += 1;
        }
        let has_truth = events[i..j]
            .iter()
            .any(|e| matches!(e, Event::Truth { .. }));
        let due = match (period_ns, next_sample.as_mut()) {
            // A regular sample at this very instant, or a scoring one for a truth row.
            (Some(p), Some(next)) => {
                let regular = *next == t;
                if regular {
                    *next += p;
                }
                regular || has_truth
            }
            _ => ticked || has_truth,
        };
        if due {
            pose = Some(est.update(t, &wheels, interpolate));
        }
        for e in &events[i..j] {
            if let Event::Truth {
                x_m,
                y_m,
                theta_rad,
                ..
            } = *e
            {
                let estimate = pose.unwrap_or_else(|| est.update(t, &wheels, interpolate));
                score.add(t, estimate, Pose2::new(x_m, y_m, theta_rad));
            }
        }
        i = j;
    }
    Ok(score)
}

#[derive(Default)]
struct Scorer {
    last_truth: Option<Pose2>,
    path: f64,
    max: f64,
    last: Option<(Pose2, Pose2)>,
    track: Vec<(f64, Pose2, Pose2)>,
}

impl Scorer {
    fn add(&mut self, t_ns: u64, estimate: Pose2, truth: Pose2) {
        if let Some(prev) = self.last_truth {
            self.path += prev.distance_to(truth);
        }
        self.last_truth = Some(truth);
        self.max = self.max.max(estimate.distance_to(truth));
        self.last = Some((estimate, truth));
        self.track.push((t_ns as f64 / 1e9, estimate, truth));
    }

    fn finish(self, name: &str) -> Result<Score> {
        let (estimate, truth) = self
            .last
            .context("the stream has no truth rows: nothing to score against")?;
        let mut errors: Vec<f64> = self
            .track
            .iter()
            .map(|(_, e, t)| e.distance_to(*t))
            .collect();
        errors.sort_by(f64::total_cmp);
        Ok(Score {
            name: name.into(),
            median_error_m: errors[errors.len() / 2],
            final_error_m: estimate.distance_to(truth),
            max_error_m: self.max,
            final_heading_error_rad: wrap_angle(estimate.theta - truth.theta),
            path_length_m: self.path,
            truth_rows: self.track.len(),
            track: self.track,
        })
    }
}
