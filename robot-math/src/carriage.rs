//! Seed 004's measuring carriage: two free-rolling measuring wheels on one axle, on a swivel
//! whose angle relative to the body an absolute encoder reads.
//!
//! Geometry (all in the carriage frame: x along the carriage's heading φ, y to its left):
//! the axle midpoint `A` trails the swivel pivot by `trail` metres; the pivot sits at the
//! body's reference point. Wheel 0 (left) is at (0, +L/2), wheel 1 (right) at (0, −L/2), both
//! rolling along +x. With no lateral slip the carriage moves like a differential drive:
//! v = (s0' + s1')/2, φ' = (s1' − s0')/L. Because the axle trails the pivot, the carriage
//! swings behind whatever direction the (omni-directional) body translates in, like a caster.
//!
//! Body pose from carriage pose: θ = φ − β (β from the absolute encoder) and
//! P = A + trail·(cos φ, sin φ).

use crate::se2::{wrap_angle, Pose2};
use core::f64::consts::PI;

/// Measuring-carriage geometry and sensor resolution.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CarriageGeometry {
    /// Distance between the two measuring wheels, metres (seed 004's L).
    pub wheel_base: f64,
    /// Pivot to axle midpoint, metres (> 0: the carriage trails).
    pub trail: f64,
    /// Wheel travel per quadrature count, metres, per wheel (π·D / (4·pulses per rev)).
    pub metres_per_count: [f64; 2],
    /// Absolute encoder resolution in bits (seed 004's E6CP-AG5C: 8 bits, 256 positions).
    pub abs_bits: u8,
}

impl CarriageGeometry {
    /// Seed 004's sensors: Omron E6B2-C 1200 P/R (x4 = 4800 counts/rev) on 50 mm measuring
    /// wheels 200 mm apart, 60 mm trail, 256-position absolute encoder. The wheel size,
    /// spacing and trail are not given in the paper; these are ours (docs/design.md, "The
    /// simulated robot, and what we assumed").
    pub const SEED_004: CarriageGeometry = CarriageGeometry {
        wheel_base: 0.200,
        trail: 0.060,
        metres_per_count: [PI * 0.050 / 4800.0, PI * 0.050 / 4800.0],
        abs_bits: 8,
    };

    /// The two measuring wheels in the carriage frame (left, right): on the axle through the
    /// frame's origin, both rolling along +x.
    pub fn wheels(&self) -> (crate::wheel::Wheel, crate::wheel::Wheel) {
        let half = self.wheel_base / 2.0;
        (
            crate::wheel::Wheel::at(0.0, half, 0.0),
            crate::wheel::Wheel::at(0.0, -half, 0.0),
        )
    }

    /// The trail in Q40 metres, the position unit of [`crate::exact::FixedPose`].
    pub fn trail_q40(&self) -> i64 {
        libm::round(self.trail * crate::exact::FixedPose::METRE as f64) as i64
    }

    /// Absolute encoder step, radians.
    pub fn abs_step(&self) -> f64 {
        2.0 * PI / (1u32 << self.abs_bits) as f64
    }

    /// Swivel angle β (carriage heading minus body heading) that a code stands for: code k
    /// covers β in [(k − ½)·q, (k + ½)·q), so k·q is the best estimate.
    pub fn swivel_angle(&self, code: u16) -> f64 {
        let n = 1u32 << self.abs_bits;
        wrap_angle((code as u32 % n) as f64 * self.abs_step())
    }

    /// The code an ideal absolute encoder shows at swivel angle β (round to nearest).
    pub fn abs_code(&self, beta: f64) -> u16 {
        let n = 1i64 << self.abs_bits;
        let k = libm::round(beta / self.abs_step()) as i64;
        k.rem_euclid(n) as u16
    }

    /// The carriage pose (axle midpoint, heading φ) for a body pose and swivel angle.
    pub fn carriage_pose(&self, body: Pose2, beta: f64) -> Pose2 {
        let phi = body.theta + beta;
        Pose2::new(
            body.x - self.trail * crate::trig::cos(phi),
            body.y - self.trail * crate::trig::sin(phi),
            phi,
        )
    }

    /// The body pose for a carriage pose and swivel angle.
    pub fn body_pose(&self, carriage: Pose2, beta: f64) -> Pose2 {
        Pose2::new(
            carriage.x + self.trail * crate::trig::cos(carriage.theta),
            carriage.y + self.trail * crate::trig::sin(carriage.theta),
            carriage.theta - beta,
        )
    }
}

/// Odometry for the measuring carriage: the arc per update, from *cumulative* counts.
///
/// The carriage heading is recomputed from the total counts since the last reset at every
/// update, so count quantisation never accumulates into heading drift; the position follows
/// each update's constant-curvature arc exactly (the SE(2) exponential, not the chord).
#[derive(Clone, Copy, Debug)]
pub struct CarriageOdometry {
    geom: CarriageGeometry,
    phi0: f64,
    counts0: [i64; 2],
    last_counts: [i64; 2],
    carriage: Pose2,
    body: Pose2,
}

impl CarriageOdometry {
    /// Start at `body` with the sensors currently reading `counts` and `abs_code`.
    pub fn new(geom: CarriageGeometry, body: Pose2, counts: [i64; 2], abs_code: u16) -> Self {
        let beta = geom.swivel_angle(abs_code);
        let carriage = geom.carriage_pose(body, beta);
        CarriageOdometry {
            geom,
            phi0: carriage.theta,
            counts0: counts,
            last_counts: counts,
            carriage,
            body: geom.body_pose(carriage, beta),
        }
    }

    /// Restart from `body` (e.g. a set-pose command).
    pub fn reset(&mut self, body: Pose2, counts: [i64; 2], abs_code: u16) {
        *self = Self::new(self.geom, body, counts, abs_code);
    }

    /// One update with the current cumulative counts and absolute code; returns the body pose.
    pub fn update(&mut self, counts: [i64; 2], abs_code: u16) -> Pose2 {
        let k = self.geom.metres_per_count;
        let s = |i: usize, c: [i64; 2], c0: [i64; 2]| (c[i] - c0[i]) as f64 * k[i];
        let phi = self.phi0
            + (s(1, counts, self.counts0) - s(0, counts, self.counts0)) / self.geom.wheel_base;
        let ds = (s(0, counts, self.last_counts) + s(1, counts, self.last_counts)) / 2.0;
        let mut next = self
            .carriage
            .compose_increment(ds, 0.0, phi - self.carriage.theta);
        next.theta = phi; // exactly the cumulative value, not a sum of increments
        self.carriage = next;
        self.last_counts = counts;
        self.body = self.geom.body_pose(next, self.geom.swivel_angle(abs_code));
        self.body
    }

    pub fn body(&self) -> Pose2 {
        self.body
    }

    pub fn carriage(&self) -> Pose2 {
        self.carriage
    }

    pub fn geometry(&self) -> &CarriageGeometry {
        &self.geom
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const G: CarriageGeometry = CarriageGeometry::SEED_004;

    #[test]
    fn swivel_code_round_trip() {
        for k in 0..256u16 {
            assert_eq!(G.abs_code(G.swivel_angle(k)), k);
        }
        assert_eq!(G.abs_code(PI / 2.0), 64);
        assert_eq!(G.abs_code(-PI / 2.0), 192);
    }

    #[test]
    fn pose_conversions_invert() {
        let body = Pose2::new(1.0, -2.0, 0.3);
        let c = G.carriage_pose(body, 1.1);
        let b = G.body_pose(c, 1.1);
        assert!(b.distance_to(body) < 1e-12 && (b.theta - body.theta).abs() < 1e-12);
    }

    #[test]
    fn driving_a_circle_with_the_carriage_ends_where_it_started() {
        // Carriage heading +y at code 64 (β = 90°, body heading 0). Left wheel travels less:
        // turn left around a circle of radius R; after a full turn the pose is back.
        let r = 0.5;
        let l = G.wheel_base;
        let k = G.metres_per_count[0];
        let body0 = Pose2::new(0.0, 0.0, 0.0);
        let mut odo = CarriageOdometry::new(G, body0, [0, 0], 64);
        let steps = 2000;
        let total = [2.0 * PI * (r - l / 2.0) / k, 2.0 * PI * (r + l / 2.0) / k];
        let mut pose = body0;
        for i in 1..=steps {
            let c = [
                (total[0] * i as f64 / steps as f64).round() as i64,
                (total[1] * i as f64 / steps as f64).round() as i64,
            ];
            // The body keeps heading 0, so the swivel follows the carriage round.
            let phi = PI / 2.0 + 2.0 * PI * i as f64 / steps as f64;
            pose = odo.update(c, G.abs_code(phi));
        }
        // Quantisation: one count of heading error is k/L rad; position error is of order r·k/L.
        assert!(pose.distance_to(body0) < 2.0 * r * k / l + 1e-6, "{pose:?}");
    }
}

/// [`CarriageOdometry`] in fixed point: the slave's default, integer-only on the update path.
///
/// The carriage is a differential drive in its own frame (the axle solver of
/// [`crate::wheelset`]) integrated by [`crate::exact::ExactOdometry`], with its reference
/// point at the **pivot**, not the axle: the pivot is a point of the rigid carriage `trail`
/// ahead of the axle midpoint A, so it moves as A does plus trail·φ' sideways, and its
/// per-count constants are the axle's with `ky += trail·kth` ([`Self::from_params`]). The
/// exact step is exact for any point of a body moving at a constant twist, so this integrates
/// the same model as P = A + trail·(cos φ, sin φ) — without the sine and cosine of φ and the
/// two trail products every update (about 150 instructions on the M3). The body pose is then
/// (P, θ = φ − β), β straight from the absolute code as a binary angle. The constants are
/// derived with floats once, by [`CarriageExact::new`] (or arrive as integers:
/// [`Self::from_params`]); [`CarriageExact::update`] uses integers only.
#[derive(Clone, Copy, Debug)]
pub struct CarriageExact {
    /// The pivot's pose (x, y) with the carriage's heading φ.
    pivot: crate::exact::ExactOdometry,
    abs_bits: u8,
    body: crate::exact::FixedPose,
}

impl CarriageExact {
    /// `None` if the geometry cannot be integrated (non-positive wheel base, absurd sizes).
    pub fn new(
        geom: &CarriageGeometry,
        body: Pose2,
        counts: [i64; 2],
        abs_code: u16,
    ) -> Option<Self> {
        use crate::exact::{ExactParams, FixedPose};
        let (left, right) = geom.wheels();
        let solver = crate::wheelset::WheelSolver::new(&[left, right]).ok()?;
        let params = ExactParams::new(&solver, &geom.metres_per_count).ok()?;
        Self::from_params(
            params,
            geom.trail_q40(),
            geom.abs_bits,
            FixedPose::from_pose2(body),
            // The integrator takes Q16 counts.
            [counts[0] << 16, counts[1] << 16],
            abs_code,
        )
    }

    /// From the integer constants alone (no floats): the carriage axle's [`ExactParams`] (two
    /// encoders, left then right), the trail in Q40 metres and the absolute encoder's bits.
    /// Starts at `body` with the wheels at `counts_q16` and the swivel at position `abs_code`.
    /// `None` for anything but two encoders or 1..=16 absolute bits, or constants that moved
    /// to the pivot leave the fixed-point range (a trail of kilometres).
    pub fn from_params(
        params: crate::exact::ExactParams,
        trail_q40: i64,
        abs_bits: u8,
        body: crate::exact::FixedPose,
        counts_q16: [i64; 2],
        abs_code: u16,
    ) -> Option<Self> {
        use crate::exact::{ExactOdometry, FixedPose};
        if !(1..=16).contains(&abs_bits) || params.encoders() != 2 {
            return None;
        }
        let mut s = CarriageExact {
            pivot: ExactOdometry::new(
                pivot_params(params, trail_q40)?,
                FixedPose::default(),
                &[counts_q16[0], counts_q16[1], 0, 0],
            ),
            abs_bits,
            body: FixedPose::default(),
        };
        s.set_body(body, abs_code);
        Some(s)
    }

    /// The swivel angle of a code as a binary angle (code k of 2^bits stands for k/2^bits turn).
    ///
    /// In 32 bits, then moved up: `abs_bits` is 1..=16, so the code fills the top bits of
    /// the high word and the low word is zero. A 64-bit shift by a variable amount is a
    /// library call on the M3 (two of them ran every update), a 32-bit one an instruction.
    fn swivel(&self, code: u16) -> u64 {
        let bits = self.abs_bits as u32;
        let high = (code as u32 & ((1u32 << bits) - 1)) << (32 - bits);
        (high as u64) << 32
    }

    /// Restart from this body pose at the current counts (a set-pose command).
    pub fn set_body(&mut self, body: crate::exact::FixedPose, abs_code: u16) {
        // The body's reference point is the pivot; the carriage heads φ = θ + β.
        self.pivot.set_pose(crate::exact::FixedPose {
            theta: body.theta.wrapping_add(self.swivel(abs_code)),
            ..body
        });
        self.body = body;
    }

    /// One update with the cumulative counts and the absolute code. Integer-only.
    pub fn update(&mut self, counts: [i64; 2], abs_code: u16) -> crate::exact::FixedPose {
        self.update_q16(&[counts[0] << 16, counts[1] << 16, 0, 0], abs_code)
    }

    /// One update with the wheels' positions in Q16 counts (interpolated between ticks in
    /// tick-timestamp mode; entries past the two measuring wheels are ignored). Integer-only.
    /// Taken by reference and handed on as it is: building a new array was 12 instructions.
    pub fn update_q16(
        &mut self,
        q16: &[i64; crate::exact::MAX_ENCODERS],
        abs_code: u16,
    ) -> crate::exact::FixedPose {
        let p = self.pivot.update_q16(q16);
        self.body = crate::exact::FixedPose {
            theta: p.theta.wrapping_sub(self.swivel(abs_code)),
            ..p
        };
        self.body
    }

    pub fn body(&self) -> crate::exact::FixedPose {
        self.body
    }
}

/// The carriage axle's constants for its pivot, `trail_q40` ahead of the axle midpoint: a
/// point of a rigid body at (trail, 0) from A moves at v_A + ω × (trail, 0), that is with
/// trail·ω more to the left. Per count: `ky += trail · kth`, in the constants' units
/// (Q40 m × 2^-48 turn × 2π rad/turn → Q44 m: trail · kth · 2π / 2^44, with 2π as
/// `PI_Q29` = 2π · 2^28, so a shift of 72 in all). Integer-only (the slave builds it from the
/// master's constants); `None` past the fixed-point range.
pub(crate) fn pivot_params(
    axle: crate::exact::ExactParams,
    trail_q40: i64,
) -> Option<crate::exact::ExactParams> {
    use crate::exact::{ExactParams, MAX_ENCODERS};
    /// round(π · 2^29) = round(2π · 2^28).
    const TWO_PI_Q28: i128 = 1_686_629_713;
    // `CarriageExact::new` and `from_params` are public: the bound `Layout` checks is checked
    // here too, so the products below cannot overflow whoever calls.
    if trail_q40.unsigned_abs() >= crate::odometry::MAX_TRAIL_Q40 as u64 {
        return None;
    }
    let (kx, mut ky, kth) = (axle.kx(), axle.ky(), axle.kth());
    for j in 0..MAX_ENCODERS {
        // |trail| < 2^47 (above), |kth| < 2^46 (`ExactParams`): below 2^124, no overflow.
        let side = (trail_q40 as i128 * kth[j] as i128 * TWO_PI_Q28 + (1 << 71)) >> 72;
        ky[j] = ky[j].checked_add(i64::try_from(side).ok()?)?;
    }
    ExactParams::from_raw(axle.encoders(), kx, ky, kth).ok()
}

#[cfg(test)]
mod exact_tests {
    use super::*;

    const G: CarriageGeometry = CarriageGeometry::SEED_004;

    #[test]
    fn fixed_point_carriage_matches_the_float_one() {
        // The same counts and codes through both: they integrate the same model, so they agree
        // to far below a count (the float one is the reference here).
        let start = Pose2::new(0.3, -0.2, 0.1);
        let mut float = CarriageOdometry::new(G, start, [0, 0], 64);
        let mut fixed = CarriageExact::new(&G, start, [0, 0], 64).unwrap();
        let (mut c0, mut c1) = (0i64, 0i64);
        for k in 0..20_000i64 {
            c0 += 1 + (k % 7 == 0) as i64 - (k % 11 == 0) as i64;
            c1 += 1 + (k % 5 == 0) as i64;
            let code = (64 + (k / 300) % 40) as u16;
            let a = float.update([c0, c1], code);
            let b = fixed.update([c0, c1], code).to_pose2();
            if k % 1000 == 0 || k == 19_999 {
                assert!(a.distance_to(b) < 2e-8, "step {k}: {a:?} vs {b:?}");
                assert!(
                    crate::se2::wrap_angle(a.theta - b.theta).abs() < 1e-7,
                    "step {k}"
                );
            }
        }
    }

    #[test]
    fn set_body_round_trips() {
        let mut fixed = CarriageExact::new(&G, Pose2::default(), [5, 7], 10).unwrap();
        let p = Pose2::new(1.5, 2.5, -0.7);
        fixed.set_body(crate::exact::FixedPose::from_pose2(p), 10);
        let b = fixed.update([5, 7], 10).to_pose2();
        assert!(
            b.distance_to(p) < 1e-8 && (b.theta - p.theta).abs() < 1e-8,
            "{b:?}"
        );
    }
}
