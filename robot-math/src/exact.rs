//! `exact`: our odometry (SPEC §3.4), integer-only on the update path.
//!
//! Per update, the wheels' count differences give the body displacement and turn
//! (`d_b`, `Δθ`) through the wheel solver's pseudo-inverse, and the pose moves along the
//! constant-twist arc exactly: `p += sinc(Δθ/2) · R(θ + Δθ/2) · d_b` (the SE(2) exponential;
//! not the chord, not an Euler step).
//!
//! * **Heading** is a `u64` binary angle (2^64 = one turn) accumulated from exact integer
//!   products of per-count constants and count differences, so it equals the
//!   cumulative-count formula bit for bit: quantisation never accumulates, and it wraps for
//!   free.
//! * **Counts** come in Q16 (65 536 per count): whole counts shifted up in fixed-rate mode,
//!   interpolated fractions in tick-timestamp mode.
//! * **Position** is Q40 metres (`i64`, about ±8·10^6 m, 1 pm resolution). On a steady
//!   motion every update rounds the same way, so rounding error grows linearly with the
//!   number of updates: the grid must be far finer than the result needs (Q32 measurably
//!   drifted 1e-6 of the distance at 1 kHz updates; Q40 keeps it near 1e-8). Shifts round to
//!   nearest, symmetrically about zero.
//! * Steps too large for the 64-bit products are split into equal chunks.
//!
//! [`ExactParams::new`] derives the integer constants with floats once (on the host, or at
//! boot); [`ExactOdometry::update_q16`] then uses integers only. [`ExactOracle`] is the f64
//! twin that the tests hold it to.

use crate::fixed::{mul_q30_wide, mul_q31, shr_round, sin_cos};
use crate::se2::Pose2;
use crate::wheelset::WheelSolver;

/// Most encoders the fixed-point integrator takes.
pub const MAX_ENCODERS: usize = 4;

/// Displacement per count is below this in magnitude, 2^40 Q44 = 1/16 m (the chunking's
/// bounds and the fraction products rely on it).
const MAX_DISPLACEMENT_CONSTANT: i64 = 1 << 40;
/// Turn per count is below this in magnitude, 2^46 × 2^-48 = a quarter turn. The heading sum
/// wraps exactly whatever its size; the bound keeps `turn_per_count` far from overflow.
/// (Coarse encoders on a short axle turn a lot per count: 1 cm counts 20 cm apart are
/// 0.05 rad, 2^41.2 units.)
const MAX_TURN_CONSTANT: i64 = 1 << 46;

/// Per-chunk limits that keep every 64-bit product in range.
const MAX_CHUNK_DISPLACEMENT_Q44: i64 = 1 << 43; // 0.5 m
/// 1/8 turn, in the unit of `turn_per_count` × whole counts: 2^-48 turns.
const MAX_CHUNK_TURN_48: u64 = 1 << 45;

/// Integer constants of a sensor layout.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ExactParams {
    n: usize,
    /// Body-frame displacement per count, Q44 metres: 0.1 mm per count is about 1.8·10^9,
    /// so the constant carries 31 significant bits (a scale error below 10^-9).
    kx: [i64; MAX_ENCODERS],
    ky: [i64; MAX_ENCODERS],
    /// Turn per count in 2^-48 turns (times a Q16 count gives 2^-64 turns).
    kth: [i64; MAX_ENCODERS],
    /// Σ_j max(|kx_j|, |ky_j|): bounds the displacement of a step (Q44 m per count).
    disp_per_count: i64,
    /// Σ_j |kth_j|, bounds the turn of a step (2^-48 turns per count).
    turn_per_count: u64,
    /// The most whole counts (plus one) an update may move and still be one chunk: what
    /// `disp_per_count` and `turn_per_count` allow, divided out once here so an update
    /// compares instead of multiplying and dividing.
    one_chunk_whole_counts: i64,
}

/// Why a layout cannot be integrated in fixed point.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ExactParamsError {
    /// More than [`MAX_ENCODERS`], or not one travel per count for each wheel.
    TooManyEncoders,
    /// A per-count constant does not fit the fixed-point format (absurd geometry), or a raw
    /// constant past the encoders is not zero.
    OutOfRange,
}

impl ExactParams {
    /// Constants for wheels solved by `solver`, each travelling `metres_per_count[j]` per count.
    pub fn new(solver: &WheelSolver, metres_per_count: &[f64]) -> Result<Self, ExactParamsError> {
        let n = solver.wheels();
        if n > MAX_ENCODERS || metres_per_count.len() != n {
            return Err(ExactParamsError::TooManyEncoders);
        }
        let pinv = solver.pseudo_inverse();
        let to_fixed = |v: f64, scale: f64, max: i64| -> Result<i64, ExactParamsError> {
            let f = libm::round(v * scale);
            if f.is_finite() && f.abs() < max as f64 {
                Ok(f as i64)
            } else {
                Err(ExactParamsError::OutOfRange)
            }
        };
        let (mut kx, mut ky, mut kth) = ([0; MAX_ENCODERS], [0; MAX_ENCODERS], [0; MAX_ENCODERS]);
        const Q44: f64 = (1u64 << 44) as f64;
        const TURN_48: f64 = (1u64 << 48) as f64 / (2.0 * core::f64::consts::PI);
        for j in 0..n {
            let k = metres_per_count[j];
            kx[j] = to_fixed(pinv[0][j] * k, Q44, MAX_DISPLACEMENT_CONSTANT)?;
            ky[j] = to_fixed(pinv[1][j] * k, Q44, MAX_DISPLACEMENT_CONSTANT)?;
            kth[j] = to_fixed(pinv[2][j] * k, TURN_48, MAX_TURN_CONSTANT)?;
        }
        Self::from_raw(n, kx, ky, kth)
    }

    /// Rebuild the constants from their raw integers (as [`kx`](Self::kx), [`ky`](Self::ky),
    /// [`kth`](Self::kth) give them, e.g. shipped over a wire): the same integers give the
    /// same integrator, bit for bit. Entries past `n` must be zero (unused encoders move
    /// nothing); `kx`, `ky` must be below 2^40 in magnitude (1/16 m per count), `kth` below
    /// 2^46 (a quarter turn per count). Integer-only.
    pub const fn from_raw(
        n: usize,
        kx: [i64; MAX_ENCODERS],
        ky: [i64; MAX_ENCODERS],
        kth: [i64; MAX_ENCODERS],
    ) -> Result<Self, ExactParamsError> {
        if n > MAX_ENCODERS {
            return Err(ExactParamsError::TooManyEncoders);
        }
        let (mut disp_per_count, mut turn_per_count) = (0i64, 0u64);
        // `while`: this is a `const fn` (seed 004's constants are compiled in).
        let mut j = 0;
        while j < MAX_ENCODERS {
            let ks = [kx[j], ky[j], kth[j]];
            let max = [
                MAX_DISPLACEMENT_CONSTANT,
                MAX_DISPLACEMENT_CONSTANT,
                MAX_TURN_CONSTANT,
            ];
            let mut i = 0;
            while i < 3 {
                // `unsigned_abs` so i64::MIN cannot overflow.
                if ks[i].unsigned_abs() >= max[i] as u64 || (j >= n && ks[i] != 0) {
                    return Err(ExactParamsError::OutOfRange);
                }
                i += 1;
            }
            let (ax, ay) = (kx[j].abs(), ky[j].abs());
            disp_per_count += if ax > ay { ax } else { ay };
            turn_per_count += kth[j].unsigned_abs();
            j += 1;
        }
        // whole · disp < MAX ⟺ whole ≤ (MAX − 1) / disp, and the same for the turn.
        let by_disp = match (MAX_CHUNK_DISPLACEMENT_Q44 - 1).checked_div(disp_per_count) {
            Some(k) => k,
            None => i64::MAX,
        };
        let by_turn = match (MAX_CHUNK_TURN_48 - 1).checked_div(turn_per_count) {
            Some(k) => k as i64,
            None => i64::MAX,
        };
        Ok(ExactParams {
            n,
            kx,
            ky,
            kth,
            disp_per_count,
            turn_per_count,
            one_chunk_whole_counts: if by_disp < by_turn { by_disp } else { by_turn },
        })
    }

    /// Body x displacement per count of each encoder, Q44 metres (zero past the encoders).
    pub fn kx(&self) -> [i64; MAX_ENCODERS] {
        self.kx
    }

    /// Body y displacement per count, Q44 metres.
    pub fn ky(&self) -> [i64; MAX_ENCODERS] {
        self.ky
    }

    /// Turn per count, 2^-48 turns.
    pub fn kth(&self) -> [i64; MAX_ENCODERS] {
        self.kth
    }

    pub fn encoders(&self) -> usize {
        self.n
    }
}

/// A pose in the integrator's own units.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FixedPose {
    /// Q40 metres.
    pub x: i64,
    pub y: i64,
    /// Binary angle, 2^64 = one turn.
    pub theta: u64,
}

impl FixedPose {
    /// One metre in position units.
    pub const METRE: i64 = 1 << 40;
    const Q40: f64 = (1u64 << 40) as f64;
    const TURN: f64 = 18_446_744_073_709_551_616.0;

    pub fn from_pose2(p: Pose2) -> Self {
        let turns = p.theta / (2.0 * core::f64::consts::PI);
        let frac = turns - libm::floor(turns);
        FixedPose {
            x: libm::round(p.x * Self::Q40) as i64,
            y: libm::round(p.y * Self::Q40) as i64,
            // The top 53 bits carry the value; the wrap at exactly 1.0 is what a turn does.
            theta: (frac * Self::TURN) as u64,
        }
    }

    /// (x m, y m, θ in (-π, π]).
    pub fn to_pose2(self) -> Pose2 {
        Pose2::new(
            self.x as f64 / Self::Q40,
            self.y as f64 / Self::Q40,
            self.theta as i64 as f64 / Self::TURN * 2.0 * core::f64::consts::PI,
        )
    }

    /// From the wire format (micrometres, 32-bit binary angle). Integer-only: one metre is
    /// 2^40 units and 10^6 = 2^6 · 15 625, so x_um · 2^40 / 10^6 = x_um · 2^34 / 15 625,
    /// computed as (x_um · 2^31 / 15 625) · 2^3 to stay inside 64 bits.
    // Out of line: called where the slave starts or sets a pose, and two inlined copies took
    // 140 B of its flash.
    #[inline(never)]
    pub fn from_micrometres(x_um: i32, y_um: i32, heading_bam: u32) -> Self {
        let q40 = |um: i32| ((um as i64) << 31) / 15_625 * 8;
        FixedPose {
            x: q40(x_um),
            y: q40(y_um),
            theta: (heading_bam as u64) << 32,
        }
    }

    /// Position in micrometres, rounded, saturated to `i32` (the wire format). Integer-only.
    pub fn micrometres(self) -> (i32, i32) {
        let um = |v: i64| -> i32 {
            // Q40 -> Q20 first so the product with 10^6 stays in range (|v| < 2^43 m would
            // be needed to overflow), then round.
            let q20 = shr_round(v, 20);
            let scaled = shr_round(q20.saturating_mul(1_000_000), 20);
            scaled.clamp(i32::MIN as i64, i32::MAX as i64) as i32
        };
        (um(self.x), um(self.y))
    }

    /// Heading as a 32-bit binary angle (the wire format).
    pub fn heading_bam(self) -> u32 {
        (self.theta >> 32) as u32
    }
}

/// The fixed-point exact integrator.
#[derive(Clone, Copy, Debug)]
pub struct ExactOdometry {
    p: ExactParams,
    last: [i64; MAX_ENCODERS],
    /// The update's count changes (zero past the layout's encoders). Kept here, not on the
    /// stack: a zeroed local array is a `memclr` call at opt-level "z", 44 instructions.
    dq: [i64; MAX_ENCODERS],
    pose: FixedPose,
}

impl ExactOdometry {
    /// Start at `pose` with the encoders at `counts_q16` (Q16 counts, cumulative; entries
    /// past the layout's encoders are ignored). Fixed-size arrays keep bounds checks, and
    /// with them any panic path, out of the firmware.
    pub fn new(p: ExactParams, pose: FixedPose, counts_q16: &[i64; MAX_ENCODERS]) -> Self {
        ExactOdometry {
            p,
            last: *counts_q16,
            dq: [0; MAX_ENCODERS],
            pose,
        }
    }

    pub fn pose(&self) -> FixedPose {
        self.pose
    }

    /// Restart from `pose` at the current counts.
    pub fn set_pose(&mut self, pose: FixedPose) {
        self.pose = pose;
    }

    /// Whole-count convenience for fixed-rate sampling.
    pub fn update_counts(&mut self, counts: &[i64; MAX_ENCODERS]) -> FixedPose {
        // A loop, not `map`: an out-of-line `array::map` shares its name with float callers'
        // and blurs the no-float check's call graph.
        let mut q16 = [0i64; MAX_ENCODERS];
        for (q, &c) in q16.iter_mut().zip(counts) {
            *q = c.wrapping_shl(16);
        }
        self.update_q16(&q16)
    }

    /// Move to the encoders' new cumulative positions (Q16 counts). Integer-only.
    pub fn update_q16(&mut self, counts_q16: &[i64; MAX_ENCODERS]) -> FixedPose {
        let mut biggest = 0i64;
        // The layout's encoders only: unused slots have zero constants and move nothing.
        // (One loop that also keeps the counts: a separate copy is a `memcpy` call. Indexed,
        // not zipped: at opt-level "z" the zipped form is 20 instructions an update more.)
        #[allow(clippy::needless_range_loop)]
        for j in 0..self.p.n.min(MAX_ENCODERS) {
            let d = counts_q16[j].wrapping_sub(self.last[j]);
            self.dq[j] = d;
            self.last[j] = counts_q16[j];
            biggest = biggest.max(d.saturating_abs());
        }
        let dq = &self.dq;
        // How many chunks keep displacement and turn per chunk in range. Almost always 1.
        let whole_counts = (biggest >> 16) + 1;
        let chunks = if whole_counts <= self.p.one_chunk_whole_counts {
            1 // compared, not multiplied and divided (64-bit division is a library call)
        } else {
            let disp = whole_counts.saturating_mul(self.p.disp_per_count);
            let turn = (whole_counts as u64).saturating_mul(self.p.turn_per_count);
            (disp / MAX_CHUNK_DISPLACEMENT_Q44).max((turn / MAX_CHUNK_TURN_48) as i64) + 1
        };
        if chunks == 1 {
            Self::step(&self.p, &mut self.pose, dq);
        } else {
            Self::steps_in_chunks(&self.p, &mut self.pose, dq, chunks);
        }
        self.pose
    }

    /// A move too big for one step, in `chunks` equal parts that add up to `dq` exactly
    /// ([`chunk_end`]: in 64 bits; the 128-bit division it replaces was 0.5 KB of the slave's
    /// flash). Cold: only a jump of hundreds of counts in one update comes here.
    #[cold]
    #[inline(never)]
    fn steps_in_chunks(
        p: &ExactParams,
        pose: &mut FixedPose,
        dq: &[i64; MAX_ENCODERS],
        chunks: i64,
    ) {
        let mut done = [0i64; MAX_ENCODERS];
        for k in 1..=chunks {
            let mut part = [0i64; MAX_ENCODERS];
            for j in 0..MAX_ENCODERS {
                let upto = chunk_end(dq[j], k, chunks);
                part[j] = upto - done[j];
                done[j] = upto;
            }
            Self::step(p, pose, &part);
        }
    }

    /// One chunk's step (the parts of `self` it needs, apart: `dq` may be `self.dq`).
    fn step(p: &ExactParams, pose: &mut FixedPose, dq: &[i64; MAX_ENCODERS]) {
        let (mut dx, mut dy, mut dth) = (0i64, 0i64, 0u64);
        // The layout's encoders only (the unused slots' constants are zero).
        let n = p.n.min(MAX_ENCODERS);
        for (((&d, &kx), &ky), &kth) in dq[..n].iter().zip(&p.kx).zip(&p.ky).zip(&p.kth) {
            // Whole counts and the Q16 fraction apart, so neither product can overflow:
            // constant (Q44) × whole counts (bounded by the chunking) is Q44 directly.
            let (whole, frac) = (d >> 16, d & 0xFFFF);
            dx += kx * whole;
            dy += ky * whole;
            if frac != 0 {
                // Interpolated positions only (sampled counters are whole).
                dx += shr_round(kx * frac, 16);
                dy += shr_round(ky * frac, 16);
            }
            // Heading lives modulo a turn: wrapping arithmetic is exact arithmetic here.
            dth = dth.wrapping_add(kth.wrapping_mul(d) as u64);
        }
        // Body displacement, Q44 -> Q40.
        let (dx, dy) = (shr_round(dx, 4), shr_round(dy, 4));
        let half = half_toward_zero(dth as i64);
        let mid = pose.theta.wrapping_add(half as u64);
        let (s, c) = sin_cos((mid >> 32) as u32);
        let wx = mul_q30_wide(dx, c) - mul_q30_wide(dy, s);
        let wy = mul_q30_wide(dx, s) + mul_q30_wide(dy, c);
        // sinc(h) = 1 - h²/6 + h⁴/120 for the half-turn h (< 1/16 turn per chunk: the next
        // term is below 1e-8 relative, and per update at real rates far smaller still).
        // BAM·π, Q31 radians; |h| < π/8 (half the chunking's 1/8 turn), so it fits 32 bits
        // and the squares are `smull`s.
        let h_q31 = (((half >> 32) * 1_686_629_713 + (1 << 28)) >> 29) as i32;
        let h2 = mul_q31(h_q31, h_q31);
        let h4 = mul_q31(h2, h2);
        // 1 - sinc(h), Q30 (below 0.026: 32 bits); applied as a correction so the big product
        // never forms. h²/6 and h⁴/120 as multiply-and-shift: no 64-bit divisions.
        let eps_q30 = half_toward_zero(
            (((h2 as i64 * 357_913_941) >> 31) - ((h4 as i64 * 17_895_697) >> 31)) + 1,
        ) as i32;
        pose.x += wx - mul_q30_wide(wx, eps_q30);
        pose.y += wy - mul_q30_wide(wy, eps_q30);
        pose.theta = pose.theta.wrapping_add(dth);
    }
}

/// Where the `k`-th of `chunks` equal parts of `dq` ends: trunc(dq·k / chunks), for
/// 0 < k ≤ chunks ≤ 2^20 + 1 (what `update_q16`'s chunking can ask: a saturated 2^63 over
/// the 2^43 chunk). As q·k + trunc(r·k / chunks) with dq = q·chunks + r, both truncations
/// toward zero with q and r of dq's sign; |q·k| ≤ |dq| and |r·k| < chunks² ≤ 2^42: no
/// overflow, no 128-bit division.
fn chunk_end(dq: i64, k: i64, chunks: i64) -> i64 {
    // `checked_*`: `chunks` is at least 2 here, but out of line the compiler cannot see that,
    // and a division's panic path must not reach the board (`scripts/check-no-float.py`).
    let (Some(q), Some(r)) = (dq.checked_div(chunks), dq.checked_rem(chunks)) else {
        return 0;
    };
    q * k + (r * k).checked_div(chunks).unwrap_or(0)
}

/// `x / 2` (rounding toward zero) by shifts: at opt-level "z" a 64-bit division, even by
/// two, is a library call on the M3.
#[inline(always)]
fn half_toward_zero(x: i64) -> i64 {
    (x + ((x as u64) >> 63) as i64) >> 1
}

/// The f64 twin of [`ExactOdometry`]: same model, floating point, heading from the
/// cumulative counts. The reference the fixed-point version is tested against.
#[derive(Clone, Copy, Debug)]
pub struct ExactOracle {
    solver: WheelSolver,
    k: [f64; MAX_ENCODERS],
    start: [f64; MAX_ENCODERS],
    last: [f64; MAX_ENCODERS],
    theta0: f64,
    pose: Pose2,
}

impl ExactOracle {
    /// `counts` may be fractional (interpolated).
    pub fn new(solver: WheelSolver, metres_per_count: &[f64], pose: Pose2, counts: &[f64]) -> Self {
        let n = solver.wheels().min(MAX_ENCODERS);
        let mut k = [0.0; MAX_ENCODERS];
        let mut start = [0.0; MAX_ENCODERS];
        k[..n].copy_from_slice(&metres_per_count[..n]);
        start[..n].copy_from_slice(&counts[..n]);
        ExactOracle {
            solver,
            k,
            start,
            last: start,
            theta0: pose.theta,
            pose,
        }
    }

    pub fn update(&mut self, counts: &[f64]) -> Pose2 {
        let n = self.solver.wheels().min(MAX_ENCODERS);
        let mut step = [0.0; MAX_ENCODERS];
        let mut total = [0.0; MAX_ENCODERS];
        for j in 0..n {
            step[j] = (counts[j] - self.last[j]) * self.k[j];
            total[j] = (counts[j] - self.start[j]) * self.k[j];
            self.last[j] = counts[j];
        }
        let d = self.solver.solve(&step[..n]);
        let theta = self.theta0 + self.solver.solve(&total[..n]).omega;
        let mut next = self
            .pose
            .compose_increment(d.vx, d.vy, theta - self.pose.theta);
        next.theta = theta;
        self.pose = next;
        next
    }

    pub fn pose(&self) -> Pose2 {
        self.pose
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::se2::{wrap_angle, Twist};

    #[test]
    fn chunk_ends_are_the_exact_truncated_fractions() {
        let dqs = [
            0i64,
            1,
            -1,
            7,
            -7,
            65_535,
            -65_537,
            1 << 40,
            -(1 << 47) - 3,
            i64::MAX / 3,
        ];
        for dq in dqs {
            for chunks in [2i64, 3, 7, 1_000, (1 << 20) + 1] {
                for k in [1, 2, chunks / 2, chunks - 1, chunks] {
                    let exact = (dq as i128 * k as i128 / chunks as i128) as i64;
                    assert_eq!(chunk_end(dq, k, chunks), exact, "{dq} {k} {chunks}");
                }
            }
        }
    }
    use crate::wheel::Wheel;
    use core::f64::consts::PI;
    use proptest::prelude::*;

    /// Seed 000's layout: three omni measuring wheels on a 20 cm triangle, 45° mounting.
    fn triangle() -> [Wheel; 3] {
        core::array::from_fn(|i| {
            let a = i as f64 * 2.0 * PI / 3.0;
            let r = 0.2 / 3f64.sqrt();
            Wheel::at(r * a.cos(), r * a.sin(), a + PI / 2.0 + PI / 4.0)
        })
    }

    const K: f64 = 1e-4; // 0.1 mm per count

    fn setup() -> (WheelSolver, ExactParams) {
        let solver = WheelSolver::new(&triangle()).unwrap();
        let params = ExactParams::new(&solver, &[K; 3]).unwrap();
        (solver, params)
    }

    /// Drive a constant twist for `t` seconds in `steps` updates, feeding exact (fractional,
    /// Q16) counts: returns the fixed-point and oracle poses and the closed form.
    fn drive(twist: Twist, t: f64, steps: usize, start: Pose2) -> (Pose2, Pose2, Pose2) {
        let (solver, params) = setup();
        let wheels = triangle();
        let mut fixed = ExactOdometry::new(params, FixedPose::from_pose2(start), &[0; 4]);
        let mut oracle = ExactOracle::new(solver, &[K; 3], start, &[0.0; 3]);
        for i in 1..=steps {
            let tt = t * i as f64 / steps as f64;
            let counts: [f64; 3] =
                core::array::from_fn(|j| wheels[j].rolling_speed(twist) * tt / K);
            let q = [0, 1, 2, 3].map(|j| counts.get(j).map_or(0, |c| (c * 65536.0).round() as i64));
            fixed.update_q16(&q);
            oracle.update(&counts);
        }
        (
            fixed.pose().to_pose2(),
            oracle.pose(),
            start.integrate(twist, t),
        )
    }

    fn assert_close(a: Pose2, b: Pose2, tol: f64, what: &str) {
        let e = a.distance_to(b);
        let eh = wrap_angle(a.theta - b.theta).abs();
        assert!(
            e < tol && eh < tol,
            "{what}: {a:?} vs {b:?} ({e:e} m, {eh:e} rad)"
        );
    }

    #[test]
    fn straight_line() {
        let (f, o, truth) = drive(
            Twist::new(0.5, 0.2, 0.0),
            4.0,
            1000,
            Pose2::new(1.0, -1.0, 0.3),
        );
        assert_close(o, truth, 1e-9, "oracle");
        assert_close(f, truth, 1e-7, "fixed");
    }

    #[test]
    fn pure_spin() {
        let (f, o, truth) = drive(
            Twist::new(0.0, 0.0, 3.0),
            10.0,
            1000,
            Pose2::new(0.5, 0.5, 0.0),
        );
        assert_close(o, truth, 1e-9, "oracle");
        assert_close(f, truth, 1e-7, "fixed");
    }

    #[test]
    fn constant_curvature_arc_even_in_few_big_steps() {
        // Radius 1 m, 1.5 turns, in only 12 updates (over 0.7 rad each): the arc is exact,
        // the chord would be off by centimetres.
        let (f, o, truth) = drive(Twist::new(1.0, 0.0, 1.0), 3.0 * PI, 12, Pose2::default());
        assert_close(o, truth, 1e-9, "oracle");
        assert_close(f, truth, 1e-6, "fixed");
    }

    #[test]
    fn heading_wraps_freely_over_many_turns() {
        let (f, _, truth) = drive(
            Twist::new(0.0, 0.0, 2.0 * PI),
            100.5,
            20_000,
            Pose2::default(),
        );
        assert_close(f, truth, 1e-7, "fixed");
        assert!((f.theta.abs() - PI).abs() < 1e-6);
    }

    #[test]
    fn huge_steps_are_split_not_overflowed() {
        // 10 m in one update (100 000 counts): chunked internally, still on the line.
        let (f, _, truth) = drive(Twist::new(10.0, 0.0, 0.0), 1.0, 1, Pose2::default());
        assert_close(f, truth, 1e-6, "fixed");
    }

    #[test]
    fn big_turns_in_one_update_are_split_too() {
        // 0.4 and 0.7 of a turn in a single update, driving forwards: split into chunks of at
        // most 1/8 turn, where the sinc series holds (one step would be off by millimetres,
        // and past half a turn would turn the wrong way round the arc).
        for turns in [0.4, 0.7] {
            let w = turns * 2.0 * PI;
            let (f, o, truth) = drive(Twist::new(0.1, 0.0, w), 1.0, 1, Pose2::default());
            assert_close(o, truth, 1e-9, "oracle");
            assert_close(f, truth, 1e-6, "fixed");
        }
    }

    #[test]
    fn wire_units_round_trip() {
        for &(x, y, h) in &[
            (0, 0, 0u32),
            (1, -1, 1),
            (2_500_000, 3_000_000, 1 << 30),
            (i32::MAX, i32::MIN, u32::MAX),
        ] {
            let p = FixedPose::from_micrometres(x, y, h);
            assert_eq!(p.micrometres(), (x, y));
            assert_eq!(p.heading_bam(), h);
            let f = p.to_pose2();
            assert!((f.x - x as f64 * 1e-6).abs() < 1e-11 && (f.y - y as f64 * 1e-6).abs() < 1e-11);
        }
    }

    #[test]
    fn counts_can_start_anywhere_and_wrap() {
        let (_, params) = setup();
        let base = i64::MAX - 5 * 65536; // the Q16 totals wrap during this run
        let mut a = ExactOdometry::new(params, FixedPose::default(), &[base; 4]);
        let mut b = ExactOdometry::new(params, FixedPose::default(), &[0; 4]);
        for i in 1..50i64 {
            let c = [i * 3, -i * 2, i, 0].map(|v| v * 65536);
            a.update_q16(&c.map(|v| base.wrapping_add(v)));
            b.update_q16(&c);
        }
        assert_eq!(a.pose(), b.pose());
    }

    proptest! {
        /// Any count sequence: the fixed-point integrator stays within 10 nm + 1e-7 rad of its
        /// f64 oracle (documented tolerance).
        #[test]
        fn fixed_tracks_the_oracle(steps in prop::collection::vec(prop::array::uniform3(-40i64..40), 1..400)) {
            let (solver, params) = setup();
            let mut fixed = ExactOdometry::new(params, FixedPose::default(), &[0; 4]);
            let mut oracle = ExactOracle::new(solver, &[K; 3], Pose2::default(), &[0.0; 3]);
            let mut c = [0i64; 4];
            for s in steps {
                for j in 0..3 { c[j] += s[j]; }
                fixed.update_counts(&c);
                oracle.update(&c.map(|v| v as f64)[..3]);
            }
            let (f, o) = (fixed.pose().to_pose2(), oracle.pose());
            prop_assert!(f.distance_to(o) < 1e-8, "{:?} vs {:?}", f, o);
            prop_assert!(wrap_angle(f.theta - o.theta).abs() < 1e-7);
        }
    }
}
