//! The images' 64-bit division, small: `__udivmoddi4` and `__divmoddi4`, which the EABI's
//! `__aeabi_uldivmod` and `__aeabi_ldivmod` call, in place of `compiler_builtins`' (weak
//! symbols, so these win at link).
//!
//! `compiler_builtins` divides through an 866 B routine. These are Hacker's Delight's (2nd
//! ed., 9-4 and 9-5): a 64-bit dividend over a 32-bit divisor as two 16-bit quotient digits,
//! each estimated by the M3's 32-bit hardware divider and corrected at most twice; a wider
//! divisor through the same on its top 32 bits, then one correction. Each image 456 B
//! smaller; the slave's time-stamp update takes 2 063 instructions against 1 850
//! (`scripts/m3-bench`; its counts update divides nothing). A shift-and-subtract loop, 190 B
//! smaller still, took 3 652: 17 steps of 64-bit arithmetic a division, six an update.
//! Written with 32-bit division and 64-bit multiplication only: a 64-bit `/` here would
//! call itself.

/// `(u1·2³² + u0) / v` and its remainder, for `u1 < v` (so the quotient fits 32 bits).
fn div_64_32(u1: u32, u0: u32, v: u32) -> (u32, u32) {
    const B: u32 = 1 << 16;
    // Normalised: the divisor's top bit set, so each digit's estimate is at most 2 over.
    let s = v.leading_zeros();
    let v = v << s;
    // `v`'s top half: at least 2¹⁵ once normalised (a zero `v` is no caller's: see `udivmod`);
    // `max(1)` tells the compiler so: its divisions carry no zero check and no panic path.
    let (vn1, vn0) = ((v >> 16).max(1), v & 0xffff);
    let un32 = if s == 0 {
        u1
    } else {
        (u1 << s) | (u0 >> (32 - s))
    };
    let un10 = u0 << s;
    // One quotient digit of `top·2¹⁶ + next` over `v` (`top < v`, so it is below 2¹⁶), from
    // the top halves, then lowered while it is too big.
    let digit = |top: u32, next: u32| {
        let mut q = top / vn1;
        let mut rhat = top - q * vn1;
        while q >= B || q * vn0 > (rhat << 16) + next {
            q -= 1;
            rhat += vn1;
            if rhat >= B {
                break;
            }
        }
        q
    };
    let q1 = digit(un32, un10 >> 16);
    // What is left, below v: exact in 32 bits, whatever the products' wrapping.
    let un21 = (un32 << 16)
        .wrapping_add(un10 >> 16)
        .wrapping_sub(q1.wrapping_mul(v));
    let q0 = digit(un21, un10 & 0xffff);
    let r = (un21 << 16)
        .wrapping_add(un10 & 0xffff)
        .wrapping_sub(q0.wrapping_mul(v));
    ((q1 << 16) | q0, r >> s)
}

/// `n / d` and `n % d`; `d == 0` gives `(u64::MAX, n)` (every Rust division checks for
/// zero before it gets here). Not inlined: both symbols below call this one copy.
#[inline(never)]
pub fn udivmod(n: u64, d: u64) -> (u64, u64) {
    if d == 0 {
        return (u64::MAX, n);
    }
    let (n1, n0) = ((n >> 32) as u32, n as u32);
    if d >> 32 == 0 {
        // Not zero (checked above); `max(1)` tells the compiler so (no zero check, no panic
        // path).
        let d = (d as u32).max(1);
        if n1 == 0 {
            return ((n0 / d) as u64, (n0 % d) as u64);
        }
        // The high word's quotient, then the rest (its remainder below d) as one digit pair.
        let (q1, k) = (n1 / d, n1 % d);
        let (q0, r) = div_64_32(k, n0, d);
        return (((q1 as u64) << 32) | q0 as u64, r as u64);
    }
    if d > n {
        return (0, n);
    }
    // d ≥ 2³², so the quotient fits 32 bits. Estimated from d's top 32 bits (normalised) and
    // half the dividend, it is exact or one over; one less is exact or one under.
    let s = d.leading_zeros();
    let d1 = ((d << s) >> 32) as u32;
    let half = n >> 1;
    let (q1, _) = div_64_32((half >> 32) as u32, half as u32, d1);
    let mut q = ((q1 as u64) << s) >> 31;
    q = q.saturating_sub(1);
    let mut r = n - q * d;
    if r >= d {
        q += 1;
        r -= d;
    }
    (q, r)
}

/// `a / b` and `a % b` rounded toward zero, as Rust's: the quotient negative when the signs
/// differ, the remainder with `a`'s sign.
#[inline(always)]
pub fn idivmod(a: i64, b: i64) -> (i64, i64) {
    let (q, r) = udivmod(a.unsigned_abs(), b.unsigned_abs());
    let (q, r) = (q as i64, r as i64);
    (
        if (a < 0) != (b < 0) {
            q.wrapping_neg()
        } else {
            q
        },
        if a < 0 { r.wrapping_neg() } else { r },
    )
}

#[cfg(target_os = "none")]
mod symbols {
    /// C's `__udivmoddi4`: the quotient, and the remainder through `rem` unless null.
    #[no_mangle]
    extern "C" fn __udivmoddi4(n: u64, d: u64, rem: *mut u64) -> u64 {
        let (q, r) = super::udivmod(n, d);
        if !rem.is_null() {
            // SAFETY: the caller's pointer to its remainder (the EABI shim's stack slot).
            unsafe { *rem = r };
        }
        q
    }

    /// C's `__divmoddi4`: the quotient, and the remainder through `rem` (never null here:
    /// `__aeabi_ldivmod` passes its stack slot).
    #[no_mangle]
    extern "C" fn __divmoddi4(a: i64, b: i64, rem: *mut i64) -> i64 {
        let (q, r) = super::idivmod(a, b);
        if !rem.is_null() {
            // SAFETY: as above.
            unsafe { *rem = r };
        }
        q
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Rust's own division on the edges of every case: digits at 0, 1, 2¹⁶ and 2³² apart,
    /// divisors with every top bit, an estimate's corrections at their limits.
    #[test]
    fn divides_as_rust_does_on_the_edges() {
        let mut values = Vec::new();
        for bit in 0..64 {
            let p = 1u64 << bit;
            values.extend([p, p - 1, p + 1, p | (p >> 1), !p, u64::MAX >> bit]);
        }
        values.extend([
            0xffff_0000_ffff,
            0x8000_0000_ffff_ffff,
            0x1_0000_ffff,
            0xffff_ffff_0000_0001,
        ]);
        for &n in &values {
            for &d in values.iter().filter(|&&d| d != 0) {
                assert_eq!(udivmod(n, d), (n / d, n % d), "{n:#x} / {d:#x}");
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(20_000))]

        /// Rust's own division, on numbers of every size: both fitting 32 bits, a quotient of
        /// one bit or of 64, divisors above the dividend.
        #[test]
        fn divides_as_rust_does(n in any::<u64>(), d in 1..u64::MAX, shift in 0..64u32, wide in 0..64u32) {
            for (n, d) in [(n, d), (n >> shift, d >> wide | 1), (n, d >> shift | 1), (n >> wide, d)] {
                prop_assert_eq!(udivmod(n, d), (n / d, n % d));
                let (a, b) = (n as i64, (d as i64) | 1);
                if !(a == i64::MIN && b == -1) {
                    prop_assert_eq!(idivmod(a, b), (a / b, a % b));
                }
            }
        }
    }
}
