//! Tick-timestamp mode: where each wheel is *between* its ticks.
//!
//! With edge interrupts or input capture the slave knows when every count happened. An ideal
//! encoder ticks when its wheel's rolling distance crosses a multiple of its step, so at a
//! tick the wheel is exactly on that edge; between ticks it is somewhere in the next step.
//! Integrating only at tick instants with whole counts lets the wheels that have not ticked
//! yet lag by up to a step, and that lag turns into heading error. Interpolating each wheel
//! to the update instant removes most of it. Seed 000 estimates speed as Δ / interval and
//! suggests higher-order fits as the improvement; a constant-speed guess lags whenever the
//! wheel accelerates or brakes (most of all near standstill, where intervals are long), so
//! this fits a constant *acceleration* to the last two intervals T1, T2 (same direction).
//! In units of steps and of x = τ / T2 (τ since the last tick), with ρ = T2 / T1:
//!
//! ```text
//! s(x) = x + c·(x + x²),   c = (1 − ρ)·ρ / (1 + ρ)
//! ```
//!
//! (the mean speeds 1/T1, 1/T2 belong to the interval midpoints; the acceleration between
//! them, extrapolated from the last edge). Constant speed gives ρ = 1, c = 0, s = x. When
//! braking (c < 0) the fit stops at x* = −(1 + c) / (2c) and holds there. The estimate is
//! clamped so it never passes the next edge (no tick has said so) and is corrected by the
//! next real tick, so its errors do not accumulate.
//!
//! Integer-only: times in nanoseconds, positions in Q16 counts.

pub mod edges;
mod recent;
pub mod start;

use edges::WINDOW;
pub use edges::{EdgeTable, Learner};
pub use recent::RecentTicks;

use core::num::NonZeroU64;

/// One wheel's tick history.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TickTracker {
    /// Cumulative count after the last tick.
    count: i64,
    /// The edge (multiple of the step, in counts) the last tick crossed.
    edge: i64,
    /// The last tick's time (meaningful once `dir` is not 0: a plain `u64`, because the tag
    /// of an `Option<u64>` costs moves and checks on every edge on the M3).
    last_t: u64,
    /// Interval between the last two ticks, when they went the same way (never 0: a tick
    /// at the same instant gives none, so `NonZeroU64` needs no tag).
    interval: Option<NonZeroU64>,
    /// The interval before that, when it went the same way too.
    prev_interval: Option<NonZeroU64>,
    dir: i8,
    /// Power-on (or when the estimator started watching the wheel).
    start_ns: u64,
    /// The first ticks after power-on while they all go one way, for the fit of where inside
    /// its count the wheel stood ([`start`]): the first four, then the fifth and the ninth
    /// take the last places ([`fit_ticks`](Self::fit_ticks)).
    first: [u64; PLACING_TICKS],
    /// The ticks counted one way so far (up to [`SPAN_TICKS`]; set to it when the wheel turns
    /// back first).
    first_len: u8,
    first_dir: i8,
    /// That position, Q16 counts above the count at power-on (φ ∈ [0, 1]; on learned uneven
    /// edges between the count's own edges, which lie up to 0.4 count off); half a count
    /// until a fit places it.
    phase_q16: i64,
    /// A fit of the wheel's own first ticks placed it.
    placed: bool,
    /// How many ticks one way were gathered (up to [`SPAN_TICKS`]).
    gathered: u8,
    /// The count at power-on (the first ticks' edges follow from it).
    start_count: i64,
    /// The encoder's edges, as learned so far ([`edges`]).
    learner: Learner,
}

/// Windows learned before a wheel's start is fitted again on its learned edges.
const REPLACE_AFTER: u8 = edges::SETTLED / 2;

/// A wheel's first ticks in one direction that place it inside its count (fits of degree 1 to
/// 3 through 2 to 4 of them): after these no tick of its own moves its start (on learned
/// edges, [`TickTracker::learn`] places it once more).
pub const PLACING_TICKS: usize = 4;

/// Ticks one way gathered while placing: the start is fitted again on learned edges through
/// the first, second, fifth and ninth ([`TickTracker::fit_ticks`]).
const SPAN_TICKS: u8 = 9;

/// Where a wheel is taken to stand inside its count before its ticks say: the middle, so the
/// error is at most half a count either way.
const UNKNOWN_PHASE_Q16: i64 = 1 << 15;

impl TickTracker {
    pub const fn new() -> Self {
        Self::starting(0, 0)
    }

    /// A wheel that has not ticked yet, standing at `count`, powered on (or first seen) at
    /// time 0.
    pub const fn at(count: i64) -> Self {
        Self::starting(count, 0)
    }

    /// A wheel that has not ticked yet, standing somewhere inside `count` at `t_ns` (its
    /// power-on, or when the estimator started watching it).
    pub const fn starting(count: i64, t_ns: u64) -> Self {
        Self::starting_learning(count, t_ns, true)
    }

    /// [`starting`](Self::starting), learning its encoder's edges or not
    /// ([`set_edge_learning`](Self::set_edge_learning)).
    pub const fn starting_learning(count: i64, t_ns: u64, learn_edges: bool) -> Self {
        TickTracker {
            count,
            edge: count,
            last_t: 0,
            interval: None,
            prev_interval: None,
            dir: 0,
            start_ns: t_ns,
            first: [0; PLACING_TICKS],
            first_len: 0,
            first_dir: 0,
            phase_q16: UNKNOWN_PHASE_Q16,
            placed: false,
            gathered: 0,
            start_count: count,
            learner: Learner::new(learn_edges),
        }
    }

    /// A tick at `t_ns`, `step` = +1 or -1 (anything else is ignored: a corrupt event must
    /// not move the count by more than one).
    // Out of line so `scripts/check-no-float.py` can see it in the object code (small functions
    // are otherwise only generated where they are used).
    #[inline(never)]
    pub fn tick(&mut self, t_ns: u64, step: i8) {
        if step == 1 || step == -1 {
            self.advance(t_ns, step);
        }
    }

    /// [`tick`](Self::tick) for a `step` known to be ±1. One copy, called: the slave's edge
    /// only keeps its tick ([`RecentTicks`]), and this runs for a wheel's first ticks and at
    /// the update, where a call is little (two inlined copies were 230 B of the slave's flash).
    #[inline(never)]
    fn advance(&mut self, t_ns: u64, step: i8) {
        // Forward to count m crosses edge m; backward to count m - 1 crosses edge m too.
        self.edge = if step > 0 { self.count + 1 } else { self.count };
        self.count += step as i64;
        let same_way = self.dir == step;
        let since = t_ns.saturating_sub(self.last_t);
        self.prev_interval = if same_way { self.interval } else { None };
        // `same_way` implies a tick before (`dir` is 0 until the first).
        self.interval = if same_way {
            NonZeroU64::new(since)
        } else {
            None
        };
        self.learner.advance(same_way, since, self.edge);
        self.last_t = t_ns;
        self.dir = step;
        // Only a wheel's first ticks: every later one skips the fit's call altogether.
        if self.placing() {
            self.fit_start(t_ns, step);
        }
    }

    /// The first ticks in one direction place the wheel inside its count at power-on.
    #[cold]
    #[inline(never)]
    fn fit_start(&mut self, t_ns: u64, step: i8) {
        let n = self.first_len as usize;
        // The first four, then the fifth in the fourth's place, then the fifth and the ninth in
        // the last two: the times stay in order ([`fit_ticks`](Self::fit_ticks)).
        let f = &mut self.first;
        let go_on = match n {
            // The wheel turned back: keep what we have.
            _ if n != 0 && step != self.first_dir => false,
            0..PLACING_TICKS => {
                f[n] = t_ns;
                true
            }
            4 => {
                f[3] = t_ns;
                true
            }
            // Only if the wheel went on from the fifth at least half as fast as it came to it
            // (t9 − t5 ≤ 2 (t5 − t1), without differences: the times grow; wrapping only for
            // times past a century): a pause or a stop in between would leave the cubic
            // nothing to follow. Else the fifth stays.
            8 => {
                let on = t_ns.wrapping_add(f[0].wrapping_mul(2)) <= f[3].wrapping_mul(3);
                if on {
                    (f[2], f[3]) = (f[3], t_ns);
                }
                on
            }
            _ => true,
        };
        if !go_on {
            self.first_len = SPAN_TICKS;
            return;
        }
        self.first_dir = step;
        self.first_len += 1;
        self.gathered = self.first_len;
        // The first fit, on the first four: nothing is learned yet (a window is nine ticks one
        // way), so their edges are whole counts, the fit on the learned places is the fit on
        // even ones, and one copy of it serves both (the slave's flash).
        if n < PLACING_TICKS {
            self.place_on_learned_edges();
        }
    }

    /// Learn the encoder's edges from the last two cycles, if the last tick completed them
    /// (at an update: the slave's edges only keep their time). Once the edges are known well
    /// enough, and found uneven ([`edges::UNEVEN_Q16`]), the wheel's start is fitted again on
    /// the edges its first ticks really crossed; `true` then, and the caller places the wheels
    /// that fit cannot place together again ([`place_together`], on their learned edges).
    /// Integer-only.
    pub fn learn(&mut self) -> bool {
        // Once: the count of windows reaches it once (it starts again only with the table).
        let refit = self.learner.learn(self.edge, self.dir)
            && self.learner.table().windows() == REPLACE_AFTER
            && self.learner.table().uneven();
        if refit {
            // Uneven edges can make an abrupt start's first ticks look like a start from rest:
            // a fit that took them is undone when the learned edges say otherwise.
            self.placed = self.place_on_learned_edges();
        }
        refit
    }

    /// Learn this wheel's edges from now on ([`learn`](Self::learn); the default), or not
    /// (turned off, what was learned is forgotten: the edges are whole counts again). A start
    /// already fitted again on learned edges stays where it was placed: for the arithmetic of
    /// a tracker that never learned (`exact+even`), turn it off before the first tick.
    pub fn set_edge_learning(&mut self, on: bool) {
        self.learner.set_on(on);
    }

    /// This wheel learns its edges.
    pub fn edge_learning(&self) -> bool {
        self.learner.on()
    }

    /// The start fit on the first ticks gathered, at their learned edges (whole counts until
    /// some are learned). Fitted again once the edges are known ([`learn`](Self::learn)), a
    /// wheel its own first ticks placed is placed better, and one they could not (an uneven
    /// edge made them look like an abrupt start) may be placed now. Whether the fit placed it
    /// (else the wheel keeps what it had).
    #[cold]
    #[inline(never)]
    fn place_on_learned_edges(&mut self) -> bool {
        let times = &self.first[..(self.gathered as usize).min(PLACING_TICKS)];
        let places = self.fit_ticks().map(|k| self.first_place_q16(k) << 8);
        let Some(u) = start::start_position_on_q16(self.start_ns, times, &places) else {
            return false;
        };
        self.set_start(u);
        self.placed = true;
        true
    }

    /// Which ticks one way (from 0: the first) `first` holds: the first four; once the wheel
    /// went nine ticks one way, the first, second, fifth and ninth. Spread out, they hold the
    /// cubic's extrapolation back to rest against each line's placement on the code wheel,
    /// which no learned offset holds (`scripts/start-fit-noise.py`, 400 jerk-limited starts:
    /// misplaced by 0.089 count in the median and 1.69 at worst through the first four, 0.057
    /// and 0.55 through these; least squares over the first twelve, 0.049 and 0.33, would
    /// take a 4×4 solver the slave's flash has no room for).
    fn fit_ticks(&self) -> [i64; PLACING_TICKS] {
        match self.gathered {
            0..=4 => [0, 1, 2, 3],
            5..=8 => [0, 1, 2, 4],
            _ => [0, 1, 4, 8],
        }
    }

    /// Where the first direction's `k`-th tick's edge lies (k = 0: the first tick's, −1: the
    /// count's other edge), Q16 counts along that direction from the count's first edge's
    /// whole-count place (c0 forward, c0 + 1 backward): `k + 1`, moved by the edge's learned
    /// offset. Out of line: the start's fits call it for a wheel's first ticks only.
    #[inline(never)]
    fn first_place_q16(&self, k: i64) -> i64 {
        let d = self.first_dir as i64;
        let first = if d > 0 {
            self.start_count + 1
        } else {
            self.start_count
        };
        // Edges not found uneven are whole counts here, as before anything was learned: what a
        // window learns of even edges is its time stamps' rounding.
        let offset = if self.learner.table().uneven() {
            self.learner.offset_q16(first + d * k)
        } else {
            0
        };
        ((k + 1) << 16) + d * offset
    }

    /// The start `u` (Q16, along the first direction from the count's first edge's place) as
    /// the phase: backwards the first edge is the count's lower one.
    fn set_start(&mut self, u: i64) {
        self.phase_q16 = if self.first_dir > 0 { u } else { (1 << 16) - u };
    }

    /// The encoder's edges as learned so far.
    pub fn edges(&self) -> &EdgeTable {
        self.learner.table()
    }

    /// A wheel its own first ticks could not place, moving at its first interval's speed:
    /// the window `[t1 − before, t1]` (not before power-on) in which it must have started for
    /// its start to lie inside its count (`before`: the time from the count's other edge to
    /// the first tick's at that speed; the first interval itself on even edges), the first
    /// interval, and the places of that edge and the first tick's and the interval's span
    /// ([`first_place_q16`](Self::first_place_q16)).
    fn start_window(&self) -> Option<(u64, u64, u64, [i64; 3])> {
        if self.placed || self.first_len < 2 {
            return None;
        }
        let (t1, t2) = (self.first[0], self.first[1]);
        let interval = t2.checked_sub(t1).filter(|&i| i > 0 && i < 1 << 40)?;
        let [p0, p1, p2] = [-1, 0, 1].map(|k| self.first_place_q16(k));
        // Learned offsets stay within 0.4 count of their places: a span is 0.2 to 1.8 counts
        // (positive, under 2^17), and `interval < 2^40`, so the product fits 64 bits.
        let span = p2 - p1;
        let before = (interval * (p1 - p0) as u64).checked_div(span as u64)?;
        let earliest = t1.saturating_sub(before).max(self.start_ns);
        Some((earliest, t1, interval, [p0, p1, span]))
    }

    /// Place an unplaced wheel as if it started at `t_start` at its first interval's speed.
    fn place_from(&mut self, t_start: u64) {
        if let Some((earliest, t1, interval, [p0, p1, span])) = self.start_window() {
            // `earliest ≤ t_start ≤ t1` ([`place_together`]'s common window).
            let before = t1.saturating_sub(t_start.max(earliest));
            // u = p1 − span · (t1 − t_start) / interval, Q16, inside the count: [p0, p1).
            // `before` is at most nine intervals (a span of 1.8 counts over one of 0.2), under
            // 2^44, the span under 2^17: the
            // product fits; `checked_div` keeps panics out.
            let Some(frac) = (before * span as u64).checked_div(interval) else {
                return;
            };
            // `max`, `min`: `clamp` keeps a panic for bounds it cannot see are in order.
            self.set_start((p1 - frac as i64).max(p0).min(p1 - 1));
        }
    }

    /// Cumulative whole counts.
    pub fn count(&self) -> i64 {
        self.count
    }

    /// True while the wheel's first ticks are still being gathered (the first four place it,
    /// up to the ninth are kept for its fit on learned edges): only then can a tick change
    /// where it (or, through [`place_together`], another wheel) is placed.
    pub fn placing(&self) -> bool {
        self.first_len < SPAN_TICKS
    }

    /// Where inside its count the wheel stood at power-on, as far as its ticks tell: Q16
    /// counts in `[0, 1]` (half a count until they tell; on learned uneven edges, between the
    /// count's own edges).
    pub fn phase_q16(&self) -> i64 {
        self.phase_q16
    }

    /// Best estimate of the wheel's travel since power-on at `t_ns` (not before the last
    /// tick), Q16 counts, plus the count at power-on: an edge is `phase` after the count it
    /// starts. Before the first tick it is the count at power-on (no motion seen).
    pub fn position_q16(&self, t_ns: u64) -> i64 {
        if self.dir == 0 {
            return self.count << 16;
        }
        self.edge_position_q16(t_ns) - self.phase_q16
    }

    /// Position on the encoder's own scale (edges at whole counts, moved by the learned
    /// offsets). After a reversal until a second tick in the new direction there is no speed to
    /// go on: the wheel is taken to be at its last edge.
    fn edge_position_q16(&self, t_ns: u64) -> i64 {
        let at_edge = (self.edge << 16) + self.learner.offset_q16(self.edge);
        let Some(interval) = self.interval else {
            return at_edge;
        };
        // Dividing by the `NonZeroU64` itself: no divide-by-zero panic path reaches the board.
        let (nz, interval) = (interval, interval.get());
        let since = t_ns.saturating_sub(self.last_t);
        if interval >= 1 << 40 {
            // Over 18 minutes between two edges: a stopped wheel.
            return at_edge;
        }
        let dir = self.dir;
        let table = &self.learner;
        // In 32 bits with 64-bit products (`smull`; the M3's 64 × 64 multiply is three
        // instructions, and the spans no longer fold to constants): every value below fits, as
        // each comment's bound says.
        // The last interval's span and the next one's, along the travel (Q16 counts: one count
        // each on ideal edges; within 1 ± 0.8 counts, under 2^17).
        let back = self.edge - dir as i64;
        let s2 = table.span_q16(back, dir) as i32;
        let next = table.span_q16(self.edge, dir) as i32;
        // x = τ / T2 in Q16, capped at 8 steps' worth of time (well past any clamp below): 2^19.
        let x = ((since.min(interval * 8) << 16) / nz) as i32;
        let frac = match self.prev_interval {
            None => mul_q16(s2, x), // one interval only: constant speed
            Some(t1) => {
                let s1 = table.span_q16(back - dir as i64, dir) as i32;
                // ρ = T2 / T1 in Q16, limited to [1/16, 16] so one odd interval cannot
                // throw the fit far.
                // `interval < 2^40` (checked above), so the shift fits 64 bits.
                let rho = ((interval << 16) / t1).clamp(1 << 12, 1 << 20) as i32;
                // The mean speeds s1/T1 and s2/T2 belong to the intervals' midpoints; the
                // acceleration between them, from the last edge: s(x) = s2·x + c·(x + x²),
                // c = (s2 − ρ·s1)·ρ / (1 + ρ), Q16 (ideal edges: (1 − ρ)·ρ / (1 + ρ));
                // s2 − ρ·s1 under 17·2^17, c under 2^21.
                let c =
                    ((s2 - mul_q16(rho, s1)) as i64 * rho as i64 / ((1 << 16) + rho) as i64) as i32;
                // Braking: the fitted speed s2 + c·(1 + 2x) reaches zero at
                // x* = −(s2 + c) / (2c); hold there (x* may pass 32 bits; the least not).
                // A fit braking so hard that it stopped before the last edge (x* < 0: the last
                // interval over 1 + √2 times the one before) is evaluated at x* all the same,
                // where the curve stands ahead of the edge (a fifth of a count at 4 times,
                // up to the next edge at 8): holding at the edge instead measured worse on
                // the accuracy suite (the median case while moving on ideal edges 926x to
                // 732x below the best baseline, taking edges a count apart), so it stays,
                // known, until a better model of a hard stop.
                let x = if c < 0 {
                    (x as i64).min(((s2 + c) as i64) * (1 << 16) / (-2 * c as i64)) as i32
                } else {
                    x
                };
                // x + x² under 2^23; c·(x + x²) / 2^16 under 2^28.
                mul_q16(s2, x) + mul_q16(c, x + mul_q16(x, x))
            }
        };
        // Never at or past the next edge: no tick has said so (`max`, `min`: `clamp` keeps a
        // panic for bounds it cannot see are in order).
        let frac = frac.max(0).min(next - 1) as i64;
        at_edge + if dir > 0 { frac } else { -frac }
    }
}

/// `a·b / 2^16` of two Q16 values, through a 64-bit product (one `smull`), floored.
#[inline(always)]
fn mul_q16(a: i32, b: i32) -> i32 {
    ((a as i64 * b as i64) >> 16) as i32
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A place inside a count (of even edges) never reaches its upper edge: 1 - 2^-16.
    const MAX_FRACTION: i64 = 0xFFFF;

    #[test]
    fn constant_speed_is_interpolated_exactly() {
        let mut w = TickTracker::new();
        // Edges every 1 ms, moving forward.
        for k in 1..=5u64 {
            w.tick(k * 1_000_000, 1);
        }
        assert_eq!(w.count(), 5);
        assert_eq!(w.position_q16(5_000_000), 5 << 16);
        assert_eq!(w.position_q16(5_250_000), (5 << 16) + (1 << 14));
        // Never past the next edge, however long the wheel is silent.
        assert_eq!(w.position_q16(99_000_000), (5 << 16) + MAX_FRACTION);
    }

    #[test]
    fn backward_ticks_sit_on_the_upper_edge() {
        let mut w = TickTracker::new();
        w.tick(1_000, 1); // count 1, on edge 1
        w.tick(2_000, -1); // back over edge 1: count 0, position 1
        assert_eq!(w.count(), 0);
        assert_eq!(
            w.edge_position_q16(2_500),
            1 << 16,
            "no speed yet after a reversal"
        );
        w.tick(3_000, -1); // over edge 0: count -1, position 0
        assert_eq!(w.edge_position_q16(3_000), 0);
        assert_eq!(w.edge_position_q16(3_500), -(1 << 15));
    }

    #[test]
    fn constant_acceleration_is_followed_between_ticks() {
        // s(t) = t² (steps, t in ms): edges at t = √k ms. Between edges the fit must land on
        // the parabola far closer than constant-speed interpolation does.
        let edge_at = |k: f64| (k.sqrt() * 1e6).round() as u64;
        let mut w = TickTracker::new();
        for k in 1..=9 {
            w.tick(edge_at(k as f64), 1);
        }
        let t = edge_at(9.5); // halfway (in distance) to edge 10
        let truth = 9.5 * 65536.0;
        let fitted = w.position_q16(t) as f64;
        // Constant speed from the last interval alone would say:
        let t8 = edge_at(8.0) as f64;
        let t9 = edge_at(9.0) as f64;
        let constant = (9.0 + (t as f64 - t9) / (t9 - t8)) * 65536.0;
        assert!(
            (fitted - truth).abs() < 0.01 * 65536.0,
            "fit {} vs {}",
            fitted / 65536.0,
            9.5
        );
        assert!((constant - truth).abs() > 3.0 * (fitted - truth).abs());
    }

    #[test]
    fn braking_holds_at_the_predicted_stop() {
        // Intervals doubling: braking hard. Long after the last tick the estimate must hold
        // below the next edge, not run up to it.
        let mut w = TickTracker::new();
        for t in [1_000u64, 2_000, 4_000, 8_000] {
            w.tick(t, 1);
        }
        let held = w.position_q16(1_000_000);
        assert!(
            held > 4 << 16 && held < (4 << 16) + MAX_FRACTION,
            "{}",
            held as f64 / 65536.0
        );
        assert_eq!(held, w.position_q16(9_000_000), "holds once stopped");
    }

    #[test]
    fn a_wheel_powered_on_inside_its_count_is_placed_by_its_first_ticks() {
        // 0.3 of a count in at power-on, then 1000 counts/s: ticks at 0.7, 1.7, 2.7 ms.
        let mut w = TickTracker::starting(10, 0);
        w.tick(700_000, 1);
        assert_eq!(
            w.phase_q16(),
            1 << 15,
            "one tick: not placed yet, the middle"
        );
        w.tick(1_700_000, 1);
        assert!((w.phase_q16() - 19_661).abs() <= 1, "{}", w.phase_q16()); // 0.3 count
                                                                           // Travel since power-on: 2.5 counts at 2.5 ms.
        let p = w.position_q16(2_500_000) - (10 << 16);
        assert!((p - 163_840).abs() <= 2, "{}", p as f64 / 65536.0);
    }

    #[test]
    fn wheels_that_start_abruptly_after_a_rest_are_placed_together() {
        // At rest for 1 s, then 1000 and 600 counts/s at once from 0.35 and 0.8 of a count.
        let start = 1_000_000_000u64;
        let ticks = |phi: f64, per_s: f64| -> [u64; 2] {
            core::array::from_fn(|k| start + ((k as f64 + 1.0 - phi) / per_s * 1e9) as u64)
        };
        let mut wheels = [TickTracker::starting(0, 0), TickTracker::starting(0, 0)];
        for (w, t) in wheels
            .iter_mut()
            .zip([ticks(0.35, 1000.0), ticks(0.8, 600.0)])
        {
            for &t in &t {
                w.tick(t, 1);
            }
        }
        // Neither wheel's own ticks can place it (any start before the first tick fits).
        assert!(wheels.iter().all(|w| w.phase_q16() == 1 << 15));
        place_together(&mut wheels);
        // Common window: [0.35 ms after the start − 1 ms, ...]: each wheel within half the
        // window at its own speed, under half a count; here both land within 0.2 count.
        for (w, phi) in wheels.iter().zip([0.35, 0.8]) {
            let got = w.phase_q16() as f64 / 65536.0;
            assert!((got - phi).abs() < 0.2, "{got} vs {phi}");
        }
    }

    #[test]
    fn an_abrupt_start_on_uneven_edges_is_placed_together_once_they_are_learned() {
        // At rest for 1 s, then at full speed at once, on encoders whose edges sit off their
        // whole-count places by a HEDS-9040's typical state widths (counts, by edge mod 4).
        let start = 1_000_000_000u64;
        let (a, b) = (
            [0.0267, -0.0289, -0.0175, 0.0196],
            [-0.0117, -0.0321, 0.0235, 0.0203],
        );
        let b2 = [0.0235, 0.0203, -0.0117, -0.0321];
        // Each of the first three lands outside its bound when the wheels are placed together
        // on even edges only (at their first ticks, before anything is learned).
        for (offsets, phases, speeds) in [
            ([a, b], [0.05, 0.05], [1300.0, 700.0]),
            ([a, b], [0.05, 0.41], [1300.0, 700.0]),
            ([a, b2], [0.23, 0.05], [1300.0, 700.0]),
            ([a, b], [0.7458, 0.5666], [1300.0, 700.0]),
            ([a, b], [0.4315, 0.8833], [700.0, 1300.0]),
            ([b, a], [0.25, 0.55], [1000.0, 900.0]),
        ] {
            // (time, wheel) of each wheel's first 300 edges, in time order.
            let mut ticks: Vec<(u64, usize)> = (0..2)
                .flat_map(|j| {
                    let (off, phi, v) = (offsets[j], phases[j], speeds[j]);
                    (1..=300).map(move |m: i64| {
                        let place = m as f64 + off[(m & 3) as usize];
                        (start + ((place - phi) / v * 1e9) as u64, j)
                    })
                })
                .collect();
            ticks.sort();
            let mut wheels = [TickTracker::starting(0, 0), TickTracker::starting(0, 0)];
            for (t, j) in ticks {
                tick_wheel(&mut wheels, j, t, 1);
                // An update after every tick.
                learn_edges(&mut wheels);
            }
            // The window each wheel's start must lie in (s): from where its count's lower
            // edge is to its first tick's, at its first interval's speed; and their overlap.
            let window = |j: usize| {
                let (off, phi, v) = (offsets[j], phases[j], speeds[j]);
                let t1 = (1.0 + off[1] - phi) / v;
                (t1 - (1.0 + off[1] - off[0]) / v, t1)
            };
            let (lo, hi) = (window(0).0.max(window(1).0), window(0).1.min(window(1).1));
            for ((w, phi), v) in wheels.iter().zip(phases).zip(speeds) {
                assert!(
                    !w.placed,
                    "{phases:?}: no fit tells an abrupt start's instant"
                );
                let got = w.phase_q16() as f64 / 65536.0;
                // Within half the common window at its own speed (the bound on even edges),
                // give or take what learning leaves: 0.01 count.
                let bound = (hi - lo) / 2.0 * v + 0.01;
                assert!(
                    (got - phi).abs() < bound,
                    "{phases:?}: {got} vs {phi}, bound {bound}"
                );
            }
        }
    }

    /// Where a wheel's start from rest at power-on is placed, against where it stood: a start
    /// at constant acceleration (5000 counts/s² up to 1000 counts/s) in direction `dir`,
    /// `pause` seconds at a standstill after its fifth tick, on an encoder whose edges sit off
    /// by a HEDS-9040's typical state widths and each code-wheel line up to ±1/60 count off,
    /// at 24 power-on places. Returns the errors (counts) after 300 ticks, with an update
    /// after each, and those of the fit through the first four ticks on the same learned
    /// places; and whether every wheel's own fit placed it.
    fn start_errors_from_rest(dir: i8, pause: f64) -> (Vec<f64>, Vec<f64>, bool) {
        let kinds = [0.0267, -0.0289, -0.0175, 0.0196];
        let mut seed = 7u64;
        let mut unit = move || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        let (mut spread, mut first_four, mut placed) = (Vec::new(), Vec::new(), true);
        for _ in 0..24 {
            let (phi, q) = (0.05 + 0.9 * unit(), (unit() * 4.0) as i64);
            let lines: Vec<f64> = (0..200).map(|_| (unit() - 0.5) / 30.0).collect();
            // Edge e's place, counts; the k-th tick (from 1) crosses edge k forward, 1 − k
            // backward, after this much travel.
            let place = |e: i64| {
                let line = lines[((e + q).div_euclid(4) + 100) as usize];
                e as f64 + kinds[(e + q).rem_euclid(4) as usize] + line
            };
            let travel = |k: i64| {
                if dir > 0 {
                    place(k) - phi
                } else {
                    phi - place(1 - k)
                }
            };
            // s(t) = A t² to the top speed at 0.1 s (25 counts), then 1000 counts/s.
            let at = |s: f64| {
                if s < 25.0 {
                    (s / 5000.0).sqrt()
                } else {
                    0.1 + (s - 25.0) / 1000.0
                }
            };
            let mut w = TickTracker::starting(0, 0);
            let mut times = Vec::new();
            for k in 1..=300 {
                let stood = if k > 5 { pause } else { 0.0 };
                let t = ((at(travel(k)) + stood) * 1e9) as u64;
                times.push(t);
                w.tick(t, dir);
                w.learn();
            }
            placed &= w.placed;
            let got = w.phase_q16() as f64 / 65536.0;
            spread.push((got - phi).abs());
            let places = [0, 1, 2, 3].map(|k| w.first_place_q16(k) << 8);
            let u = start::start_position_on_q16(0, &times[..4], &places).unwrap_or(1 << 15);
            let four = if dir > 0 { u } else { (1 << 16) - u };
            first_four.push((four as f64 / 65536.0 - phi).abs());
        }
        spread.sort_by(f64::total_cmp);
        first_four.sort_by(f64::total_cmp);
        (spread, first_four, placed)
    }

    #[test]
    fn a_start_from_rest_is_fitted_again_through_spread_ticks() {
        for dir in [1, -1] {
            let (spread, first_four, placed) = start_errors_from_rest(dir, 0.0);
            let (median, worst) = (spread[12], spread[23]);
            // Each line's placement, magnified by the cubic's extrapolation back to rest.
            assert!(placed && median < 0.05 && worst < 0.2, "{dir}: {spread:?}");
            assert!(
                median < first_four[12] && worst < first_four[23],
                "{dir}: {spread:?} {first_four:?}"
            );
        }
    }

    #[test]
    fn a_pause_after_the_fifth_tick_keeps_the_fit_off_the_ninth() {
        // Standing 0.2 s after the fifth tick: the ninth says nothing of the start's curve.
        let (spread, _, placed) = start_errors_from_rest(1, 0.2);
        assert!(
            placed && spread[12] < 0.05 && spread[23] < 0.25,
            "{placed} {spread:?}"
        );
    }

    #[test]
    fn edges_learned_even_leave_a_joint_placement_on_whole_counts() {
        // The abrupt start of `wheels_that_start_abruptly_after_a_rest_are_placed_together`,
        // each wheel's learner holding offsets under `UNEVEN_Q16` (what windows learn of even
        // edges: their time stamps' rounding): placed exactly as with nothing learned.
        let start = 1_000_000_000u64;
        let ticks = |phi: f64, per_s: f64| -> [u64; 6] {
            core::array::from_fn(|k| start + ((k as f64 + 1.0 - phi) / per_s * 1e9) as u64)
        };
        let place = |offsets: [i32; 4]| {
            let mut wheels = [TickTracker::starting(0, 0), TickTracker::starting(0, 0)];
            for w in &mut wheels {
                w.learner = Learner::with_offsets_q16(offsets);
            }
            let mut all: Vec<(u64, usize)> = (0..2)
                .flat_map(|j| {
                    let (phi, v) = [(0.35, 1000.0), (0.8, 600.0)][j];
                    ticks(phi, v).map(|t| (t, j))
                })
                .collect();
            all.sort();
            for (t, j) in all {
                tick_wheel(&mut wheels, j, t, 1);
            }
            wheels.map(|w| w.phase_q16())
        };
        assert_eq!(place([300, -200, 100, -300]), place([0; 4]));
    }

    #[test]
    fn corrupt_steps_are_ignored() {
        let mut w = TickTracker::new();
        w.tick(1, 3);
        w.tick(2, 0);
        assert_eq!(w.count(), 0);
        assert_eq!(w.position_q16(10), 0);
    }
}

/// A tick of wheel `j` of `wheels` at `t_ns`, `step` = ±1; while that wheel's first ticks
/// are being gathered, every wheel is placed again ([`place_together`]), and after that the
/// tick costs nothing more. Integer-only. Returns the wheel's count, or `None` (and changes
/// nothing) for a wheel that is not in `wheels` or a step that is not ±1.
pub fn tick_wheel(wheels: &mut [TickTracker], j: usize, t_ns: u64, step: i8) -> Option<i64> {
    let w = wheels.get_mut(j)?;
    if step != 1 && step != -1 {
        return None;
    }
    let placing = w.placing();
    w.advance(t_ns, step);
    let count = w.count();
    if placing {
        place_together(wheels);
    }
    Some(count)
}

/// Each wheel learns its edges, as at an update ([`TickTracker::learn`]); if one was fitted
/// again on them, the wheels no fit places are placed together again ([`place_together`], on
/// their learned edges). Integer-only.
pub fn learn_edges(wheels: &mut [TickTracker]) {
    let mut refit = false;
    for w in wheels.iter_mut() {
        refit |= w.learn();
    }
    if refit {
        place_together(wheels);
    }
}

/// Wheels that their own first ticks could not place started moving together: after a rest
/// the body starts as one, so an abrupt start (whose instant no single wheel can tell) must lie
/// in every such wheel's window ([`TickTracker::start_window`]: `[t1 − first interval, t1]` on
/// even edges, the span from the count's other edge on learned uneven ones). Each is placed as
/// if it started in the middle of their common window; a wheel's error is then at most half
/// the window at its own speed (under half a count on even edges), and the fastest wheel
/// narrows the window for all. Called by [`tick_wheel`] after a tick of a wheel that was
/// [`placing`](TickTracker::placing) before it, and by [`learn_edges`] once a wheel's start
/// was fitted again on learned edges: no other tick changes a window. Integer-only.
// Cold and out of line: it runs for a wheel's first few ticks only, and inlined its frame
// would be set up on every edge.
#[cold]
#[inline(never)]
pub fn place_together(trackers: &mut [TickTracker]) {
    let (mut lo, mut hi, mut any) = (0u64, u64::MAX, false);
    for w in trackers.iter().filter_map(TickTracker::start_window) {
        lo = lo.max(w.0);
        hi = hi.min(w.1);
        any = true;
    }
    if any && lo <= hi {
        let t_start = lo + (hi - lo) / 2;
        for t in trackers.iter_mut() {
            t.place_from(t_start);
        }
    }
}

/// Feed per-tick methods (seed 001's table method) from sampled counts: the change of each
/// wheel's count since `applied` becomes that many ±1 ticks, the wheels interleaved so no
/// wheel runs ahead of the others by more than a tick. `applied` is brought up to `counts`.
pub fn counts_as_ticks(applied: &mut [i64], counts: &[i64], mut tick: impl FnMut(usize, i8)) {
    loop {
        let mut moved = false;
        for (j, (a, &c)) in applied.iter_mut().zip(counts).enumerate() {
            if *a != c {
                let step = (c - *a).signum() as i8;
                tick(j, step);
                *a += step as i64;
                moved = true;
            }
        }
        if !moved {
            break;
        }
    }
}

#[cfg(test)]
mod position_in_32_bits_tests {
    use super::*;
    use proptest::prelude::*;

    /// [`TickTracker::edge_position_q16`] as it was written in 64 bits throughout.
    fn in_64_bits(w: &TickTracker, t_ns: u64) -> i64 {
        let at_edge = (w.edge << 16) + w.learner.offset_q16(w.edge);
        let Some(nz) = w.interval else {
            return at_edge;
        };
        let interval = nz.get();
        let since = t_ns.saturating_sub(w.last_t);
        if interval >= 1 << 40 {
            return at_edge;
        }
        let (dir, table) = (w.dir, &w.learner);
        let back = w.edge - dir as i64;
        let s2 = table.span_q16(back, dir);
        let next = table.span_q16(w.edge, dir);
        let x = ((since.min(interval * 8) << 16) / nz) as i64;
        let frac = match w.prev_interval {
            None => (s2 * x) >> 16,
            Some(t1) => {
                let s1 = table.span_q16(back - dir as i64, dir);
                let rho = ((interval << 16) / t1).clamp(1 << 12, 1 << 20) as i64;
                let c = (s2 - ((rho * s1) >> 16)) * rho / ((1 << 16) + rho);
                let x = if c < 0 {
                    x.min((s2 + c) * (1 << 16) / (-2 * c))
                } else {
                    x
                };
                ((s2 * x) >> 16) + ((c * (x + ((x * x) >> 16))) >> 16)
            }
        };
        at_edge + dir as i64 * frac.clamp(0, next - 1)
    }

    proptest! {
        /// The 32-bit form (64-bit products) gives what the 64-bit one gave, on any learned
        /// offsets, intervals and instant.
        #[test]
        fn the_interpolation_in_32_bits_equals_it_in_64(
            offsets in proptest::array::uniform4(-26_214i32..=26_214),
            edge in -100_000i64..100_000,
            forward in proptest::bool::ANY,
            interval in 1u64..1 << 41,
            prev in proptest::option::of(1u64..1 << 41),
            since in 0u64..1 << 43,
        ) {
            let mut w = TickTracker::starting(edge, 0);
            w.learner = Learner::with_offsets_q16(offsets);
            w.edge = edge;
            w.dir = if forward { 1 } else { -1 };
            w.last_t = 1 << 20;
            w.interval = NonZeroU64::new(interval);
            w.prev_interval = prev.and_then(NonZeroU64::new);
            let t = w.last_t + since;
            prop_assert_eq!(w.edge_position_q16(t), in_64_bits(&w, t));
        }
    }
}

#[cfg(test)]
mod counts_as_ticks_tests {
    use super::counts_as_ticks;

    #[test]
    fn interleaves_and_catches_up() {
        let mut applied = [0i64, 5];
        let mut seen = [0i64; 2];
        let mut order = [0usize; 16];
        let mut n = 0;
        counts_as_ticks(&mut applied, &[3, 3], |j, s| {
            seen[j] += s as i64;
            order[n] = j;
            n += 1;
        });
        assert_eq!(applied, [3, 3]);
        assert_eq!(seen, [3, -2]);
        assert_eq!(&order[..n], &[0, 1, 0, 1, 0]);
    }
}
