//! A run to emulate: the robot, where it starts, and what the host asks of it.

use protocol::serial::DriveGeometry;
use robot_math::motor::DcMotor;
use robot_math::odometry::Layout;
use serde::Serialize;

use super::Faults;

/// A run to emulate: the robot, where it starts and what the host asks of it. Built in
/// ([`Scenario::seed004_pursuit`]) or read from a scenario file (`formats::scenario`).
#[derive(Clone, Debug, Serialize)]
pub struct Scenario {
    pub name: String,
    pub description: String,
    /// The robot's name.
    pub robot: String,
    /// Its drive, sent to the master (`SetDrive`) at the start of the session.
    #[serde(skip)]
    pub drive: DriveGeometry,
    /// Its drive motors (the plant's; the master knows only what `drive` says of them).
    #[serde(skip)]
    pub motor: DcMotor,
    /// Its measuring sensors, which the emulated slave is built with.
    #[serde(skip)]
    pub layout: Layout,
    /// Initial body pose (x m, y m, θ rad); the host sends it as set-pose.
    pub start: (f64, f64, f64),
    /// Initial carriage swivel, radians (carriage heading minus body heading).
    pub start_swivel: f64,
    pub motion: Motion,
    /// How long to run by default, seconds.
    pub duration: f64,
    /// Seed 004's Euler pursuit period (None: the master's own, continuous pursuit).
    pub pursuit_period_s: Option<f64>,
    /// Where each measuring-wheel encoder stands within its count at power-on (None: drawn
    /// from the run's seed).
    pub encoder_phase: Option<[f64; 2]>,
    /// The files it was read from (the scenario file, the robot file it names): what a run's
    /// outputs must not write over. Empty for a built-in.
    #[serde(skip)]
    pub source_files: Vec<(&'static str, std::path::PathBuf)>,
    /// Where the measuring encoders put their edges (ideal, or a datasheet's errors).
    #[serde(skip)]
    pub encoder_edges: crate::sim::generate::EdgeErrors,
    pub faults: Faults,
    /// The robot as it really is, when it is not as the boards are told (`--true-robot`,
    /// the scenario's `true_robot`): the simulated wheels, encoders and carriage follow it,
    /// while the slave gets `layout` and the master `drive`. None: as the boards are told.
    #[serde(skip)]
    pub true_robot: Option<RobotModel>,
}

/// A robot file as a run uses it.
#[derive(Clone, Debug)]
pub struct RobotModel {
    pub name: String,
    /// Its drive (the master's, with the robot file's own controller gains).
    pub drive: DriveGeometry,
    /// Its measuring sensors (the slave's).
    pub layout: Layout,
    /// Its drive motors.
    pub motor: DcMotor,
}

/// What the host asks of the robot.
#[derive(Clone, Debug, Serialize)]
pub enum Motion {
    /// Seed 004: a target moving from `target_from` to `target_to` at `target_speed`, pursued
    /// at `robot_speed` holding `heading` (radians).
    Pursue {
        target_from: (f64, f64),
        target_to: (f64, f64),
        target_speed: f64,
        robot_speed: f64,
        heading: f64,
    },
    /// Seed 002: the tracked point follows a catalogue trajectory, streamed to the master one
    /// sample (position, velocity, heading) every `sample_period_s`.
    Track {
        trajectory: String,
        sample_period_s: f64,
        /// How far ahead of the body's reference point the tracked point is, when the
        /// trajectory is the body's (UMBmark's squares, whose corners are turns in place):
        /// the master is sent that point's path. 0: the trajectory is the tracked point's own.
        ahead_m: f64,
    },
}

/// What a scenario without a robot file runs: the boards' compiled-in robot.
pub const POWER_ON_ROBOT: &str = "seed004 (power-on)";

impl Scenario {
    /// Seed 004's pursuit: the target moves from (0, 300) cm along +x at 35 cm/s to
    /// (250, 300) cm; the robot starts at the origin and pursues at 60 cm/s.
    pub fn seed004_pursuit() -> Self {
        Scenario {
            name: "seed004-pursuit".into(),
            description: "Xu, Zhu and Hu (2015): target (0,3) m -> (2.5,3) m at 0.35 m/s, robot at 0.6 m/s from the origin".into(),
            robot: POWER_ON_ROBOT.into(),
            drive: firmware_master::drive_setup::SEED_004_DRIVE,
            motor: DcMotor::SEED_004,
            layout: Layout::SEED_004,
            start: (0.0, 0.0, 0.0),
            // The carriage trails the first direction of travel (+y), with the swivel at the
            // centre of an absolute-encoder code (see docs/design.md, "The simulated robot, and
            // what we assumed").
            start_swivel: std::f64::consts::FRAC_PI_2,
            motion: Motion::Pursue {
                target_from: (0.0, 3.0),
                target_to: (2.5, 3.0),
                target_speed: 0.35,
                robot_speed: 0.60,
                heading: 0.0,
            },
            duration: 12.0,
            pursuit_period_s: None,
            encoder_phase: None,
            encoder_edges: crate::sim::generate::EdgeErrors::IDEAL,
            faults: Faults::default(),
            source_files: Vec::new(),
            true_robot: None,
        }
    }

    pub fn builtin(name: &str) -> Option<Self> {
        match name {
            "seed004-pursuit" => Some(Self::seed004_pursuit()),
            _ => None,
        }
    }

    pub const BUILTIN_NAMES: &'static [&'static str] = &["seed004-pursuit"];
}
