//! `host-bench record`: capture what the slave's real encoders see, with the slave's poses,
//! into a tick stream that `replay` and `play` take.
//!
//! The slave streams its raw readings as reports (every edge with its time stamp, or every
//! count sample, the absolute code when it changes, lost-event counters) and its pose every
//! few updates; the master relays them. A simulated board (`host-bench virtual-board`) also
//! sends the true pose, which becomes the stream's truth rows; a real board cannot.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use protocol::events::{Event, EventDecoder};
use protocol::link::GbnReceiver;
use protocol::serial::{status as serial_status, HostToMaster, MasterToHost};
use protocol::spi::{Report, Reports, SensorSource};
use serde::Serialize;

use super::link::Link;
use super::session;
use crate::formats::tickstream::{self, Event as Row, TickStream};

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
}

#[derive(Clone, Debug, Serialize)]
pub struct RecordOutcome {
    pub out: String,
    pub robot_file: String,
    pub board_poses_file: String,
    pub sensor: String,
    pub seconds: f64,
    pub ticks: u64,
    pub abs_readings: u64,
    pub truth_rows: u64,
    pub board_poses: u64,
    /// Events and updates the slave could not send (the link could not keep up): the
    /// stream has gaps there, reported in its comments.
    pub lost_events: u64,
    pub lost_updates: u64,
    pub stopped_by: String,
    /// Why the recording ended before the user stopped it (the board went silent, a record
    /// did not decode, a value out of range, the slave reset, the port failed), as the
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

/// Latest time stamp a board may send, in microseconds (about 285 years): a larger one is no
/// clock reading, and in nanoseconds it would not fit the stream's 64 bits.
const MAX_T_US: u64 = u64::MAX / 1000 / 2;

/// A board's time stamp in nanoseconds, or why it is refused (`what` names the field).
fn board_ns(t_us: u64, what: &str) -> std::result::Result<u64, String> {
    if t_us > MAX_T_US {
        return Err(format!(
            "the board sent {what} = {t_us} us, beyond any clock reading (at most {MAX_T_US})"
        ));
    }
    Ok(t_us * 1000)
}

/// The seed 004 robot file, for recordings of the slave's power-on robot.
const SEED_004_TOML: &str = include_str!("../../../robots/seed004.toml");

struct Collected {
    rows: Vec<Row>,
    board: Vec<(u64, protocol::Pose)>,
    ticks: u64,
    abs: u64,
    lost_events: u64,
    lost_updates: u64,
    truth: u64,
    /// Whether the robot has an absolute encoder (else the slave's pins read nothing).
    has_abs: bool,
}

/// The files written beside a recording `out`: `STEM.robot.toml` and `STEM.board.csv`.
fn companion_files(out: &Path) -> (PathBuf, PathBuf) {
    let stem = out
        .file_name()
        .and_then(|n| n.to_str())
        .map(|n| {
            n.trim_end_matches(".gz")
                .trim_end_matches(".csv")
                .to_string()
        })
        .unwrap_or_else(|| "recording".into());
    let dir = out.parent().unwrap_or(Path::new(""));
    (
        dir.join(format!("{stem}.robot.toml")),
        dir.join(format!("{stem}.board.csv")),
    )
}

pub fn record(link: &mut Link, req: &RecordRequest) -> Result<RecordOutcome> {
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
                    "the slave runs robot {:08x}, not its power-on seed 004 ({seed:08x}): name \
                     the robot file with --robot FILE",
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
    session::set_method_and_source(
        link,
        method,
        source,
        Reports::Record {
            pose_every: POSE_EVERY,
        },
        start,
    )?;

    let stop = Arc::new(AtomicBool::new(false));
    let _own_ctrl_c = crate::formats::atomic::OwnCtrlC::take();
    // Ctrl-C ends the recording cleanly: the file is still written whole.
    signal_hook::flag::register(signal_hook::consts::SIGINT, stop.clone())
        .context("installing the Ctrl-C handler")?;
    let wall = Instant::now();
    let mut rx: GbnReceiver<8192> = GbnReceiver::new();
    let mut bytes: Vec<u8> = Vec::new();
    let mut c = Collected {
        rows: Vec::new(),
        board: Vec::new(),
        ticks: 0,
        abs: 0,
        lost_events: 0,
        lost_updates: 0,
        truth: 0,
        has_abs,
    };
    let mut edges = EventDecoder::new();
    let period_us = info.period_us.max(1) as u64;
    // Where the report stream is (bytes decoded so far), and when its last record came.
    let mut stream_offset = 0u64;
    let mut last_record = Instant::now();
    let mut bytes_at_record = link.stats.bytes_received;
    // Why it stopped: the user's stop (`Ok`) or an early end (`Err`, the reason).
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
            Ok(Some(msg)) => msg,
            Ok(None) => continue,
            Err(e) => {
                break Err(Early::new(
                    "port failure",
                    format!("the port failed: {e:#}"),
                ))
            }
        };
        match msg {
            MasterToHost::Reports(frame) => {
                rx.on_data(&frame);
                let mut buf = [0u8; 8192];
                let n = rx.read(&mut buf);
                bytes.extend_from_slice(&buf[..n]);
            }
            // The slave started again from power-on: its clock, pose and settings are new,
            // so what comes after does not continue this recording.
            MasterToHost::Telemetry(t) if t.status & serial_status::SLAVE_RESET != 0 => {
                break Err(Early::new(
                    "slave reset",
                    "the slave reset (it started again from power-on)",
                ));
            }
            MasterToHost::SimTruth { t_us, pose } => {
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
        if let Some(a) = rx.poll_ack() {
            if let Err(e) = link.send(&HostToMaster::ReportsAck(a)) {
                break Err(Early::new(
                    "port failure",
                    format!("the port failed: {e:#}"),
                ));
            }
        }
        match take_reports(&mut bytes, &mut stream_offset, &mut c, &mut edges) {
            Ok(0) => {}
            Ok(_) => {
                last_record = Instant::now();
                bytes_at_record = link.stats.bytes_received;
            }
            Err(e) => break Err(e),
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
    Ok(outcome)
}

/// The signal test's lever (`tests/bench_cli.rs`): `OMNIBENCH_RECORD_WRITE_PAUSE_MS` widens
/// the final write, a few milliseconds on its own, so that signals sent at random moments land
/// inside it between one file and the next, where a set written file by file would be torn.
fn pause_for_signal_tests() {
    if let Some(ms) = std::env::var("OMNIBENCH_RECORD_WRITE_PAUSE_MS")
        .ok()
        .and_then(|v| v.parse::<u64>().ok())
    {
        std::thread::sleep(Duration::from_millis(ms.min(1000)));
    }
}

/// Why a recording ended before the user stopped it: a short name (`stopped_by`) and what
/// happened, for the stream's header and the error.
#[derive(Debug)]
struct Early {
    by: &'static str,
    why: String,
}

impl Early {
    fn new(by: &'static str, why: impl Into<String>) -> Self {
        Early {
            by,
            why: why.into(),
        }
    }
}

/// The whole records at the front of `bytes` into the collection (a partial one waits for its
/// remaining bytes); how many. A record that does not decode ends the recording: records are
/// written back to back without framing, so nothing after it can be told apart.
fn take_reports(
    bytes: &mut Vec<u8>,
    offset: &mut u64,
    c: &mut Collected,
    edges: &mut EventDecoder,
) -> std::result::Result<usize, Early> {
    let mut rest: &[u8] = bytes;
    let mut n = 0;
    let result = loop {
        match postcard::take_from_bytes::<Report>(rest) {
            Ok((r, tail)) => {
                let at = *offset + (bytes.len() - rest.len()) as u64;
                if let Err((by, e)) = take_report(r, c, edges) {
                    break Err(Early::new(
                        by,
                        format!("report record at byte {at} of the report stream: {e}"),
                    ));
                }
                rest = tail;
                n += 1;
            }
            Err(postcard::Error::DeserializeUnexpectedEnd) => break Ok(n),
            Err(e) => {
                let at = *offset + (bytes.len() - rest.len()) as u64;
                break Err(Early::new(
                    "undecodable record",
                    format!(
                        "the report record at byte {at} of the report stream does not decode \
                         ({e}): the records after it cannot be told apart"
                    ),
                ));
            }
        }
    };
    let used = bytes.len() - rest.len();
    *offset += used as u64;
    bytes.drain(..used);
    if result.is_err() {
        bytes.clear(); // nothing of it is read any more
    }
    result
}

/// The newest true pose a simulated board sends within 50 ms (none from a real board).
fn latest_truth(link: &mut Link) -> Result<Option<protocol::Pose>> {
    let until = Instant::now() + Duration::from_millis(50);
    let mut latest = None;
    while Instant::now() < until {
        if let Some(MasterToHost::SimTruth { pose, .. }) = link.recv(Duration::from_millis(5))? {
            latest = Some(pose);
        }
    }
    Ok(latest)
}

/// One report record into the collection. In counts mode the slave reports each update's
/// count changes as that many ticks at the update instant, so both modes decode alike.
fn take_report(
    r: Report,
    c: &mut Collected,
    edges: &mut EventDecoder,
) -> std::result::Result<(), (&'static str, String)> {
    let bad = |e: String| ("bad value", e);
    match r {
        Report::Sensors(b) => {
            let mut err = None;
            let mut undecodable = false;
            edges.feed(b.as_slice(), |e| match e {
                _ if err.is_some() => {}
                Ok(Event::Tick {
                    t_us,
                    encoder,
                    step,
                }) => match board_ns(t_us, "an edge's time stamp (Sensors, Tick.t_us)") {
                    Ok(t_ns) => {
                        c.ticks += 1;
                        c.rows.push(Row::Tick {
                            t_ns,
                            encoder: encoder as u16,
                            step: step.delta(),
                        });
                    }
                    Err(e) => err = Some(e),
                },
                Ok(Event::Abs { .. }) if !c.has_abs => {}
                Ok(Event::Abs { t_us, code }) => {
                    match board_ns(t_us, "an absolute reading's time stamp (Sensors, Abs.t_us)") {
                        Ok(t_ns) => {
                            c.abs += 1;
                            c.rows.push(Row::Abs {
                                t_ns,
                                encoder: 0,
                                code: code as u32,
                            });
                        }
                        Err(e) => err = Some(e),
                    }
                }
                Err(e) => {
                    undecodable = true;
                    err = Some(format!("the slave's sensor events do not decode: {e:?}"))
                }
            });
            if let Some(e) = err {
                let by = if undecodable {
                    "undecodable record"
                } else {
                    "bad value"
                };
                return Err((by, e));
            }
        }
        Report::PoseAt { t_us, pose } => c.board.push((
            board_ns(t_us, "a board pose's time stamp (PoseAt.t_us)").map_err(bad)?,
            pose,
        )),
        Report::Lost { events, updates } => {
            c.lost_events += events as u64;
            c.lost_updates += updates as u64;
            // The slave's event code starts from time 0 again at the marker.
            *edges = EventDecoder::new();
        }
        Report::Pose { .. } | Report::BadEvents { .. } => {}
    }
    Ok(())
}

fn write(
    req: &RecordRequest,
    robot_text: &str,
    robot_name: &str,
    mut c: Collected,
    seconds: f64,
    period_us: u64,
    stopped: &std::result::Result<&str, Early>,
) -> Result<RecordOutcome> {
    let (stopped_by, partial) = match stopped {
        Ok(by) => (by.to_string(), None),
        Err(early) => (early.by.to_string(), Some(early.why.clone())),
    };
    if c.rows.iter().all(|r| matches!(r, Row::Truth { .. })) {
        if let Err(early) = stopped {
            bail!(
                "nothing recorded: the recording ended after {seconds:.1} s, before any encoder \
                 event reached the host: {}",
                early.why
            );
        }
        bail!(
            "nothing recorded in {seconds:.1} s: no encoder event reached the host (is the \
             slave in a sensor mode that reports? {} truth rows, {} board poses)",
            c.truth,
            c.board.len()
        );
    }
    // The truth comes straight from the simulation, the sensors through the slave's report
    // stream, tens of milliseconds behind: truth past the slave's last pose may have no
    // ticks yet. The slave flushes its sensor records before each pose, so up to that pose
    // every tick is in; later truth rows go.
    if let Some(&(covered, _)) = c.board.last() {
        c.rows
            .retain(|r| !matches!(*r, Row::Truth { t_ns, .. } if t_ns > covered));
    }
    // One clock for everything (the slave's), starting at the first row.
    c.rows.sort_by_key(|r| r.t_ns());
    // With truth, the stream starts at the first truth row (replay starts from its pose):
    // ticks before it would move the robot twice; the absolute reading then is kept.
    if let Some(first) = c.rows.iter().position(|r| matches!(r, Row::Truth { .. })) {
        let t = c.rows[first].t_ns();
        let abs = c.rows[..first].iter().rev().find_map(|r| match *r {
            Row::Abs { encoder, code, .. } => Some(Row::Abs {
                t_ns: t,
                encoder,
                code,
            }),
            _ => None,
        });
        c.rows.drain(..first);
        if let Some(a) = abs {
            c.rows.insert(1, a);
        }
        c.board.retain(|b| b.0 >= t);
    }
    let t0 = c.rows[0]
        .t_ns()
        .min(c.board.first().map_or(u64::MAX, |b| b.0));
    for r in &mut c.rows {
        match r {
            Row::Tick { t_ns, .. } | Row::Abs { t_ns, .. } | Row::Truth { t_ns, .. } => *t_ns -= t0,
        }
    }
    let out = req.out;
    let (robot_path, board_file) = companion_files(out);
    let dir = out.parent().unwrap_or(Path::new(""));
    let robot_file = robot_path
        .file_name()
        .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
    let mut comments = Vec::new();
    if let Some(why) = &partial {
        // First, where a reader looks: this stream ends where the recording broke off.
        comments.push(format!(
            "PARTIAL: the recording ended early after {seconds:.3} s: {why}; the stream holds \
             what came before"
        ));
    }
    comments.extend([
        format!("recorded by host-bench record from robot {robot_name} ({stopped_by} after {seconds:.3} s)"),
        if req.counts {
            format!(
                "sensor: counts@{}Hz; each sample's count change is written as that many ticks \
                 at the sample instant (replay with --counts-rate {})",
                1_000_000 / period_us,
                1_000_000 / period_us
            )
        } else {
            "sensor: timestamps (every edge, time-stamped by the slave in microseconds)".into()
        },
    ]);
    if c.lost_events > 0 || c.lost_updates > 0 {
        comments.push(format!(
            "GAPS: the link could not keep up; the slave dropped {} encoder events and {} \
             updates (the counts after a gap are off by what was dropped)",
            c.lost_events, c.lost_updates
        ));
    }
    // What is written (rows before the first truth row, or past the last pose, are not).
    let written = |f: fn(&Row) -> bool| c.rows.iter().filter(|r| f(r)).count() as u64;
    let ticks = written(|r| matches!(r, Row::Tick { .. }));
    let abs_readings = written(|r| matches!(r, Row::Abs { .. }));
    let truth_rows = written(|r| matches!(r, Row::Truth { .. }));
    let stream = TickStream {
        robot: Some(robot_file.clone()),
        comments,
        events: c.rows,
    };
    // The three files appear together or not at all, and until they do, a recording of the
    // same name from before stays whole (`atomic::Staged`).
    let mut staged = crate::formats::atomic::Staged::default();
    tickstream::stage(&mut staged, out, &stream)?;
    pause_for_signal_tests();
    staged.write(&dir.join(&robot_file), |f| {
        f.write_all(robot_text.as_bytes())?;
        Ok(())
    })?;
    pause_for_signal_tests();
    let mut poses = String::from("t_ns,x_m,y_m,theta_rad\n");
    for (t, p) in &c.board {
        let (x, y, th) = p.to_si();
        poses.push_str(&format!("{},{x},{y},{th}\n", t.saturating_sub(t0)));
    }
    staged.write(&board_file, |f| {
        f.write_all(poses.as_bytes())?;
        Ok(())
    })?;
    pause_for_signal_tests();
    staged.commit()?;
    Ok(RecordOutcome {
        out: out.display().to_string(),
        robot_file: dir.join(&robot_file).display().to_string(),
        board_poses_file: PathBuf::from(&board_file).display().to_string(),
        sensor: if req.counts { "counts" } else { "timestamps" }.into(),
        seconds,
        ticks,
        abs_readings,
        truth_rows,
        board_poses: c.board.len() as u64,
        lost_events: c.lost_events,
        lost_updates: c.lost_updates,
        stopped_by,
        partial,
        switch_back_failed: None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use firmware_slave::recorder::{RecordSink, Recorder};

    /// The report stream, full (taking nothing) while `open` is false.
    struct Stream {
        open: bool,
        records: Vec<Report>,
    }

    impl RecordSink for Stream {
        fn put(&mut self, r: &Report) -> bool {
            if self.open {
                self.records.push(*r);
            }
            self.open
        }
    }

    /// The slave's recorder with its stream full for a while, read back as `record` reads it:
    /// every tick that arrives has the board's own time stamp, and the ones that do not are
    /// counted. (They did not: the slave starts its event code from time 0 again after a gap,
    /// and the host kept adding to the time before it, so every tick after the first gap was
    /// placed later by that much.)
    #[test]
    fn ticks_after_a_gap_keep_the_boards_time_stamps() {
        let mut rec = Recorder::new();
        let mut stream = Stream {
            open: true,
            records: Vec::new(),
        };
        let mut made = Vec::new();
        let mut t = 1_000u64;
        for update in 0..400u64 {
            // Full for two stretches: a gap of updates (with their poses), then another.
            stream.open = !(140..160).contains(&update) && !(250..252).contains(&update);
            for k in 0..3u64 {
                t += 40 + (update * 7 + k * 13) % 50;
                rec.tick(&mut stream, t, (k % 2) as u8, 1);
                made.push(t);
            }
            if update == 300 {
                // A time stamp before the last: the code cannot carry it, it is counted lost.
                rec.tick(&mut stream, t - 100, 0, 1);
                made.push(t - 100);
            }
            rec.update(&mut stream, t, protocol::Pose::default(), POSE_EVERY);
            t += 1;
        }
        let mut c = Collected {
            rows: Vec::new(),
            board: Vec::new(),
            ticks: 0,
            abs: 0,
            lost_events: 0,
            lost_updates: 0,
            truth: 0,
            has_abs: false,
        };
        let mut edges = EventDecoder::new();
        for r in &stream.records {
            take_report(*r, &mut c, &mut edges).unwrap();
        }
        assert!(c.lost_events > 0 && c.lost_updates > 0, "the gaps happened");
        let got: Vec<u64> = c.rows.iter().map(|r| r.t_ns() / 1000).collect();
        assert_eq!(got.len() as u64 + c.lost_events, made.len() as u64);
        // Each one the board's, in order.
        let mut made_iter = made.iter();
        for g in &got {
            assert!(
                made_iter.any(|m| m == g),
                "tick at {g} us is none the board made (after a gap?)"
            );
        }
    }
}
