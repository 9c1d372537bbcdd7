//! The exact tick-stream generator (SPEC §5): what ideal encoders would report while the robot
//! follows a [`Trajectory`].
//!
//! Incremental encoder `i` has rolled `s_i(t) = ∫_0^t rolling_speed_i(twist(τ)) dτ` at time `t`
//! and shows the count `floor(s_i(t) / step_i)`. It ticks `+1` at the exact instant `s_i`
//! reaches a multiple `m·step` from below and `-1` at the instant it falls below one, so the sum
//! of its ticks up to any time is its count then, and the total is `floor(s_i(T) / step_i)`.
//!
//! How the instants are found:
//! 1. `[0, T]` is cut at the trajectory's [`breakpoints`](Trajectory::breakpoints) (so the
//!    twist is analytic on every piece) and each piece into equal intervals of at most
//!    [`MAX_INTERVAL_S`] (1 ms).
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
//! 4. `s_i` over each sub-interval is 5-point Gauss–Legendre quadrature of the rolling speed.
//!    The running total is kept with compensated (Neumaier) summation, so 100 s of 1 ms
//!    intervals does not drift.
//! 5. Every multiple of the step between the sub-interval's start and end values is crossed
//!    exactly once; its instant is the root of `s_i(a) + ∫_a^t speed − m·step`, found by
//!    Newton's method (the derivative is the rolling speed itself) safeguarded by bisection
//!    inside the bracket, to [`TIME_TOL_S`] (1 ps). The event time is that instant rounded to
//!    the nearest nanosecond.
//!
//! **Swivel carriage** (seed 004): the measuring wheels ride a trailing caster whose heading φ
//! is not part of the trajectory. It follows the caster equation (see `Frames` below): the
//! axle trails the pivot (the body reference point) by `trail_m` and cannot slide sideways. It
//! starts aligned with the body (swivel 0). φ is integrated with classic RK4 from one sample
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

use anyhow::bail;

use crate::formats::robot::{AbsMeasures, AbsoluteEncoder, Robot};
use crate::formats::tickstream::{Event, TickStream};
use crate::sim::trajectory::{gl5, Drive, Trajectory};
use robot_math::wheel::Wheel;

/// Longest integration interval, seconds.
pub const MAX_INTERVAL_S: f64 = 1e-3;
/// Precision of tick and reversal instants before rounding to nanoseconds, seconds.
pub const TIME_TOL_S: f64 = 1e-12;
/// Largest sideways speed (m/s) tolerated on a robot that cannot move sideways.
pub const SIDEWAYS_TOL_M_S: f64 = 1e-9;

/// Rates of the sampled rows.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GenerateOptions {
    /// Truth rows per second (plus one at the end).
    pub truth_rate_hz: f64,
    /// Absolute-encoder readings per second (plus one at the end), if the robot has one.
    pub abs_rate_hz: f64,
}

impl Default for GenerateOptions {
    fn default() -> Self {
        GenerateOptions {
            truth_rate_hz: 100.0,
            abs_rate_hz: 1000.0,
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
        if !(rate.is_finite() && rate > 0.0) {
            bail!("{what} must be a positive number, got {rate}");
        }
    }
    let duration = traj.duration();
    if !(duration.is_finite() && duration > 0.0) {
        bail!("the trajectory's duration must be positive and finite, got {duration}");
    }
    if duration * 1e9 >= u64::MAX as f64 {
        bail!("the trajectory is too long for nanosecond times ({duration} s)");
    }
    let end_ns = to_ns(duration);

    let differential = is_differential(robot);
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
        phi: traj.pose(0.0).theta,
    };
    let mut ticks = Ticker::new(robot);
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
            let body = Interp::sample(t0, t1, |t| {
                let w = traj.twist(t);
                [w.vx, w.vy, w.omega, 0.0]
            });
            for (t, w) in body.t.iter().zip(&body.v) {
                if !w.iter().all(|x| x.is_finite()) {
                    bail!("the trajectory's twist at t = {t} s is not finite: {w:?}");
                }
                if differential && w[1].abs() > SIDEWAYS_TOL_M_S {
                    bail!(
                        "the trajectory moves sideways (v_y = {} m/s at t = {t:.6} s) but robot {} \
                         is differential-drive (its wheels all roll along body x)",
                        w[1],
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
            ticks.interval(&frame);
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

    let rolled = ticks.rolled();
    events.append(&mut ticks.events);
    // Stable: each encoder's ticks are already in time order; ties keep truth, abs, ticks.
    events.sort_by_key(Event::t_ns);

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
            "carriage: trailing caster, trail {trail} m, swivel 0 at the start, \
             heading integrated with RK4"
        ));
    }
    for (i, (e, s)) in robot.encoders.iter().zip(&rolled).enumerate() {
        comments.push(format!(
            "encoder {i} ({}): rolled {s:.9} m, {} counts",
            e.name,
            (s / e.metres_per_count).floor()
        ));
    }
    Ok(TickStream {
        robot: robot_path_for_header.map(str::to_string),
        comments,
        events,
    })
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

/// Sample points per interval: Chebyshev–Lobatto, degree 10.
const SAMPLES: usize = 11;

/// A polynomial interpolant on one interval of four quantities: the wheels' frame twist
/// (v_x, v_y, ω) and, with a carriage, its heading φ.
struct Interp {
    /// Sample points, increasing, from the interval's start to its end.
    t: [f64; SAMPLES],
    v: [[f64; 4]; SAMPLES],
}

impl Interp {
    fn points(t0: f64, t1: f64) -> [f64; SAMPLES] {
        let (m, r) = (0.5 * (t0 + t1), 0.5 * (t1 - t0));
        let n = (SAMPLES - 1) as f64;
        let mut t: [f64; SAMPLES] =
            std::array::from_fn(|j| m - r * (std::f64::consts::PI * j as f64 / n).cos());
        t[0] = t0;
        t[SAMPLES - 1] = t1;
        t
    }

    fn sample(t0: f64, t1: f64, f: impl FnMut(f64) -> [f64; 4]) -> Interp {
        let t = Interp::points(t0, t1);
        Interp { t, v: t.map(f) }
    }

    /// The interpolant at `t` (barycentric formula; Chebyshev–Lobatto weights (−1)^j, halved
    /// at both ends).
    fn eval(&self, t: f64) -> [f64; 4] {
        let mut num = [0.0; 4];
        let mut den = 0.0;
        for j in 0..SAMPLES {
            let d = t - self.t[j];
            if d == 0.0 {
                return self.v[j];
            }
            let mut w = if j % 2 == 0 { 1.0 } else { -1.0 };
            if j == 0 || j == SAMPLES - 1 {
                w *= 0.5;
            }
            let q = w / d;
            den += q;
            for (n, v) in num.iter_mut().zip(&self.v[j]) {
                *n += q * v;
            }
        }
        num.map(|n| n / den)
    }
}

/// The frame the encoders' wheels are in: the body, or a trailing swivel carriage whose
/// heading φ follows the caster equation. The pivot is the body reference point P; the axle
/// midpoint trails it by `trail` and cannot slide sideways, so with P's field velocity w,
/// φ' = (−sin φ·w_x + cos φ·w_y) / trail and the carriage moves forward at
/// cos φ·w_x + sin φ·w_y (the same model as the emulator's plant). φ(0) = θ(0): the swivel
/// angle is 0 at the start.
struct Frames<'a> {
    traj: &'a dyn Trajectory,
    trail: Option<f64>,
    /// Carriage heading at the end of the last interval.
    phi: f64,
}

impl Frames<'_> {
    /// The wheels' frame over the interval that `body` (the body twist) samples; intervals
    /// come in order, each starting where the last ended.
    fn interval(&mut self, body: Interp) -> Interp {
        let Some(trail) = self.trail else {
            return body;
        };
        // The pivot's field velocity at the sample points, and its interpolant.
        let world = Interp {
            t: body.t,
            v: std::array::from_fn(|j| {
                let theta = self.traj.pose(body.t[j]).theta;
                let (s, c) = theta.sin_cos();
                let [vx, vy, _, _] = body.v[j];
                [c * vx - s * vy, s * vx + c * vy, 0.0, 0.0]
            }),
        };
        let rate = |w: [f64; 4], phi: f64| {
            let (sp, cp) = phi.sin_cos();
            ((-sp * w[0] + cp * w[1]) / trail, cp * w[0] + sp * w[1])
        };
        // RK4 from one sample point to the next.
        let mut phi = [0.0; SAMPLES];
        phi[0] = self.phi;
        for j in 0..SAMPLES - 1 {
            let (ta, tb) = (world.t[j], world.t[j + 1]);
            let h = tb - ta;
            let mid = world.eval(0.5 * (ta + tb));
            let k1 = rate(world.v[j], phi[j]).0;
            let k2 = rate(mid, phi[j] + 0.5 * h * k1).0;
            let k3 = rate(mid, phi[j] + 0.5 * h * k2).0;
            let k4 = rate(world.v[j + 1], phi[j] + h * k3).0;
            phi[j + 1] = phi[j] + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
        }
        self.phi = phi[SAMPLES - 1];
        Interp {
            t: body.t,
            v: std::array::from_fn(|j| {
                let (phi_dot, forward) = rate(world.v[j], phi[j]);
                [forward, 0.0, phi_dot, phi[j]]
            }),
        }
    }
}

/// A running sum with Neumaier compensation.
#[derive(Clone, Copy, Debug, Default)]
struct Sum {
    hi: f64,
    lo: f64,
}

impl Sum {
    fn add(&mut self, x: f64) {
        let t = self.hi + x;
        if self.hi.abs() >= x.abs() {
            self.lo += (self.hi - t) + x;
        } else {
            self.lo += (x - t) + self.hi;
        }
        self.hi = t;
    }
    fn value(&self) -> f64 {
        self.hi + self.lo
    }
    /// `self − e`, without losing the compensation.
    fn minus(&self, e: f64) -> f64 {
        (self.hi - e) + self.lo
    }
}

struct Ticker {
    wheels: Vec<Wheel>,
    steps: Vec<f64>,
    rolled: Vec<Sum>,
    events: Vec<Event>,
}

impl Ticker {
    fn new(robot: &Robot) -> Ticker {
        Ticker {
            wheels: robot.encoder_wheels(),
            steps: robot.encoders.iter().map(|e| e.metres_per_count).collect(),
            rolled: vec![Sum::default(); robot.encoders.len()],
            events: Vec::new(),
        }
    }

    fn rolled(&self) -> Vec<f64> {
        self.rolled.iter().map(Sum::value).collect()
    }

    /// Advances every encoder over the interval of `frame` (the twist of the wheels' frame).
    fn interval(&mut self, frame: &Interp) {
        let (t0, t1) = (frame.t[0], frame.t[SAMPLES - 1]);
        for i in 0..self.wheels.len() {
            let row = self.wheels[i].row();
            let speed = |v: &[f64; 4]| row[0] * v[0] + row[1] * v[1] + row[2] * v[2];
            let rate = |t: f64| speed(&frame.eval(t));
            let speeds = frame.v.map(|v| speed(&v));
            // Reversals: where the sign of the speed changes between non-zero samples.
            let mut splits = Vec::new();
            let mut last: Option<usize> = None;
            for k in 0..SAMPLES {
                if speeds[k] == 0.0 {
                    continue;
                }
                if let Some(l) = last {
                    if (speeds[l] > 0.0) != (speeds[k] > 0.0) {
                        splits.push(bisect_sign(&rate, frame.t[l], frame.t[k], speeds[l] > 0.0));
                    }
                }
                last = Some(k);
            }
            let mut a = t0;
            for b in splits.into_iter().chain(std::iter::once(t1)) {
                if b > a {
                    let ds = gl5(a, b, rate);
                    self.piece(i, &rate, a, b, ds);
                    a = b;
                }
            }
        }
    }

    /// Encoder `i` rolls `ds` monotonically over `[a, b]`: emit its edge crossings.
    fn piece(&mut self, i: usize, rate: &dyn Fn(f64) -> f64, a: f64, b: f64, ds: f64) {
        let step = self.steps[i];
        let start = self.rolled[i];
        let mut end = start;
        end.add(ds);
        let c0 = (start.value() / step).floor() as i64;
        let c1 = (end.value() / step).floor() as i64;
        self.rolled[i] = end;
        if c0 == c1 {
            return;
        }
        let up = c1 > c0;
        let dir = if up { 1.0 } else { -1.0 };
        let edges: Box<dyn Iterator<Item = i64>> = if up {
            Box::new(c0 + 1..=c1)
        } else {
            Box::new((c1 + 1..=c0).rev())
        };
        // g(t) = dir·(s(t) − edge): negative before the crossing, ≥ 0 after it. At `a` it is
        // dir·base; at the previous crossing about −step; at `b` dir·(base + ds).
        let mut lo = a;
        for m in edges {
            let edge = m as f64 * step;
            let base = start.minus(edge);
            let g = |t: f64| dir * (base + gl5(a, t, rate));
            let g_lo = if lo == a { dir * base } else { -step };
            let g_hi = dir * (base + ds);
            let t = find_crossing(&g, &|t| dir * rate(t), (lo, g_lo), (b, g_hi));
            self.events.push(Event::Tick {
                t_ns: to_ns(t),
                encoder: i as u16,
                step: if up { 1 } else { -1 },
            });
            lo = t;
        }
    }
}

/// The first instant in `[lo, hi]` where the non-decreasing `g` reaches 0, given `g` at both
/// ends (if `g(lo) ≥ 0` already, `lo`; if `g(hi) < 0`, `hi`). Newton's method with derivative
/// `dg`, safeguarded by bisection: every iterate stays inside the shrinking bracket.
fn find_crossing(
    g: &dyn Fn(f64) -> f64,
    dg: &dyn Fn(f64) -> f64,
    (lo, g_lo): (f64, f64),
    (hi, g_hi): (f64, f64),
) -> f64 {
    let (mut lo, mut hi) = (lo, hi);
    if g_lo >= 0.0 {
        return lo;
    }
    if g_hi < 0.0 {
        // Rounding put the edge past the end of the piece: it is crossed at its very end.
        return hi;
    }
    // Start from the secant guess.
    let mut t = lo + (hi - lo) * (-g_lo / (g_hi - g_lo));
    for _ in 0..200 {
        if !(t > lo && t < hi) {
            t = 0.5 * (lo + hi);
        }
        let gt = g(t);
        if gt >= 0.0 {
            hi = t;
        } else {
            lo = t;
        }
        if hi - lo <= TIME_TOL_S {
            break;
        }
        let d = dg(t);
        let next = if d > 0.0 { t - gt / d } else { f64::NAN };
        if next > lo && next < hi {
            if (next - t).abs() <= TIME_TOL_S {
                return next;
            }
            t = next;
        } else {
            t = 0.5 * (lo + hi);
        }
    }
    hi
}

/// Where `rate` changes sign in `[a, b]` (positive at `a` iff `positive_at_a`), by bisection.
fn bisect_sign(rate: &dyn Fn(f64) -> f64, a: f64, b: f64, positive_at_a: bool) -> f64 {
    let (mut lo, mut hi) = (a, b);
    while hi - lo > TIME_TOL_S {
        let mid = 0.5 * (lo + hi);
        if mid <= lo || mid >= hi {
            break;
        }
        let r = rate(mid);
        if r != 0.0 && (r > 0.0) == positive_at_a {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crossing_of_a_line_is_exact() {
        // g(t) = 0.3·t − 0.1: root 1/3.
        let t = find_crossing(&|t| 0.3 * t - 0.1, &|_| 0.3, (0.0, -0.1), (1.0, 0.2));
        assert!((t - 1.0 / 3.0).abs() < 1e-12, "{t}");
        // Non-linear: g = t³ − 0.2 on [0, 1].
        let t = find_crossing(
            &|t| t * t * t - 0.2,
            &|t| 3.0 * t * t,
            (0.0, -0.2),
            (1.0, 0.8),
        );
        assert!((t - 0.2f64.cbrt()).abs() < 1e-12, "{t}");
    }

    #[test]
    fn compensated_sum_does_not_drift() {
        let mut s = Sum::default();
        for _ in 0..100_000 {
            s.add(0.0004);
        }
        assert!((s.value() - 40.0).abs() < 1e-13, "{}", s.value());
    }

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
}
