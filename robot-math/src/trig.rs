//! sin and cos of the angles a robot meets: headings and mounting angles within a few thousand
//! turns.
//!
//! Why not `libm::sin` / `libm::cos`: they reduce any f64 (up to 1e308) exactly, with a
//! Payne–Hanek reduction whose code and tables cost ~4.1 KB of the master's flash, where
//! soft-float f64 makes every byte count (the goal is 48 KiB for the whole image). Here the
//! reduction is Cody–Waite with π/2 split in three parts (exact quotient for |x| < 2^20·π/2,
//! 1.6e6 rad), then Taylor kernels on [-π/4, π/4] carried past the last term that can show in
//! an f64. Agreement with libm is tested: within 1 ulp over ±10 rad, 4 ulp over ±1.6e6 rad; beyond that range
//! the angle is first wrapped to one turn (less precise there, never unbounded).
//!
//! Every f64 sin/cos in robot-math goes through here, so the board, the emulator and the
//! analysis all compute the same bits.

use core::f64::consts::{FRAC_2_PI, TAU};

/// π/2 = PIO2_1 + PIO2_2 + PIO2_3 to 1e-37 (fdlibm's split, given as bits so no decimal
/// rounding can slip in): the first two have their low 33 bits zero, so `k * PIO2_1` and
/// `k * PIO2_2` are exact for |k| < 2^20.
const PIO2_1: f64 = f64::from_bits(0x3FF9_21FB_5440_0000);
const PIO2_2: f64 = f64::from_bits(0x3DD0_B461_1A60_0000);
const PIO2_3: f64 = f64::from_bits(0x3BA3_198A_2E03_7073);

/// Beyond this the quotient no longer keeps `k * PIO2_1` exact.
const REDUCE_LIMIT: f64 = 1_647_099.0; // 2^20 · π/2

/// Both at once: `(sin x, cos x)`. NaN and ±inf give NaN.
pub fn sin_cos(x: f64) -> (f64, f64) {
    let x = if libm::fabs(x) < REDUCE_LIMIT {
        x
    } else {
        // Far outside any heading: one turn first (approximate, but bounded).
        x - TAU * libm::round(x / TAU)
    };
    let k = libm::round(x * FRAC_2_PI);
    let r = ((x - k * PIO2_1) - k * PIO2_2) - k * PIO2_3;
    let (s, c) = kernels(r);
    // NaN's quadrant is irrelevant: s and c are already NaN.
    match (k as i64) & 3 {
        0 => (s, c),
        1 => (c, -s),
        2 => (-s, -c),
        _ => (-c, s),
    }
}

pub fn sin(x: f64) -> f64 {
    sin_cos(x).0
}

pub fn cos(x: f64) -> f64 {
    sin_cos(x).1
}

/// Taylor series of sin (to r^17) and cos (to r^18) for |r| <= π/4 (a hair over, from
/// rounding): the first omitted terms are below 1e-19, far under half an ulp.
fn kernels(r: f64) -> (f64, f64) {
    // 1/n! for n = 2..=18.
    const F: [f64; 17] = [
        1.0 / 2.0,
        1.0 / 6.0,
        1.0 / 24.0,
        1.0 / 120.0,
        1.0 / 720.0,
        1.0 / 5_040.0,
        1.0 / 40_320.0,
        1.0 / 362_880.0,
        1.0 / 3_628_800.0,
        1.0 / 39_916_800.0,
        1.0 / 479_001_600.0,
        1.0 / 6_227_020_800.0,
        1.0 / 87_178_291_200.0,
        1.0 / 1_307_674_368_000.0,
        1.0 / 20_922_789_888_000.0,
        1.0 / 355_687_428_096_000.0,
        1.0 / 6_402_373_705_728_000.0,
    ];
    // The Horner steps' factors, smallest term first: for sin 1/(2n+1)! = F[2n - 1], n = 8..1;
    // for cos 1/(2n)! = F[2n - 2], n = 9..2. Taken out of `F` by index (the same bits), and
    // walked as arrays: at the images' opt-level "z" the counted-down ranges this once looped
    // over stayed a call per step (the master's control step 56 488 -> 53 756 instructions,
    // `scripts/m3-bench`; 3.8 M of the 4.8 M an emulation spent in `sin_cos` at "z").
    const SIN_HORNER: [f64; 8] = [F[15], F[13], F[11], F[9], F[7], F[5], F[3], F[1]];
    const COS_HORNER: [f64; 8] = [F[16], F[14], F[12], F[10], F[8], F[6], F[4], F[2]];
    let r2 = r * r;
    // sin r = r - r³/3! + r⁵/5! - ... ; Horner from the smallest term (1/17!).
    let mut s = 0.0;
    for &f in SIN_HORNER.iter() {
        s = f - r2 * s;
    }
    let sin = r - r * r2 * s;
    // cos r = 1 - r²/2! + r⁴/4! - ...
    let mut c = 0.0;
    for &f in COS_HORNER.iter() {
        c = f - r2 * c;
    }
    let cos = 1.0 - r2 * (F[0] - r2 * c);
    (sin, cos)
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::f64::consts::PI;
    use proptest::prelude::*;

    /// Distance in units in the last place of the larger magnitude (near zero: of 1e-16, the
    /// absolute floor of a reduction carried in f64).
    fn ulps(a: f64, b: f64) -> f64 {
        let scale = a.abs().max(b.abs()).max(1e-16);
        (a - b).abs() / (scale * f64::EPSILON)
    }

    #[test]
    fn exact_where_it_must_be() {
        assert_eq!(sin_cos(0.0), (0.0, 1.0));
        assert_eq!(sin(-0.0), 0.0);
        assert!(sin(f64::NAN).is_nan() && cos(f64::INFINITY).is_nan());
        assert!((sin(PI / 6.0) - 0.5).abs() <= 2.0 * f64::EPSILON);
        assert!((cos(PI / 3.0) - 0.5).abs() <= 2.0 * f64::EPSILON);
    }

    #[test]
    fn every_quadrant_on_a_fine_grid() {
        let mut worst = 0.0f64;
        for i in -100_000..=100_000 {
            let x = i as f64 * 1e-4; // ±10 rad
            let (s, c) = sin_cos(x);
            worst = worst.max(ulps(s, libm::sin(x))).max(ulps(c, libm::cos(x)));
        }
        assert!(worst <= 1.0, "worst {worst} ulp");
    }

    #[test]
    fn far_angles_stay_bounded() {
        for x in [1e7, -3.3e9, 1e300] {
            let (s, c) = sin_cos(x);
            assert!(s.abs() <= 1.0 && c.abs() <= 1.0, "{x}: {s} {c}");
            assert!((s * s + c * c - 1.0).abs() < 1e-12);
        }
    }

    proptest! {
        #[test]
        fn agrees_with_libm(x in -REDUCE_LIMIT..REDUCE_LIMIT) {
            let (s, c) = sin_cos(x);
            prop_assert!(ulps(s, libm::sin(x)) <= 4.0, "sin {} {} {}", x, s, libm::sin(x));
            prop_assert!(ulps(c, libm::cos(x)) <= 4.0, "cos {} {} {}", x, c, libm::cos(x));
        }
    }
}
