//! A robot file as a run uses it: its drive for the master, its sensors for the slave, its
//! motors; the robot the boards are told of (`--robot`) and the robot as it really is
//! (`--true-robot`), which must be the same kind.

use std::path::Path;

use anyhow::{anyhow, Context as _, Result};
use robot_math::motor::DcMotor;

use super::robot::Robot;
use crate::sim::emulator::{RobotModel, Scenario, POWER_ON_ROBOT};

/// A robot file as a run uses it: its drive for the master, its measuring sensors for the
/// slave, its motors.
pub fn robot_model(robot: Robot) -> Result<RobotModel> {
    let drive = robot.drive_geometry()?;
    let layout = robot.odometry_layout()?;
    // drive_geometry() has checked the motor is there.
    let motor = robot.motor.map(|m| m.model).unwrap_or(DcMotor::SEED_004);
    Ok(RobotModel {
        name: robot.name,
        drive,
        layout,
        motor,
    })
}

/// The boards' power-on robot, seed 004's.
pub fn power_on_robot() -> RobotModel {
    RobotModel {
        name: POWER_ON_ROBOT.to_string(),
        drive: firmware_master::drive_setup::SEED_004_DRIVE,
        layout: robot_math::odometry::Layout::SEED_004,
        motor: DcMotor::SEED_004,
    }
}

/// A robot as it really is must be the kind of robot the boards are told it is: the same
/// drive, the same number of encoders, a carriage on both or on neither. Its numbers may
/// differ as much as they like.
pub(super) fn same_kind(told: &RobotModel, truly: &RobotModel) -> Result<()> {
    use protocol::serial::DriveKind;
    let drive = |d: &DriveKind| match d {
        DriveKind::Omni3 { .. } => "three omni wheels",
        DriveKind::OffsetDiff { .. } => "a differential drive",
    };
    let (a, b) = (drive(&told.drive.kind), drive(&truly.drive.kind));
    if a != b {
        return Err(anyhow!("it has {b}, the robot the boards are told of {a}"));
    }
    let encoders = |l: &robot_math::odometry::Layout| l.encoders();
    if encoders(&told.layout) != encoders(&truly.layout) {
        return Err(anyhow!(
            "it has {} measuring encoders, the robot the boards are told of {}",
            encoders(&truly.layout),
            encoders(&told.layout)
        ));
    }
    let carriage = |l: &robot_math::odometry::Layout| l.carriage_geometry().is_some();
    if carriage(&told.layout) != carriage(&truly.layout) {
        let has = |c: bool| {
            if c {
                "a swivel carriage"
            } else {
                "no carriage"
            }
        };
        return Err(anyhow!(
            "it has {}, the robot the boards are told of {}",
            has(carriage(&truly.layout)),
            has(carriage(&told.layout))
        ));
    }
    Ok(())
}

impl Scenario {
    /// Give the boards the robot in `path` instead of the scenario's (its encoders to the
    /// slave, its drive to the master, with the scenario's controller gains).
    pub fn set_robot(&mut self, path: &Path) -> Result<()> {
        let what = || format!("--robot {}", path.display());
        let robot = Robot::load(path).map_err(|e| anyhow!("{}: {e}", what()))?;
        let mut told = robot_model(robot).with_context(what)?;
        let gains = self.drive;
        let d = &mut told.drive;
        d.k_forward_milli = gains.k_forward_milli;
        d.k_lateral_milli = gains.k_lateral_milli;
        d.ff_forward_milli = gains.ff_forward_milli;
        d.ff_lateral_milli = gains.ff_lateral_milli;
        d.diff_forward_milli = gains.diff_forward_milli;
        d.diff_lateral_milli = gains.diff_lateral_milli;
        d.speed_kp_micro = gains.speed_kp_micro;
        d.speed_ki_micro = gains.speed_ki_micro;
        d.speed_kd_micro = gains.speed_kd_micro;
        if firmware_master::drive_setup::DriveSetup::from_geometry(d).is_none() {
            return Err(anyhow!(
                "{}: the master cannot drive this robot (its drive geometry is impossible)",
                what()
            ));
        }
        if let Some(truly) = &self.true_robot {
            same_kind(&told, truly).with_context(|| format!("the true robot {}", truly.name))?;
        }
        self.robot = told.name;
        self.drive = told.drive;
        self.layout = told.layout;
        self.motor = told.motor;
        self.source_files
            .push(("the --robot file", path.to_path_buf()));
        Ok(())
    }

    /// Make the simulated robot the one in `path` (its wheels, encoders, carriage and motors),
    /// while the boards are still told of the scenario's.
    pub fn set_true_robot(&mut self, path: &Path) -> Result<()> {
        let what = || format!("--true-robot {}", path.display());
        let robot = Robot::load(path).map_err(|e| anyhow!("{}: {e}", what()))?;
        let truly = robot_model(robot).with_context(what)?;
        let told = RobotModel {
            name: self.robot.clone(),
            drive: self.drive,
            layout: self.layout,
            motor: self.motor,
        };
        same_kind(&told, &truly).with_context(what)?;
        self.true_robot = Some(truly);
        self.source_files
            .push(("the --true-robot file", path.to_path_buf()));
        Ok(())
    }
}
