//! The exact tick-stream generator (SPEC §5): what ideal encoders would report while the robot
//! follows a [`Trajectory`].
//!
//! Incremental encoder `i` has rolled `s_i(t) = ∫_0^t rolling_speed_i(twist(τ)) dτ` at time `t`.
//! It powered on at phase φ_i in `[0, 1)` of a count ([`PowerOnPhase`], random by default: real
//! encoders do not start on an edge), so it shows the count `floor((φ_i·step_i + s_i(t)) /
//! step_i)`, 0 at t = 0. It ticks `+1` at the exact instant `φ_i·step_i + s_i` reaches a
//! multiple `m·step` from below and `-1` at the instant it falls below one, so the sum of its
//! ticks up to any time is its count then, and the total is `floor((φ_i·step_i + s_i(T)) /
//! step_i)`.
//!
//! How the instants are found:
//! 1. `[0, T]` is cut at the trajectory's [`breakpoints`](Trajectory::breakpoints) (so the
//!    twist is analytic on every piece) and each piece into equal intervals of at most
//!    [`MAX_INTERVAL_S`] (1 ms). Where the twist jumps at a cut (constant-twist segments), each
//!    interval takes its last sample from the left ([`Trajectory::twist_before`]).
//! 2. On each interval the twist of the wheels' frame is sampled at the 11 Chebyshev–Lobatto
//!    points and interpolated (barycentric formula, degree 10). For an analytic twist on 1 ms
//!    the interpolation error is far below rounding (about (h/τ)^11 for a motion time scale
//!    τ), and every later evaluation is cheap.
//! 3. Where a wheel's rolling speed changes sign between two sample points (the wheel
//!    reverses) the reversal instant is found by bisection on the speed (to [`TIME_TOL_S`])
//!    and the interval is split there, so `s_i` is monotonic on every sub-interval.
//!    **Assumption:** a wheel reverses at most once between two consecutive sample points
//!    (at most 0.16 ms apart); two reversals closer than that could hide a back-and-forth edge
//!    crossing.
//! 4. `s_i` over each sub-interval is the exact integral of the interpolated rolling speed
//!    (the interpolant in Chebyshev form, integrated term by term: `cheb`). The running total is kept with compensated (Neumaier) summation, so 100 s of 1 ms
//!    intervals does not drift.
//! 5. Every multiple of the step between the sub-interval's start and end values is crossed
//!    exactly once; its instant is the root of `s_i(a) + ∫_a^t speed − m·step`, found by
//!    Newton's method (the derivative is the rolling speed itself) safeguarded by bisection
//!    inside the bracket, to [`TIME_TOL_S`] (1 ps). The event time is that instant rounded to
//!    the nearest nanosecond.
//!
//! **Swivel carriage** (seed 004): the measuring wheels ride a trailing caster whose heading φ
//! is not part of the trajectory. It follows the caster equation (see `interp::Frames`): the
//! axle trails the pivot (the body reference point) by `trail_m` and cannot slide sideways. It
//! starts at `start_swivel_rad` from the body (0: aligned). φ is integrated with classic RK4 from one sample
//! point to the next (steps of at most 0.16 ms, local error about (h·v/trail)^5 ≈ 1e-15 rad),
//! using the interpolated velocity of the pivot, and the wheels' rolling speeds are those of
//! the carriage twist (forward speed, 0, φ'). So with a carriage the tick instants are exact
//! for this RK4 solution of the caster. A pivot moving straight towards the axle is the
//! caster's unstable equilibrium: the model keeps it there, a real caster would flip.
//!
//! Absolute encoders are read at `abs_rate_hz` (and at the end): the body heading θ, or the
//! swivel angle φ − θ, as position `round(angle / step) mod 2^bits`, written as the raw output
//! word ([`AbsoluteEncoder::levels`]: Gray code and inversion applied, as the robot file says).
//! Truth rows are written at `truth_rate_hz` and at the very end. Each row's pose or reading is
//! taken at its rounded nanosecond, so rows are exact at their stamped time.

use anyhow::{bail, Context};

use crate::formats::robot::{AbsMeasures, AbsoluteEncoder, Robot};
use crate::formats::tickstream::{Event, TickStream};
use crate::sim::trajectory::{Drive, Trajectory};
use robot_math::wheel::Wheel;

pub use edges::{EdgeErrors, EdgeMap};
use interp::{Frames, Interp};
pub use phase::{phases, PowerOnPhase};
use ticker::{Ticker, WheelMotion};

mod cheb;
mod edges;
mod interp;
mod phase;
mod ticker;

/// Longest integration interval, seconds.
pub const MAX_INTERVAL_S: f64 = 1e-3;
/// Precision of tick and reversal instants before rounding to nanoseconds, seconds.
pub const TIME_TOL_S: f64 = 1e-12;
/// Largest sideways speed (m/s) tolerated on a robot that cannot move sideways.
pub const SIDEWAYS_TOL_M_S: f64 = 1e-9;

/// The fastest truth or absolute-encoder sampling, Hz (a row every 10 µs; time stamps are
/// in ns).
pub const MAX_SAMPLE_RATE_HZ: f64 = 1e5;
/// The most truth and absolute-encoder rows one stream may hold (held in memory while written:
/// about 190 MB resident at this bound).
pub const MAX_SAMPLE_ROWS: f64 = 2e6;

/// The most encoder ticks one stream may hold (about 100 bytes of memory each while made).
pub const MAX_TICKS: f64 = 2e6;

/// An upper bound on the ticks `robot`'s encoders make along `traj`: each rolls at most
/// |v| + |ω|·(its distance from the reference point + the carriage's trail), sampled finely
/// enough for the catalogue's smooth and piecewise-constant motions.
fn tick_bound(robot: &Robot, traj: &dyn Trajectory, trail: f64) -> f64 {
    const SAMPLES: usize = 10_000;
    let dt = traj.duration() / SAMPLES as f64;
    let wheels = robot.encoder_wheels();
    let mut rolled = vec![0.0; wheels.len()];
    for k in 0..SAMPLES {
        let t = traj.twist((k as f64 + 0.5) * dt);
        let v = t.vx.hypot(t.vy);
        for (r, w) in rolled.iter_mut().zip(&wheels) {
            *r += (v + t.omega.abs() * (w.x.hypot(w.y) + trail)) * dt;
        }
    }
    rolled
        .iter()
        .zip(&robot.encoders)
        .map(|(r, e)| (r / e.metres_per_count).ceil() + 1.0)
        .sum()
}

/// Rates of the sampled rows, and where the encoders stand at power-on.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GenerateOptions {
    /// Truth rows per second (plus one at the end).
    pub truth_rate_hz: f64,
    /// Absolute-encoder readings per second (plus one at the end), if the robot has one.
    pub abs_rate_hz: f64,
    /// Where each incremental encoder stands inside its count at t = 0.
    pub phase: PowerOnPhase,
    /// Where the encoders put their edges ([`EdgeErrors`]); each encoder's are drawn from the
    /// power-on phase's seed (0 for a phase that has none).
    pub edges: EdgeErrors,
    /// A carriage's swivel at the start, radians (carriage heading minus body heading): where
    /// the last motion left it, anywhere inside an absolute-encoder code.
    pub start_swivel_rad: f64,
}

impl Default for GenerateOptions {
    /// 100 Hz truth, 1 kHz absolute readings, random phases with seed 0 (as the CLI).
    fn default() -> Self {
        GenerateOptions {
            truth_rate_hz: 100.0,
            abs_rate_hz: 1000.0,
            phase: PowerOnPhase::Random { seed: 0 },
            edges: EdgeErrors::IDEAL,
            start_swivel_rad: 0.0,
        }
    }
}

/// True when the robot cannot move (or its encoders cannot see it move) sideways: every
/// encoder (fixed to the body, not on a swivel carriage), or every drive wheel of a robot that
/// has some, rolls along the body x axis.
pub fn is_differential(robot: &Robot) -> bool {
    let along_x = |w: &Wheel| w.uy.abs() < 1e-9;
    let encoders_along_x = robot.carriage.is_none()
        && !robot.encoders.is_empty()
        && robot.encoders.iter().all(|e| along_x(&e.wheel));
    let drive_along_x =
        !robot.drive_wheels.is_empty() && robot.drive_wheels.iter().all(|d| along_x(&d.wheel));
    encoders_along_x || drive_along_x
}

/// On a differential robot, the x (body frame) of the line across the body that cannot slide
/// sideways: its axle. A point (x, y) of the body moves sideways at v_y + ω·x, so only a
/// robot whose axle passes through the reference point (x = 0) can follow a trajectory with
/// v_y = 0 while turning. The encoders' axle if they roll along x, else the drive wheels' if
/// they share one; 0 (the reference point) when there is no single axle.
fn axle_x(robot: &Robot) -> f64 {
    let common_x = |xs: &mut dyn Iterator<Item = f64>| {
        let xs: Vec<f64> = xs.collect();
        let first = *xs.first()?;
        xs.iter().all(|x| (x - first).abs() < 1e-9).then_some(first)
    };
    let encoders = robot.carriage.is_none()
        && !robot.encoders.is_empty()
        && robot.encoders.iter().all(|e| e.wheel.uy.abs() < 1e-9);
    if encoders {
        if let Some(x) = common_x(&mut robot.encoders.iter().map(|e| e.wheel.x)) {
            return x;
        }
    }
    let drive = robot.drive_wheels.iter().all(|d| d.wheel.uy.abs() < 1e-9);
    if drive {
        if let Some(x) = common_x(&mut robot.drive_wheels.iter().map(|d| d.wheel.x)) {
            return x;
        }
    }
    0.0
}

/// Refuses a holonomic trajectory on a differential robot.
pub fn check_drive(robot: &Robot, drive: Drive) -> anyhow::Result<()> {
    if drive == Drive::Holonomic && is_differential(robot) {
        bail!(
            "robot {} is differential-drive (its wheels all roll along body x) and cannot follow \
             a holonomic trajectory (sideways motion or heading independent of the path); \
             choose one marked differential",
            robot.name
        );
    }
    Ok(())
}

/// The tick stream ideal sensors of `robot` would produce along `traj`. `robot_path_for_header`
/// becomes the stream's `# robot:` line.
pub fn generate(
    robot: &Robot,
    robot_path_for_header: Option<&str>,
    traj: &dyn Trajectory,
    opts: &GenerateOptions,
) -> anyhow::Result<TickStream> {
    let mut streams = generate_phases(robot, robot_path_for_header, traj, opts, &[opts.phase])?;
    streams.pop().context("one stream per phase")
}

/// [`generate`] once for each of `phases` (`opts.phase` is not used), in one pass along the
/// trajectory: the wheels' motion is worked out once and every phase's encoders tick through
/// it, so each stream is the one [`generate`] writes with that phase, for a fraction of the
/// cost (`accuracy` runs every case over many power-on phases).
pub fn generate_phases(
    robot: &Robot,
    robot_path_for_header: Option<&str>,
    traj: &dyn Trajectory,
    opts: &GenerateOptions,
    phase_choices: &[PowerOnPhase],
) -> anyhow::Result<Vec<TickStream>> {
    if robot.encoders.is_empty() {
        bail!(
            "robot {} has no incremental encoders: nothing to generate",
            robot.name
        );
    }
    let abs: Vec<(u16, &AbsoluteEncoder)> = robot
        .absolute_encoders
        .iter()
        .enumerate()
        .map(|(i, a)| (i as u16, a))
        .collect();
    let trail = robot.carriage.map(|c| c.trail_m);
    if let Some(trail) = trail {
        if !(trail.is_finite() && trail > 0.0) {
            bail!(
                "robot {}: the carriage's trail must be > 0 (a trailing caster), got {trail} m",
                robot.name
            );
        }
    } else if let Some((_, a)) = abs
        .iter()
        .find(|(_, a)| a.measures == AbsMeasures::CarriageSwivel)
    {
        bail!(
            "robot {}: absolute encoder {} measures the carriage swivel but there is no carriage",
            robot.name,
            a.name
        );
    }
    for (what, rate) in [
        ("truth_rate_hz", opts.truth_rate_hz),
        ("abs_rate_hz", opts.abs_rate_hz),
    ] {
        if !(rate > 0.0 && rate <= MAX_SAMPLE_RATE_HZ) {
            bail!("{what} must be in (0, {MAX_SAMPLE_RATE_HZ}] Hz, got {rate}");
        }
    }
    let duration = traj.duration();
    if !(duration.is_finite() && duration > 0.0) {
        bail!("the trajectory's duration must be positive and finite, got {duration}");
    }
    // The events are held and written: bounded by what a file of this kind is for, before any
    // is made (about 100 bytes of memory each).
    let abs_rate = if abs.is_empty() {
        0.0
    } else {
        opts.abs_rate_hz * abs.len() as f64
    };
    let rows = duration * (opts.truth_rate_hz + abs_rate);
    if rows > MAX_SAMPLE_ROWS {
        bail!(
            "{rows:.0} truth and absolute-encoder rows over the trajectory's {duration:.1} s: at \
             most {MAX_SAMPLE_ROWS:.0} (lower the rates)"
        );
    }
    let ticks = tick_bound(robot, traj, trail.unwrap_or(0.0)) * phase_choices.len() as f64;
    if ticks > MAX_TICKS {
        bail!(
            "robot {}: up to {ticks:.3e} encoder ticks along {duration:.1} s of this trajectory \
             (its counts are {:.3e} m): at most {MAX_TICKS:.0} in one stream",
            robot.name,
            robot
                .encoders
                .iter()
                .map(|e| e.metres_per_count)
                .fold(f64::INFINITY, f64::min)
        );
    }
    if duration * 1e9 >= u64::MAX as f64 {
        bail!("the trajectory is too long for nanosecond times ({duration} s)");
    }
    let end_ns = to_ns(duration);

    let differential = is_differential(robot);
    let axle = axle_x(robot);
    let phase_sets = phase_choices
        .iter()
        .map(|&p| phases(robot, p))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let abs_times = if abs.is_empty() {
        Vec::new()
    } else {
        sample_times(end_ns, opts.abs_rate_hz)
    };
    // The carriage heading at each abs time (with a carriage).
    let mut swivel_phi: Vec<f64> = Vec::new();
    let mut frames = Frames {
        traj,
        trail,
        phi: traj.pose(0.0).theta + opts.start_swivel_rad,
    };
    let wheels = robot.encoder_wheels();
    let mut tickers: Vec<Ticker> = phase_sets
        .iter()
        .zip(phase_choices)
        .map(|(p, choice)| Ticker::new(robot, p, edge_maps(robot, &opts.edges, *choice)))
        .collect();
    let mut cuts: Vec<f64> = traj
        .breakpoints()
        .into_iter()
        .filter(|&b| b > 0.0 && b < duration)
        .collect();
    cuts.push(0.0);
    cuts.push(duration);
    cuts.sort_by(f64::total_cmp);
    cuts.dedup();
    for piece in cuts.windows(2) {
        let (a, b) = (piece[0], piece[1]);
        let n = ((b - a) / MAX_INTERVAL_S).ceil().max(1.0) as usize;
        let h = (b - a) / n as f64;
        for j in 0..n {
            let t0 = a + h * j as f64;
            let t1 = if j + 1 == n {
                b
            } else {
                a + h * (j + 1) as f64
            };
            if t1 <= t0 {
                continue;
            }
            let body = Interp::sample(t0, t1, |t, at_end| {
                // The interval ends at a cut or inside a piece: either way its last sample
                // belongs to it, not to the piece that may start there with another twist.
                let w = if at_end {
                    traj.twist_before(t)
                } else {
                    traj.twist(t)
                };
                [w.vx, w.vy, w.omega, 0.0]
            });
            for (t, w) in body.t.iter().zip(&body.v) {
                if !w.iter().all(|x| x.is_finite()) {
                    bail!("the trajectory's twist at t = {t} s is not finite: {w:?}");
                }
                let sideways = w[1] + w[2] * axle;
                if differential && sideways.abs() > SIDEWAYS_TOL_M_S {
                    if axle == 0.0 {
                        bail!(
                            "the trajectory moves sideways (v_y = {} m/s at t = {t:.6} s) but \
                             robot {} is differential-drive (its wheels all roll along body x)",
                            w[1],
                            robot.name
                        );
                    }
                    bail!(
                        "the trajectory moves the axle of robot {} sideways (v_y + ω·x = \
                         {sideways} m/s at its axle, x = {axle} m, t = {t:.6} s): a \
                         differential-drive robot's axle cannot slide; a trajectory with v_y = 0 \
                         that turns needs the reference point on the axle line",
                        robot.name
                    );
                }
            }
            let frame = frames.interval(body);
            if trail.is_some() {
                while let Some(&t_ns) = abs_times.get(swivel_phi.len()) {
                    let t = t_ns as f64 * 1e-9;
                    if t > t1 && t1 < duration {
                        break;
                    }
                    swivel_phi.push(frame.eval(t.clamp(t0, t1))[3]);
                }
            }
            let motion = WheelMotion::of(&wheels, &frame);
            for ticker in &mut tickers {
                ticker.interval(&motion);
            }
        }
    }

    let mut events = Vec::new();
    for t_ns in sample_times(end_ns, opts.truth_rate_hz) {
        let p = traj.pose(t_ns as f64 * 1e-9);
        if !(p.x.is_finite() && p.y.is_finite() && p.theta.is_finite()) {
            bail!("the trajectory's pose at {t_ns} ns is not finite: {p:?}");
        }
        events.push(Event::Truth {
            t_ns,
            x_m: p.x,
            y_m: p.y,
            theta_rad: p.theta,
        });
    }
    for (k, &t_ns) in abs_times.iter().enumerate() {
        let theta = traj.pose(t_ns as f64 * 1e-9).theta;
        for &(id, a) in &abs {
            let angle = match a.measures {
                AbsMeasures::BodyHeading => theta,
                // Only with a carriage (checked above).
                AbsMeasures::CarriageSwivel => {
                    swivel_phi.get(k).copied().unwrap_or(frames.phi) - theta
                }
            };
            events.push(Event::Abs {
                t_ns,
                encoder: id,
                code: abs_code(a, angle),
            });
        }
    }

    let mut comments = vec![
        "generator: omnibench exact tick generator (crossings by root finding, rounded to 1 ns)"
            .to_string(),
        format!(
            "duration_s: {duration}; truth_rate_hz: {}; abs_rate_hz: {}",
            opts.truth_rate_hz, opts.abs_rate_hz
        ),
    ];
    if let Some(trail) = trail {
        comments.push(format!(
            "carriage: trailing caster, trail {trail} m, swivel {} deg at the start, \
             heading integrated with RK4",
            opts.start_swivel_rad.to_degrees()
        ));
    }
    let mut streams = Vec::new();
    for ((ticks, phase), choice) in tickers.iter_mut().zip(&phase_sets).zip(phase_choices) {
        let mut comments = comments.clone();
        let each: Vec<String> = robot
            .encoders
            .iter()
            .zip(phase)
            .enumerate()
            .map(|(i, (e, p))| format!("encoder {i} ({}) at {p:.6} of a count", e.name))
            .collect();
        comments.push(format!("power-on phase: {choice}; {}", each.join(", ")));
        if !opts.edges.is_ideal() {
            comments.push(edges_comment(&opts.edges, &ticks.edges));
        }
        for (i, (e, (s, count))) in robot.encoders.iter().zip(&ticks.totals()).enumerate() {
            comments.push(format!(
                "encoder {i} ({}): rolled {s:.9} m, {count} counts",
                e.name
            ));
        }
        let mut events = events.clone();
        events.append(&mut ticks.events);
        // Stable: each encoder's ticks are already in time order; ties keep truth, abs, ticks.
        events.sort_by_key(Event::t_ns);
        streams.push(TickStream {
            robot: robot_path_for_header.map(str::to_string),
            comments,
            events,
        });
    }
    Ok(streams)
}

/// Each encoder's edges: drawn from `errors` with the power-on phase's seed.
fn edge_maps(robot: &Robot, errors: &EdgeErrors, phase: PowerOnPhase) -> Vec<EdgeMap> {
    let seed = match phase {
        PowerOnPhase::Random { seed } => seed,
        PowerOnPhase::Zero | PowerOnPhase::Fraction(_) => 0,
    };
    robot
        .encoders
        .iter()
        .enumerate()
        .map(|(i, e)| EdgeMap::draw(errors, seed, i, e.metres_per_count))
        .collect()
}

/// The stream's record of its encoders' edges: what a reader that learns them can be
/// checked against (a comment: readers of the format skip it).
fn edges_comment(errors: &EdgeErrors, maps: &[EdgeMap]) -> String {
    let each: Vec<String> = maps
        .iter()
        .enumerate()
        .map(|(i, m)| {
            format!(
                "encoder {i} power-on state {} edges [{:+.4} {:+.4} {:+.4} {:+.4}] counts",
                m.q0, m.cycle_edges[0], m.cycle_edges[1], m.cycle_edges[2], m.cycle_edges[3]
            )
        })
        .collect();
    format!(
        "encoder edges: {errors} (state width {} °e, pulse width {} °e, phase {} °e, cycle {} \
         °e, position {} arcmin over {} counts, runout {} m, capture latency up to {} ns, slip \
         {}); {}",
        errors.state_width_error_deg_e,
        errors.pulse_width_error_deg_e,
        errors.phase_error_deg_e,
        errors.cycle_error_deg_e,
        errors.position_error_arcmin,
        errors.counts_per_rev,
        errors.wheel_runout_m,
        errors.capture_jitter_ns,
        errors.slip,
        each.join(", ")
    )
}

fn to_ns(t: f64) -> u64 {
    (t * 1e9).round().max(0.0) as u64
}

/// `round(k·1e9 / rate)` for every k while at most `end_ns`, and `end_ns` itself.
fn sample_times(end_ns: u64, rate_hz: f64) -> Vec<u64> {
    let mut out = Vec::new();
    let mut k = 0u64;
    loop {
        let t = (k as f64 * 1e9 / rate_hz).round() as u64;
        if t > end_ns {
            break;
        }
        out.push(t);
        k += 1;
    }
    if out.last() != Some(&end_ns) {
        out.push(end_ns);
    }
    out
}

/// The raw code an ideal absolute encoder shows at heading `theta`.
pub fn abs_code(a: &AbsoluteEncoder, theta: f64) -> u32 {
    let n = a.positions() as i64;
    let k = (theta / a.step_rad()).round() as i64;
    a.levels(k.rem_euclid(n) as u16) as u32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sample_times_end_with_the_end() {
        assert_eq!(
            sample_times(25_000_000, 100.0),
            vec![0, 10_000_000, 20_000_000, 25_000_000]
        );
        assert_eq!(
            sample_times(20_000_000, 100.0),
            vec![0, 10_000_000, 20_000_000]
        );
    }

    /// `accuracy` makes its seeds' streams a few at a time: a seed's stream must not depend on
    /// which others share its pass.
    #[test]
    fn a_seeds_stream_is_the_same_in_any_pass() {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../robots/seed001.toml");
        let robot = Robot::load(&path).unwrap();
        let traj = crate::sim::trajectory::build("twist-arcs").unwrap();
        let opts = GenerateOptions::default();
        let phase = |seed| PowerOnPhase::Random { seed };
        let together = generate_phases(
            &robot,
            None,
            traj.as_ref(),
            &opts,
            &[phase(0), phase(1), phase(2)],
        )
        .unwrap();
        let apart = [
            generate_phases(&robot, None, traj.as_ref(), &opts, &[phase(0)]).unwrap(),
            generate_phases(&robot, None, traj.as_ref(), &opts, &[phase(1), phase(2)]).unwrap(),
        ]
        .concat();
        assert_eq!(together.len(), 3);
        assert!(together == apart, "the streams differ");
    }
}
