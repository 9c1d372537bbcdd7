//! `host-bench play`: stream a tick stream to the boards and check that the slave computes,
//! update for update, the very poses the host computes with the same code on the same bytes.
//!
//! The host runs [`firmware_slave::played::PlayedSensors`] over the bytes it sends (the
//! expected reports, [`super::expected`]), loads the robot into the slave, switches it to
//! played sensors, then streams the bytes over the go-back-N link while collecting the slave's
//! pose reports, which must equal the expected ones exactly (micrometre pose and the digest of
//! the full-precision pose). Playback runs as fast as the link allows, in played time.

use std::cell::RefCell;
use std::path::Path;
use std::time::Duration;

use anyhow::{anyhow, bail, Context, Result};
use firmware_slave::played::PlayKind;
use protocol::link::{GbnReceiver, GbnSender, DEFAULT_TIMEOUT_US};
use protocol::serial::{status as serial_status, HostToMaster, MasterToHost};
use protocol::spi::{PoseChecks, Report, Reports, SensorSource};
use robot_math::exact::FixedPose;
use robot_math::odometry::Method;
use robot_math::Pose2;
use serde::Serialize;

use super::expected::Expected;
use super::link::Link;
use super::played_stream::{self, PlayedStream};
use super::scorer::Scorer;
use super::session;
use crate::formats::robot::Robot;
use crate::serial::clock::Instant;
use crate::viewer::{topics, View};

/// Host-side event buffer: bytes offered to the link ahead of the master's credit.
const SEND_BUFFER: usize = 16 * 1024;
/// How much written and not yet on the line `play` allows: enough to keep the line busy
/// between two turns of its loop, little enough that an acknowledgement is not held up.
const LINE_AHEAD: Duration = Duration::from_millis(4);
/// No progress for this long means the board stopped playing. Progress is an update reported
/// or event bytes acknowledged that were not before: a board that keeps talking (telemetry,
/// the same acknowledgement again) without either is stuck all the same.
const STALL: Duration = Duration::from_secs(5);

#[derive(Clone, Debug, Serialize)]
pub struct Mismatch {
    pub update: u64,
    pub board: String,
    pub host: String,
}

#[derive(Clone, Debug, Serialize)]
pub struct PlayOutcome {
    pub port: String,
    pub robot: String,
    pub robot_fingerprint: String,
    pub algorithm: String,
    /// Whether the method is integer-only on its update path (exact) or per tick (lut); the
    /// float methods run the same IEEE arithmetic and are compared all the same.
    pub integer_method: bool,
    pub sensor: String,
    pub events: u64,
    pub samples: u64,
    /// Updates the board is known to have computed as the host did: all of them up to its
    /// last report that matched (each report's digest covers every update before it).
    pub board_updates: u64,
    pub expected_updates: u64,
    pub mismatches: u64,
    pub first_mismatch: Option<Mismatch>,
    /// The board reported every `check_every`-th pose in full (and every pose of the last
    /// window): the rest are checked by the running digest.
    pub check_every: u16,
    pub poses_reported: u64,
    /// Bytes of the event stream (what the slave decodes).
    pub wire_bytes: u64,
    pub bytes_per_event: f64,
    /// The link's rate during the play, and what the host asked for.
    pub baud: u32,
    pub baud_asked: u32,
    /// Everything the host put on the serial line (framing, acks, retransmissions).
    pub link_bytes_sent: u64,
    pub link_bytes_received: u64,
    pub frames_corrupted: u64,
    pub frames_dropped: u64,
    pub frames_rejected_by_host: u64,
    /// Event frames the host sent again (go-back-N after a gap or a timeout).
    pub frames_resent: u64,
    pub played_seconds: f64,
    /// How long the play took on the host's clock: the wall's, or with `--clock` the board
    /// model's simulated time.
    pub wall_seconds: f64,
    pub played_per_wall_second: f64,
    /// Truth rows in the stream, and those scored (the rest lie past the last update).
    pub truth_rows: usize,
    pub scored_rows: usize,
    pub final_error_m: Option<f64>,
    pub max_error_m: Option<f64>,
}

pub struct PlayRequest<'a> {
    /// The stream's file, named in errors about its rows.
    pub ticks: &'a Path,
    pub robot: &'a Robot,
    pub method: Method,
    pub kind: PlayKind,
    pub stream: &'a crate::formats::tickstream::TickStream,
    /// Report every this many updates in full (1: all of them).
    pub check_every: u16,
    pub progress: Option<&'a indicatif::ProgressBar>,
    /// Where the play is shown as it goes (`--mcap`, `--live`): the channels of
    /// [`crate::viewer::topics::serial_channels`].
    pub view: Option<&'a RefCell<View>>,
}

/// Updates between the poses a play reports in full, by default: a pose report every 50 ms
/// of played time at 1 kHz, about 0.3 bytes an update on the link instead of 24.
pub const CHECK_EVERY: u16 = 50;

fn wire_pose(p: Pose2) -> protocol::Pose {
    protocol::Pose::from_si(p.x, p.y, p.theta)
}

/// The full-precision pose the slave starts from, given `p` on the wire.
fn fixed(p: protocol::Pose) -> FixedPose {
    FixedPose::from_micrometres(p.x_um, p.y_um, p.heading.0)
}

/// Where the last window starts: the updates after the last multiple of `every` that no
/// later report closes, reported one by one so the end of the stream is checked too.
fn last_window(updates: u64, every: u16) -> u32 {
    let every = u64::from(every.max(1));
    let closed = (updates.saturating_sub(1) / every) * every;
    u32::try_from(closed + 1).unwrap_or(u32::MAX)
}

/// Play `req` to the boards on `link`.
pub fn play(link: &mut Link, req: &PlayRequest) -> Result<PlayOutcome> {
    let in_file = |e: anyhow::Error| anyhow!("{}: {e:#}", req.ticks.display());
    let layout = req.robot.odometry_layout()?;
    // What the rows are is checked before the board is asked; what its period makes of them
    // (the updates, none at all) once it has said its period.
    played_stream::check_rows(req.stream, req.robot).map_err(in_file)?;
    let info = session::hello(link)?;
    let stream =
        PlayedStream::new(req.stream, req.robot, req.kind, info.period_us).map_err(in_file)?;
    // Both sides start from the micrometre pose on the wire.
    let start_wire = wire_pose(stream.start());
    // The method is checked against the stream before the board is asked.
    Expected::new(&layout, req.method, &stream, fixed(start_wire))?;
    let fingerprint = session::load_robot(link, &layout)?;
    let every = req.check_every.max(1);
    let plan = Pass {
        layout: &layout,
        method: req.method,
        stream: &stream,
        start_wire,
        checks: PoseChecks {
            every,
            all_from: last_window(stream.updates, every),
        },
        until: stream.updates,
        progress: req.progress,
        view: req.view,
    };
    let wall = Instant::now();
    let mut run = plan.run(link)?;
    let wall_seconds = wall.elapsed().as_secs_f64();
    let frames_resent = run.frames_resent;
    if let Some(bad) = run.first_bad.take() {
        // A report's digest covers every update before it: the first to differ lies after
        // the last report that matched. Play the stream again with every update of that
        // window reported in full, to name it (the board computes what it did before: the
        // same integer code on the same bytes).
        let window = Pass {
            checks: PoseChecks {
                every,
                all_from: u32::try_from(run.good + 1).unwrap_or(u32::MAX),
            },
            until: bad.update,
            progress: None,
            // Shown once: the window played again would take the run's time back.
            view: None,
            ..plan
        };
        let again = window.run(link)?;
        run.good = run.good.max(again.good);
        run.first_bad = Some(again.first_bad.unwrap_or(Mismatch {
            host: format!(
                "{} (played again with every update from {} reported, the board matched the \
                 host up to update {}: it does not compute the same every time)",
                bad.host,
                run.good + 1,
                again.good
            ),
            ..bad
        }));
    }
    // Leave the board as it was: its power-on robot back if it had it, its own sensors, the
    // method it ran (left on the played one, the next `record` recorded with it: after a
    // play of `lut`, its board poses were 0.03 mm and 0.009 deg off `replay`'s).
    let power_on = robot_math::odometry::Layout::SEED_004;
    if info.robot == firmware_slave::robot_wire::layout_fingerprint(&power_on) {
        let _ = session::load_robot(link, &power_on);
    }
    let _ = session::set_method_and_source(
        link,
        session::method_of(info.algorithm),
        SensorSource::Ticks,
        Reports::Off,
        protocol::Pose::default(),
    );
    let (final_error_m, max_error_m, scored_rows) = run.scores;
    let played_seconds = run.good as f64 * stream.period_us as f64 * 1e-6;
    Ok(PlayOutcome {
        port: link.name().to_string(),
        robot: req.robot.name.clone(),
        robot_fingerprint: format!("{fingerprint:08x}"),
        algorithm: req.method.name().to_string(),
        integer_method: matches!(req.method, Method::Exact | Method::Lut),
        sensor: match req.kind {
            PlayKind::Ticks => "timestamps".into(),
            PlayKind::Counts => format!("counts@{}Hz", 1e6 / stream.period_us as f64),
        },
        events: stream.events,
        samples: stream.samples,
        board_updates: run.good,
        expected_updates: stream.updates,
        mismatches: u64::from(run.first_bad.is_some()),
        first_mismatch: run.first_bad,
        check_every: every,
        poses_reported: run.reports,
        wire_bytes: stream.wire_bytes,
        bytes_per_event: stream.wire_bytes as f64 / stream.events.max(1) as f64,
        baud: link.baud(),
        baud_asked: link.baud_asked(),
        link_bytes_sent: link.stats.bytes_sent,
        link_bytes_received: link.stats.bytes_received,
        frames_corrupted: link.stats.events_frames_corrupted,
        frames_dropped: link.stats.events_frames_dropped,
        frames_rejected_by_host: link.stats.frames_rejected,
        frames_resent,
        played_seconds,
        wall_seconds,
        played_per_wall_second: played_seconds / wall_seconds.max(1e-9),
        truth_rows: stream.truth().count(),
        scored_rows,
        final_error_m,
        max_error_m,
    })
}

/// One pass of the stream through the boards, from the start, up to update `until`.
#[derive(Clone, Copy)]
struct Pass<'p, 's, 'a> {
    layout: &'p robot_math::odometry::Layout,
    method: Method,
    stream: &'s PlayedStream<'a>,
    /// Where odometry starts, as the wire carries it: both sides start from it.
    start_wire: protocol::Pose,
    checks: PoseChecks,
    until: u64,
    progress: Option<&'p indicatif::ProgressBar>,
    view: Option<&'p RefCell<View>>,
}

/// What a pass showed.
struct Passed {
    /// The last update the board's reports proved the same as the host's.
    good: u64,
    /// The first report that differed.
    first_bad: Option<Mismatch>,
    reports: u64,
    frames_resent: u64,
    scores: (Option<f64>, Option<f64>, usize),
}

impl Pass<'_, '_, '_> {
    fn run(&self, link: &mut Link) -> Result<Passed> {
        let stream = self.stream;
        let start = fixed(self.start_wire);
        // The host's own reports: every update's, with the digest running through them all.
        let mut expected = Expected::new(self.layout, self.method, stream, start)?;
        let source = match stream.kind {
            PlayKind::Ticks => SensorSource::PlayedTicks,
            PlayKind::Counts => SensorSource::PlayedCounts,
        };
        session::set_method_and_source(
            link,
            self.method,
            source,
            Reports::Poses(self.checks),
            self.start_wire,
        )?;
        // A new session now that the slave's streams restarted: report bytes of an earlier
        // stream (a play interrupted, its reports never acknowledged) that the master took in
        // before the slave switched are dropped with the old session, not read as this one's.
        session::hello(link)?;

        let wall = Instant::now();
        let clock = |w: Instant| w.elapsed().as_micros() as u64;
        let resend_us = link
            .wait(Duration::from_micros(DEFAULT_TIMEOUT_US))
            .as_micros() as u64;
        let mut tx: GbnSender<SEND_BUFFER> = GbnSender::new(resend_us);
        let mut rx: GbnReceiver<4096> = GbnReceiver::new();
        let mut wire = stream.bytes();
        // Bytes made and not yet taken by the sender: `out[out_at..]`.
        let mut out: Vec<u8> = Vec::with_capacity(SEND_BUFFER);
        let mut out_at = 0usize;
        let mut offered = 0u64;
        let mut report_bytes: Vec<u8> = Vec::new();
        let mut good = 0u64;
        let mut reports = 0u64;
        let mut first_bad = None;
        let mut scorer = Scorer::new(stream.truth(), stream.period_us, start.to_pose2());
        if self.view.is_some() {
            scorer = scorer.keep_rows();
        }
        let period_s = stream.period_us as f64 * 1e-6;
        // The host's poses as it computes them, and the rows scored, for the view.
        let mut host_poses: Vec<(u64, Pose2)> = Vec::new();
        let mut progress = Progress::new(link);
        if let Some(bar) = self.progress {
            bar.set_length(self.until);
        }
        while good < self.until && first_bad.is_none() {
            if out_at == out.len() {
                out.clear();
                out_at = 0;
                wire.fill(&mut out, SEND_BUFFER)?;
            }
            let n = tx.offer(&out[out_at..]);
            out_at += n;
            offered += n as u64;
            // No more than the line carries in a few milliseconds waits to go out.
            while link.backlog() < LINE_AHEAD {
                let Some(frame) = tx.poll_transmit(clock(wall)) else {
                    break;
                };
                link.send(&HostToMaster::Events(frame))?;
            }
            progress.see(good, offered - tx.unacked() as u64, link);
            if progress.since.elapsed() > link.wait(STALL) {
                bail!(
                    "{} for {} s, after {good} of {} updates ({} of {} event bytes \
                     acknowledged)",
                    progress.stuck_how(link),
                    link.wait(STALL).as_secs(),
                    stream.updates,
                    progress.acked,
                    stream.wire_bytes
                );
            }
            let Some(msg) = link.recv(Duration::from_millis(5))? else {
                continue;
            };
            match msg {
                MasterToHost::EventsAck(a) => tx.on_ack(a, clock(wall)),
                MasterToHost::Reports(frame) => {
                    rx.on_data(&frame);
                    let mut buf = [0u8; 4096];
                    let n = rx.read(&mut buf);
                    report_bytes.extend_from_slice(&buf[..n]);
                }
                MasterToHost::Rejected(r) => bail!("the master rejected a command: {r:?}"),
                MasterToHost::Telemetry(t) if t.status & serial_status::SLAVE_RESET != 0 => bail!(
                    "the slave reset after {good} of {} updates: it started again from \
                     power-on, so this play is void (play it again)",
                    stream.updates
                ),
                _ => {}
            }
            if let Some(a) = rx.poll_ack() {
                link.send(&HostToMaster::ReportsAck(a))?;
            }
            // Whole records only; a partial one waits for its remaining bytes.
            let mut rest: &[u8] = &report_bytes;
            while first_bad.is_none() {
                let r = match postcard::take_from_bytes::<Report>(rest) {
                    Ok((r, tail)) => {
                        rest = tail;
                        r
                    }
                    Err(postcard::Error::DeserializeUnexpectedEnd) => break,
                    Err(e) => bail!(
                        "after {good} updates the board's reports cannot be read ({e}): not \
                         the records this play's slave writes"
                    ),
                };
                match r {
                    Report::Pose { update, .. } => {
                        reports += 1;
                        let want = expected.report_of(u64::from(update), |k, p| {
                            let (x, y, th) = p.to_si();
                            scorer.push(Pose2::new(x, y, th));
                            if self.view.is_some() {
                                host_poses.push((k, Pose2::new(x, y, th)));
                            }
                        })?;
                        if let Some(v) = self.view {
                            let board = match r {
                                Report::Pose { pose, .. } => {
                                    let (x, y, th) = pose.to_si();
                                    Pose2::new(x, y, th)
                                }
                                _ => unreachable!(),
                            };
                            show(
                                &mut v.borrow_mut(),
                                period_s,
                                (u64::from(update), board),
                                &mut host_poses,
                                scorer.take_rows(),
                                link,
                                good,
                            )?;
                        }
                        if want.as_ref() == Some(&r) {
                            good = u64::from(update);
                        } else {
                            first_bad = Some(Mismatch {
                                update: u64::from(update),
                                board: format!("{r:?}"),
                                host: want.map_or("no such update".into(), |w| format!("{w:?}")),
                            });
                        }
                    }
                    Report::BadEvents { offset } => {
                        bail!("the slave could not decode the event stream at byte {offset}")
                    }
                    _ => {}
                }
            }
            let consumed = report_bytes.len() - rest.len();
            report_bytes.drain(..consumed);
            if let Some(bar) = self.progress {
                bar.set_position(good);
            }
        }
        if good == stream.updates && expected.report_of(good + 1, |_, _| {})?.is_some() {
            bail!(
                "the host's own decoder makes more than the {} updates counted from the \
                 stream: a host bug",
                stream.updates
            );
        }
        Ok(Passed {
            good,
            first_bad,
            reports,
            frames_resent: tx.stats().frames_retransmitted.into(),
            scores: scorer.finish(),
        })
    }
}

/// A board pose report as the view's messages, with the host's poses and the truth rows up
/// to it.
fn show(
    view: &mut View,
    period_s: f64,
    (update, board): (u64, Pose2),
    host: &mut Vec<(u64, Pose2)>,
    truth_rows: Vec<(u64, Pose2, Pose2)>,
    link: &Link,
    good: u64,
) -> Result<()> {
    let si = |p: Pose2| (p.x, p.y, p.theta);
    // The truth rows and the host's poses, each in time order, merged: every message is
    // logged at its own time.
    let mut rows = truth_rows.into_iter().peekable();
    let mut poses = host.drain(..).peekable();
    loop {
        let row_t = rows.peek().map(|r| r.0 as f64 * 1e-9);
        let pose_t = poses.peek().map(|(k, _)| *k as f64 * period_s);
        let row_first = match (row_t, pose_t) {
            (Some(r), Some(p)) => r <= p,
            (r, _) => r.is_some(),
        };
        if row_first {
            let (t_ns, est, truth) = rows.next().expect("peeked");
            let t = t_ns as f64 * 1e-9;
            view.transform("/tf", "robot", t, si(truth))?;
            view.pose("/truth/pose", t, si(truth))?;
            view.json("/board/error", t, &topics::pose_error(si(est), si(truth)))?;
        } else if let Some((k, p)) = poses.next() {
            view.pose("/host/pose", k as f64 * period_s, si(p))?;
        } else {
            break;
        }
    }
    let t = update as f64 * period_s;
    view.pose("/board/pose", t, si(board))?;
    view.json(
        "/link",
        t,
        &link.view_counters(serde_json::json!({
            "events_frames": link.stats.events_frames,
            "updates_checked": good,
        })),
    )
}

/// When the play last moved on: an update more, or event bytes acknowledged that were not.
struct Progress {
    since: Instant,
    updates: u64,
    acked: u64,
    /// What the board had sent when the play last moved on.
    bytes_then: u64,
}

impl Progress {
    fn new(link: &Link) -> Self {
        Progress {
            since: Instant::now(),
            updates: 0,
            acked: 0,
            bytes_then: link.stats.bytes_received,
        }
    }

    fn see(&mut self, updates: u64, acked: u64, link: &Link) {
        if updates > self.updates || acked > self.acked {
            self.since = Instant::now();
            self.updates = updates;
            self.acked = acked;
            self.bytes_then = link.stats.bytes_received;
        }
    }

    fn stuck_how(&self, link: &Link) -> String {
        match link.stats.bytes_received - self.bytes_then {
            // Less than a frame or two: what was on its way when it stopped.
            n if n < 64 => format!("the board stopped answering ({n} bytes received)"),
            n => format!(
                "the board keeps talking ({n} bytes) but plays nothing: no update reported and \
                 no event acknowledged that was not before"
            ),
        }
    }
}

/// Used by the CLI: the robot's layout or a clear error.
pub fn method_from_name(name: &str) -> Result<Method> {
    Method::from_name(name).with_context(|| {
        format!(
            "unknown algorithm {name:?}; available: {}",
            Method::ALL.map(|m| m.name()).join(", ")
        )
    })
}
