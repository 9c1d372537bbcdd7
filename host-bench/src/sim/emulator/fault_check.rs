//! A run with link faults against the same run clean, and driven the same way.

use std::sync::{Arc, Mutex};

use anyhow::Result;
use serde::Serialize;

use super::{hw, run, Faults, Options, Scenario, Summary};

/// A run with link faults against the same run clean.
///
/// "Clean" means without the link faults (SPI and serial); a slave that resets or loses
/// power, or a host that falls silent, does so in the clean run too, or the two could never
/// be compared (a reset puts the slave back at its power-on pose).
///
/// In the closed loop the two cannot end at the same pose: while frames are lost the master
/// steers on older ones, so the robot itself moves a little differently. What the links must
/// not do is lose or corrupt odometry. So the faulty run is made a second time with the robot
/// driven by the clean run's duties, control step by control step, and the faults on: the
/// robot then moves exactly as in the clean run, and the slave's pose must end bit for bit
/// where the clean run's did, and the master's last view of it be the slave's own.
#[derive(Clone, Debug, Serialize)]
pub struct FaultCheck {
    /// The clean run's final slave pose (x, y m; heading rad).
    pub clean_final_estimate_m: (f64, f64),
    pub clean_final_estimate_heading_rad: f64,
    /// How far the faulty closed-loop run's final slave pose is from the clean one's, metres.
    pub closed_loop_apart_m: f64,
    /// Faults on, robot driven through the clean run's duties: its final slave pose.
    pub same_motion_final_estimate_m: (f64, f64),
    pub same_motion_final_estimate_heading_rad: f64,
    /// ... equal to the clean run's, every bit of x, y and heading.
    pub same_motion_equals_clean: bool,
    pub same_motion_master_view_matches_slave: Option<bool>,
    /// Bad frames both ways in the same-motion run (all of them counted and dropped).
    pub same_motion_spi_frames_rejected: u64,
}

/// [`FaultCheck`] for `faulty`, a closed-loop run of `scenario` with `opts` (whose faults are
/// on): runs it clean, recording the duties, then faulty again on those duties.
pub fn fault_check(scenario: &Scenario, opts: &Options, faulty: &Summary) -> Result<FaultCheck> {
    let duties = Arc::new(Mutex::new(Vec::new()));
    let clean_opts = Options {
        faults: Faults {
            spi: Default::default(),
            serial: Default::default(),
            ..opts.faults.clone()
        },
        keep_log: false,
        duties: hw::DutySource::Record(duties.clone()),
        ..opts.clone()
    };
    let clean = run(scenario, &clean_opts)?.summary;
    let script = std::mem::take(&mut *duties.lock().unwrap_or_else(|e| e.into_inner()));
    // The same motion under the same SPI faults, on a quiet serial line: the host's settings
    // must reach the slave while the robot stands, as in the clean run, and serial noise
    // that delayed them would let the replayed duties move it first.
    let same_opts = Options {
        keep_log: false,
        duties: hw::DutySource::Replay(Arc::new(script)),
        faults: Faults {
            serial: Default::default(),
            ..opts.faults.clone()
        },
        ..opts.clone()
    };
    let same = run(scenario, &same_opts)?.summary;
    let pose = |s: &Summary| {
        (
            s.final_estimate_m.0,
            s.final_estimate_m.1,
            s.final_estimate_heading_rad,
        )
    };
    let bits = |(x, y, t): (f64, f64, f64)| [x.to_bits(), y.to_bits(), t.to_bits()];
    let (cx, cy, _) = pose(&clean);
    Ok(FaultCheck {
        clean_final_estimate_m: clean.final_estimate_m,
        clean_final_estimate_heading_rad: clean.final_estimate_heading_rad,
        closed_loop_apart_m: (faulty.final_estimate_m.0 - cx).hypot(faulty.final_estimate_m.1 - cy),
        same_motion_final_estimate_m: same.final_estimate_m,
        same_motion_final_estimate_heading_rad: same.final_estimate_heading_rad,
        same_motion_equals_clean: bits(pose(&same)) == bits(pose(&clean)),
        same_motion_master_view_matches_slave: same.master_view_matches_slave,
        same_motion_spi_frames_rejected: same.spi_frames_rejected,
    })
}
