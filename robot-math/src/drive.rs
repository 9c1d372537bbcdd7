//! The driven wheels the master commands, whichever platform it is: seed 003's three omni
//! wheels or seed 002's differential chassis with an offset tracked point. Motor order is the
//! robot file's `[[drive_wheels]]` order; a platform with fewer than three motors leaves the
//! rest at zero.

use crate::offset_diff::OffsetDiff;
use crate::omni3::Omni3;
use crate::Twist;

/// 2/√3: an omni triangle's top translation speed over v_max (seed 003).
const TWO_BY_SQRT_3: f64 = 1.154_700_538_379_251_5;

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum DriveKinematics {
    Omni3(Omni3),
    OffsetDiff(OffsetDiff),
}

impl DriveKinematics {
    /// Highest wheel speed, m/s.
    pub fn v_max(&self) -> f64 {
        match self {
            DriveKinematics::Omni3(o) => o.v_max,
            DriveKinematics::OffsetDiff(d) => d.v_max,
        }
    }

    /// Where the tracked point is in the body frame: A for seed 002's chassis, the reference
    /// point itself for an omni robot (which is holonomic everywhere).
    pub fn tracked_point(&self) -> (f64, f64) {
        match self {
            DriveKinematics::Omni3(_) => (0.0, 0.0),
            DriveKinematics::OffsetDiff(d) => (d.offset, 0.0),
        }
    }

    /// Whether the platform chooses its heading (omni), or the heading follows from the
    /// tracked point's motion (seed 002's chassis: its top plate turns on its own motor).
    pub fn holds_heading(&self) -> bool {
        matches!(self, DriveKinematics::Omni3(_))
    }

    /// Fastest the tracked point can move in its best direction, m/s: a request above it can
    /// never be met.
    pub fn max_speed(&self) -> f64 {
        match self {
            DriveKinematics::Omni3(o) => o.v_max * TWO_BY_SQRT_3,
            DriveKinematics::OffsetDiff(d) => d.v_max,
        }
    }

    /// The tracked point's body-frame velocity (forward, left) under a twist of the reference
    /// point.
    pub fn point_velocity(&self, t: Twist) -> (f64, f64) {
        let (px, py) = self.tracked_point();
        (t.vx - t.omega * py, t.vy + t.omega * px)
    }

    /// Motor speeds for a body-frame velocity (forward, left) of the tracked point and, where
    /// the platform can choose it, a spin `omega`, scaled as a whole to keep every wheel within
    /// `v_max`. Returns the speeds and the twist of the reference point they produce.
    pub fn command(&self, forward: f64, left: f64, omega: f64) -> ([f64; 3], Twist) {
        match self {
            DriveKinematics::Omni3(o) => {
                let (w, _) = o.wheel_speeds_saturated(Twist::new(forward, left, omega));
                (w, o.twist(w))
            }
            DriveKinematics::OffsetDiff(d) => {
                let ([l, r], _) = d.wheel_speeds_saturated(forward, left);
                ([l, r, 0.0], d.twist([l, r]))
            }
        }
    }

    /// The twist of the reference point that motor speeds produce (the plant's physics).
    pub fn twist(&self, wheels: [f64; 3]) -> Twist {
        match self {
            DriveKinematics::Omni3(o) => o.twist(wheels),
            DriveKinematics::OffsetDiff(d) => d.twist([wheels[0], wheels[1]]),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_differential_command_leaves_motor_3_off() {
        let d = DriveKinematics::OffsetDiff(OffsetDiff::symmetric(0.15, 0.2, 1.0).unwrap());
        let (w, t) = d.command(0.2, 0.1, 5.0);
        assert_eq!(w[2], 0.0);
        assert!(
            (t.omega - 0.5).abs() < 1e-12,
            "spin follows from A's sideways speed"
        );
        assert_eq!(d.twist(w), t);
    }
}
