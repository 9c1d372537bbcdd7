//! The one function that turns a robot file's drive into what the master is sent
//! (`HostToMaster::SetDrive`): [`Robot::drive_geometry`].

use anyhow::{bail, Result};
use firmware_master::drive_setup::{DriveSetup, SEED_004_DRIVE};
use protocol::metres_to_um as um;
use protocol::serial::{DriveGeometry, DriveKind};
use robot_math::omni3::Omni3;

use super::robot::Robot;

impl Robot {
    /// The master's drive for this robot: seed 003's three omni wheels (any d), or a
    /// differential axle through the reference point with a `[tracked_point]` ahead of it
    /// (seed 002). Every wheel's `v_max_m_s` must be the same; full duty gives the `[motor]`'s
    /// steady speed, and its shaft encoders feed the speed loops. The gains are the power-on
    /// defaults (a scenario may change the tracking gains).
    pub fn drive_geometry(&self) -> Result<DriveGeometry> {
        let name = &self.name;
        let wheels = &self.drive_wheels;
        let Some(first) = wheels.first() else {
            bail!("robot {name} has no [[drive_wheels]]: the master has nothing to drive");
        };
        let v_max = first.v_max_m_s;
        if wheels.iter().any(|w| (w.v_max_m_s - v_max).abs() > 1e-9) {
            bail!("robot {name}: the master takes one v_max_m_s for every drive wheel");
        }
        let kind = match wheels.len() {
            3 => {
                let d = first.wheel.x.hypot(first.wheel.y);
                let seed_003 = Omni3::wheels(d);
                let same = wheels.iter().zip(seed_003.iter()).all(|(w, s)| {
                    let w = w.wheel;
                    [w.x - s.x, w.y - s.y, w.ux - s.ux, w.uy - s.uy]
                        .iter()
                        .all(|e| e.abs() < 1e-6)
                });
                if !same {
                    bail!(
                        "robot {name}: three drive wheels must be the layout of Yan 2013 (at 0, 120 and \
                         240 degrees round the reference point, rolling counter-clockwise)"
                    );
                }
                if self.tracked_point_x_m.is_some() {
                    bail!("robot {name}: an omni robot tracks its reference point; drop [tracked_point]");
                }
                DriveKind::Omni3 { d_um: um(d) as u32 }
            }
            2 => {
                let on_axle = wheels
                    .iter()
                    .all(|w| w.wheel.x.abs() < 1e-9 && (w.wheel.ux - 1.0).abs() < 1e-9);
                if !on_axle {
                    bail!(
                        "robot {name}: two drive wheels must sit on the axle through the reference \
                         point (x_m = 0), both rolling along +x (direction_deg = 0)"
                    );
                }
                let Some(offset) = self.tracked_point_x_m else {
                    bail!(
                        "robot {name}: a differential drive needs [tracked_point] x_m != 0 (seed \
                         002's point A; a point on the axle cannot move sideways)"
                    );
                };
                let (left, right) = (wheels[0].wheel.y, wheels[1].wheel.y);
                if left <= right {
                    bail!(
                        "robot {name}: list the left drive wheel (larger y_m) first: motor 1 is \
                         the left, motor 2 the right"
                    );
                }
                DriveKind::OffsetDiff {
                    y_left_um: um(left),
                    y_right_um: um(right),
                    offset_um: um(offset),
                }
            }
            n => bail!("robot {name}: the master drives 3 omni wheels or 2 on an axle, not {n}"),
        };
        let Some(motor) = self.motor else {
            bail!(
                "robot {name} has no [motor]: the master's feed-forward and the emulator's \
                 plant need its drive motors"
            );
        };
        let full = motor.model.steady_speed(1.0);
        if full < v_max {
            bail!(
                "robot {name}: its motors reach {full:.3} m/s at full duty, under v_max_m_s \
                 {v_max} (the speed loops could never hold it)"
            );
        }
        let g = DriveGeometry {
            kind,
            v_max_um_s: um(v_max) as u32,
            speed_at_full_duty_um_s: um(full) as u32,
            motor_nm_per_count: motor
                .metres_per_count()
                .map_or(0, |m| (m * 1e9).round() as u32),
            ..SEED_004_DRIVE
        };
        if DriveSetup::from_geometry(&g).is_none() {
            bail!("robot {name}: the master cannot drive this geometry");
        }
        Ok(g)
    }
}
