//! Integer trigonometry on binary angles, for the slave's FPU-less Cortex-M3.
//!
//! Angles are `u32` binary angles (2^32 = one turn); results are Q30 (`1 << 30` = 1.0).
//! `sin_cos` reduces to one octant and evaluates Taylor polynomials in Q31, each product one
//! 32 × 32 → 64-bit multiply (a single `smull` on the M3): no floats, no tables, no
//! divisions, about 2e-9 absolute error.

/// Q30 one.
pub const ONE_Q30: i64 = 1 << 30;

/// π in Q29 (for the octant reduction: an octant spans 2^29 binary-angle units).
const PI_Q29: i64 = 1_686_629_713; // round(π · 2^29)

/// Multiply two Q31 numbers of magnitude below 2^31, rounding to nearest: one 32 × 32-bit
/// multiply (a 64 × 64 one is three on the M3, and the divisions the old Horner form took
/// were library calls).
///
/// Written as `(p >> 31) + bit 30 of p`, which is `(p + 2^30) >> 31` exactly (p = q·2^31 + r
/// with 0 <= r < 2^31: both are q plus whether r >= 2^30). With the addition in 64 bits, LLVM
/// carried the operands as 64-bit values and made each product a 64 × 32-bit multiply; this
/// way each is one `smull` and four 32-bit instructions.
#[inline(always)]
pub fn mul_q31(a: i32, b: i32) -> i32 {
    let p = a as i64 * b as i64;
    ((p >> 31) as i32).wrapping_add(((p >> 30) & 1) as i32)
}

/// The Taylor coefficients in Q31: sin x = x(1 + S1 x² + S2 x⁴ + S3 x⁶ + S4 x⁸),
/// cos x = 1 + C1 x² + … + C5 x¹⁰ (the first omitted terms are below 2e-9 up to π/4).
const S: [i32; 4] = [-357_913_941, 17_895_697, -426_088, 5_918];
const C: [i32; 5] = [-1_073_741_824, 89_478_485, -2_982_616, 53_261, -592];

/// sin and cos of x in [0, π/4], x in Q31, results in Q30, rounded from Q31 (half up).
///
/// Horner's form on −x² and the negated partial sums: each product (−x²)·(−p) is x²·p exactly,
/// so the results are those of the plain form to the bit. Why: LLVM knows x² ≥ 0 and widens
/// it as unsigned, which makes each product an unsigned multiply plus a sign fix-up (and at
/// "z" an outlined call); −x² ≤ 0 must be widened as signed, and each product is one `smull`.
fn sin_cos_octant(x: i32) -> (i32, i32) {
    let nx2 = -mul_q31(x, x);
    // n_k = −(S[k] + x²·s_{k+1}) = −S[k] − (−x²)·(−s_{k+1}).
    let n = -S[2] - mul_q31(nx2, -S[3]);
    let n = -S[1] - mul_q31(nx2, n);
    let n = -S[0] - mul_q31(nx2, n);
    // x + x·x²·s in Q31, then to Q30: (v + 1) >> 1. In 32 bits: x < π/4 · 2^31 and the
    // product is negative, so the sum stays below 2^31 (in 64 bits it cost 8 instructions).
    let sin = (x + mul_q31(x, mul_q31(nx2, n)) + 1) >> 1;
    let n = -C[3] - mul_q31(nx2, -C[4]);
    let n = -C[2] - mul_q31(nx2, n);
    let n = -C[1] - mul_q31(nx2, n);
    let n = -C[0] - mul_q31(nx2, n);
    // (2^31 + m + 1) >> 1 = 2^30 + ((m + 1) >> 1) exactly (2^31 is even), and m = −x²·c
    // is above −2^30: all in 32 bits, although cos 0 = 2^31 does not fit them in Q31.
    let cos = (1 << 30) + ((mul_q31(nx2, n) + 1) >> 1);
    (sin, cos)
}

/// (sin, cos) of a binary angle, Q30 (32 bits: the products with them are `smull`s).
pub fn sin_cos(angle: u32) -> (i32, i32) {
    let octant = angle >> 29;
    let within = (angle & ((1 << 29) - 1)) as i64;
    // Odd octants run backwards from the next multiple of π/4.
    let t = if octant & 1 == 0 {
        within
    } else {
        (1 << 29) - within
    };
    // Radians in Q31: t / 2^29 · π/4 · 2^31 = t · π (at most π/4 · 2^31 < 2^31), that is
    // `(p >> 29) as i32` for the product p. Taken from p's two words by hand: written as a
    // shift, LLVM kept the (zero) upper word and made x² a 64-bit multiply.
    let p = (t * PI_Q29 + (1 << 28)) as u64;
    let x = (((p >> 32) as u32) << 3 | (p as u32) >> 29) as i32;
    // Q30 in 32 bits: the octant's signs and swaps move 32-bit values, not 64-bit pairs.
    let (s, c) = sin_cos_octant(x);
    match octant {
        0 => (s, c),
        1 => (c, s),
        2 => (c, -s),
        3 => (s, -c),
        4 => (-s, -c),
        5 => (-c, -s),
        6 => (-c, s),
        _ => (-s, c),
    }
}

/// Multiply by a Q30 factor, rounding to nearest (ties away from zero is fine: unbiased
/// enough, as errors of either sign are equally likely).
#[inline]
pub fn mul_q30(a: i64, f: i64) -> i64 {
    let p = a * f;
    if p >= 0 {
        (p + (1 << 29)) >> 30
    } else {
        -((-p + (1 << 29)) >> 30)
    }
}

/// `round(a · f / 2^30)` for |a| < 2^46 without overflowing 64 bits: `a` is split into a
/// high part (exact multiple of 2^16) and a 16-bit low part, each multiplied and rounded
/// separately (at most one unit of error in the result). The factor is 32 bits (a Q30 sine,
/// cosine or sinc correction), so every product is one `smull`.
#[inline(always)]
pub fn mul_q30_wide(a: i64, f: i32) -> i64 {
    if a == a as i32 as i64 {
        // Fits 32 bits (a step's displacement, nearly always): one exact multiply.
        return shr_round(a as i32 as i64 * f as i64, 30);
    }
    mul_q30_split(a, f)
}

/// [`mul_q30_wide`] for a value past 32 bits (the carriage's trail, always).
#[inline(never)]
fn mul_q30_split(a: i64, f: i32) -> i64 {
    let hi = a >> 16;
    let lo = (a & 0xFFFF) as i32;
    let hi_f = if hi == hi as i32 as i64 {
        hi as i32 as i64 * f as i64 // |a| < 2^47: one `smull`
    } else {
        hi * f as i64
    };
    shr_round(hi_f, 14) + shr_round(lo as i64 * f as i64, 30)
}

/// Shift right by `n` with rounding to nearest, symmetric about zero (no drift towards −∞):
/// `(a + h) >> n` for `a >= 0` and `−((−a + h) >> n)` below, h = 2^(n−1).
///
/// Without a branch: for a = −b < 0, ⌊(h − 1 − b) / 2^n⌋ = −⌈(b − h + 1) / 2^n⌉
/// = −⌊(b + h) / 2^n⌋ (as 2^n − h = h), so adding the sign (−1) before the shift is the same.
/// Inlined in a dozen places, the branching form was 0.6 KB of the slave's flash.
#[inline(always)]
pub fn shr_round(a: i64, n: u32) -> i64 {
    (a + (1 << (n - 1)) + (a >> 63)) >> n
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shr_round_is_the_symmetric_rounding_at_every_tie() {
        let branching = |a: i64, n: u32| {
            let h = 1i64 << (n - 1);
            if a >= 0 {
                (a + h) >> n
            } else {
                -((-a + h) >> n)
            }
        };
        for n in 1..40u32 {
            for k in -4i64..4 {
                let h = 1i64 << (n - 1);
                for d in [-h - 1, -h, -h + 1, -1, 0, 1, h - 1, h, h + 1] {
                    let a = (k << n) + d;
                    assert_eq!(shr_round(a, n), branching(a, n), "{a} >> {n}");
                }
            }
        }
        for a in (-100_000i64..100_000).map(|a| a * 7_919) {
            assert_eq!(shr_round(a, 4), branching(a, 4), "{a}");
        }
    }

    #[test]
    fn matches_libm_everywhere() {
        let mut worst = 0.0f64;
        // Every 2^16-th angle, plus the octant edges.
        let angles = (0..=u32::MAX >> 16)
            .map(|k| k << 16)
            .chain((0..8).map(|o| o << 29))
            .chain((1..8).map(|o| (o << 29) - 1));
        for a in angles {
            let rad = a as f64 / 4_294_967_296.0 * 2.0 * core::f64::consts::PI;
            let (s, c) = sin_cos(a);
            let es = (s as f64 / ONE_Q30 as f64 - rad.sin()).abs();
            let ec = (c as f64 / ONE_Q30 as f64 - rad.cos()).abs();
            worst = worst.max(es).max(ec);
        }
        assert!(worst < 4e-9, "worst error {worst:e}");
    }

    #[test]
    fn wide_multiply_matches_exact_arithmetic() {
        for &a in &[
            0i64,
            1,
            -1,
            123_456_789_012,
            -(1 << 45) + 7,
            (1 << 45) - 3,
            65_535,
            -65_536,
        ] {
            for &f in &[
                0i32,
                1 << 30,
                -(1 << 30),
                i32::MAX,
                i32::MIN,
                759_250_124,
                -3,
            ] {
                let exact = (a as i128 * f as i128) as f64 / (1u64 << 30) as f64;
                let got = mul_q30_wide(a, f);
                assert!(
                    (got as f64 - exact).abs() <= 1.0,
                    "{a} * {f}: {got} vs {exact}"
                );
            }
        }
    }

    #[test]
    fn rounding_shifts_are_symmetric() {
        assert_eq!(shr_round(5, 1), 3);
        assert_eq!(shr_round(-5, 1), -3);
        assert_eq!(shr_round(4, 2), 1);
        assert_eq!(mul_q30(-(1 << 30), 3), -3);
    }
}
