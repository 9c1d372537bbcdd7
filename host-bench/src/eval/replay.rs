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
//! Every method runs through robot-math's one odometry layer ([`Odometry`], the code the
//! slave runs), over any layout the robot format accepts, seed 004's swivel carriage included
//! (its absolute encoder events feed the swivel angle).

use anyhow::{bail, Context, Result};
use robot_math::exact::{FixedPose, MAX_ENCODERS};
use robot_math::odometry::{Method, Odometry, SensorKind};
use robot_math::se2::wrap_angle;
use robot_math::ticks::TickTracker;
use robot_math::wheelset::WheelSolver;
use robot_math::Pose2;
use serde::Serialize;

use super::replay_checks::{check_counts_rate, check_events, check_scorable};
use crate::formats::robot::Robot;
use crate::formats::tickstream::{Event, TickStream};

/// The estimators `replay` knows, in report order.
pub const ALGORITHMS: &[&str] = &["arc", "lut", "timing", "exact"];

// The report order is robot-math's.
const _: () = assert!(ALGORITHMS.len() == Method::ALL.len());

/// Also accepted by [`replay`]: `exact`'s f64 twin, fed the same (interpolated) counts, for
/// checking the fixed-point version against it.
pub const ORACLE: &str = "exact-f64";
/// Added to `exact` (or its twin): it takes every edge a whole count after the last instead of
/// learning where each encoder puts the four edges of its quadrature cycle
/// (`Odometry::set_edge_learning`): `exact` as it was before it learned them, for a comparison.
pub const EVEN_EDGES: &str = "+even";

/// How the estimator sees the encoders.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Mode {
    /// Every tick with its time stamp.
    Timestamps,
    /// Whole counts sampled at a fixed rate.
    Counts { rate_hz: f64 },
}

impl Mode {
    /// With counts, the sampling period in ns (at least 1).
    pub fn period_ns(self) -> Option<u64> {
        match self {
            Mode::Counts { rate_hz } => Some(((1e9 / rate_hz).round() as u64).max(1)),
            Mode::Timestamps => None,
        }
    }
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
        crate::formats::atomic::write_atomically(path, |file| self.write_track_to(file))
    }

    /// The track as CSV into `out` ([`write_track`](Self::write_track)'s content).
    pub fn write_track_to(&self, out: impl std::io::Write) -> Result<()> {
        {
            let mut w = csv::Writer::from_writer(out);
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
        }
    }
}

/// What the replay driver tells an estimator. The trackers hold every tick up to `t_ns`.
trait Estimator {
    /// A single tick, as it happens.
    fn tick(&mut self, _t_ns: u64, _encoder: usize, _step: i8) {}
    /// The absolute encoder's raw output.
    fn abs(&mut self, _raw: u16) {}
    /// An update at `t_ns`. `interpolate` is true in tick-timestamp mode (the estimator may
    /// place wheels between their ticks), false when it sees whole sampled counts.
    fn update(
        &mut self,
        t_ns: u64,
        wheels: &[TickTracker; MAX_ENCODERS],
        interpolate: bool,
    ) -> Pose2;
}

/// Any method, as the slave runs it.
impl Estimator for Odometry {
    fn tick(&mut self, t_ns: u64, encoder: usize, step: i8) {
        // Ignored with sampled counts: those come with the update.
        Odometry::tick(self, t_ns, encoder, step);
    }

    fn abs(&mut self, raw: u16) {
        self.set_abs(raw);
    }

    fn update(
        &mut self,
        t_ns: u64,
        wheels: &[TickTracker; MAX_ENCODERS],
        _interpolate: bool,
    ) -> Pose2 {
        self.set_counts(&wheels.map(|w| w.count()));
        Odometry::update(self, t_ns).to_pose2()
    }
}

/// What `exact`'s f64 twin sees of each wheel, in Q16 counts: the same as `exact`
/// (interpolated between ticks with time stamps, whole counts otherwise), so the comparison
/// is of the arithmetic alone; unused slots zero.
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

/// Origin of seed 001's unsigned coordinate square (in its 10^-8 m units) that keeps the
/// stream's truth rows, with a 1 m margin, inside the representable range. `lut` tracks a
/// wheel, not the reference point: the margin grows by the robot's reach (a wheel 1 m off
/// the centre wrapped to 42.9 m at the first step). Refused when the run does not fit the
/// square at all.
fn lut_origin(stream: &TickStream, robot: &Robot) -> Result<(u32, u32)> {
    let reach = robot
        .encoders
        .iter()
        .map(|e| e.wheel.x.hypot(e.wheel.y))
        .fold(0.0f64, f64::max)
        + robot.carriage.as_ref().map_or(0.0, |c| c.trail_m.abs());
    let margin = 1.0 + reach;
    let (mut lo, mut hi) = ((0.0f64, 0.0f64), (0.0f64, 0.0f64));
    for e in &stream.events {
        if let Event::Truth { x_m, y_m, .. } = *e {
            lo = (lo.0.min(x_m), lo.1.min(y_m));
            hi = (hi.0.max(x_m), hi.1.max(y_m));
        }
    }
    let span = (hi.0 - lo.0).max(hi.1 - lo.1) + 2.0 * margin;
    let square = u32::MAX as f64 * 1e-8;
    if span > square {
        bail!(
            "`lut` (Batbayar and Zoljargal 2013) keeps positions in 32-bit units of 10 nm, a \
             {square:.1} m square; this run needs {span:.1} m (its truth's extent, plus \
             {margin:.1} m either side for the robot's reach)"
        );
    }
    let lsb = |m: f64| ((margin - m) * 1e8).clamp(0.0, u32::MAX as f64) as u32;
    Ok((lsb(lo.0), lsb(lo.1)))
}

/// Run `algorithm` over `stream` for `robot`, seeing the encoders as `mode` says.
pub fn replay(robot: &Robot, stream: &TickStream, algorithm: &str, mode: Mode) -> Result<Score> {
    replay_tracked(robot, stream, algorithm, mode, true)
}

/// [`replay`] without [`Score::track`] (left empty): the figures alone, in 8 bytes a truth row
/// rather than 64.
pub fn replay_untracked(
    robot: &Robot,
    stream: &TickStream,
    algorithm: &str,
    mode: Mode,
) -> Result<Score> {
    replay_tracked(robot, stream, algorithm, mode, false)
}

fn replay_tracked(
    robot: &Robot,
    stream: &TickStream,
    algorithm: &str,
    mode: Mode,
    keep_track: bool,
) -> Result<Score> {
    // Once, before the walk: every row one the robot can have made (`replay` names the line
    // first; other callers get the same message).
    check_events(robot, stream).map_err(|e| anyhow::Error::msg(e.message))?;
    check_scorable(stream, mode)?;
    let (mut estimator, n, learn) = estimator(robot, stream, algorithm, mode)?;
    let est = estimator.as_mut();
    let mut score = Scorer {
        keep_track,
        ..Scorer::default()
    };
    let wheels = Wheels { n, learn };
    drive(
        robot,
        stream,
        mode,
        wheels,
        est,
        Samples::Changed,
        &mut score,
    )?;
    score.finish(algorithm)
}

/// `algorithm` for `robot`, started at the stream's first truth row, its encoder count, and
/// whether the walk's own trackers must learn the edges (`exact-f64` reads them; `exact`
/// learns in its own; neither with [`EVEN_EDGES`]).
fn estimator(
    robot: &Robot,
    stream: &TickStream,
    algorithm: &str,
    mode: Mode,
) -> Result<(Box<dyn Estimator>, usize, bool)> {
    let (algorithm, learn) = match algorithm.strip_suffix(EVEN_EDGES) {
        Some(base @ ("exact" | ORACLE)) => (base, false),
        Some(_) => bail!("only `exact` and `{ORACLE}` learn edges (`{algorithm}`)"),
        None => (algorithm, true),
    };
    if !learn && mode != Mode::Timestamps {
        bail!(
            "`{algorithm}{EVEN_EDGES}` is about time-stamped ticks: with sampled counts `exact` \
             sees no edges to learn"
        );
    }
    if let Mode::Counts { rate_hz } = mode {
        check_counts_rate(rate_hz)?;
    }
    let layout = robot.odometry_layout()?;
    let n = layout.encoders();
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
    let t0 = stream.events.first().map_or(0, |e| e.t_ns());
    // The absolute encoder as it reads at the start (the stream's first reading of it there).
    let abs0 = robot.start_reading(&stream.events).map(|(_, code)| code);
    let estimator: Box<dyn Estimator> = if algorithm == ORACLE {
        if robot.carriage.is_some() {
            bail!(
                "robot {}: `{ORACLE}` (exact's f64 twin) is for body-fixed encoders; on a \
                 swivel carriage compare `exact` with the float baselines instead",
                robot.name
            );
        }
        let solver = WheelSolver::new(&robot.encoder_wheels())
            .map_err(|e| anyhow::anyhow!("robot {}: {e:?}", robot.name))?;
        let k = &layout.metres_per_count()[..n];
        Box::new(ExactF64 {
            odo: robot_math::exact::ExactOracle::new(solver, k, start, &vec![0.0; n]),
            n,
        })
    } else {
        let method = Method::from_name(algorithm).with_context(|| {
            format!(
                "unknown algorithm {algorithm:?}; available: {}, or all",
                ALGORITHMS.join(", ")
            )
        })?;
        let sensors = match mode {
            Mode::Timestamps => SensorKind::Ticks,
            Mode::Counts { .. } => SensorKind::Counts,
        };
        let mut odo = Odometry::new(
            &layout,
            method,
            sensors,
            FixedPose::from_pose2(start),
            t0,
            [0; MAX_ENCODERS],
            abs0,
        )
        .map_err(|e| anyhow::anyhow!("robot {}: {e}", robot.name))?;
        odo.set_edge_learning(learn);
        // Seed 001 keeps coordinates unsigned (about 42.9 m of range at 10^-8 m): like the
        // paper, put the field origin so the whole run stays positive, 1 m inside the square.
        if method == Method::Lut {
            Box::new(odo.with_lut_origin(lut_origin(stream, robot)?))
        } else {
            Box::new(odo)
        }
    };
    // Only the twin reads the walk's trackers' positions.
    Ok((estimator, n, learn && algorithm == ORACLE))
}

/// The walk's own wheel trackers (what `exact`'s f64 twin reads): how many, and whether they
/// learn their edges as `exact` does (the twin's; not for `exact-f64+even`).
#[derive(Clone, Copy)]
struct Wheels {
    n: usize,
    learn: bool,
}

/// Which fixed-rate samples [`drive`] hands to the estimator.
#[derive(Clone, Copy, PartialEq)]
enum Samples {
    /// Every one, as the slave's fixed-rate update does.
    Every,
    /// Only those after a reading changed (and the scoring ones at truth rows).
    Changed,
}

/// Walk the stream in time order: ticks into the trackers (and the estimator), updates at
/// every tick instant (time stamps) or every sample (counts), scores at every truth row.
///
/// With counts, `Samples::Changed` skips a sample that sees the same counts and absolute
/// reading as the update before it: every method's update is a function of those readings
/// alone there, so it would return the same pose, and most samples at 10 kHz fall between two
/// ticks. `replay_skips_only_samples_that_change_nothing` checks it bit for bit against
/// `Samples::Every`, which is what the slave does.
fn drive(
    robot: &Robot,
    stream: &TickStream,
    mode: Mode,
    Wheels { n, learn }: Wheels,
    est: &mut dyn Estimator,
    samples: Samples,
    score: &mut Scorer,
) -> Result<()> {
    let t0 = stream.events.first().map_or(0, |e| e.t_ns());
    let mut wheels = [TickTracker::starting(0, t0); MAX_ENCODERS];
    wheels.iter_mut().for_each(|w| w.set_edge_learning(learn));
    let period_ns = mode.period_ns();
    let interpolate = period_ns.is_none();
    // With counts, the next fixed-rate sample; `None` once it would be at 2^64 ns or later,
    // after any event can be.
    let mut next_sample = period_ns.and_then(|p| t0.checked_add(p));
    let mut pose = None;
    // A reading (a count or the absolute encoder) changed since the last update.
    let mut changed = true;
    let every = samples == Samples::Every;
    let events = &stream.events;
    let mut i = 0;
    while i < events.len() {
        let t = events[i].t_ns();
        // Fixed-rate samples strictly before this instant see the counts as they were.
        if let Some(p) = period_ns {
            while let Some(next) = next_sample.filter(|&next| next < t) {
                // Samples that would see the same readings as the last update are jumped in
                // one step: a gap of years between two ticks costs nothing.
                let skip = if changed || every {
                    pose = Some(est.update(next, &wheels, false));
                    changed = false;
                    Some(p)
                } else {
                    (t - next).div_ceil(p).checked_mul(p)
                };
                next_sample = skip.and_then(|skip| next.checked_add(skip));
            }
        }
        // Everything at one instant first: ticks together, then the truth at that instant.
        let mut j = i;
        let mut ticked = false;
        while j < events.len() && events[j].t_ns() == t {
            if let Event::Tick { encoder, step, .. } = events[j] {
                let e = encoder as usize;
                robot_math::ticks::tick_wheel(&mut wheels[..n], e, t, step);
                est.tick(t, e, step);
                ticked = true;
                changed = true;
            }
            if let Event::Abs { encoder, code, .. } = events[j] {
                if let Some(code) = robot.abs_reading(encoder, code, t)? {
                    est.abs(code);
                    changed = true;
                }
            }
            j += 1;
        }
        let has_truth = events[i..j]
            .iter()
            .any(|e| matches!(e, Event::Truth { .. }));
        let due = match period_ns {
            // A regular sample at this very instant, or a scoring one for a truth row.
            Some(p) => {
                let regular = next_sample == Some(t);
                if regular {
                    next_sample = t.checked_add(p);
                }
                (regular && (changed || every)) || has_truth
            }
            None => ticked || has_truth,
        };
        if due {
            if interpolate {
                // What `exact` does at its update: its f64 twin reads these wheels.
                robot_math::ticks::learn_edges(&mut wheels[..n]);
            }
            pose = Some(est.update(t, &wheels, interpolate));
            changed = false;
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
    Ok(())
}

/// The scores over the truth rows. What makes a stream scorable at all (two truth rows, ticks
/// and motion between them) is checked before, by [`check_scorable`].
#[derive(Default)]
struct Scorer {
    last_truth: Option<Pose2>,
    path: f64,
    max: f64,
    last: Option<(Pose2, Pose2)>,
    errors: Vec<f64>,
    keep_track: bool,
    track: Vec<(f64, Pose2, Pose2)>,
}

impl Scorer {
    fn add(&mut self, t_ns: u64, estimate: Pose2, truth: Pose2) {
        if let Some(prev) = self.last_truth {
            self.path += prev.distance_to(truth);
        }
        self.last_truth = Some(truth);
        let error = estimate.distance_to(truth);
        self.max = self.max.max(error);
        self.last = Some((estimate, truth));
        self.errors.push(error);
        if self.keep_track {
            self.track.push((t_ns as f64 / 1e9, estimate, truth));
        }
    }

    fn finish(mut self, name: &str) -> Result<Score> {
        let (estimate, truth) = self
            .last
            .context("the stream has no truth rows: nothing to score against")?;
        let truth_rows = self.errors.len();
        let errors = &mut self.errors;
        errors.sort_by(f64::total_cmp);
        Ok(Score {
            name: name.into(),
            median_error_m: errors[errors.len() / 2],
            final_error_m: estimate.distance_to(truth),
            max_error_m: self.max,
            final_heading_error_rad: wrap_angle(estimate.theta - truth.theta),
            path_length_m: self.path,
            truth_rows,
            track: self.track,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::generate::{generate, GenerateOptions};
    use crate::sim::trajectory;

    fn robot(file: &str) -> Robot {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../robots")
            .join(file);
        Robot::load(&path).expect("robot loads")
    }

    #[test]
    fn replay_skips_only_samples_that_change_nothing() {
        // Coarse and fine counts, a differential drive, an omni layout that is not the seeds',
        // and seed 004's swivel carriage (its absolute encoder read at 1 kHz): every method,
        // at both rates, gives the same pose at every truth row, to the bit, whether it is
        // updated at every sample (as on the slave) or only after a reading changed.
        let cases = [
            ("seed000-0.8mm.toml", "seed000-bezier-90deg"),
            ("seed001.toml", "seed001-figure-eight"),
            ("skewed3.toml", "twist-sideways-spin"),
            ("seed004.toml", "seed000-bezier-90deg"),
        ];
        for (file, name) in cases {
            let r = robot(file);
            let traj = trajectory::build(name).expect("trajectory");
            let stream = generate(&r, None, traj.as_ref(), &GenerateOptions::default()).unwrap();
            let names = ALGORITHMS.iter().chain([&ORACLE]).filter(|&&a| {
                // The f64 twin is for body-fixed encoders; `timing` needs time stamps.
                !(a == ORACLE && r.carriage.is_some()) && a != "timing"
            });
            for &algorithm in names {
                for rate_hz in [1_000.0, 10_000.0] {
                    let mode = Mode::Counts { rate_hz };
                    if estimator(&r, &stream, algorithm, mode).is_err() {
                        // `lut` runs on differential drives and seed 000's symmetric triangle.
                        assert_eq!((algorithm, file), ("lut", "skewed3.toml"));
                        continue;
                    }
                    let run = |samples| {
                        let (mut est, n, learn) = estimator(&r, &stream, algorithm, mode).unwrap();
                        let mut score = Scorer {
                            keep_track: true,
                            ..Scorer::default()
                        };
                        let est = est.as_mut();
                        let wheels = Wheels { n, learn };
                        drive(&r, &stream, mode, wheels, est, samples, &mut score).unwrap();
                        score
                    };
                    let (every, changed) = (run(Samples::Every), run(Samples::Changed));
                    assert!(every.track.len() > 100, "{file} {name}");
                    let bits = |s: &Scorer| -> Vec<[u64; 3]> {
                        s.track
                            .iter()
                            .map(|(_, e, _)| [e.x.to_bits(), e.y.to_bits(), e.theta.to_bits()])
                            .collect()
                    };
                    assert!(
                        bits(&every) == bits(&changed),
                        "{file} {name} {algorithm} {mode}: skipping a sample changed a pose"
                    );
                }
            }
        }
    }
}
