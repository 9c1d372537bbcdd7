//! Where a wheel stood inside its count at power-on, from its first ticks.
//!
//! An incremental encoder says nothing about where inside a count it powers on: the wheel sits
//! at `c0 + φ` (edges at whole numbers), φ ∈ [0, 1) unknown. Its first forward tick comes after
//! `1 − φ` counts of travel, not one, so taking φ = 0 (the tick tracker's old assumption) leaves
//! every wheel with a constant offset of up to a count. On an omni layout the offsets do not
//! cancel: the heading is off by a constant and the position error grows with the distance.
//!
//! φ is the wheel's position at the start of its motion, and the first ticks show how it moved
//! from there. In units `u` that count the ticks of the first direction (the k-th tick is at
//! `u = k`, forward or backward) the start position is `u_s ∈ [0, 1)`; the polynomial through
//! the first ticks (`(t_k, k)`, degree 1, 2, 3 as 2, 3, 4 ticks arrive) is extrapolated back to
//! the start of motion, taken as
//!
//! * the latest instant before the first tick where the fitted speed is zero (a start from
//!   rest: a constant acceleration from rest is fitted exactly from three ticks, a cubic start
//!   (jerk-limited, or a smooth ramp) from four), or failing that where it dips to under a
//!   quarter of its value at power-on (a double zero blurred by rounding);
//! * otherwise the power-on instant itself (the wheel was already moving: a constant speed or
//!   a constant acceleration from power-on is fitted exactly).
//!
//! A fit whose start position is not inside the count (beyond a small margin for model error)
//! is refused: then motion started at an unknown instant at a speed the ticks cannot tell
//! (e.g. an abrupt start after a rest), and the caller keeps what it had.
//!
//! Integer-only (the slave has no FPU), in `i64` (128-bit arithmetic costs the 64 KiB flash
//! kilobytes): times are normalised to `x = (t − t1) / (t_n − t1)` in Q24 and the fit is
//! Newton's divided differences; first ticks more uneven than 1 : 256 of their span, or a fit
//! whose numbers leave 64 bits, are refused (no motion worth extrapolating looks like that).
//! The speed's zeros need one integer square root. It runs for the first four ticks, and once
//! more on learned uneven edges (the 1st, 2nd, 5th and 9th ticks: `TickTracker::learn`).

/// Fraction bits of the fit's numbers.
const Q: u32 = 24;
/// Q24 one.
const ONE: i64 = 1 << Q;
/// The furthest back (in units of the first ticks' span) the fit is extrapolated.
const MAX_BACK: i64 = 8;
/// Shortest interval between first ticks, in units of their span (1/256).
const MIN_GAP: i64 = ONE / 256;
/// How far outside the count a fitted start may land and still be taken (model error):
/// 1/8 count.
const MARGIN: i64 = ONE / 8;

/// `a·b` in Q24; past 64 bits, 0 with `ok` cleared. Out of line (as [`div`]): a checked 64-bit
/// multiply is dozens of instructions on the M3, and each inlined copy cost flash in a fit that
/// runs for a wheel's first ticks only. The flag, not an `Option`: a fit that overflows
/// anywhere is refused all the same, checked once before its result is used, and the
/// `Option`s' tags through memory were 130 B of the slave's flash.
#[inline(never)]
fn mul(ok: &mut bool, a: i64, b: i64) -> i64 {
    checked(ok, a.checked_mul(b).map(|p| p >> Q))
}

/// `a / b` in Q24; past 64 bits or for `b` = 0, 0 with `ok` cleared.
#[inline(never)]
fn div(ok: &mut bool, a: i64, b: i64) -> i64 {
    checked(ok, a.checked_mul(ONE).and_then(|n| n.checked_div(b)))
}

/// `a·b`, unscaled; past 64 bits, 0 with `ok` cleared. Out of line as [`mul`].
#[inline(never)]
fn raw(ok: &mut bool, a: i64, b: i64) -> i64 {
    checked(ok, a.checked_mul(b))
}

/// The value, or 0 with `ok` cleared.
#[inline(never)]
fn checked(ok: &mut bool, v: Option<i64>) -> i64 {
    v.unwrap_or_else(|| {
        *ok = false;
        0
    })
}

/// The start position `u_s` (Q16 counts, in `[0, 1)`) of a wheel whose first `times.len()`
/// ticks (2 to 4, one direction, strictly increasing) came at `times` after power-on at
/// `power_on_ns`; `None` if the fit does not place the start inside the count.
pub fn start_position_q16(power_on_ns: u64, times: &[u64]) -> Option<i64> {
    start_position_on_q16(power_on_ns, times, &EVEN)
}

/// Whole counts apart: the k-th tick one count after the (k−1)-th, Q24.
const EVEN: [i64; 4] = [ONE, 2 * ONE, 3 * ONE, 4 * ONE];

/// [`start_position_q16`] for ticks at `places` (Q24 counts along the first direction from
/// the count's first edge's whole-count place: `(k + 1)·ONE` for evenly spaced edges), where an
/// encoder's learned edges ([`super::edges`]) put them.
pub fn start_position_on_q16(power_on_ns: u64, times: &[u64], places: &[i64; 4]) -> Option<i64> {
    let n = times.len();
    if !(2..=4).contains(&n) {
        return None;
    }
    let (&t1, &tn) = (times.first()?, times.last()?);
    let span = tn.checked_sub(t1)?;
    // Under 9 minutes, so the shifts below stay inside 64 bits.
    if span == 0 || span >= 1 << 39 || t1 < power_on_ns {
        return None;
    }
    // Nodes in Q24 units of the span, x1 = 0. (`checked_*` and `get` throughout: no
    // panic path may reach the board.)
    let mut x = [0i64; 4];
    let mut prev = 0;
    // An index loop: a `skip` iterator adaptor left an out-of-line `next` in the image.
    let mut k = 1;
    while k < n {
        let xk = ((times.get(k)?.checked_sub(t1)? << Q).checked_div(span)?) as i64;
        if xk - prev < MIN_GAP {
            return None;
        }
        *x.get_mut(k)? = xk;
        prev = xk;
        k += 1;
    }
    let back = t1 - power_on_ns;
    let x_pow = if back >= MAX_BACK as u64 * span {
        -MAX_BACK * ONE
    } else {
        -((back << Q).checked_div(span)? as i64)
    };
    // Newton's divided differences of u_k = places[k] at the nodes (all Q24): a[1..n). From
    // here any product or quotient past 64 bits clears `ok`, and the fit is refused.
    let ok = &mut true;
    let mut dd = *places;
    let mut a = [0i64; 4];
    for level in 1..n {
        for k in (level..n).rev() {
            let (hi, lo) = (*dd.get(k)?, *dd.get(k - 1)?);
            let dx = x.get(k)? - x.get(k - level)?;
            *dd.get_mut(k)? = div(ok, hi - lo, dx);
        }
        *a.get_mut(level)? = *dd.get(level)?;
    }
    // Monomials about x = 0: u(x) = c0 + c1 x + c2 x² + c3 x³.
    let c3 = a[3];
    let c2 = a[2] - mul(ok, c3, x[1] + x[2]);
    let c1 = a[1] - mul(ok, a[2], x[1]);
    let c3_x1 = mul(ok, c3, x[1]);
    let c1 = c1 + mul(ok, c3_x1, x[2]);
    let poly = Poly {
        c0: places[0],
        c1,
        c2,
        c3,
    };
    if !*ok || c1 <= 0 {
        return None; // overflowed, or not moving at the first tick
    }
    let start = match poly.latest_zero(ok, x_pow) {
        Some(z) => z,
        // A dip to near rest (a double zero that rounding lifted above the axis).
        None if c3 > 0 => {
            let v = -div(ok, c2, 3 * c3);
            let dip = v > x_pow && v < 0 && {
                let at_v = poly.speed(ok, v).checked_mul(4);
                let four_times = checked(ok, at_v);
                four_times <= poly.speed(ok, x_pow)
            };
            if dip {
                v
            } else {
                x_pow
            }
        }
        None => x_pow,
    };
    let us = poly.at(ok, start);
    if !*ok || !(-MARGIN..=ONE + MARGIN).contains(&us) {
        return None;
    }
    // To Q16, rounded.
    Some(((us + (1 << (Q - 17))) >> (Q - 16)).clamp(0, 0xFFFF))
}

/// `u(x) = c0 + c1 x + c2 x² + c3 x³`, Q24.
struct Poly {
    c0: i64,
    c1: i64,
    c2: i64,
    c3: i64,
}

// Past 64 bits each clears `ok` (and its value is then meaningless).
impl Poly {
    fn at(&self, ok: &mut bool, x: i64) -> i64 {
        let x2 = mul(ok, x, x);
        let x3 = mul(ok, x2, x);
        self.c0 + mul(ok, self.c1, x) + mul(ok, self.c2, x2) + mul(ok, self.c3, x3)
    }

    /// `u'(x) = c1 + 2 c2 x + 3 c3 x²`.
    fn speed(&self, ok: &mut bool, x: i64) -> i64 {
        let x2 = mul(ok, x, x);
        self.c1 + 2 * mul(ok, self.c2, x) + 3 * mul(ok, self.c3, x2)
    }

    /// The latest zero of the speed in `(x_pow, 0)`, if any.
    fn latest_zero(&self, ok: &mut bool, x_pow: i64) -> Option<i64> {
        let inside = |r: i64| (r > x_pow && r < 0).then_some(r);
        let (c1, c2, c3) = (self.c1, self.c2, self.c3);
        if c3 == 0 {
            return if c2 == 0 {
                None
            } else {
                inside(-div(ok, c1, 2 * c2))
            };
        }
        // Roots (−c2 ± √(c2² − 3 c1 c3)) / (3 c3); the discriminant in Q48.
        let c1_c3 = raw(ok, c1, c3);
        let (square, product) = (raw(ok, c2, c2), raw(ok, c1_c3, 3));
        let disc = checked(ok, square.checked_sub(product));
        if disc < 0 {
            return None;
        }
        let root = isqrt(disc as u64) as i64;
        let r1 = inside(div(ok, root - c2, 3 * c3));
        let r2 = inside(div(ok, -root - c2, 3 * c3));
        match (r1, r2) {
            (Some(p), Some(q)) => Some(p.max(q)),
            (p, q) => p.or(q),
        }
    }
}

/// ⌊√v⌋ by Newton's method (a few lines of code, where `u64::isqrt` is a kilobyte).
fn isqrt(v: u64) -> u64 {
    if v < 2 {
        return v;
    }
    // A start above the root: 2^⌈bits/2⌉.
    let mut r = 1u64 << (64 - v.leading_zeros()).div_ceil(2);
    loop {
        // `r ≥ 1` throughout; `checked_div` says so to the compiler (no panic path).
        let next = (r + v.checked_div(r).unwrap_or(0)) / 2;
        if next >= r {
            return r;
        }
        r = next;
    }
}

#[cfg(test)]
mod tests;
