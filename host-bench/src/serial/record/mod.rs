//! `host-bench record`: capture what the slave's real encoders see, with the slave's poses,
//! into a tick stream that `replay` and `play` take.
//!
//! The slave streams its raw readings as reports (every edge with its time stamp, or every
//! count sample, the absolute code when it changes, lost-event counters) and its pose every
//! few updates; the master relays them. A simulated board (`host-bench virtual-board`) also
//! sends the true pose, which becomes the stream's truth rows; a real board cannot.

use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

use anyhow::{bail, Context, Result};
use protocol::events::EventDecoder;
use protocol::serial::{status as serial_status, MasterToHost};
use protocol::spi::{Reports, SensorSource};
use serde::Serialize;

use crate::serial::clock::Instant;

mod collect;
mod show;
mod write;

use collect::{board_ns, take_reports, Collected, Early};
pub use write::companion_files;
use write::write;

use super::link::Link;
use super::reports::ReportReader;
use super::session;
use crate::formats::tickstream::Event as Row;

/// Board poses in the report stream: one every this many updates.
pub const POSE_EVERY: u16 = 50;

pub struct RecordRequest<'a> {
    pub out: &'a Path,
    pub duration_s: Option<f64>,
    pub counts: bool,
    /// The robot file to load into the slave and name in the stream; `None`: the slave's
    /// power-on robot (seed 004), whose file is written beside the stream.
    pub robot: Option<&'a Path>,
    pub progress: Option<&'a indicatif::ProgressBar>,
    /// Where the recording is shown as it goes: the channels of
    /// [`crate::viewer::topics::serial_channels`].
    pub view: Option<&'a std::cell::RefCell<crate::viewer::View>>,
}

#[derive(Clone, Debug, Serialize)]
pub struct RecordOutcome {
    pub out: String,
    pub robot_file: String,
    pub board_poses_file: String,
    pub sensor: String,
    pub seconds: f64,
    /// Encoder edges recorded, each with its time stamp (`ticks` under its older name).
    pub edges: u64,
    pub ticks: u64,
    pub abs_readings: u64,
    pub truth_rows: u64,
    pub board_poses: u64,
    /// Events and updates the slave could not send (the link could not keep up): the
    /// stream has gaps there, reported in its comments.
    pub lost_events: u64,
    pub lost_updates: u64,
    /// Spans of the recording with events missing (the link lost them, or records were
    /// passed over), each a `# GAP` comment in the stream.
    pub gaps: u64,
    /// The link's rate during the recording, and what the host asked for.
    pub baud: u32,
    pub baud_asked: u32,
    /// Report records that did not decode, passed over; and the `Sensors` records after
    /// them that were passed over until the slave's event code started again (at most a
    /// board pose's interval, 50 updates). The stream's comments say so.
    pub records_undecodable: u64,
    pub records_unplaced: u64,
    pub stopped_by: String,
    /// Why the recording ended before the user stopped it (the board went silent or sent no
    /// reports, a value out of range, the slave reset, the port failed), as the
    /// stream's header says; `None` when it ran until Ctrl-C or `--duration`.
    pub partial: Option<String>,
    /// The slave could not be switched back to its own sensors afterwards (the recording is
    /// written all the same).
    pub switch_back_failed: Option<String>,
}

/// No new record for this long (times `--patience`): the board went silent. A recording slave
/// sends its pose every [`POSE_EVERY`] updates (50 ms at 1 kHz) even when the robot stands
/// still; the chip model, at a tenth of real time, takes half a second for that.
const SILENCE: Duration = Duration::from_secs(1);

/// The seed 004 robot file, for recordings of the slave's power-on robot.
const SEED_004_TOML: &str = include_str!("../../../../robots/seed004.toml");

/// Something that moves the robot while it is recorded (`calibrate --port` drives squares
/// through the master): told where the recording starts, then called at every turn of the
/// recording's loop.
pub trait Mover {
    /// The recording starts now, the board's odometry at `start` (the truth's pose on a
    /// simulated board, the origin on a real one).
    fn start(&mut self, link: &mut Link, start: protocol::Pose) -> Result<()>;
    /// One turn of the loop, with the frame just received, if any: `Ok(true)` once the
    /// motion is over and the recording may end; an error ends the recording early.
    fn step(&mut self, link: &mut Link, msg: Option<&MasterToHost>) -> Result<bool>;
}

pub fn record(link: &mut Link, req: &RecordRequest) -> Result<RecordOutcome> {
    record_moving(link, req, None)
}

/// [`record`], with `mover` moving the robot meanwhile; the recording ends when its motion
/// is over ("motion over"), or early with the mover's error.
pub fn record_moving(
    link: &mut Link,
    req: &RecordRequest,
    mut mover: Option<&mut dyn Mover>,
) -> Result<RecordOutcome> {
    // Where it all goes, checked before a second is recorded: a recording that cannot be
    // written at the end is a recording lost.
    let (robot_out, board_out) = companion_files(req.out);
    for path in [req.out, robot_out.as_path(), board_out.as_path()] {
        crate::formats::atomic::check_output(path).context("--out")?;
    }
    let info = session::hello(link)?;
    // The robot: the one given (loaded into the slave), or the slave's power-on seed 004.
    let (robot_text, robot_name, has_abs) = match req.robot {
        Some(p) => {
            let robot = crate::formats::robot::Robot::load(p)?;
            let layout = robot
                .odometry_layout()
                .with_context(|| format!("--robot {}", p.display()))?;
            crate::sim::plant::slave_board_reads(&layout)
                .map_err(|e| anyhow::anyhow!("--robot {}: {e}", p.display()))?;
            session::load_robot(link, &layout)?;
            (
                crate::formats::toml_file::read_bounded_text(p)
                    .map_err(|e| anyhow::anyhow!("reading {}: {e}", p.display()))?,
                robot.name,
                layout.abs().is_some(),
            )
        }
        None => {
            let seed = firmware_slave::robot_wire::layout_fingerprint(
                &robot_math::odometry::Layout::SEED_004,
            );
            if info.robot != seed {
                bail!(
                    "the slave runs robot {:08x}, not its power-on robot, the carriage robot of \
                     Xu, Zhu and Hu 2015 ({seed:08x}): name the robot file with --robot FILE",
                    info.robot
                );
            }
            (SEED_004_TOML.to_string(), "seed004".to_string(), true)
        }
    };
    let method = session::method_of(info.algorithm);
    let source = if req.counts {
        SensorSource::Counts
    } else {
        SensorSource::Ticks
    };
    // Quiet first (no reports), then a new session, so the report stream starts clean at the
    // first record of this recording.
    session::set_method_and_source(
        link,
        method,
        source,
        Reports::Off,
        protocol::Pose::default(),
    )?;
    session::hello(link)?;
    // A simulated board knows where the robot is: start the board's odometry there, so its
    // poses compare with the truth. A real board starts at the origin.
    let start = latest_truth(link)?.unwrap_or_default();
    // The link takes the report stream in from its first byte, while the switch is still
    // being confirmed.
    link.receive_reports();
    session::set_method_and_source(
        link,
        method,
        source,
        Reports::Record {
            pose_every: POSE_EVERY,
        },
        start,
    )?;
    if let Some(m) = mover.as_deref_mut() {
        m.start(link, start)?;
    }

    let stop = Arc::new(AtomicBool::new(false));
    let _own_ctrl_c = crate::formats::atomic::OwnCtrlC::take();
    // Ctrl-C ends the recording cleanly: the file is still written whole.
    signal_hook::flag::register(signal_hook::consts::SIGINT, stop.clone())
        .context("installing the Ctrl-C handler")?;
    let wall = Instant::now();
    let mut reports = ReportReader::default();
    let mut c = Collected::new(has_abs);
    let mut edges = EventDecoder::new();
    let period_us = info.period_us.max(1) as u64;
    // When the report stream's last record came.
    let mut last_record = Instant::now();
    let mut bytes_at_record = link.stats.bytes_received;
    // Why it stopped: the user's stop (`Ok`) or an early end (`Err`, the reason).
    let mut shown = show::Shown::default();
    let stopped: std::result::Result<&str, Early> = loop {
        if stop.load(Ordering::Relaxed) {
            break Ok("ctrl-c");
        }
        if req
            .duration_s
            .is_some_and(|d| wall.elapsed().as_secs_f64() >= d)
        {
            break Ok("duration");
        }
        // A stream is read back whole into memory: a recording stops at what a reader takes.
        let most = crate::formats::tickstream::MAX_EVENTS;
        if c.rows.len() >= most || c.board.len() >= crate::eval::board_poses::MAX_ROWS {
            break Err(Early::new(
                "size limit",
                "the stream reached its size limit (docs/limits.md)",
            ));
        }
        if last_record.elapsed() > link.wait(SILENCE) {
            let why = match link.stats.bytes_received - bytes_at_record {
                n if n < 64 => "the board went silent".to_string(),
                n => format!("the board sends ({n} bytes) but no reports"),
            };
            break Err(Early::new(
                "silence",
                format!("{why}: no report for {} s", link.wait(SILENCE).as_secs()),
            ));
        }
        if let Some(bar) = req.progress {
            bar.set_message(format!("{} ticks, {} truth rows", c.ticks, c.truth));
            bar.tick();
        }
        let msg = match link.recv(Duration::from_millis(10)) {
            Ok(msg) => msg,
            Err(e) => {
                break Err(Early::new(
                    "port failure",
                    format!("the port failed: {e:#}"),
                ))
            }
        };
        if let Some(m) = mover.as_deref_mut() {
            match m.step(link, msg.as_ref()) {
                Ok(false) => {}
                Ok(true) => break Ok("motion over"),
                Err(e) => break Err(Early::new("motion", format!("{e:#}"))),
            }
        }
        let mut taken = Vec::new();
        link.read_reports(&mut taken);
        reports.push(&taken);
        match msg {
            // The slave started again from power-on: its clock, pose and settings are new,
            // so what comes after does not continue this recording.
            Some(MasterToHost::Telemetry(t)) if t.status & serial_status::SLAVE_RESET != 0 => {
                break Err(Early::new(
                    "slave reset",
                    "the slave reset (it started again from power-on)",
                ));
            }
            Some(MasterToHost::SimTruth { t_us, pose }) => {
                let t_ns = match board_ns(t_us, "a true pose's time stamp (SimTruth.t_us)") {
                    Ok(t) => t,
                    Err(e) => break Err(Early::new("bad value", e)),
                };
                let (x_m, y_m, theta_rad) = pose.to_si();
                c.rows.push(Row::Truth {
                    t_ns,
                    x_m,
                    y_m,
                    theta_rad,
                });
                c.truth += 1;
            }
            _ => {}
        }
        match take_reports(&mut reports, &mut c, &mut edges) {
            Ok(0) => {}
            Ok(_) => {
                last_record = Instant::now();
                bytes_at_record = link.stats.bytes_received;
            }
            Err(e) => break Err(e),
        }
        if let Some(v) = req.view {
            if let Err(e) = shown.show(v, &c, link) {
                break Err(Early::new("view", format!("{e:#}")));
            }
        }
    };
    let seconds = wall.elapsed().as_secs_f64();
    // Written first, switched back after (whether the write worked or not): switching back
    // may wait for a board that does not answer, and a user who gives up on that must not
    // lose the recording.
    let written = write(
        req,
        &robot_text,
        &robot_name,
        c,
        seconds,
        period_us,
        &stopped,
    );
    // A board that went silent or a port that failed will not answer this either.
    let switch_back_failed = match &stopped {
        Err(early) if early.by == "port failure" => Some("not tried: the port failed".to_string()),
        _ => session::set_method_and_source(
            link,
            method,
            SensorSource::Ticks,
            Reports::Off,
            protocol::Pose::default(),
        )
        .err()
        .map(|e| format!("{e:#}")),
    };
    let mut outcome = written?;
    outcome.switch_back_failed = switch_back_failed;
    (outcome.baud, outcome.baud_asked) = (link.baud(), link.baud_asked());
    Ok(outcome)
}

/// The newest true pose a simulated board sends within 50 ms (none from a real board).
pub fn latest_truth(link: &mut Link) -> Result<Option<protocol::Pose>> {
    let until = Instant::now() + Duration::from_millis(50);
    let mut latest = None;
    while Instant::now() < until {
        if let Some(MasterToHost::SimTruth { pose, .. }) = link.recv(Duration::from_millis(5))? {
            latest = Some(pose);
        }
    }
    Ok(latest)
}
