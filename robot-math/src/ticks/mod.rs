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
    /// until its ticks place it.
    phase_q16: i64,
    /// The wheel's own first ticks placed it: a fit, or shaken across its first edge.
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
            // The wheel turned back: keep what we have (below: right after its first tick).
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
            if n == 1 {
                // It turned back right after its first tick, over the edge it had just
                // crossed: it stood by that edge, shaken across it (a motor holding the wheel,
                // a bump, a hand setting the robot down), not anywhere in its count. Placed
                // there now (one tick fits nothing, so nothing placed it yet), as no later fit
                // will: half a count off otherwise, a heading error for the whole run; and
                // there again once its edges are learned. A wheel that really went most of a
                // count and back is the rarer case at power-on.
                // (`ticks::tests::a_wheel_shaken_across_*`.)
                self.place_on_learned_edges();
            }
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
    /// edge made them look like an abrupt start) may be placed now; a wheel shaken across its
    /// first edge at power-on ([`fit_start`](Self::fit_start)) is placed on that edge, which
    /// no fit places. Whether it placed the wheel (else the wheel keeps what it had).
    #[cold]
    #[inline(never)]
    fn place_on_learned_edges(&mut self) -> bool {
        let times = &self.first[..(self.gathered as usize).min(PLACING_TICKS)];
        let places = self.first_places_q16(self.fit_ticks());
        let u = if times.len() == 1 && !self.placing() {
            places[0]
        } else {
            let places = places.map(|p| p << 8);
            let Some(u) = start::start_position_on_q16(self.start_ns, times, &places) else {
                return false;
            };
            u
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

    /// Where the first direction's `k`-th ticks' edges lie, for each `k` of `ticks` (0: the
    /// first tick's, −1: the count's other edge), Q16 counts along that direction from the
    /// count's first edge's whole-count place (c0 forward, c0 + 1 backward): `k + 1`, moved by
    /// the edge's learned offset. Out of line: the start's fits call it for a wheel's first
    /// ticks only.
    #[inline(never)]
    fn first_places_q16(&self, ticks: [i64; 4]) -> [i64; 4] {
        let d = self.first_dir as i64;
        let first = if d > 0 {
            self.start_count + 1
        } else {
            self.start_count
        };
        // Edges not found uneven are whole counts here, as before anything was learned: what a
        // window learns of even edges is its time stamps' rounding.
        let uneven = self.learner.table().uneven();
        ticks.map(|k| {
            let offset = if uneven {
                self.learner.offset_q16(first + d * k)
            } else {
                0
            };
            ((k + 1) << 16) + d * offset
        })
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
    /// ([`first_places_q16`](Self::first_places_q16)).
    fn start_window(&self) -> Option<(u64, u64, u64, [i64; 3])> {
        if self.placed || self.first_len < 2 {
            return None;
        }
        let (t1, t2) = (self.first[0], self.first[1]);
        let interval = t2.checked_sub(t1).filter(|&i| i > 0 && i < 1 << 40)?;
        let [p0, p1, p2, _] = self.first_places_q16([-1, 0, 1, 1]);
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
mod tests;
