//! Integer units shared by every message.

use postcard::experimental::max_size::MaxSize;
use postcard_schema::Schema;
use serde::{Deserialize, Serialize};

/// A heading as a binary angle: the full `u32` range is one turn, so addition wraps exactly
/// like the angle does and no normalisation is ever needed.
#[derive(Serialize, Deserialize, Schema, MaxSize, Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BinaryAngle(pub u32);

impl BinaryAngle {
    const TURN: f64 = 4_294_967_296.0;

    /// The angle in radians, in (-pi, pi].
    pub fn to_radians(self) -> f64 {
        (self.0 as i32) as f64 * (2.0 * core::f64::consts::PI / Self::TURN)
    }

    /// The binary angle nearest to `rad` (any real value; whole turns wrap away).
    pub fn from_radians(rad: f64) -> Self {
        let turns = rad / (2.0 * core::f64::consts::PI);
        let frac = turns - floor(turns);
        // `frac` is in [0, 1); rounding can give exactly 2^32, which wraps to 0 as it should.
        BinaryAngle((frac * Self::TURN + 0.5) as u64 as u32)
    }

    /// Single-precision variant for the master, where f32 is cheaper in soft float.
    pub fn to_radians_f32(self) -> f32 {
        (self.0 as i32) as f32 * (2.0 * core::f32::consts::PI / 4_294_967_296.0)
    }

    /// Single-precision variant of [`BinaryAngle::from_radians`].
    pub fn from_radians_f32(rad: f32) -> Self {
        Self::from_radians(rad as f64)
    }
}

// `f64::floor` is not in core; this is all the protocol needs of libm.
fn floor(x: f64) -> f64 {
    let t = x as i64 as f64;
    if t > x {
        t - 1.0
    } else {
        t
    }
}

/// A point in the field frame, in micrometres (about +-2 km of range).
#[derive(Serialize, Deserialize, Schema, MaxSize, Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Point {
    pub x_um: i32,
    pub y_um: i32,
}

impl Point {
    pub fn from_metres(x: f64, y: f64) -> Self {
        Point {
            x_um: metres_to_um(x),
            y_um: metres_to_um(y),
        }
    }
    pub fn to_metres(self) -> (f64, f64) {
        (self.x_um as f64 * 1e-6, self.y_um as f64 * 1e-6)
    }
}

/// A robot pose in the field frame: position of the body's reference point and heading.
#[derive(Serialize, Deserialize, Schema, MaxSize, Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Pose {
    pub x_um: i32,
    pub y_um: i32,
    pub heading: BinaryAngle,
}

impl Pose {
    pub fn from_si(x_m: f64, y_m: f64, theta_rad: f64) -> Self {
        Pose {
            x_um: metres_to_um(x_m),
            y_um: metres_to_um(y_m),
            heading: BinaryAngle::from_radians(theta_rad),
        }
    }
    /// (x m, y m, heading rad in (-pi, pi]).
    pub fn to_si(self) -> (f64, f64, f64) {
        (
            self.x_um as f64 * 1e-6,
            self.y_um as f64 * 1e-6,
            self.heading.to_radians(),
        )
    }
}

/// Metres to micrometres, rounded to nearest and saturated to the `i32` range.
pub fn metres_to_um(m: f64) -> i32 {
    let um = m * 1e6;
    let rounded = if um >= 0.0 { um + 0.5 } else { um - 0.5 };
    // `as` saturates on overflow and maps NaN to 0: no UB, no panic.
    rounded as i32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn binary_angle_round_trips_and_wraps() {
        for &rad in &[0.0, 0.5, -0.5, 3.0, -3.0, core::f64::consts::PI - 1e-9] {
            let back = BinaryAngle::from_radians(rad).to_radians();
            assert!((back - rad).abs() < 2e-9, "{rad} -> {back}");
        }
        // A whole turn more is the same angle.
        let a = BinaryAngle::from_radians(1.0);
        let b = BinaryAngle::from_radians(1.0 + 2.0 * core::f64::consts::PI);
        assert!(a.0.abs_diff(b.0) <= 1);
        assert_eq!(
            BinaryAngle::from_radians(core::f64::consts::FRAC_PI_2).0,
            1 << 30
        );
    }

    #[test]
    fn metres_round_and_saturate() {
        assert_eq!(metres_to_um(1.2345675), 1_234_568);
        assert_eq!(metres_to_um(-0.0000015), -2);
        assert_eq!(metres_to_um(1e9), i32::MAX);
        assert_eq!(metres_to_um(f64::NAN), 0);
    }
}
