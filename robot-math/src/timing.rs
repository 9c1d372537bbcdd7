//! `timing`: seed 000's timing method (SPEC §3.3), kept faithful to the paper as a baseline.
//!
//! # What the paper does, and how it is reproduced here
//!
//! * **Wheel speeds from tick times.** The encoder interrupt instants are recorded and each
//!   wheel's speed function is reconstructed from them (abstract); the conclusion names the
//!   rule: the speed is reconstructed by "its mean value between two consecutive time
//!   instants" (and suggests splines instead). The mean speed of a wheel between its two
//!   latest ticks is Δ / (t_k − t_{k−1}) (Δ = the wheel's travel per count), taken with the
//!   direction of the ticks.
//! * **Body twist.** The three measured speeds give the velocity of wheel A's point and the
//!   turn rate in closed form, eqs. 20–23 (the exact 3×3 inverse of the rolling equations
//!   12–14/17). [`WheelSolver`] is that inverse (and its least-squares version for N wheels),
//!   so the twist comes from `solver.solve(speeds)`; the velocity of the tracked point is
//!   v + ω × r.
//! * **Integration.** Eqs. 24–25: `r_A(t) = r_A(0) + ∫ v_A dτ`, `θ(t) = ∫ ω dτ`, where v_A is
//!   A's velocity in the field frame, i.e. the body velocity turned by the current θ
//!   (eqs. 9–11, 15–16). The paper gives no other scheme, so the simple explicit Euler step is
//!   used between consecutive events (each tick instant and each [`update`] call): the velocity
//!   is turned by the heading at the *start* of the step, `r += R(θ_k)·v·dt`,
//!   `θ_{k+1} = θ_k + ω·dt`. The paper integrates **wheel A's point** and obtains the other
//!   points from it with eqs. 1–2; [`TimingOdometry::from_wheels`] does exactly that (wheel
//!   A = `wheels[0]`), as does [`TimingOdometry::with_tracked_point`] for any body point.
//!   [`TimingOdometry::new`] — whose solver does not carry the wheels' positions — tracks the
//!   body origin. The pose returned is always the body origin's, `origin = r − R(θ)·r_body`.
//!
//! # Ambiguities and choices
//!
//! 1. **Which two instants, and where the speed is put in time.** The surviving text only
//!    says "mean value between two consecutive time instants"; SPEC §3.3 paraphrases it as
//!    averaging two consecutive intervals. Read literally it is the mean over *one* interval,
//!    the one between the wheel's two consecutive ticks, Δ/(t_k − t_{k−1}); that is what is
//!    used, and it belongs to that interval (for a steadily changing speed, to its midpoint).
//!    The paper's simulation ran offline (MATLAB), applying each interval's mean over the
//!    interval itself, so each wheel's reconstructed travel between two ticks is exactly Δ.
//!    A causal estimator only learns the mean at t_k. Here, while an interval is open, the
//!    wheel is predicted with the last closed interval's mean (zero-order hold); when the
//!    interval closes (the tick), the travel is *settled* to what the paper's reconstruction
//!    gives for it, Δ in the tick's direction (0 after a reversal: the wheel re-crossed the
//!    edge of its last tick), the difference applied as one Euler step at the tick instant.
//!    So at every tick each wheel's integrated travel equals the paper's; in between it is
//!    the held prediction, and an accelerating wheel lags by about half an interval.
//! 2. **The start.** Seed 000's simulation cuts each path from s = 0, i.e. every encoder sits
//!    on an edge at the start. The first instant the estimator sees (the first `update` or
//!    `tick`) is taken as that edge for every wheel: before a wheel's first tick its speed
//!    is unknown (0), and its first tick settles its first step Δ and gives its first speed.
//! 3. **A wheel that stops.** The paper does not say (offline, a stopped wheel just has no
//!    more samples); holding the last speed would let a stopped wheel run forever. Here a
//!    wheel silent for longer than its last interval must be slower than Δ/(time since its
//!    last tick), so its speed is bounded by that, and its predicted travel since its last
//!    tick is capped at Δ (it cannot have crossed the next edge without ticking). A stopped
//!    wheel therefore adds at most one step of phantom travel.
//! 4. **Reversals.** An interval counts only between two ticks in the same direction; after a
//!    reversal the wheel's speed is 0 until its second tick in the new direction.
//!
//! # Accuracy (what the tests hold it to)
//!
//! For a constant twist driven by exact tick instants (wheel j ticks at k·Δ/|s_j|), after
//! every wheel's first tick (t₁ = max_j Δ/|s_j|) the predicted speeds are exact, and the
//! heading, linear in the settled travels, is exact. The position error is bounded by
//! * the startup: until t₁ the motion is applied late, by at most
//!   `(v_r·t₁ + δp)·(|ω|·t₁ + δθ)` with δθ = Σ|P_ωj|Δ, δp = Σ|P_vj|Δ + |r|·δθ (P the solver's
//!   pseudo-inverse, r the tracked point, v_r its speed);
//! * Euler's heading lag of ω·dt/2 per step over the tracked point's path s:
//!   `s·|ω|·dt_max/2` (dt_max the longest gap between events) — the dominant term on arcs,
//!   and the reason a spin tracked at wheel A (as the paper does) drifts;
//! * the nanosecond rounding of the tick times (≤ 1 ns per interval).
//!
//! Floats throughout: this baseline runs on the host.
//!
//! [`update`]: TimingOdometry::update

use crate::se2::Pose2;
use crate::wheel::Wheel;
use crate::wheelset::{GeometryError, WheelSolver, MAX_WHEELS};

/// One wheel's timing state.
#[derive(Clone, Copy, Debug, Default)]
struct WheelTiming {
    /// Instant of the last tick (or of the start edge).
    last_t: Option<u64>,
    /// Interval between the last two ticks in the same direction (ns).
    interval: Option<u64>,
    /// Direction of the last tick (0 at the start edge: either way forms an interval).
    dir: i8,
    /// Travel estimated since the last tick, metres, magnitude.
    since_tick: f64,
}

/// Seed 000's timing odometry.
#[derive(Clone, Debug)]
pub struct TimingOdometry {
    solver: WheelSolver,
    n: usize,
    delta: [f64; MAX_WHEELS],
    wheels: [WheelTiming; MAX_WHEELS],
    /// The instant integrated up to.
    t_now: Option<u64>,
    /// The tracked point in the body frame, and its field position.
    r_body: (f64, f64),
    px: f64,
    py: f64,
    theta: f64,
}

impl TimingOdometry {
    /// Wheels solved by `solver`, each travelling `metres_per_count[j]` per count, starting at
    /// `start` (the body origin's pose). Tracks the body origin.
    ///
    /// # Panics
    /// If `metres_per_count` does not have one entry per wheel of `solver`.
    pub fn new(solver: WheelSolver, metres_per_count: &[f64], start: Pose2) -> Self {
        let mut t = TimingOdometry {
            solver,
            ..Self::EMPTY
        };
        t.begin(metres_per_count, start);
        t
    }

    /// No wheels, at rest at the origin: what [`init_from_wheels`](Self::init_from_wheels)
    /// fills where the state lives.
    pub(crate) const EMPTY: TimingOdometry = TimingOdometry {
        solver: WheelSolver::EMPTY,
        n: 0,
        delta: [0.0; MAX_WHEELS],
        wheels: [WheelTiming {
            last_t: None,
            interval: None,
            dir: 0,
            since_tick: 0.0,
        }; MAX_WHEELS],
        t_now: None,
        r_body: (0.0, 0.0),
        px: 0.0,
        py: 0.0,
        theta: 0.0,
    };

    /// Everything but the solver, as [`new`](Self::new) sets it.
    fn begin(&mut self, metres_per_count: &[f64], start: Pose2) {
        let n = self.solver.wheels();
        assert_eq!(
            metres_per_count.len(),
            n,
            "one travel per count for each wheel"
        );
        self.n = n;
        self.delta = [0.0; MAX_WHEELS];
        self.delta[..n].copy_from_slice(metres_per_count);
        self.wheels = [WheelTiming::default(); MAX_WHEELS];
        self.t_now = None;
        self.r_body = (0.0, 0.0);
        self.px = start.x;
        self.py = start.y;
        self.theta = start.theta;
    }

    /// Seed 000 as published: the solver of `wheels`, integrating wheel A's point
    /// (`wheels[0]`, eq. 24).
    ///
    /// # Panics
    /// If `metres_per_count` does not have one entry per wheel.
    pub fn from_wheels(
        wheels: &[Wheel],
        metres_per_count: &[f64],
        start: Pose2,
    ) -> Result<Self, GeometryError> {
        let mut t = Self::EMPTY;
        t.init_from_wheels(wheels, metres_per_count, start)?;
        Ok(t)
    }

    /// [`from_wheels`](Self::from_wheels) written where the state lives: each pass of the
    /// 0.9 KB value through a builder would be a copy on a board's stack (the slave with its
    /// baselines). On `Err` the state is not usable.
    pub(crate) fn init_from_wheels(
        &mut self,
        wheels: &[Wheel],
        metres_per_count: &[f64],
        start: Pose2,
    ) -> Result<(), GeometryError> {
        self.solver.init(wheels)?;
        self.begin(metres_per_count, start);
        self.track_point(wheels[0].x, wheels[0].y);
        Ok(())
    }

    /// Integrate the body point `(x, y)` (body frame, metres) instead of the origin, as the
    /// paper does with wheel A (eq. 24). Call before the first tick or update. The pose
    /// returned is still the body origin's.
    pub fn with_tracked_point(mut self, x: f64, y: f64) -> Self {
        self.track_point(x, y);
        self
    }

    /// [`with_tracked_point`](Self::with_tracked_point), in place.
    pub fn track_point(&mut self, x: f64, y: f64) {
        let o = self.pose();
        let (s, c) = (crate::trig::sin(o.theta), crate::trig::cos(o.theta));
        self.r_body = (x, y);
        self.px = o.x + c * x - s * y;
        self.py = o.y + s * x + c * y;
    }

    /// A tick of `encoder` at `t_ns` (step = ±1). Integrates up to `t_ns` first with the
    /// speeds known before the tick. Unknown encoders and other steps are ignored.
    pub fn tick(&mut self, t_ns: u64, encoder: usize, step: i8) {
        self.integrate_to(t_ns);
        if encoder >= self.n || (step != 1 && step != -1) {
            return;
        }
        let delta = self.delta[encoder];
        let w = &mut self.wheels[encoder];
        let same_way = w.dir == step || w.dir == 0;
        w.interval = match w.last_t {
            Some(prev) if same_way && t_ns > prev => Some(t_ns - prev),
            _ => None,
        };
        // Settle the interval that just closed: its mean speed times its length is one step
        // (Δ) in the tick's direction, or nothing after a reversal (the wheel re-crossed the
        // edge of its last tick). What the prediction missed is applied now.
        // A tick at the very instant of the start edge is that edge: no travel yet.
        let is_start_edge = w.dir == 0 && w.last_t == Some(t_ns);
        let predicted = w.dir as f64 * w.since_tick;
        let target = if same_way && !is_start_edge {
            step as f64 * delta
        } else {
            0.0
        };
        w.last_t = Some(t_ns);
        w.dir = step;
        w.since_tick = 0.0;
        let mut travel = [0.0; MAX_WHEELS];
        travel[encoder] = target - predicted;
        self.apply(&travel);
    }

    /// Integrate up to `t_ns` (called at every tick instant and at scoring instants) and
    /// return the pose.
    pub fn update(&mut self, t_ns: u64) -> Pose2 {
        self.integrate_to(t_ns);
        self.pose()
    }

    /// The body origin's pose (θ not wrapped).
    pub fn pose(&self) -> Pose2 {
        let (s, c) = (crate::trig::sin(self.theta), crate::trig::cos(self.theta));
        let (x, y) = self.r_body;
        Pose2::new(
            self.px - (c * x - s * y),
            self.py - (s * x + c * y),
            self.theta,
        )
    }

    /// The current speed estimate of each wheel at `t_ns` (m/s, signed), for inspection.
    pub fn wheel_speed(&self, encoder: usize, t_ns: u64) -> f64 {
        if encoder >= self.n {
            return 0.0;
        }
        self.speed(encoder, t_ns)
    }

    /// Mean speed over the wheel's last interval, bounded by Δ / (time since its last tick).
    fn speed(&self, j: usize, t_ns: u64) -> f64 {
        let w = &self.wheels[j];
        let (Some(last), Some(interval)) = (w.last_t, w.interval) else {
            return 0.0;
        };
        let since = t_ns.saturating_sub(last);
        let dt = since.max(interval) as f64 * 1e-9;
        w.dir as f64 * self.delta[j] / dt
    }

    /// One explicit Euler step from the last instant to `t_ns`.
    fn integrate_to(&mut self, t_ns: u64) {
        let Some(t0) = self.t_now else {
            // The first instant: every encoder is taken to sit on an edge (seed 000's start).
            for w in &mut self.wheels[..self.n] {
                w.last_t = Some(t_ns);
            }
            self.t_now = Some(t_ns);
            return;
        };
        if t_ns <= t0 {
            return;
        }
        let dt = (t_ns - t0) as f64 * 1e-9;
        let mut travel = [0.0; MAX_WHEELS];
        for (j, tr) in travel.iter_mut().enumerate().take(self.n) {
            // Speed bounded at the end of the step (the tighter bound), travel capped at Δ.
            let v = self.speed(j, t_ns);
            let w = &mut self.wheels[j];
            let room = (self.delta[j] - w.since_tick).max(0.0);
            let mag = (libm::fabs(v) * dt).min(room);
            w.since_tick += mag;
            *tr = if v < 0.0 { -mag } else { mag };
        }
        self.apply(&travel);
        self.t_now = Some(t_ns);
    }

    /// One explicit Euler step for the wheels' travels `travel` (speeds × dt): the body
    /// displacement through the solver (linear), the tracked point moved along the heading
    /// at the start of the step, then the heading.
    fn apply(&mut self, travel: &[f64; MAX_WHEELS]) {
        let d = self.solver.solve(&travel[..self.n]);
        let (x, y) = self.r_body;
        // The tracked point's body velocity v + ω × r, times dt.
        let bx = d.vx - d.omega * y;
        let by = d.vy + d.omega * x;
        let (s, c) = (crate::trig::sin(self.theta), crate::trig::cos(self.theta));
        self.px += c * bx - s * by;
        self.py += s * bx + c * by;
        self.theta += d.omega;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Twist;
    use core::f64::consts::PI;

    /// Seed 000's simulated layout: an equilateral triangle of side 20 cm, wheels at the
    /// corners A, B, C, each rolling along its edge (AB, BC, CA) turned by 45°.
    fn seed000_wheels() -> [Wheel; 3] {
        let side = 0.2;
        let rc = side / 3f64.sqrt();
        let corners: [(f64, f64); 3] = core::array::from_fn(|i| {
            let a = PI / 2.0 + i as f64 * 2.0 * PI / 3.0;
            (rc * a.cos(), rc * a.sin())
        });
        core::array::from_fn(|i| {
            let (x, y) = corners[i];
            let (nx, ny) = corners[(i + 1) % 3];
            let edge = (ny - y).atan2(nx - x);
            Wheel::at(x, y, edge + PI / 4.0)
        })
    }

    /// Exact tick instants of wheels with constant rolling speeds: wheel j ticks at
    /// k·Δ/|s_j| (k ≥ 1) up to `t_end` seconds, in the direction of s_j.
    fn tick_stream(wheels: &[Wheel], delta: f64, tw: Twist, t_end: f64) -> Vec<(u64, usize, i8)> {
        let mut ev = Vec::new();
        for (j, w) in wheels.iter().enumerate() {
            let s = w.rolling_speed(tw);
            if s.abs() < 1e-12 {
                continue;
            }
            let dir = if s > 0.0 { 1 } else { -1 };
            let mut k = 1u64;
            loop {
                let t = k as f64 * delta / s.abs();
                if t > t_end {
                    break;
                }
                ev.push(((t * 1e9).round() as u64, j, dir));
                k += 1;
            }
        }
        ev.sort();
        ev
    }

    /// The bound of the module doc for a constant twist: (position bound, heading bound).
    fn bound(
        solver: &WheelSolver,
        wheels: &[Wheel],
        delta: f64,
        tw: Twist,
        t_end: f64,
        r: (f64, f64),
        dt_max: f64,
    ) -> (f64, f64) {
        let p = solver.pseudo_inverse();
        let (mut dth_s, mut dp_s, mut dth_r, mut dp_r, mut t1) = (0.0, 0.0, 0.0, 0.0, 0.0f64);
        for (j, w) in wheels.iter().enumerate() {
            let s = w.rolling_speed(tw).abs();
            if s < 1e-12 {
                continue;
            }
            // Startup: one step per wheel, settled at the wheel's first tick Δ/s.
            dth_s += p[2][j].abs() * delta;
            dp_s += p[0][j].hypot(p[1][j]) * delta;
            t1 = t1.max(delta / s);
            // The tick times' ½ ns rounding: ≤ 1 ns per interval of Δ/s, N = sT/Δ intervals.
            let m = s * t_end / delta * 1e-9 * s;
            dth_r += p[2][j].abs() * m;
            dp_r += p[0][j].hypot(p[1][j]) * m;
        }
        let rn = r.0.hypot(r.1);
        let w = tw.omega.abs();
        let speed = (tw.vx - tw.omega * r.1).hypot(tw.vy + tw.omega * r.0);
        let s_path = speed * t_end;
        let startup = (speed * t1 + dp_s + rn * dth_s) * (w * t1 + dth_s);
        let euler = s_path * w * dt_max / 2.0;
        let rounding = dp_r + dth_r * (s_path + 2.0 * rn);
        (startup + euler + rounding + 1e-12, dth_r + 1e-12)
    }

    fn run(tw: Twist, t_end: f64, delta: f64, track_a: bool) -> (f64, f64) {
        let wheels = seed000_wheels();
        let solver = WheelSolver::new(&wheels).unwrap();
        let start = Pose2::new(0.4, -0.1, 0.3);
        let mut o = TimingOdometry::new(solver, &[delta; 3], start);
        let r = if track_a {
            (wheels[0].x, wheels[0].y)
        } else {
            (0.0, 0.0)
        };
        if track_a {
            o = o.with_tracked_point(r.0, r.1);
        }
        let ev = tick_stream(&wheels, delta, tw, t_end);
        o.update(0);
        let mut prev = 0u64;
        let mut dt_max = 0u64;
        for &(t, j, s) in &ev {
            o.tick(t, j, s);
            o.update(t);
            dt_max = dt_max.max(t - prev);
            prev = t;
        }
        let t_end_ns = (t_end * 1e9) as u64;
        dt_max = dt_max.max(t_end_ns - prev);
        let p = o.update(t_end_ns);
        let want = start.integrate(tw, t_end);
        let (b, b_th) = bound(&solver, &wheels, delta, tw, t_end, r, dt_max as f64 * 1e-9);
        // The heading is linear in the wheels' travels, which are settled exactly at ticks.
        assert!((p.theta - want.theta).abs() <= b_th, "{p:?} vs {want:?}");
        (p.distance_to(want), b)
    }

    #[test]
    fn constant_twists_within_the_stated_bound() {
        let cases = [
            ("straight", Twist::new(0.2, 0.1, 0.0), 2.0),
            ("spin", Twist::new(0.0, 0.0, 1.0), 2.0),
            ("arc", Twist::new(0.3, 0.0, 0.5), 3.0),
            ("arc with sideways drift", Twist::new(0.2, -0.15, -0.8), 2.0),
        ];
        for delta in [0.0001, 0.0004, 0.0008] {
            for (name, tw, t_end) in cases {
                for track_a in [false, true] {
                    let (e, b) = run(tw, t_end, delta, track_a);
                    eprintln!(
                        "{name:24} Δ {:.1} mm, tracking {}: error {e:.3e} m, bound {b:.3e} m",
                        delta * 1e3,
                        if track_a { "A     " } else { "origin" }
                    );
                    assert!(e <= b, "{name} Δ {delta} A {track_a}: {e} > {b}");
                }
            }
        }
    }

    #[test]
    fn spin_about_the_tracked_origin_is_exact() {
        // Pure spin tracked at the origin: the heading is settled exactly at every tick and
        // the origin only wobbles during the startup (before every wheel has ticked).
        let wheels = seed000_wheels();
        let solver = WheelSolver::new(&wheels).unwrap();
        let delta = 0.0004;
        let tw = Twist::new(0.0, 0.0, 2.0);
        let mut o = TimingOdometry::new(solver, &[delta; 3], Pose2::default());
        o.update(0);
        for (t, j, s) in tick_stream(&wheels, delta, tw, 1.0) {
            o.tick(t, j, s);
        }
        let p = o.update(1_000_000_000);
        assert!((p.theta - 2.0).abs() < 1e-6, "{p:?}");
        let (b, _) = bound(&solver, &wheels, delta, tw, 1.0, (0.0, 0.0), 0.0);
        assert!(p.x.hypot(p.y) <= b, "{p:?} vs {b}");
    }

    #[test]
    fn tracking_wheel_a_drifts_in_a_spin_as_the_paper_reports() {
        // Seed 000 integrates wheel A's point with an Euler step: in a spin A runs along its
        // tangents and drifts outwards, the error "grows sharply with rotation".
        let tw = Twist::new(0.0, 0.0, 2.0);
        let (e_origin, _) = run(tw, 2.0, 0.0004, false);
        let (e_a, _) = run(tw, 2.0, 0.0004, true);
        assert!(e_a > 10.0 * e_origin, "{e_a} vs {e_origin}");
    }

    #[test]
    fn a_stopped_wheel_does_not_keep_its_speed() {
        // Straight at 0.2 m/s for 1 s, then the robot stops: no more ticks. Without a bound
        // the last speeds would carry it 2 m further in 10 s.
        let wheels = seed000_wheels();
        let solver = WheelSolver::new(&wheels).unwrap();
        let delta = 0.0004;
        let tw = Twist::new(0.2, 0.0, 0.0);
        let mut o = TimingOdometry::new(solver, &[delta; 3], Pose2::default());
        o.update(0);
        let ev = tick_stream(&wheels, delta, tw, 1.0);
        for &(t, j, s) in &ev {
            o.tick(t, j, s);
        }
        let at_stop = o.update(1_000_000_000);
        let later = o.update(11_000_000_000);
        let much_later = o.update(1_000_000_000_000);
        // At most one step of phantom travel per wheel, then nothing.
        let p = solver.pseudo_inverse();
        let one_step: f64 = (0..3).map(|j| p[0][j].hypot(p[1][j]) * delta).sum();
        assert!(
            later.distance_to(at_stop) <= one_step,
            "{later:?} vs {at_stop:?}"
        );
        assert_eq!(later, much_later);
        assert!(later.distance_to(Pose2::new(0.2, 0.0, 0.0)) < 3.0 * one_step);
        for j in 0..3 {
            assert!(o.wheel_speed(j, 11_000_000_000).abs() < delta / 9.0);
        }
    }

    #[test]
    fn speed_is_the_mean_over_the_last_interval_then_bounded() {
        let wheels = seed000_wheels();
        let solver = WheelSolver::new(&wheels).unwrap();
        let mut o = TimingOdometry::new(solver, &[0.001; 3], Pose2::default());
        o.update(0);
        o.tick(10_000_000, 0, 1); // first interval from the start edge: 10 ms
        assert!((o.wheel_speed(0, 10_000_000) - 0.1).abs() < 1e-12);
        o.tick(14_000_000, 0, 1); // 4 ms
        assert!((o.wheel_speed(0, 15_000_000) - 0.25).abs() < 1e-12);
        // Silent for 8 ms > 4 ms: slower than 1 mm / 8 ms.
        assert!((o.wheel_speed(0, 22_000_000) - 0.125).abs() < 1e-12);
        // A reversal has no speed until its second tick.
        o.tick(30_000_000, 0, -1);
        assert_eq!(o.wheel_speed(0, 30_000_000), 0.0);
        o.tick(32_000_000, 0, -1);
        assert!((o.wheel_speed(0, 32_000_000) + 0.5).abs() < 1e-12);
    }

    #[test]
    fn a_tick_at_the_first_instant_is_the_start_edge() {
        let wheels = seed000_wheels();
        let mut o = TimingOdometry::from_wheels(&wheels, &[0.0004; 3], Pose2::default()).unwrap();
        o.tick(5_000, 1, 1);
        assert_eq!(o.pose(), Pose2::default());
        assert_eq!(o.wheel_speed(1, 5_000), 0.0);
        // The next tick of that wheel is one step and gives its speed.
        o.tick(1_005_000, 1, 1);
        assert!((o.wheel_speed(1, 1_005_000) - 0.4).abs() < 1e-12);
        assert!(o.pose().distance_to(Pose2::default()) > 0.0);
    }

    #[test]
    fn tracked_point_does_not_change_the_start_pose() {
        let wheels = seed000_wheels();
        let solver = WheelSolver::new(&wheels).unwrap();
        let start = Pose2::new(1.0, 2.0, 0.7);
        let o = TimingOdometry::new(solver, &[0.0004; 3], start)
            .with_tracked_point(wheels[0].x, wheels[0].y);
        assert!(o.pose().distance_to(start) < 1e-15 && o.pose().theta == start.theta);
    }
}
