//! The drive as the protocol carries it ([`DriveGeometry`], integers) turned into robot-math's
//! kinematics and gains. The compiled-in default and a host's `SetDrive` go through the same
//! door, so the emulator's plant and the master agree on what a geometry means.

use protocol::serial::{DriveGeometry, DriveKind};
use robot_math::drive::DriveKinematics;
use robot_math::offset_diff::OffsetDiff;
use robot_math::omni3::Omni3;
use robot_math::pid::PidGains;
use robot_math::tracking::TrackingGains;

/// Everything the controller needs to know about the driven platform.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DriveSetup {
    pub kinematics: DriveKinematics,
    /// Wheel speed at 100 % duty, m/s.
    pub speed_at_full_duty: f64,
    pub gains: TrackingGains,
    /// Each motor's speed loop (its feed-forward is `1 / speed_at_full_duty`).
    pub speed_pid: PidGains,
    /// Rim travel per motor-encoder count, m; `None`: no motor encoders, open loop.
    pub metres_per_motor_count: Option<f64>,
}

const UM: f64 = 1e-6;
const MILLI: f64 = 1e-3;
const MICRO: f64 = 1e-6;

impl DriveSetup {
    /// `None` for a geometry no controller can drive (see `RejectReason::InvalidDrive`).
    pub fn from_geometry(g: &DriveGeometry) -> Option<Self> {
        let v_max = g.v_max_um_s as f64 * UM;
        let kinematics = match g.kind {
            DriveKind::Omni3 { d_um } => {
                DriveKinematics::Omni3(Omni3::new(d_um as f64 * UM, v_max)?)
            }
            DriveKind::OffsetDiff {
                y_left_um,
                y_right_um,
                offset_um,
            } => DriveKinematics::OffsetDiff(OffsetDiff::new(
                y_left_um as f64 * UM,
                y_right_um as f64 * UM,
                offset_um as f64 * UM,
                v_max,
            )?),
        };
        let gains = TrackingGains {
            k_forward: g.k_forward_milli as f64 * MILLI,
            k_lateral: g.k_lateral_milli as f64 * MILLI,
            ff_forward: g.ff_forward_milli as f64 * MILLI,
            ff_lateral: g.ff_lateral_milli as f64 * MILLI,
            diff_forward: g.diff_forward_milli as f64 * MILLI,
            diff_lateral: g.diff_lateral_milli as f64 * MILLI,
        };
        let speed_at_full_duty = g.speed_at_full_duty_um_s as f64 * UM;
        if !(gains.valid() && speed_at_full_duty > 0.0) {
            return None;
        }
        let speed_pid = PidGains {
            kp: g.speed_kp_micro as f64 * MICRO,
            ki: g.speed_ki_micro as f64 * MICRO,
            kd: g.speed_kd_micro as f64 * MICRO,
            ff: 1.0 / speed_at_full_duty,
        };
        let metres_per_motor_count =
            (g.motor_nm_per_count > 0).then_some(g.motor_nm_per_count as f64 * 1e-9);
        Some(DriveSetup {
            kinematics,
            speed_at_full_duty,
            gains,
            speed_pid,
            metres_per_motor_count,
        })
    }
}

/// Seed 004's robot: seed 003's three omni wheels, d = 0.22 m, v_max 1 m/s, its motors; seed 002's
/// law with our gains (docs/motion.md, "Track a path").
pub const SEED_004_DRIVE: DriveGeometry = DriveGeometry {
    kind: DriveKind::Omni3 { d_um: 220_000 },
    v_max_um_s: 1_000_000,
    // robot_math::motor::DcMotor::SEED_004.steady_speed(1.0) (tested in host-bench).
    speed_at_full_duty_um_s: 1_174_886,
    k_forward_milli: 8_000,
    k_lateral_milli: 8_000,
    ff_forward_milli: 1_000,
    ff_lateral_milli: 1_000,
    diff_forward_milli: 200,
    diff_lateral_milli: 200,
    motor_nm_per_count: SEED_004_MOTOR_NM_PER_COUNT,
    speed_kp_micro: 1_000_000,
    speed_ki_micro: 8_000_000,
    speed_kd_micro: 0,
};

/// Seed 004's drive motors (robots/seed004.toml `[motor]`): 48 counts per motor turn (x4) ×
/// 30:1 on a 60 mm wheel, π·60 mm / 1440.
pub const SEED_004_MOTOR_NM_PER_COUNT: u32 = 130_900;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_default_drive_is_seed_003s() {
        let s = DriveSetup::from_geometry(&SEED_004_DRIVE).unwrap();
        assert_eq!(
            s.kinematics,
            DriveKinematics::Omni3(Omni3::new(0.22, 1.0).unwrap())
        );
        assert!(s.gains.valid());
    }

    #[test]
    fn impossible_drives_are_refused() {
        let on_axle = DriveGeometry {
            kind: DriveKind::OffsetDiff {
                y_left_um: 150_000,
                y_right_um: -150_000,
                offset_um: 0,
            },
            ..SEED_004_DRIVE
        };
        assert!(DriveSetup::from_geometry(&on_axle).is_none());
        let no_gain = DriveGeometry {
            k_lateral_milli: 0,
            ..SEED_004_DRIVE
        };
        assert!(DriveSetup::from_geometry(&no_gain).is_none());
        let no_speed = DriveGeometry {
            speed_at_full_duty_um_s: 0,
            ..SEED_004_DRIVE
        };
        assert!(DriveSetup::from_geometry(&no_speed).is_none());
    }
}
