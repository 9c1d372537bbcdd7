//! Where a wheel's encoder really puts the four edges of its quadrature cycle, learned while it
//! moves.
//!
//! A quadrature encoder's edges are not a count apart: its two channels' high times, their
//! phase and the code wheel's lines are off by a few electrical degrees (Broadcom's HEDS-9040:
//! state width error 5 °e typical, 30 °e at most, of a count's 90 °e). Taking every edge to be
//! one count after the last misplaces the wheel at each tick by up to a third of a count, and
//! the interpolation between ticks reads a narrow state as a burst of speed.
//!
//! Edges of one kind (A rising, say) are one cycle, four counts, apart, whatever the state
//! widths: the edge number modulo 4 says which kind an edge is. So two whole cycles (nine ticks
//! one way) span exactly eight counts between their first, middle and last edges, and the
//! motion through them, fitted as a constant acceleration through those three, says where the
//! six edges between really were. Each offset (counts off its whole-count place, the four
//! centred on zero) moves toward what a window measured: as a running mean over the first
//! [`SETTLED`] windows, then by 1/[`SETTLED`] of the difference, so the table follows a slow
//! drift (temperature) and a few windows' noise averages out.
//!
//! Integer-only (the slave has no FPU), in 32 bits with 64-bit products and no 64-bit division
//! (Q24 inside the fit, Q16 counts out): the slave learns as the host does, bit for bit.

use core::num::NonZeroU32;

/// Fraction bits inside the window's fit.
const Q: u32 = 24;
const ONE: i32 = 1 << Q;
/// Windows after which the offsets follow at a fixed gain (1/16) instead of a running mean.
pub const SETTLED: u8 = 16;
/// The first cycle of a window takes at most this share of it off one half (1/2 ± 1/8): harder
/// accelerations (or a wheel slowing to a stop) are not measured.
const MAX_SKEW: i32 = ONE / 8;
/// The most the two cycles of a window may disagree on an edge's place, Q24 counts: 1/64 of a
/// count (1.4 °e). A step in speed inside the window (its two cycles then disagree by the
/// step's share of a count) is not measured; nor is a window whose two lines are placed
/// further apart than that (HEDS-9040's cycle error: 3 °e typical, 5.5 at most; at the
/// typical, about a quarter of the windows), which slows learning but keeps the lines' error out
/// of the kinds' offsets. 1/32 measured no better on the accuracy suite (2026-11-29).
const MAX_DISAGREEMENT: i32 = ONE / 64;
/// Offsets under this (Q16 counts: 1/64 of a count, [`MAX_DISAGREEMENT`]'s width) are within
/// what a window's own noise leaves (its time stamps' rounding): edges no further off than this
/// are not taken to be uneven, so a wheel's start is not fitted again on them (that fit
/// extrapolates back to rest and magnifies the noise: on ideal edges it cost the emulated
/// pursuit's worst error 0.045 → 0.067 mm, and the suite's median case while moving 467× →
/// 416× below the best baseline; 2026-11-29).
pub const UNEVEN_Q16: u32 = 1 << 10;
/// No learned edge is taken further than this from its whole-count place (Q16 counts): 0.4 of
/// a count, past any datasheet's maximum.
const MAX_OFFSET_Q16: i32 = 26_214;
// Two offsets apart keep a span above zero (the interpolation's clamp needs it).
const _: () = assert!(2 * MAX_OFFSET_Q16 < 1 << 16);

/// The four edges of a wheel's quadrature cycle, as far as its motion has shown them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct EdgeTable {
    /// Edge `e` lies at `e + offset_q16[e & 3] / 65536` counts.
    offset_q16: [i32; 4],
    /// Windows measured, up to [`SETTLED`].
    windows: u8,
}

impl EdgeTable {
    /// Nothing learned: every edge at its whole-count place.
    pub const fn new() -> Self {
        EdgeTable {
            offset_q16: [0; 4],
            windows: 0,
        }
    }

    /// Edge `e`'s offset from its whole-count place, Q16 counts.
    #[inline(always)]
    pub fn offset_q16(&self, edge: i64) -> i64 {
        self.offset_q16[(edge & 3) as usize] as i64
    }

    /// The distance from edge `from` to the next edge in direction `dir` (±1), Q16 counts
    /// along that direction.
    #[inline(always)]
    pub fn span_q16(&self, from: i64, dir: i8) -> i64 {
        let to = from + dir as i64;
        let apart = self.offset_q16(to) - self.offset_q16(from);
        (1 << 16) + if dir > 0 { apart } else { -apart }
    }

    /// Windows measured so far (saturating at [`SETTLED`]).
    pub fn windows(&self) -> u8 {
        self.windows
    }

    /// Some kind's offset is past [`UNEVEN_Q16`]: the edges are measurably uneven.
    pub fn uneven(&self) -> bool {
        self.offset_q16
            .iter()
            .any(|o| o.unsigned_abs() > UNEVEN_Q16)
    }

    /// Learn from a window of nine ticks one way, given as the eight intervals between them
    /// (ns, oldest first), the last tick over edge `last_edge` going `dir`. A window whose
    /// motion is not smooth enough to measure (see [`MAX_SKEW`], [`MAX_DISAGREEMENT`]), or
    /// longer than 2^32 ns (4.3 s), changes nothing; returns whether it was taken.
    // Out of line and in 32 bits: the slave's flash has little room (one copy), and its
    // divisions are the M3's 32-bit ones (`reciprocal_q56`, `div_q24`).
    #[inline(never)]
    pub fn learn(&mut self, intervals: &[u32; WINDOW - 1], last_edge: i64, dir: i8) -> bool {
        let Some(measured) = measure(intervals) else {
            return false;
        };
        // The deviations are along the travel; the offsets on the encoder's own scale. Only
        // the low two bits of an edge say its kind, and the window's first edge, eight before
        // the last, is of the last one's.
        let d = dir as i32;
        let first_kind = last_edge as i32;
        // A running mean at first (the n-th window weighs 1/(n+1)), then a fixed gain.
        let gain = (self.windows as i32 + 1).min(SETTLED as i32);
        let mut i = 0;
        while i < 4 {
            let k = (first_kind.wrapping_add(d * i as i32) & 3) as usize;
            let o = self.offset_q16[k];
            let diff = d * measured[i] - o;
            // Rounded to nearest, so the offset does not stop short by up to a gain's worth.
            let step = (diff + diff.signum() * (gain / 2)) / gain;
            self.offset_q16[k] = (o + step).clamp(-MAX_OFFSET_Q16, MAX_OFFSET_Q16);
            i += 1;
        }
        self.windows = (self.windows + 1).min(SETTLED);
        true
    }
}

/// Each of the four edge kinds' offsets (Q16 counts along the travel, centred on zero) as a
/// window shows them: index `i` is the kind of the window's `i`-th edge.
fn measure(intervals: &[u32; WINDOW - 1]) -> Option<[i32; 4]> {
    // Each tick's time since the window's first, and the window's length.
    let mut since = [0u32; WINDOW];
    let mut i = 0;
    while i < WINDOW - 1 {
        since[i + 1] = since[i].checked_add(intervals[i])?;
        i += 1;
    }
    let span = since[WINDOW - 1];
    if span == 0 {
        return None;
    }
    // x_i = since_i / span in Q24 units of the window, by one reciprocal: the span scaled to
    // [2^31, 2^32), r = 2^56 / that in (2^24, 2^25], x = since·r / 2^32 (one `umull` each).
    let scale = span.leading_zeros();
    let r = reciprocal_q56(span << scale) as u64;
    let x = |i: usize| (((since[i] << scale) as u64 * r) >> 32) as i32;
    let a = x(4);
    if (a - ONE / 2).abs() > MAX_SKEW {
        return None;
    }
    // The constant acceleration through (0, 0), (a, 1/2), (1, 1) in units of the window's
    // eight counts: p(x) = x + c·x·(x − 1), c = (a − 1/2) / (a·(1 − a)), |c| < 0.54 (Q24).
    // (Above 0.23 with `a` inside the skew's bounds; `NonZeroU32` keeps a panic path off the
    // board all the same.)
    let a_1_a = NonZeroU32::new(((a as i64 * (ONE - a) as i64) >> Q) as u32)?;
    let skew = a - ONE / 2;
    let c = div_q24(skew.unsigned_abs(), a_1_a) as i64 * skew.signum() as i64;
    // Deviation of each inner edge from its whole-count place, Q24 counts: 8·p(x_i) − i.
    let mut dev = [0i32; WINDOW - 1];
    let mut i = 1;
    while i < WINDOW - 1 {
        let xi = x(i);
        let bend = (xi as i64 * (xi - ONE) as i64) >> Q;
        let p = xi + ((c * bend) >> Q) as i32;
        dev[i] = 8 * p - ((i as i32) << Q);
        i += 1;
    }
    // The two cycles' measures of each kind averaged, relative to the first edge's kind (0),
    // then centred. Cycles that disagree by more than [`MAX_DISAGREEMENT`] were not one smooth
    // motion (a step in speed, a bump): nothing is taken from them.
    let mut rel = [0i32; 4];
    let mut k = 1;
    while k < 4 {
        if (dev[k] - dev[k + 4]).abs() > MAX_DISAGREEMENT {
            return None;
        }
        rel[k] = (dev[k] + dev[k + 4]) / 2;
        k += 1;
    }
    let mean = (rel[1] + rel[2] + rel[3]) / 4;
    // Q24 to Q16, rounded.
    Some(rel.map(|r| (r - mean + (1 << 7)) >> 8))
}

/// 2^56 / `s` for `s` in [2^31, 2^32), within 2 of the quotient (the same on every machine: it
/// is integer arithmetic throughout): a seed from a 32-bit division, within 2^-14 of it, and
/// one Newton step. The M3 divides 32 bits in hardware but 64 in a few hundred instructions.
fn reciprocal_q56(s: u32) -> u32 {
    // (s / 2^16 rounded up) in [2^15 + 1, 2^16]: the seed 2^47 / that is an underestimate.
    let d = NonZeroU32::MIN.saturating_add(s >> 16);
    let r = ((1u32 << 31) / d) << 9;
    // r' = r + r·(2^56 − s·r) / 2^56; the error term is at most 2^42, taken to 22 bits.
    let e = (1u64 << 56) - s as u64 * r as u64;
    r + ((r as u64 * (e >> 20)) >> 36) as u32
}

/// ⌊n·2^24 / d⌋ for `n` < 2^22, `d` ≤ 2^22 and `n` < 2^8·`d` (the quotient under 2^32), by three
/// 32-bit divisions (long division, ten, ten and four bits at a time): exactly the 64-bit
/// quotient. (The fit's: `n` ≤ 2^21, `d` ≥ 0.23·2^24.)
fn div_q24(n: u32, d: NonZeroU32) -> u32 {
    let (q1, r1) = ((n << 10) / d, (n << 10) % d);
    let (q2, r2) = ((r1 << 10) / d, (r1 << 10) % d);
    (q1 << 14) | (q2 << 4) | ((r2 << 4) / d)
}

/// What a tracker keeps to learn its encoder's edges: the intervals between its last ticks
/// one way (two cycles' window) and the table.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Learner {
    /// Learning is on (the default; off, every edge is a whole count).
    on: bool,
    /// The intervals up to the last ticks (ns, at most `u32::MAX`), each at the slot of the
    /// edge its tick crossed (edge mod 8: no shifting), while they all went the last tick's way
    /// (`run` of them; the others are zero).
    intervals: [u32; WINDOW - 1],
    run: u8,
    /// The last tick completed a window that has not been learned from yet.
    fresh: bool,
    table: EdgeTable,
}

/// Ticks one way that span two whole quadrature cycles: what [`EdgeTable::learn`] measures.
pub const WINDOW: usize = 9;

impl Learner {
    /// Nothing learned yet; learning if `on`.
    pub const fn new(on: bool) -> Self {
        Learner {
            on,
            intervals: [0; WINDOW - 1],
            run: 0,
            fresh: false,
            table: EdgeTable::new(),
        }
    }

    /// After a tick over `edge`, `interval` ns after the one before, `same_way` as it.
    #[inline(always)]
    pub fn advance(&mut self, same_way: bool, interval: u64, edge: i64) {
        if same_way {
            // A longer one makes the window too long to measure anyway.
            self.intervals[(edge & 7) as usize] = interval.min(u32::MAX as u64) as u32;
            self.run = (self.run + 1).min(WINDOW as u8 - 1);
        } else {
            // Cleared, so the state depends on the last ticks alone (`RecentTicks`).
            self.intervals = [0; WINDOW - 1];
            self.run = 0;
        }
        self.fresh = self.run == WINDOW as u8 - 1;
    }

    pub fn on(&self) -> bool {
        self.on
    }

    /// Learning on, or off and what was learned forgotten.
    pub fn set_on(&mut self, on: bool) {
        if !on {
            *self = Learner::new(false);
        }
        self.on = on;
    }

    /// Learn from the window the last tick (over `last_edge`, way `dir`) completed, once;
    /// true if it was taken.
    pub fn learn(&mut self, last_edge: i64, dir: i8) -> bool {
        if !(self.on && self.fresh) {
            return false;
        }
        self.fresh = false;
        // Oldest first: the intervals up to edges last − 7·dir, ..., last.
        let d = dir as i64;
        let window = core::array::from_fn(|j| {
            self.intervals[((last_edge - d * (WINDOW as i64 - 2 - j as i64)) & 7) as usize]
        });
        self.table.learn(&window, last_edge, dir)
    }

    #[inline(always)]
    pub fn table(&self) -> &EdgeTable {
        &self.table
    }

    /// [`EdgeTable::offset_q16`] of what was learned.
    #[inline(always)]
    pub fn offset_q16(&self, edge: i64) -> i64 {
        self.table.offset_q16(edge)
    }

    /// [`EdgeTable::span_q16`] of what was learned.
    #[inline(always)]
    pub fn span_q16(&self, from: i64, dir: i8) -> i64 {
        self.table.span_q16(from, dir)
    }
}

#[cfg(test)]
impl Learner {
    /// A learner that has learned these offsets (Q16 counts), for tests of their use.
    pub(super) fn with_offsets_q16(offset_q16: [i32; 4]) -> Self {
        let mut l = Learner::new(true);
        l.table.offset_q16 = offset_q16;
        l
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The intervals between nine ticks at `times` (ns).
    fn intervals(times: [u64; 9]) -> [u32; 8] {
        core::array::from_fn(|k| (times[k + 1] - times[k]) as u32)
    }

    /// Nine ticks of a wheel whose edges sit at `k + off[k & 3]` counts, moving as
    /// `pos(t) = v·t + acc·t²/2` (counts, seconds) from edge 0: the intervals between them.
    fn window(off: [f64; 4], v: f64, acc: f64) -> [u32; 8] {
        intervals(core::array::from_fn(|k| {
            let p = k as f64 + off[k & 3] - off[0];
            let t = if acc == 0.0 {
                p / v
            } else {
                (-v + (v * v + 2.0 * acc * p).sqrt()) / acc
            };
            (t * 1e9).round() as u64 + 1_000
        }))
    }

    fn learned(table: &EdgeTable) -> [f64; 4] {
        table.offset_q16.map(|o| o as f64 / 65536.0)
    }

    #[test]
    fn the_reciprocal_and_the_long_division_match_64_bit_division() {
        let mut spans = vec![1u32 << 31, u32::MAX, (1 << 31) + 1, 3_000_000_000];
        let mut s = 0x9E37_79B9u32;
        for _ in 0..20_000 {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            spans.push(s | 1 << 31);
        }
        for &span in &spans {
            let exact = (1u64 << 56) / span as u64;
            let got = reciprocal_q56(span) as u64;
            assert!(exact.abs_diff(got) <= 2, "{span}: {got} vs {exact}");
        }
        for (n, d) in [
            (0, 1),
            (1 << 21, 3_932_160),
            (1, 4_194_303),
            (4_194_303, 3_932_161),
        ]
        .into_iter()
        .chain(
            spans
                .iter()
                .map(|&s| (s >> 11 & 0x1F_FFFF, (s >> 10).max(1) >> 10 | 1 << 21)),
        ) {
            assert_eq!(
                div_q24(n, NonZeroU32::new(d).unwrap()) as u64,
                ((n as u64) << 24) / d as u64,
                "{n} / {d}"
            );
        }
    }

    #[test]
    fn ideal_edges_learn_nothing() {
        let mut t = EdgeTable::default();
        assert!(t.learn(&window([0.0; 4], 2000.0, 0.0), 8, 1));
        assert!(
            learned(&t).iter().all(|o| o.abs() < 1e-4),
            "{:?}",
            learned(&t)
        );
        assert!(!t.uneven());
        // A typical datasheet's state width error (5 °e of a count's 90) is past the noise.
        let mut t = EdgeTable::default();
        assert!(t.learn(&window([0.0, 0.055, 0.0, 0.0], 2000.0, 0.0), 8, 1));
        assert!(t.uneven(), "{:?}", learned(&t));
    }

    #[test]
    fn uneven_edges_are_found_at_constant_speed_and_under_acceleration() {
        // Centred: the table reports offsets with mean zero.
        let off = [-0.03, 0.05 - 0.03, -0.02 - 0.03, 0.08 - 0.03];
        let mean = off.iter().sum::<f64>() / 4.0;
        for acc in [0.0, 4000.0, -3000.0] {
            let mut t = EdgeTable::default();
            assert!(t.learn(&window(off, 2000.0, acc), 8, 1), "acc {acc}");
            for (got, want) in learned(&t).iter().zip(off) {
                assert!(
                    (got - (want - mean)).abs() < 2e-3,
                    "acc {acc}: {got} vs {want}"
                );
            }
        }
    }

    #[test]
    fn backwards_the_same_edges_are_found() {
        // Moving down from edge 8 to edge 0: the k-th tick crosses edge 8 − k.
        let off = [0.0, 0.06, -0.04, 0.02];
        let mean = off.iter().sum::<f64>() / 4.0;
        let times: [u64; 9] = core::array::from_fn(|k| {
            let edge = 8 - k;
            let p = 8.0 + off[0] - (edge as f64 + off[edge & 3]);
            (p / 1500.0 * 1e9).round() as u64 + 7
        });
        let mut t = EdgeTable::default();
        assert!(t.learn(&intervals(times), 0, -1));
        for (got, want) in learned(&t).iter().zip(off) {
            assert!((got - (want - mean)).abs() < 2e-3, "{got} vs {want}");
        }
    }

    #[test]
    fn a_hard_stop_is_not_measured() {
        let mut t = EdgeTable::default();
        let mut iv = window([0.0; 4], 2000.0, 0.0);
        iv[7] += 10_000_000;
        assert!(!t.learn(&iv, 8, 1));
        assert_eq!(t, EdgeTable::default());
        // Nor windows of no time, or too long to measure.
        assert!(!t.learn(&[0; 8], 8, 1));
        assert!(!t.learn(&[u32::MAX / 4; 8], 8, 1));
        assert_eq!(t, EdgeTable::default());
    }

    /// A wheel at a constant 1 000 counts/s from power-on, 0.3 of a count into its count,
    /// its edges at `k + off[k & 3]`: ticked, and learned from at every tick as `exact`'s
    /// update does; the worst error (counts) between ticks over counts 150 to 200.
    fn worst_between_ticks(learn: bool) -> f64 {
        use super::super::TickTracker;
        let off = [0.0, 0.06, -0.04, 0.03];
        let mean = off.iter().sum::<f64>() / 4.0;
        let place = |k: i64| k as f64 + off[(k & 3) as usize] - mean;
        let at = |travel: f64| ((travel) / 1000.0 * 1e9).round() as u64;
        let mut w = TickTracker::starting(0, 0);
        w.set_edge_learning(learn);
        let mut worst = 0.0f64;
        for k in 1..=200i64 {
            let t = at(place(k) - 0.3);
            w.tick(t, 1);
            w.learn();
            if k >= 150 {
                // Between this tick and the next, in tenths.
                let next = at(place(k + 1) - 0.3);
                for i in 1..10 {
                    let ti = t + (next - t) * i / 10;
                    let truth = ti as f64 * 1e-9 * 1000.0;
                    let got = w.position_q16(ti) as f64 / 65536.0;
                    worst = worst.max((got - truth).abs());
                }
            }
        }
        worst
    }

    #[test]
    fn a_tracker_that_learns_its_edges_places_the_wheel_between_uneven_ticks() {
        let (without, with) = (worst_between_ticks(false), worst_between_ticks(true));
        // Taking the edges a count apart is off by their offsets (and the spans' speeds);
        // learned, the start placed again on them, a few thousandths of a count is left.
        assert!(without > 0.03, "{without}");
        assert!(with < 0.005, "{with}");
    }
}
