//! Seed 002's platform: a differential-drive chassis whose tracked point A sits a distance `l`
//! ahead of the axle. Every point off the axle line is holonomic (seed 002, eq. 7): A can be
//! given any velocity, at the price of the chassis turning to suit it.
//!
//! Both drive wheels roll along body +x on the axle line x = 0, the left at `y_left`, the right
//! at `y_right < y_left`; the body's reference point (the pose odometry reports) is on that
//! line too. A is at (`offset`, 0) in the body frame.
//!
//! In our frame (x forward, y left, heading counter-clockwise from field +x) A's body-frame
//! velocity is (V_O, l·ω): seed 002's eq. (3) and (4), whose frame has y forward and x to the
//! right and whose heading α is measured from the field's y axis (θ = π/2 − α). Its J⁻¹ (eq.
//! 10) is [`OffsetDiff::wheel_speeds`] composed with the field-to-body rotation; the unit test
//! `matches_seed_002s_j_inverse` checks them against each other.

use crate::Twist;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OffsetDiff {
    /// Lateral positions of the left and right wheels, metres (left > right).
    pub y_left: f64,
    pub y_right: f64,
    /// Distance of the tracked point A ahead of the axle (negative: behind), metres; non-zero.
    pub offset: f64,
    /// Highest wheel rolling speed, m/s.
    pub v_max: f64,
}

impl OffsetDiff {
    /// `None` unless the wheels are apart (left of right), A is off the axle and the numbers
    /// are finite with `v_max > 0`.
    pub fn new(y_left: f64, y_right: f64, offset: f64, v_max: f64) -> Option<Self> {
        let finite = [y_left, y_right, offset, v_max]
            .iter()
            .all(|v| v.is_finite());
        if !(finite && y_left > y_right && offset != 0.0 && v_max > 0.0) {
            return None;
        }
        Some(OffsetDiff {
            y_left,
            y_right,
            offset,
            v_max,
        })
    }

    /// Seed 002's symmetric chassis: wheels at ±`half_track` (the paper's b).
    pub fn symmetric(half_track: f64, offset: f64, v_max: f64) -> Option<Self> {
        Self::new(half_track, -half_track, offset, v_max)
    }

    /// Wheel speeds [left, right] that give A the body-frame velocity (forward, left):
    /// V_O = forward, ω = left / l, and each wheel rolls at V_O − ω·y_wheel.
    pub fn wheel_speeds(&self, forward: f64, left: f64) -> [f64; 2] {
        let omega = left / self.offset;
        [
            forward - omega * self.y_left,
            forward - omega * self.y_right,
        ]
    }

    /// [`wheel_speeds`](Self::wheel_speeds), scaled down as a whole when a wheel would pass
    /// `v_max` (A keeps its direction). Returns the speeds and the scale (1: none).
    pub fn wheel_speeds_saturated(&self, forward: f64, left: f64) -> ([f64; 2], f64) {
        let w = self.wheel_speeds(forward, left);
        let peak = libm::fabs(w[0]).max(libm::fabs(w[1]));
        if peak <= self.v_max {
            return (w, 1.0);
        }
        let k = self.v_max / peak;
        (w.map(|v| v * k), k)
    }

    /// Forward kinematics: the twist of the reference point (v, 0, ω) from the wheel speeds.
    pub fn twist(&self, wheels: [f64; 2]) -> Twist {
        let [l, r] = wheels;
        let omega = (r - l) / (self.y_left - self.y_right);
        Twist::new(l + omega * self.y_left, 0.0, omega)
    }

    /// A's body-frame velocity (forward, left) from the wheel speeds.
    pub fn point_velocity(&self, wheels: [f64; 2]) -> (f64, f64) {
        let t = self.twist(wheels);
        (t.vx, t.omega * self.offset)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::f64::consts::FRAC_PI_2;

    #[test]
    fn refuses_impossible_geometry() {
        assert!(
            OffsetDiff::symmetric(0.15, 0.0, 1.0).is_none(),
            "A on the axle"
        );
        assert!(
            OffsetDiff::new(-0.1, 0.1, 0.2, 1.0).is_none(),
            "left right of right"
        );
        assert!(OffsetDiff::symmetric(0.15, 0.2, 0.0).is_none());
        assert!(OffsetDiff::symmetric(f64::NAN, 0.2, 1.0).is_none());
        assert!(
            OffsetDiff::symmetric(0.15, -0.2, 1.0).is_some(),
            "A behind the axle"
        );
    }

    #[test]
    fn forward_undoes_inverse_for_any_velocity_of_a() {
        let d = OffsetDiff::new(0.24, -0.18, 0.12, 1.0).unwrap();
        for &(f, l) in &[(0.3, 0.0), (0.0, 0.3), (-0.2, 0.1), (0.05, -0.4)] {
            let (f2, l2) = d.point_velocity(d.wheel_speeds(f, l));
            assert!(
                (f - f2).abs() < 1e-12 && (l - l2).abs() < 1e-12,
                "{f},{l} -> {f2},{l2}"
            );
        }
    }

    #[test]
    fn a_moves_sideways_by_turning_the_chassis() {
        let d = OffsetDiff::symmetric(0.15, 0.2, 1.0).unwrap();
        let w = d.wheel_speeds(0.0, 0.1);
        // Pure sideways at A: the chassis turns on the spot about O at 0.1 / 0.2 rad/s.
        let t = d.twist(w);
        assert!(t.vx.abs() < 1e-15 && (t.omega - 0.5).abs() < 1e-12);
        assert!((w[0] + 0.075).abs() < 1e-12 && (w[1] - 0.075).abs() < 1e-12);
    }

    /// Seed 002's eq. (10), written in its own frame, gives the same wheel speeds.
    #[test]
    fn matches_seed_002s_j_inverse() {
        let (b, l) = (0.15, 0.2);
        let d = OffsetDiff::symmetric(b, l, 1.0).unwrap();
        for &theta in &[0.0, 0.4, 2.0, -1.3] {
            let alpha = FRAC_PI_2 - theta;
            let (sa, ca) = (crate::trig::sin(alpha), crate::trig::cos(alpha));
            for &(vx, vy) in &[(0.3, 0.1), (-0.2, 0.25), (0.0, -0.3)] {
                // Seed: v1 = (sin α + b/l cos α) V_X + (cos α − b/l sin α) V_Y, v2 likewise.
                let v1 = (sa + b / l * ca) * vx + (ca - b / l * sa) * vy;
                let v2 = (sa - b / l * ca) * vx + (ca + b / l * sa) * vy;
                let (s, c) = (crate::trig::sin(theta), crate::trig::cos(theta));
                let [left, right] = d.wheel_speeds(c * vx + s * vy, -s * vx + c * vy);
                assert!((v1 - left).abs() < 1e-12 && (v2 - right).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn saturation_keeps_the_direction_of_a() {
        let d = OffsetDiff::symmetric(0.15, 0.1, 0.5).unwrap();
        let (w, k) = d.wheel_speeds_saturated(0.4, 0.3);
        assert!(k < 1.0);
        assert!((w[0].abs().max(w[1].abs()) - 0.5).abs() < 1e-12);
        let (f, l) = d.point_velocity(w);
        assert!((f / l - 0.4 / 0.3).abs() < 1e-12);
    }
}
