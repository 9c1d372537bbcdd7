//! The driven wheels the master commands, whichever platform it is: seed 003's three omni
//! wheels or seed 002's differential chassis with an offset tracked point. Motor order is the
//! robot file's `[[drive_wheels]]` order; a platform with fewer than three motors leaves the
//! rest at zero.

use crate::offset_diff::OffsetDiff;
use crate::omni3::Omni3;
use crate::Twist;

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

    /// Fastest the tracked point can move in its slowest direction, m/s: the speed a request
    /// may ask for and always get.
    pub fn safe_speed(&self) -> f64 {
        match self {
            // Seed 003: 2·v_max/√3 in the six best directions, v_max along a wheel's rolling
            // direction (the worst).
            DriveKinematics::Omni3(o) => o.v_max,
            // Straight ahead every wheel turns at the point's speed; sideways, a wheel at y
            // turns at |y|/|l| times it.
            DriveKinematics::OffsetDiff(d) => {
                let arm = libm::fabs(d.y_left).max(libm::fabs(d.y_right)) / libm::fabs(d.offset);
                d.v_max / libm::sqrt(1.0 + arm * arm) / (1.0 + 1e-9)
            }
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
            DriveKinematics::Omni3(o) => 2.0 * o.v_max / libm::sqrt(3.0),
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

    /// Motors this platform drives.
    pub fn motors(&self) -> usize {
        match self {
            DriveKinematics::Omni3(_) => 3,
            DriveKinematics::OffsetDiff(_) => 2,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn safe_speed_is_reachable_in_every_direction() {
        let drives = [
            DriveKinematics::Omni3(Omni3::new(0.22, 1.0).unwrap()),
            DriveKinematics::OffsetDiff(OffsetDiff::new(0.24, -0.18, 0.1, 0.8).unwrap()),
        ];
        for d in drives {
            let v = d.safe_speed();
            let mut tightest = f64::INFINITY;
            for k in 0..3600 {
                let a = k as f64 * core::f64::consts::TAU / 3600.0;
                let (w, _) = d.command(v * libm::cos(a), v * libm::sin(a), 0.0);
                let peak = w.iter().fold(0.0f64, |m, x| m.max(x.abs()));
                assert!(peak <= d.v_max() * (1.0 + 1e-9), "{d:?} at {a}: {peak}");
                tightest = tightest.min(d.v_max() - peak);
            }
            assert!(tightest < 1e-3 * d.v_max(), "{d:?}: not the tightest bound");
        }
    }

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
