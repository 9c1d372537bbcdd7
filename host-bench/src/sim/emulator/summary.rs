//! What an emulation run reports: its summary, and the rows of its log.

use serde::Serialize;

use super::fault_check::FaultCheck;
use super::hw;

/// One row of the run log.
#[derive(Clone, Debug, Serialize)]
pub struct LogRow {
    pub t_s: f64,
    pub true_x_m: f64,
    pub true_y_m: f64,
    pub true_theta_rad: f64,
    pub slave_x_m: f64,
    pub slave_y_m: f64,
    pub slave_theta_rad: f64,
    pub master_x_m: Option<f64>,
    pub master_y_m: Option<f64>,
    pub master_theta_rad: Option<f64>,
    pub target_x_m: Option<f64>,
    pub target_y_m: Option<f64>,
    pub wheel_cmd_1_m_s: f64,
    pub wheel_cmd_2_m_s: f64,
    pub wheel_cmd_3_m_s: f64,
    pub duty_1_permille: i16,
    pub duty_2_permille: i16,
    pub duty_3_permille: i16,
    pub status: u16,
    /// The measuring encoders' counts (x4) since power-on: for the view (`--mcap`, `--live`),
    /// not the CSV.
    #[serde(skip)]
    pub encoder_counts: [i64; 2],
    /// The master's link counters (SPI and serial frames taken and refused): for the view.
    #[serde(skip)]
    pub link: protocol::serial::LinkCounters,
}

/// What `emulate` reports.
#[derive(Clone, Debug, Serialize)]
pub struct Summary {
    pub scenario: String,
    pub robot: String,
    /// The fingerprint of the encoders the slave was told of (`robot_wire::layout_fingerprint`):
    /// which robot its odometry ran on.
    pub robot_fingerprint: u32,
    /// The simulated robot's name when it is not the one the boards are told of
    /// (`--true-robot`).
    pub true_robot: Option<String>,
    /// The slave's odometry algorithm (as the slave reports it).
    pub algorithm: String,
    pub seed: u64,
    /// Where each measuring-wheel encoder stood within its count at power-on, in counts
    /// ([`Options::encoder_phase`], or drawn from the seed). The slave takes each wheel to
    /// start on an edge and cannot tell otherwise, so the difference tilts its carriage
    /// heading by (p1 − p0)·(travel per count)/(wheel base) for the whole run: on
    /// seed004-pursuit that tilt is nearly all of the final error (docs/odometry.md).
    pub encoder_phase: [f64; 2],
    /// Where the measuring encoders put their edges (`ideal`, or a datasheet column).
    pub encoder_edges: String,
    pub sim_seconds: f64,
    /// Wall-clock seconds the run took (the run alone: no start-up, no output).
    pub wall_seconds: f64,
    /// Simulated seconds per wall-clock second: `sim_seconds / wall_seconds`.
    pub speed_x: f64,
    pub path_length_m: f64,
    /// Slave odometry vs ground truth at the end of the run, metres.
    pub final_error_m: f64,
    /// Largest slave odometry error over the run, metres (checked at every slave update from
    /// the start of the motion, when the host's set-pose has been applied).
    pub max_error_m: f64,
    pub final_heading_error_rad: f64,
    /// Where the slave's odometry says the robot ended, metres.
    pub final_estimate_m: (f64, f64),
    /// The slave's heading at the end, radians.
    pub final_estimate_heading_rad: f64,
    /// Where the robot really ended, and how far its tracked point is from the goal.
    pub final_position_m: (f64, f64),
    /// Its true heading at the end, radians.
    pub final_heading_rad: f64,
    /// Where it started (x m, y m, heading rad): the pose the host set the slave's odometry
    /// to.
    pub start_pose: (f64, f64, f64),
    /// Each measuring encoder's count change over the run: what the slave read. With the
    /// start and end poses, what `calibrate` takes from a run.
    pub measuring_counts: [i64; 2],
    pub distance_to_goal_m: f64,
    /// Seed 002's tracking error: the true tracked point against the reference path at the
    /// same instant, at every physics step (≤ 0.1 ms) from a second after the path started to
    /// the end of the run: RMS over time, max, and the steps scored (`None` for a pursuit,
    /// which has no path to track).
    pub tracking_rms_m: Option<f64>,
    pub tracking_max_m: Option<f64>,
    pub tracking_samples: u64,
    /// Seconds of the run the tracking error covers.
    pub tracking_seconds: f64,
    pub arrived: bool,
    /// Times the motors went from standing to driven over the whole run, and after the master
    /// first reported arrival once the target or path had stopped for good (`None` if it
    /// never did): a controller that holds still at the goal switches them on no more.
    pub motor_switch_ons: u64,
    pub motor_switch_ons_after_arrival: Option<u64>,
    /// Seconds the motors were driven (some duty non-zero) after the master first reported
    /// arrival: the settling, and nothing while it holds.
    pub motor_driven_s_after_arrival: Option<f64>,
    /// SPI transactions the master ran, and frames either side dropped (CRC, decode, idle).
    pub spi_frames: u64,
    pub spi_frames_rejected: u64,
    /// The same, by who dropped them: the master (slave frames) and the slave (master frames).
    pub spi_rejected_by_master: u64,
    pub spi_rejected_by_slave: u64,
    /// What the SPI fault knobs did (all zero in a clean run).
    pub spi_injected: hw::SpiInjected,
    /// The frames each board refused, by why, as the wire saw them decoded (they add up to
    /// `spi_rejected_by_master` and `spi_rejected_by_slave`).
    pub spi_rejected_kinds_master: hw::SpiRejections,
    pub spi_rejected_kinds_slave: hw::SpiRejections,
    /// What the serial fault knobs did to the frames each way (all zero on a quiet line).
    pub serial_injected_to_master: crate::sim::serial_noise::SerialInjected,
    pub serial_injected_to_host: crate::sim::serial_noise::SerialInjected,
    /// The serial frames each end refused, by why, as a copy of its decoder at the end of the
    /// line saw them (they add up to what the master and the host counted themselves).
    pub serial_rejected_kinds_master: crate::sim::serial_noise::SerialRejections,
    pub serial_rejected_kinds_host: crate::sim::serial_noise::SerialRejections,
    /// On a noisy line, how often the host sent the drive geometry before the master's frame
    /// counters showed it taken (null on a quiet line: sent once).
    pub serial_drive_sends: Option<u32>,
    /// The slave's pose in the newest frame the master took, and whether it is the slave's own
    /// at the end, to the micrometre and binary angle: however many frames were lost on the way,
    /// the odometry's cumulative counts lose nothing.
    pub master_view_of_slave_m: Option<(f64, f64)>,
    /// Checked once the robot stands at its goal (`None` before).
    pub master_view_matches_slave: Option<bool>,
    /// Serial frames both ways, and frames either side dropped.
    pub serial_frames: u64,
    pub serial_frames_rejected: u64,
    pub protocol_version: u16,
    pub schema_fingerprint_match: bool,
    /// This run's robot (its encoders' fingerprint, `robot_wire::layout_fingerprint`) when
    /// the host uploaded it to the slave over the protocol and the slave reported running it;
    /// null when the slave powered on with this run's robot.
    pub robot_uploaded: Option<u32>,
    pub slave_updates: u64,
    /// Firmware task polls: a machine-independent measure of the work emulated.
    pub firmware_polls: u64,
    /// When the master's status first showed SLAVE_RESET (it tells a restarted slave by its
    /// clock starting again), seconds of simulated time: null unless the slave was reset.
    pub slave_reset_told_s: Option<f64>,
    /// What followed a slave reset (`--fault-slave-reset-at`), if there was one.
    pub slave_reset: Option<SlaveResetSeen>,
    /// With link faults: this run against the clean one ([`fault_check`]; null without).
    pub fault_check: Option<FaultCheck>,
}

/// A slave reset and what the boards made of it, in seconds of simulated time. After the
/// reset the slave's pose starts again from its power-on pose, so `max_error_m` is scored up
/// to the reset only, and `final_error_m` is that of the restarted slave.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct SlaveResetSeen {
    pub at_s: f64,
    /// When the host first read it in the master's telemetry.
    pub host_told_s: Option<f64>,
    /// When, after the reset, the motors first stood (every duty 0).
    pub motors_stopped_s: Option<f64>,
}

/// Why a run scored nothing, if it did: the robot never moved, so the odometry's error is
/// measured over no path at all (a slave off from the start, a link that lost every frame, a
/// goal where the robot already stands). Such a run fails rather than report a perfect 0.
pub fn nothing_scored(s: &Summary) -> Option<String> {
    (s.path_length_m < 1e-6).then(|| {
        format!(
            "nothing scored: the robot did not move in {} s (path {:.3} mm){}",
            s.sim_seconds,
            s.path_length_m * 1e3,
            if s.spi_frames > 0 && s.spi_frames_rejected == s.spi_frames {
                "; the master took no frame from the slave"
            } else {
                ""
            }
        )
    })
}
