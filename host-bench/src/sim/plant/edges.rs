//! Where a step's encoder edges fall: each whole count an encoder's position crosses, on the
//! cubic through the step's end positions and speeds, and the two encoders' edges in one
//! time order.

/// An edge: its time (s), its encoder, the count after it.
pub(super) type Edge = (f64, usize, i64);

/// Push encoder `j`'s edges in a step of `h` s from `t0`, in time order: its position goes
/// from `a` to `b` (counts) with speeds `v0`, `v1` at the ends (counts per step), and every
/// whole count between is an edge.
pub(super) fn push_crossings(
    edges: &mut Vec<Edge>,
    j: usize,
    t0: f64,
    h: f64,
    (a, b): (f64, f64),
    (v0, v1): (f64, f64),
) {
    let cubic = Cubic::hermite((a, b), (v0, v1));
    // Where the cubic reaches each edge (it is on opposite sides at the ends): Newton from
    // the inverse quintic's guess, kept inside the bracket by bisection ([`Crossing`]). The
    // guess is nearly always within 10^-9 counts already, so Newton is nearly always only a
    // check: every edge's guess first, then every guess checked, each loop without a branch
    // between edges; an edge whose guess missed (449 of the default run's 268 274) is then
    // solved again from the same guess. The check branching per edge took more time than
    // the guesses (1.9 M of the edges' 3.2 M cycles in the default run); the same arithmetic
    // on the same inputs gives the same times to the bit.
    let guess = InverseGuess::new((a, b), (v0, v1));
    let rising = b > a;
    let (fa, fb) = (whole_counts(a), whole_counts(b));
    let (lo, hi) = (fa.min(fb), fa.max(fb));
    // The edge an edge's count-after stands for.
    let edge_of = |count_after: i64| if rising { count_after } else { count_after + 1 };
    let guessed = |edge: i64| -> Edge {
        let count_after = if rising { edge } else { edge - 1 };
        (guess.at(edge as f64), j, count_after)
    };
    // In time order: downward, the higher edges are crossed first. A mapped range knows its
    // length, so `extend` writes the edges without a capacity check each (as `push` does).
    // Each edge holds its guess (the step's fraction) until it is checked.
    let first = edges.len();
    let edges_between = lo + 1..hi + 1;
    if rising {
        edges.extend(edges_between.map(guessed));
    } else {
        edges.extend(edges_between.rev().map(guessed));
    }
    let mut missed = false;
    for (u, _, count_after) in &mut edges[first..] {
        let e = edge_of(*count_after) as f64;
        // Not `>= 1e-9`: a NaN misses.
        let on_it = (cubic.position(*u) - e).abs() < 1e-9;
        missed |= !on_it;
        *u = t0 + h * *u;
    }
    if missed {
        for (t, _, count_after) in &mut edges[first..] {
            let e = edge_of(*count_after) as f64;
            *t = t0 + h * solve(&cubic, e, guess.at(e), rising);
        }
    }
}

/// [`push_crossings`] for an encoder whose edges are where `map` puts them (uneven: a real
/// encoder's, `crate::sim::generate::EdgeMap`): each edge solved on the same cubic from the
/// same guess, the count after it the map's.
pub(super) fn push_mapped_crossings(
    edges: &mut Vec<Edge>,
    j: usize,
    t0: f64,
    h: f64,
    (a, b): (f64, f64),
    (v0, v1): (f64, f64),
    map: &crate::sim::generate::EdgeMap,
) {
    let cubic = Cubic::hermite((a, b), (v0, v1));
    let guess = InverseGuess::new((a, b), (v0, v1));
    let rising = b > a;
    let (ca, cb) = (map.count_at(a), map.count_at(b));
    let mut push = |edge: i64, count_after: i64| {
        let e = map.edge(edge);
        edges.push((
            t0 + h * solve(&cubic, e, guess.at(e), rising),
            j,
            count_after,
        ));
    };
    if rising {
        for c in ca + 1..=cb {
            push(c, c);
        }
    } else {
        // Downward, edge c takes the count from c to c − 1; the higher edges come first.
        for c in (cb + 1..=ca).rev() {
            push(c, c - 1);
        }
    }
}

/// The step's fraction where `cubic` reaches `edge`, from the guess `u`: Newton kept inside
/// the bracket by bisection ([`Crossing`]), at most 60 iterations.
fn solve(cubic: &Cubic, edge: f64, u: f64, rising: bool) -> f64 {
    let mut crossing = Crossing::start(edge, u);
    for _ in 0..60 {
        if crossing.iterate(cubic, rising) {
            break;
        }
    }
    crossing.u
}

/// The whole counts at or below `x` (`x.floor()`, as an integer), for positions below 2^63
/// counts. Without SSE4.1's rounding instruction (not in the x86-64 baseline) `floor` is a
/// library call; this is a conversion and a compare.
#[inline(always)]
pub(super) fn whole_counts(x: f64) -> i64 {
    let t = x as i64; // toward zero
    t - ((t as f64) > x) as i64
}

/// A step's position in counts as a cubic in the step's fraction `u`, in monomial form: the
/// Hermite cubic through the ends' positions and speeds, so that each Newton step costs three
/// multiply-adds for the position and two for the slope (the Hermite basis cost fifteen).
#[derive(Clone, Copy, Debug)]
struct Cubic([f64; 4]);

impl Cubic {
    /// Position `a` at u = 0 and `b` at u = 1, speeds `v0` and `v1` (counts per step).
    fn hermite((a, b): (f64, f64), (v0, v1): (f64, f64)) -> Cubic {
        let d = b - a;
        Cubic([a, v0, 3.0 * d - 2.0 * v0 - v1, v0 + v1 - 2.0 * d])
    }

    #[inline(always)]
    fn position(&self, u: f64) -> f64 {
        let [c0, c1, c2, c3] = self.0;
        ((c3 * u + c2) * u + c1) * u + c0
    }

    #[inline(always)]
    fn slope(&self, u: f64) -> f64 {
        let [_, c1, c2, c3] = self.0;
        (3.0 * c3 * u + 2.0 * c2) * u + c1
    }
}

/// Where Newton starts for an edge: on the inverse quintic (the step's fraction as a quintic
/// in the position, through the ends with the inverse's slopes and curvatures there) when
/// both ends move the way the step goes; else on the straight line (a wheel starting from
/// rest or turning back inside the step). The inverse cubic (slopes only) was within Newton's
/// 10⁻⁹ counts for six edges in ten of the default scenario, and the rest each took a Newton
/// step, a division, on a branch no predictor could learn; the quintic, for all but 449 of
/// its 268 274 edges: 3 % fewer instructions in the whole emulation, and 1.05× faster
/// (`emulate --json`, medians of 21 runs in turn: 836× → 874×, 833× → 878×).
#[derive(Clone, Copy, Debug)]
struct InverseGuess {
    a: f64,
    /// 1 / (b - a): the edge's fraction of the way from `a` to `b`.
    per_count: f64,
    /// The inverse quintic's monomial coefficients of s to s⁵ (s the fraction of the way),
    /// or the straight line's.
    c: [f64; 5],
}

impl InverseGuess {
    fn new((a, b): (f64, f64), (v0, v1): (f64, f64)) -> InverseGuess {
        let d = b - a;
        // The inverse's end slopes: fractions of the step per fraction of the way.
        let (m0, m1) = (d / v0, d / v1);
        // Beyond these the cubic is far from monotone in u, its inverse no help.
        let fits = |m: f64| m > 0.25 && m < 4.0;
        let c = if fits(m0) && fits(m1) {
            // The position's second derivative at the ends (counts per step²), of the
            // Hermite cubic through (a, v0) and (b, v1); the inverse's is −p''·(du/dp)³ in
            // the way's fraction: −p''/d · m³.
            let c2 = 3.0 * d - 2.0 * v0 - v1;
            let c3 = v0 + v1 - 2.0 * d;
            let (p0, p1) = (2.0 * c2, 2.0 * c2 + 6.0 * c3);
            let (k0, k1) = (-p0 / d * m0 * m0 * m0, -p1 / d * m1 * m1 * m1);
            // Quintic Hermite: u(0) = 0, u(1) = 1, u' = m0, m1 and u'' = k0, k1.
            [
                m0,
                0.5 * k0,
                10.0 - 6.0 * m0 - 4.0 * m1 - 1.5 * k0 + 0.5 * k1,
                -15.0 + 8.0 * m0 + 7.0 * m1 + 1.5 * k0 - k1,
                6.0 - 3.0 * m0 - 3.0 * m1 - 0.5 * k0 + 0.5 * k1,
            ]
        } else {
            [1.0, 0.0, 0.0, 0.0, 0.0]
        };
        InverseGuess {
            a,
            per_count: 1.0 / d,
            c,
        }
    }

    #[inline(always)]
    fn at(&self, edge: f64) -> f64 {
        let s = (edge - self.a) * self.per_count;
        let [c1, c2, c3, c4, c5] = self.c;
        (((((c5 * s + c4) * s + c3) * s + c2) * s + c1) * s).clamp(0.0, 1.0)
    }
}

/// One edge's crossing of a step's cubic, found by Newton's method, kept inside the bracket
/// `[lo, hi]` by bisection: `u` is the fraction of the step.
#[derive(Clone, Copy, Debug)]
struct Crossing {
    edge: f64,
    u: f64,
    lo: f64,
    hi: f64,
}

impl Crossing {
    fn start(edge: f64, u: f64) -> Crossing {
        Crossing {
            edge,
            u,
            lo: 0.0,
            hi: 1.0,
        }
    }

    /// One Newton step; true once `u` is the crossing. The caller stops after 60 (`u` is
    /// then the last step's).
    #[inline(always)]
    fn iterate(&mut self, cubic: &Cubic, rising: bool) -> bool {
        let u = self.u;
        let g = cubic.position(u) - self.edge;
        // 1e-9 of a count: far below the slave's microsecond, near the rounding of positions
        // of 10^5 counts.
        if g.abs() < 1e-9 {
            return true;
        }
        if (g < 0.0) == rising {
            self.lo = u;
        } else {
            self.hi = u;
        }
        let newton = u - g / cubic.slope(u);
        let next = if newton > self.lo && newton < self.hi {
            newton
        } else {
            0.5 * (self.lo + self.hi)
        };
        self.u = next;
        (next - u).abs() < 1e-12 || self.hi - self.lo < 1e-12
    }
}

/// Merge the time-ordered runs `edges[..mid]` and `edges[mid..]` in place, stably (the
/// first run's edge first on a tie), through `scratch`: rotating each of the later run's
/// edges into place was a `memmove` call per edge, 2.4 % of an emulation.
pub(super) fn merge_by_time(edges: &mut [Edge], mid: usize, scratch: &mut Vec<Edge>) {
    if mid == 0 || mid == edges.len() || edges[mid - 1].0 <= edges[mid].0 {
        return; // already in order
    }
    scratch.clear();
    scratch.extend_from_slice(&edges[..mid]);
    // The write position never passes the later run's read position: it trails it by the
    // first run's edges not yet written.
    let (mut i, mut j) = (0, mid);
    for k in 0..edges.len() {
        if i == scratch.len() {
            break; // the later run's rest is already in place
        }
        if j < edges.len() && edges[j].0 < scratch[i].0 {
            edges[k] = edges[j];
            j += 1;
        } else {
            edges[k] = scratch[i];
            i += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// `whole_counts` is `floor` wherever a position can be: either side of zero, on whole
        /// counts and just off them.
        #[test]
        fn whole_counts_is_floor(x in -1e15f64..1e15, k in -1_000_000i64..1_000_000) {
            for v in [x, k as f64, k as f64 - 1e-9, k as f64 + 1e-9, -0.0] {
                prop_assert_eq!(whole_counts(v), v.floor() as i64, "at {}", v);
            }
        }

        /// In a step of a wheel in smooth motion the inverse quintic lands far closer to each
        /// crossing than the inverse cubic it replaced: ten times at least under a constant
        /// acceleration of up to a fifth of the step's mean speed across the step, and within
        /// the 10⁻⁹ count Newton stops at (no Newton step, a division, to take) while
        /// cruising, the speed changing by a thousandth a step with a little jerk, as the
        /// robot's wheels do at speed. In the default scenario the cubic was that close for
        /// six edges in ten, the quintic for all but 449 of its 268 274. (With jerk and a
        /// large acceleration together the quintic is not always the closer: checked over
        /// 10⁶ cases each, the two properties here held and that one did not.)
        #[test]
        fn in_smooth_motion_the_guess_is_the_crossing(
            a in -1.0e5f64..1.0e5,
            d in prop_oneof![1.0f64..40.0, -40.0f64..-1.0],
            accel in -0.1f64..0.1,
            cruise in 0.0f64..1e-3,
        ) {
            let off = |accel: f64, jerk: f64| {
                let (b, v0, v1) = (a + d, d * (1.0 - accel + jerk), d * (1.0 + accel + jerk));
                let cubic = Cubic::hermite((a, b), (v0, v1));
                let guess = InverseGuess::new((a, b), (v0, v1));
                // The inverse cubic: u(0) = 0, u(1) = 1, u' = d/v0 and d/v1.
                let (m0, m1) = (d / v0, d / v1);
                let c = [m0, 3.0 - 2.0 * m0 - m1, m0 + m1 - 2.0];
                let (lo, hi) = (a.min(b).floor() as i64, a.max(b).floor() as i64);
                (lo + 1..=hi).fold((0.0f64, 0.0f64), |(q, k), edge| {
                    let e = edge as f64;
                    let s = (e - a) / d;
                    let u3 = (((c[2] * s + c[1]) * s + c[0]) * s).clamp(0.0, 1.0);
                    let (q5, q3) = ((cubic.position(guess.at(e)) - e).abs(), (cubic.position(u3) - e).abs());
                    (q.max(q5), k.max(q3))
                })
            };
            let (quintic, cubic) = off(accel, 0.0);
            prop_assert!(quintic <= 1e-9 || quintic * 10.0 <= cubic, "{quintic:e} vs {cubic:e}");
            let (cruising, _) = off(cruise, cruise * cruise);
            prop_assert!(cruising < 1e-9, "{cruising:e} counts off");
        }

        /// Every whole count between the ends is pushed once, at an instant inside the step
        /// where the cubic is on it (to 10^-9 counts), whatever the speeds: near the straight
        /// line's, from rest, or drawn at random (braking, or turning back inside the step).
        /// When the cubic moves one way only (a real step: the plant's steps are short), the
        /// edges are also in time order.
        #[test]
        fn each_edge_is_where_the_cubic_crosses_it(
            a in -1.0e5f64..1.0e5,
            d in prop_oneof![-40.0f64..40.0, -1.5f64..1.5],
            kind in 0..3u8,
            v in (-60.0f64..60.0, -60.0f64..60.0),
            fit in 0.3f64..3.0,
            rest in -0.01f64..0.01,
        ) {
            let b = a + d;
            let (v0, v1) = match kind {
                // Near the straight line's speeds: the inverse cubic starts Newton.
                0 => (d * fit, d / fit),
                // From rest (or nearly), speeding up the way the step goes.
                1 => (rest, d * fit),
                // As drawn: braking, reversing, far from the straight line.
                _ => v,
            };
            let cubic = Cubic::hermite((a, b), (v0, v1));
            let (t0, h) = (3.0, 1e-3);
            let mut edges = Vec::new();
            push_crossings(&mut edges, 1, t0, h, (a, b), (v0, v1));
            let n = (a.floor() - b.floor()).abs() as usize;
            prop_assert_eq!(edges.len(), n);
            // Each edge's time is the one Newton finds from the guess, solving the edge alone,
            // to the bit: the guesses checked side by side change no edge.
            let guess = InverseGuess::new((a, b), (v0, v1));
            for &(t, _, count_after) in &edges {
                let edge = if b > a { count_after } else { count_after + 1 } as f64;
                let mut alone = Crossing::start(edge, guess.at(edge));
                for _ in 0..60 {
                    if alone.iterate(&cubic, b > a) {
                        break;
                    }
                }
                prop_assert_eq!(t.to_bits(), (t0 + h * alone.u).to_bits(), "edge {}", edge);
            }
            for &(t, j, count_after) in &edges {
                prop_assert_eq!(j, 1);
                let edge = if b > a { count_after } else { count_after + 1 } as f64;
                let u = (t - t0) / h;
                prop_assert!((-1e-9..=1.0 + 1e-9).contains(&u), "u {u}");
                // Off by no more than the stopping rule allows (and t's own rounding).
                let off = (cubic.position(u) - edge).abs();
                let slope = cubic.slope(u).abs().max(1.0);
                prop_assert!(off < 1e-9 + 1e-11 * slope, "edge {edge} at u {u}: {off} off");
            }
            let monotone = (0..=1000)
                .map(|i| cubic.position(i as f64 / 1000.0))
                .collect::<Vec<_>>()
                .windows(2)
                .all(|w| if d >= 0.0 { w[1] >= w[0] } else { w[1] <= w[0] });
            if monotone {
                for w in edges.windows(2) {
                    prop_assert!(w[0].0 <= w[1].0, "{:?}", w);
                }
            }
        }
    }
}
