//! [`Odometry`]: one estimator over a [`Layout`], any [`Method`], either [`SensorKind`].

use core::mem::MaybeUninit;

use super::{Layout, Method, SensorKind, Unsupported};
use crate::carriage::CarriageExact;
use crate::exact::{ExactOdometry, FixedPose, MAX_ENCODERS};
use crate::ticks::{learn_edges, tick_wheel, RecentTicks, TickTracker};
use crate::wheelset::GeometryError;

// The float baselines (`arc`, `lut`, `timing`): the host always has them; a slave image only
// with its `baselines` feature (they are 10 KB of its flash, soft-float routines included).
#[cfg(any(test, feature = "float-methods"))]
mod float_methods;
#[cfg(any(test, feature = "float-methods"))]
use float_methods::{FloatMethod, FloatState};

/// The running method's state. One at a time; the float methods are the big ones (their wheel
/// solvers), which is RAM spent once, not per update.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug)]
enum State {
    Exact(ExactState),
    #[cfg(any(test, feature = "float-methods"))]
    Float(FloatState),
}

impl State {
    /// `exact`'s state, if `exact` is the method running.
    fn exact_mut(&mut self) -> Option<&mut ExactState> {
        match self {
            State::Exact(e) => Some(e),
            #[cfg(any(test, feature = "float-methods"))]
            State::Float(_) => None,
        }
    }

    fn is_exact(&self) -> bool {
        match self {
            State::Exact(_) => true,
            #[cfg(any(test, feature = "float-methods"))]
            State::Float(_) => false,
        }
    }
}

#[derive(Clone, Copy, Debug)]
enum ExactState {
    /// Wheels fixed to the body.
    Body(ExactOdometry),
    /// Seed 004's swivel carriage.
    Carriage(CarriageExact),
}

/// One odometry estimator: a [`Layout`], the running [`Method`], the sensor readings.
///
/// Feed it [`tick`](Self::tick)s ([`SensorKind::Ticks`]) or [`set_counts`](Self::set_counts)
/// ([`SensorKind::Counts`]), and [`set_abs`](Self::set_abs) with a carriage; call
/// [`update`](Self::update) at the fixed rate. Readings of the other sensor kind are
/// ignored. No heap, no panics; with [`Method::Exact`] everything on the update path
/// ([`tick`](Self::tick)'s bookkeeping, [`set_counts`](Self::set_counts),
/// [`set_abs`](Self::set_abs), [`update`](Self::update), [`set_pose`](Self::set_pose)) is
/// integer-only. Starting or switching a method uses floats once (the float methods' solvers).
#[derive(Clone, Debug)]
pub struct Odometry {
    layout: Layout,
    method: Method,
    sensors: SensorKind,
    /// Ticks mode: each wheel's tick history (interpolation between ticks).
    trackers: [TickTracker; MAX_ENCODERS],
    /// Ticks mode with `exact`: each placed wheel's ticks since the last update, put through
    /// its tracker when its position is next needed (an edge then costs a count and a store;
    /// the result is the same to the bit, see [`RecentTicks`]).
    recent: [RecentTicks; MAX_ENCODERS],
    /// Ticks mode with `exact` running: placed wheels' ticks wait in `recent`.
    keep_edges: bool,
    /// Cumulative whole counts (zero past the layout's encoders).
    counts: [i64; MAX_ENCODERS],
    /// What `exact` saw of each wheel at the last update, Q16 counts (zero past the layout's
    /// encoders). Written in place each update: a local array returned or zeroed is a
    /// `memcpy` or `memclr` call at opt-level "z".
    positions: [i64; MAX_ENCODERS],
    /// Absolute encoder position (decoded), 0 without one.
    abs: u16,
    pose: FixedPose,
    /// Where seed 001's unsigned coordinate square has the field origin.
    lut_origin: (u32, u32),
    state: State,
}

impl Odometry {
    /// Start `method` at `start` at `t_ns`, with the encoders at `counts` (cumulative whole
    /// counts; entries past the layout's encoders are ignored) and the absolute encoder's raw
    /// output `abs_code` (`None`: none read yet, position 0).
    ///
    /// Returns the estimator by value (1.3 KB with a carriage): on the host that costs nothing,
    /// but on a 20 KiB board build it in place instead ([`init`](Self::init) into its static
    /// cell, then [`restart`](Self::restart)), which is what this does on a local slot.
    pub fn new(
        layout: &Layout,
        method: Method,
        sensors: SensorKind,
        start: FixedPose,
        t_ns: u64,
        counts: [i64; MAX_ENCODERS],
        abs_code: Option<u16>,
    ) -> Result<Odometry, Unsupported> {
        let mut slot = MaybeUninit::uninit();
        Odometry::init(&mut slot, layout)
            .restart(layout, method, sensors, start, t_ns, &counts, abs_code)?;
        // SAFETY: `init` wrote every field.
        Ok(unsafe { slot.assume_init() })
    }

    /// Build an estimator in place in `slot` (a static cell on a board: nothing of it passes
    /// through the stack), as a start for [`restart`](Self::restart): `exact` over `layout`
    /// at the origin at time 0, every count 0, the counters' way. Cannot fail.
    pub fn init<'a>(slot: &'a mut MaybeUninit<Odometry>, layout: &Layout) -> &'a mut Odometry {
        crate::init_in_place!(
            slot,
            Odometry {
                layout: *layout,
                method: Method::Exact,
                sensors: SensorKind::Counts,
                trackers: [TickTracker::starting(0, 0); MAX_ENCODERS],
                recent: [RecentTicks::default(); MAX_ENCODERS],
                keep_edges: false,
                counts: [0; MAX_ENCODERS],
                positions: [0; MAX_ENCODERS],
                abs: 0,
                pose: FixedPose::default(),
                lut_origin: (
                    crate::lut::DEFAULT_ORIGIN_LSB,
                    crate::lut::DEFAULT_ORIGIN_LSB,
                ),
                state: State::Exact(ExactState::Body(ExactOdometry::new(
                    *layout.exact(),
                    FixedPose::default(),
                    &[0; MAX_ENCODERS],
                ))),
            }
        )
    }

    /// Start again, in place, as [`new`](Self::new) would have started: `method` over
    /// `layout` at `start` at `t_ns`, the encoders at `counts`, the absolute encoder's raw
    /// output `abs_code`. Nothing larger than the method's state (a few hundred bytes) is
    /// built on the stack.
    ///
    /// On `Err` (a method this build or this layout cannot run) the readings are the new
    /// ones and `exact` runs instead, from `start`; `exact` runs any layout that
    /// [`Layout`]'s checks let through.
    #[allow(clippy::too_many_arguments)]
    pub fn restart(
        &mut self,
        layout: &Layout,
        method: Method,
        sensors: SensorKind,
        start: FixedPose,
        t_ns: u64,
        counts: &[i64; MAX_ENCODERS],
        abs_code: Option<u16>,
    ) -> Result<(), Unsupported> {
        self.layout = *layout;
        self.restart_on_own_layout(method, sensors, start, t_ns, counts, abs_code)
    }

    /// [`restart`](Self::restart) on the layout it runs already (a copy of which, to pass
    /// it, would be 320 B of a board's stack).
    #[inline(never)]
    pub fn restart_on_own_layout(
        &mut self,
        method: Method,
        sensors: SensorKind,
        start: FixedPose,
        t_ns: u64,
        counts: &[i64; MAX_ENCODERS],
        abs_code: Option<u16>,
    ) -> Result<(), Unsupported> {
        let n = self.layout.encoders();
        self.sensors = sensors;
        self.keep_edges = false;
        // Kept by the trackers themselves (a field here moved the slave's update by four
        // instructions): the new ones learn as the old did.
        let learn_edges = self.trackers[0].edge_learning();
        for (j, &count) in counts.iter().enumerate() {
            let c = if j < n { count } else { 0 };
            self.counts[j] = c;
            // Counts mode keeps them with the counts (`set_counts`) and reads them as they
            // are: they start at the counts `exact` starts from, or an update before the
            // first `set_counts` would integrate a move from there back to zero.
            self.positions[j] = c.wrapping_shl(16);
            self.trackers[j] = TickTracker::starting_learning(c, t_ns, learn_edges);
            self.recent[j] = RecentTicks::default();
        }
        self.abs = match (self.layout.abs(), abs_code) {
            (Some(a), Some(raw)) => a.decode(raw),
            _ => 0,
        };
        self.pose = start;
        self.lut_origin = (
            crate::lut::DEFAULT_ORIGIN_LSB,
            crate::lut::DEFAULT_ORIGIN_LSB,
        );
        let result = self.start(method, start, t_ns);
        if result.is_err() {
            // `exact` over a checked layout cannot fail (the carriage's bounds are `Layout`'s);
            // were it to, the wheels fixed to the body still run.
            if self.start(Method::Exact, start, t_ns).is_err() {
                self.state = State::Exact(ExactState::Body(ExactOdometry::new(
                    *self.layout.exact(),
                    start,
                    &self.positions,
                )));
                self.state_changed();
            }
        }
        self.method = if result.is_ok() {
            method
        } else {
            Method::Exact
        };
        result
    }

    /// Put the field origin at `origin_lsb` inside seed 001's unsigned coordinate square
    /// (10⁻⁸ m units; default: the middle, ±21.47 m around the origin), so a run far from
    /// the origin stays representable. Call right after [`new`](Self::new): a running `lut`
    /// restarts from the current pose.
    pub fn with_lut_origin(mut self, origin_lsb: (u32, u32)) -> Self {
        self.lut_origin = origin_lsb;
        if self.method == Method::Lut {
            // `lut` ignores time; the same method on the same layout cannot fail now.
            let _ = self.start(Method::Lut, self.pose, 0);
        }
        self
    }

    /// The state was replaced. Only `exact` lets ticks wait for the update: the float
    /// methods take each tick as it comes (their state after a tick depends on every tick).
    fn state_changed(&mut self) {
        self.keep_edges = self.state.is_exact() && self.sensors == SensorKind::Ticks;
    }

    /// Run `method` from `body` with the current readings at `t_ns`; on `Err` the running
    /// state is kept. Each method's state is built by a function of its own, out of line, so
    /// a board's stack holds one method's temporaries at a time, not all of them at once.
    fn start(&mut self, method: Method, body: FixedPose, t_ns: u64) -> Result<(), Unsupported> {
        match method {
            Method::Exact => self.start_exact(body, t_ns),
            #[cfg(any(test, feature = "float-methods"))]
            Method::Arc => self.start_float(FloatMethod::Arc, body, t_ns),
            #[cfg(any(test, feature = "float-methods"))]
            Method::Lut => self.start_float(FloatMethod::Lut, body, t_ns),
            #[cfg(any(test, feature = "float-methods"))]
            Method::Timing => self.start_float(FloatMethod::Timing, body, t_ns),
            #[cfg(not(any(test, feature = "float-methods")))]
            Method::Arc | Method::Lut | Method::Timing => Err(Unsupported::FloatMethodsNotBuilt),
        }
    }

    #[inline(never)]
    fn start_exact(&mut self, body: FixedPose, t_ns: u64) -> Result<(), Unsupported> {
        let layout = &self.layout;
        let n = layout.encoders();
        let q = self.positions_q16(t_ns);
        // Each state written into `self.state` where it is made, not through a local: the
        // locals and the copies between them made this frame the deepest of the slave's stack
        // (936 B).
        match (layout.carriage(), layout.abs()) {
            (Some(c), Some(a)) => {
                let (trail_q40, bits) = (c.trail_q40, a.bits);
                let carriage = CarriageExact::from_params(
                    *layout.exact(),
                    trail_q40,
                    bits,
                    body,
                    [q[0], q[1]],
                    self.abs,
                )
                // `Layout` guarantees two encoders and 1..=16 bits.
                .ok_or(Unsupported::Geometry(GeometryError::WheelCount(n)))?;
                self.state = State::Exact(ExactState::Carriage(carriage));
            }
            _ => {
                self.state = State::Exact(ExactState::Body(ExactOdometry::new(
                    *layout.exact(),
                    body,
                    &q,
                )))
            }
        }
        self.state_changed();
        Ok(())
    }

    /// With time-stamped ticks, `exact` learns where each encoder really puts the four edges
    /// of its quadrature cycle while it moves, interpolates on them and, once it knows them,
    /// places each wheel's start again on them ([`crate::ticks::edges`]). On by default, on the
    /// slave as on the host; off (for a comparison), every edge is a whole count.
    pub fn set_edge_learning(&mut self, on: bool) {
        for t in &mut self.trackers {
            t.set_edge_learning(on);
        }
    }

    /// What `exact` sees of each wheel, Q16 counts: interpolated between ticks at `t_ns` with
    /// time stamps, the whole counts otherwise; zero past the encoders. Integer-only.
    fn positions_q16(&self, t_ns: u64) -> [i64; MAX_ENCODERS] {
        core::array::from_fn(|j| self.position_q16(j, t_ns))
    }

    /// [`Self::positions_q16`] into `self.positions`, in place (the update's way). Counts mode
    /// has them already (`set_counts` keeps them): the check is inlined so that costs no call.
    #[inline(always)]
    fn refresh_positions(&mut self, t_ns: u64) {
        if self.sensors == SensorKind::Ticks {
            self.interpolate_positions(t_ns);
        }
    }

    /// Ticks mode's positions: each wheel's waiting ticks caught up, its edges learned (and
    /// the wheels placed again once they are: [`learn_edges`]), then interpolated to `t_ns`.
    fn interpolate_positions(&mut self, t_ns: u64) {
        let n = self.layout.encoders().min(MAX_ENCODERS);
        let out = &mut self.positions[..n];
        let (trackers, recent) = (&mut self.trackers[..n], &mut self.recent[..n]);
        for ((tracker, recent), &count) in trackers.iter_mut().zip(recent).zip(&self.counts) {
            if recent.any() {
                tracker.catch_up(count, recent);
            }
        }
        learn_edges(trackers);
        for (p, tracker) in out.iter_mut().zip(trackers.iter()) {
            *p = tracker.position_q16(t_ns);
        }
    }

    fn position_q16(&self, j: usize, t_ns: u64) -> i64 {
        // Only `exact`'s edges wait, and its update catches them up before anything reads the
        // trackers (a switch or set-pose updates first).
        debug_assert!(self.recent.iter().all(|r| !r.any()));
        if j >= self.layout.encoders() {
            0
        } else if self.sensors == SensorKind::Ticks {
            self.trackers[j].position_q16(t_ns)
        } else {
            self.counts[j].wrapping_shl(16)
        }
    }

    /// One decoded tick of `encoder` at `t_ns`, `step` = ±1 ([`SensorKind::Ticks`]; anything
    /// else, an unknown encoder or another step, is ignored).
    ///
    /// With `exact` a placed wheel's tick is only counted and kept for the update
    /// ([`RecentTicks`]): the slave's edge path, about 50 instructions on the M3.
    #[inline(always)]
    pub fn tick(&mut self, t_ns: u64, encoder: usize, step: i8) {
        if self.keep_edges && (step == 1 || step == -1) {
            // `open` only for a wheel of the layout (ticks of others are never recorded).
            if let (Some(recent), Some(c)) =
                (self.recent.get_mut(encoder), self.counts.get_mut(encoder))
            {
                if recent.open {
                    *c += step as i64;
                    recent.push(t_ns, step);
                    return;
                }
            }
        }
        self.tick_now(t_ns, encoder, step);
    }

    /// [`tick`](Self::tick) for a tick taken in at once: a wheel still placing (its first
    /// ticks feed its start fit), or a float method. Out of line, so the edge path above
    /// saves no registers for it.
    #[inline(never)]
    fn tick_now(&mut self, t_ns: u64, encoder: usize, step: i8) {
        // Without the float methods the tick is the tracker's and the count's only.
        #[cfg_attr(not(any(test, feature = "float-methods")), allow(unused_variables))]
        let recorded = self.record_tick(t_ns, encoder, step);
        #[cfg(any(test, feature = "float-methods"))]
        if let (true, State::Float(f)) = (recorded, &mut self.state) {
            f.tick(t_ns, encoder, step);
        }
    }

    /// The tick into its wheel's tracker and count; false if it is to be ignored.
    /// Integer-only (an entry point of `scripts/check-no-float.py`).
    #[inline(never)]
    fn record_tick(&mut self, t_ns: u64, encoder: usize, step: i8) -> bool {
        if self.sensors != SensorKind::Ticks
            || encoder >= self.layout.encoders()
            || (step != 1 && step != -1)
        {
            return false;
        }
        let n = self.layout.encoders();
        let (Some(wheels), Some(c)) = (self.trackers.get_mut(..n), self.counts.get_mut(encoder))
        else {
            return false;
        };
        match tick_wheel(wheels, encoder, t_ns, step) {
            Some(count) => {
                *c = count;
                if let (Some(w), Some(r)) = (wheels.get(encoder), self.recent.get_mut(encoder)) {
                    r.open = !w.placing();
                }
                true
            }
            None => false,
        }
    }

    /// The encoders' cumulative whole counts ([`SensorKind::Counts`]; ignored with ticks).
    /// Entries past the layout's encoders are ignored. Integer-only.
    #[inline(never)]
    pub fn set_counts(&mut self, counts: &[i64]) {
        if self.sensors != SensorKind::Counts {
            return;
        }
        let n = self.layout.encoders().min(MAX_ENCODERS);
        // The positions `exact` reads with them, in the same loop (a second pass at the update
        // was 40 instructions).
        let wheels = self.counts[..n].iter_mut().zip(&mut self.positions);
        for ((c, p), &new) in wheels.zip(counts) {
            *c = new;
            *p = new.wrapping_shl(16);
        }
    }

    /// The absolute encoder's raw output (decoded with the layout's [`super::AbsLayout`];
    /// ignored without one). Integer-only.
    #[inline(never)]
    pub fn set_abs(&mut self, raw_code: u16) {
        if let Some(a) = self.layout.abs() {
            self.abs = a.decode(raw_code);
        }
    }

    /// One fixed-rate update at `t_ns`: the pose with every reading so far.
    pub fn update(&mut self, t_ns: u64) -> FixedPose {
        match self.state {
            State::Exact(_) => self.update_exact(t_ns),
            #[cfg(any(test, feature = "float-methods"))]
            State::Float(_) => self.update_float(t_ns),
        }
    }

    /// `exact`'s update. Integer-only (an entry point of `scripts/check-no-float.py`).
    #[inline(never)]
    fn update_exact(&mut self, t_ns: u64) -> FixedPose {
        self.refresh_positions(t_ns);
        let q = &self.positions;
        if let Some(e) = self.state.exact_mut() {
            self.pose = match e {
                ExactState::Body(o) => o.update_q16(q),
                ExactState::Carriage(c) => c.update_q16(q, self.abs),
            };
        }
        self.pose
    }

    /// Restart from `pose` at the current readings at `t_ns` (a set-pose command): what
    /// moved before is taken in first, then the pose is replaced.
    pub fn set_pose(&mut self, pose: FixedPose, t_ns: u64) {
        if self.state.is_exact() {
            self.set_pose_exact(pose, t_ns);
            return;
        }
        // The same method on the same layout cannot fail: it is running.
        let _ = self.start(self.method, pose, t_ns);
        self.pose = pose;
    }

    /// Integer-only (an entry point of `scripts/check-no-float.py`).
    #[inline(never)]
    fn set_pose_exact(&mut self, pose: FixedPose, t_ns: u64) {
        self.refresh_positions(t_ns);
        let q = &self.positions;
        if let Some(e) = self.state.exact_mut() {
            match e {
                ExactState::Body(o) => {
                    o.update_q16(q);
                    o.set_pose(pose);
                }
                ExactState::Carriage(c) => {
                    c.update_q16(q, self.abs);
                    c.set_body(pose, self.abs);
                }
            }
        }
        self.pose = pose;
    }

    /// Switch to `method` at `t_ns`, continuing from the pose there (no jump). On
    /// `Err` the running method is kept (and has been updated to `t_ns`).
    pub fn switch(&mut self, method: Method, t_ns: u64) -> Result<(), Unsupported> {
        if method == self.method {
            return Ok(());
        }
        let here = self.update(t_ns);
        self.start(method, here, t_ns)?;
        self.method = method;
        Ok(())
    }

    pub fn method(&self) -> Method {
        self.method
    }

    pub fn sensors(&self) -> SensorKind {
        self.sensors
    }

    pub fn layout(&self) -> &Layout {
        &self.layout
    }

    /// The pose of the last update (or set-pose).
    pub fn pose(&self) -> FixedPose {
        self.pose
    }

    /// The encoders' cumulative whole counts (zero past the layout's encoders).
    pub fn counts(&self) -> [i64; MAX_ENCODERS] {
        self.counts
    }

    /// Whether the decoded (or sampled) whole counts agree with `counts` on every encoder
    /// both have: compared in place (a copy and a `memcmp` cost the M3 about 250
    /// instructions an update).
    pub fn counts_are(&self, counts: &[i64]) -> bool {
        let mut same = true;
        for (a, b) in self.counts.iter().zip(counts).take(self.layout.encoders()) {
            same &= a == b;
        }
        same
    }

    /// The absolute encoder's decoded position (0 without one).
    pub fn abs_position(&self) -> u16 {
        self.abs
    }
}
