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
//! Integer-only (the slave has no FPU), in `i64` (Q24 inside the fit, Q16 counts out).

/// Fraction bits inside the window's fit.
const Q: u32 = 24;
const ONE: i64 = 1 << Q;
/// Windows after which the offsets follow at a fixed gain (1/16) instead of a running mean.
pub const SETTLED: u8 = 16;
/// The first cycle of a window takes at most this share of it off one half (1/2 ± 1/8): harder
/// accelerations (or a wheel slowing to a stop) are not measured.
const MAX_SKEW: i64 = ONE / 8;
/// Longest window taken, in ns (a wheel slower than eight counts in 4.3 s is not measured:
/// the products below stay inside 64 bits).
const MAX_WINDOW_NS: u64 = 1 << 32;
/// The most the two cycles of a window may disagree on an edge's place, Q24 counts: 1/64 of a
/// count (1.4 °e). A step in speed inside the window (its two cycles then disagree by the
/// step's share of a count) is not measured; nor is a window whose two lines are placed
/// further apart than that (HEDS-9040's cycle error: 3 °e typical, 5.5 at most; at the
/// typical, about a quarter of the windows), which slows learning but keeps the lines' error out
/// of the kinds' offsets. 1/32 measured no better on the accuracy suite (2026-11-29).
const MAX_DISAGREEMENT: i64 = ONE / 64;
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
        (1 << 16) + dir as i64 * (self.offset_q16(to) - self.offset_q16(from))
    }

    /// Windows measured so far (saturating at [`SETTLED`]).
    pub fn windows(&self) -> u8 {
        self.windows
    }

    /// Learn from a window of nine ticks one way: `times[i]` the tick over edge
    /// `last_edge - dir·(8 − i)`. A window whose motion is not smooth enough to measure (see
    /// [`MAX_SKEW`], [`MAX_DISAGREEMENT`]), or whose times are out of order, changes nothing;
    /// returns whether it was taken.
    pub fn learn(&mut self, times: &[u64; 9], last_edge: i64, dir: i8) -> bool {
        let Some(measured) = measure(times) else {
            return false;
        };
        // The deviations are along the travel; the offsets on the encoder's own scale.
        let d = dir as i64;
        let first_edge = last_edge - 8 * d;
        let n = self.windows as i64;
        for (i, m) in measured.iter().enumerate() {
            let k = ((first_edge + d * i as i64) & 3) as usize;
            let m = d * m;
            let o = self.offset_q16[k] as i64;
            // A running mean at first (the n-th window weighs 1/(n+1)), then a fixed gain;
            // rounded to nearest, so the offset does not stop short by up to a gain's worth.
            let k_gain = (n + 1).min(SETTLED as i64);
            let diff = m - o;
            let step = (diff + diff.signum() * (k_gain / 2)) / k_gain;
            self.offset_q16[k] =
                (o + step).clamp(-MAX_OFFSET_Q16 as i64, MAX_OFFSET_Q16 as i64) as i32;
        }
        self.windows = self.windows.saturating_add(1).min(SETTLED);
        true
    }
}

/// Each of the four edge kinds' offsets (Q16 counts along the travel, centred on zero) as a
/// window shows them: index `i` is the kind of the window's `i`-th edge.
fn measure(times: &[u64; 9]) -> Option<[i64; 4]> {
    let (t0, t4, t8) = (times[0], times[4], times[8]);
    let span = t8.checked_sub(t0)?;
    if span == 0 || span >= MAX_WINDOW_NS {
        return None;
    }
    // In Q24 units of the window: x_i = (t_i − t0) / span, a = x_4.
    let x = |t: u64| -> Option<i64> {
        let since = t.checked_sub(t0).filter(|&s| s <= span)?;
        Some(((since << Q) / span) as i64)
    };
    let a = x(t4)?;
    if (a - ONE / 2).abs() > MAX_SKEW {
        return None;
    }
    // The constant acceleration through (0, 0), (a, 1/2), (1, 1) in units of the window's
    // eight counts: p(x) = x + c·x·(x − 1), c = (a − 1/2) / (a·(1 − a)).
    let c = ((a - ONE / 2) << Q) / ((a * (ONE - a)) >> Q);
    // Deviation of each inner edge from its whole-count place, Q24 counts: 8·p(x_i) − i.
    let mut dev = [0i64; 8];
    let mut before = 0;
    for (i, d) in dev.iter_mut().enumerate().skip(1) {
        let xi = x(times[i])?;
        if xi < before {
            return None; // out of order
        }
        before = xi;
        let p = xi + ((c * ((xi * (xi - ONE)) >> Q)) >> Q);
        *d = 8 * p - ((i as i64) << Q);
    }
    // The two cycles' measures of each kind averaged, relative to the first edge's kind (0),
    // then centred. Cycles that disagree by more than [`MAX_DISAGREEMENT`] were not one smooth
    // motion (a step in speed, a bump): nothing is taken from them.
    let mut rel = [0i64; 4];
    for (k, r) in rel.iter_mut().enumerate().skip(1) {
        if (dev[k] - dev[k + 4]).abs() > MAX_DISAGREEMENT {
            return None;
        }
        *r = (dev[k] + dev[k + 4]) / 2;
    }
    let mean = rel.iter().sum::<i64>() / 4;
    // Q24 to Q16, rounded.
    Some(rel.map(|r| (r - mean + (1 << 7)) >> 8))
}

/// What a tracker keeps to learn its encoder's edges: its last ticks one way (two cycles'
/// window) and the table. Compiled with the `edge-learning` feature (the host's); the slave's
/// 32 KiB has no room for it yet, so there it is a zero-sized stand-in whose table is all
/// whole counts, and the tracker's arithmetic folds to the even-edge one.
#[cfg(feature = "edge-learning")]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Learner {
    /// Learning is on (off by default: the slave cannot, and the host must agree with it).
    on: bool,
    /// The eight ticks before the last, oldest first, while they all went the last tick's
    /// way (`run` of them are).
    before: [u64; WINDOW - 1],
    run: u8,
    /// The last tick completed a window that has not been learned from yet.
    fresh: bool,
    table: EdgeTable,
}

/// Ticks one way that span two whole quadrature cycles: what [`EdgeTable::learn`] measures.
pub const WINDOW: usize = 9;

#[cfg(feature = "edge-learning")]
impl Learner {
    pub const fn new() -> Self {
        Learner {
            on: false,
            before: [0; WINDOW - 1],
            run: 0,
            fresh: false,
            table: EdgeTable::new(),
        }
    }

    /// After a tick: `same_way` as the one before, which came at `prev_t`.
    #[inline(always)]
    pub fn advance(&mut self, same_way: bool, prev_t: u64) {
        if same_way {
            let b = &mut self.before;
            for i in 1..b.len() {
                b[i - 1] = b[i];
            }
            b[WINDOW - 2] = prev_t;
            self.run = (self.run + 1).min(WINDOW as u8 - 1);
        } else {
            // Cleared, so the state depends on the last ticks alone (`RecentTicks`).
            self.before = [0; WINDOW - 1];
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
            *self = Learner::new();
        }
        self.on = on;
    }

    /// Learn from the window the last tick (at `last_t`, over `last_edge`, way `dir`)
    /// completed, once; true if it was taken.
    pub fn learn(&mut self, last_t: u64, last_edge: i64, dir: i8) -> bool {
        if !(self.on && self.fresh) {
            return false;
        }
        self.fresh = false;
        let mut window = [last_t; WINDOW];
        window[..WINDOW - 1].copy_from_slice(&self.before);
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

/// The stand-in without the `edge-learning` feature: nothing kept, every edge a whole count.
#[cfg(not(feature = "edge-learning"))]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Learner;

#[cfg(not(feature = "edge-learning"))]
impl Learner {
    pub const fn new() -> Self {
        Learner
    }

    #[inline(always)]
    pub fn advance(&mut self, _same_way: bool, _prev_t: u64) {}

    #[inline(always)]
    pub fn table(&self) -> &EdgeTable {
        &EVEN
    }

    /// Every edge at its whole-count place: constants, so the tracker's arithmetic folds to
    /// the even-edge one.
    #[inline(always)]
    pub fn offset_q16(&self, _edge: i64) -> i64 {
        0
    }

    #[inline(always)]
    pub fn span_q16(&self, _from: i64, _dir: i8) -> i64 {
        1 << 16
    }
}

#[cfg(not(feature = "edge-learning"))]
static EVEN: EdgeTable = EdgeTable::new();

#[cfg(test)]
mod tests {
    use super::*;

    /// Nine ticks of a wheel whose edges sit at `k + off[k & 3]` counts, moving as
    /// `pos(t) = v·t + acc·t²/2` (counts, seconds) from edge 0.
    fn window(off: [f64; 4], v: f64, acc: f64) -> [u64; 9] {
        core::array::from_fn(|k| {
            let p = k as f64 + off[k & 3] - off[0];
            let t = if acc == 0.0 {
                p / v
            } else {
                (-v + (v * v + 2.0 * acc * p).sqrt()) / acc
            };
            (t * 1e9).round() as u64 + 1_000
        })
    }

    fn learned(table: &EdgeTable) -> [f64; 4] {
        table.offset_q16.map(|o| o as f64 / 65536.0)
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
        assert!(t.learn(&times, 0, -1));
        for (got, want) in learned(&t).iter().zip(off) {
            assert!((got - (want - mean)).abs() < 2e-3, "{got} vs {want}");
        }
    }

    #[test]
    fn a_hard_stop_is_not_measured() {
        let mut t = EdgeTable::default();
        let mut times = window([0.0; 4], 2000.0, 0.0);
        times[8] += 10_000_000;
        assert!(!t.learn(&times, 8, 1));
        assert_eq!(t, EdgeTable::default());
        // Out of order or silly windows neither.
        assert!(!t.learn(&[5; 9], 8, 1));
        assert!(!t.learn(&[9, 8, 7, 6, 5, 4, 3, 2, 1], 8, 1));
    }

    /// A wheel at a constant 1 000 counts/s from power-on, 0.3 of a count into its count,
    /// its edges at `k + off[k & 3]`: ticked, and learned from at every tick as `exact`'s
    /// update does; the worst error (counts) between ticks over counts 150 to 200.
    #[cfg(feature = "edge-learning")]
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

    #[cfg(feature = "edge-learning")]
    #[test]
    fn a_tracker_that_learns_its_edges_places_the_wheel_between_uneven_ticks() {
        let (without, with) = (worst_between_ticks(false), worst_between_ticks(true));
        // Taking the edges a count apart is off by their offsets (and the spans' speeds);
        // learned, the start placed again on them, a few thousandths of a count is left.
        assert!(without > 0.03, "{without}");
        assert!(with < 0.005, "{with}");
    }
}
