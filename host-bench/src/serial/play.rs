//! `host-bench play`: stream a tick stream to the boards and check that the slave computes,
//! update for update, the very poses the host computes with the same code on the same bytes.
//!
//! The host runs [`firmware_slave::played::PlayedSensors`] over the bytes it is about to send
//! (the expected reports), loads the robot into the slave, switches it to played sensors, then
//! streams the bytes over the go-back-N link while collecting the slave's pose reports, which
//! must equal the expected ones exactly (micrometre pose and the digest of the full-precision
//! pose). Playback runs as fast as the link allows, in played time.

use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use firmware_slave::played::{PlayKind, PlayedSensors, ReportSink};
use protocol::link::{GbnReceiver, GbnSender, DEFAULT_TIMEOUT_US};
use protocol::serial::{status as serial_status, HostToMaster, MasterToHost};
use protocol::spi::{Report, Reports, SensorSource};
use robot_math::exact::FixedPose;
use robot_math::odometry::{Layout, Method};
use robot_math::Pose2;
use serde::Serialize;

use super::link::Link;
use super::played_stream::PlayedStream;
use super::session;

/// Host-side event buffer: bytes offered to the link ahead of the master's credit.
const SEND_BUFFER: usize = 16 * 1024;
/// No progress for this long means the board stopped answering.
const STALL: Duration = Duration::from_secs(5);

/// Reports into a plain list (the host has room for all of them).
struct ListSink(Vec<Report>);

impl ReportSink for ListSink {
    fn has_room(&self) -> bool {
        true
    }
    fn push(&mut self, r: Report) {
        self.0.push(r)
    }
}

/// What the host expects the slave to report for `stream`.
pub fn expected_reports(
    layout: &Layout,
    method: Method,
    stream: &PlayedStream,
    start: FixedPose,
) -> Result<Vec<Report>> {
    let mut engine = PlayedSensors::new(layout, method, stream.kind, stream.period_us, start)
        .map_err(|e| {
            anyhow::anyhow!(
                "--algorithm {} with --sensor {}: {e}",
                method.name(),
                match stream.kind {
                    firmware_slave::played::PlayKind::Ticks => "timestamps",
                    firmware_slave::played::PlayKind::Counts => "counts",
                }
            )
        })?;
    let mut sink = ListSink(Vec::new());
    let used = engine.feed(&stream.bytes, &mut sink);
    if used != stream.bytes.len() || engine.failed() {
        bail!("the host's own decoder refused the stream at byte {used}: an encoder bug");
    }
    Ok(sink.0)
}

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
    pub board_updates: u64,
    pub expected_updates: u64,
    pub mismatches: u64,
    pub first_mismatch: Option<Mismatch>,
    /// Bytes of the event stream (what the slave decodes).
    pub wire_bytes: u64,
    pub bytes_per_event: f64,
    /// Everything the host put on the serial line (framing, acks, retransmissions).
    pub link_bytes_sent: u64,
    pub link_bytes_received: u64,
    pub frames_corrupted: u64,
    pub frames_dropped: u64,
    pub frames_rejected_by_host: u64,
    pub played_seconds: f64,
    pub wall_seconds: f64,
    pub played_per_wall_second: f64,
    pub truth_rows: usize,
    pub final_error_m: Option<f64>,
    pub max_error_m: Option<f64>,
}

pub struct PlayRequest<'a> {
    pub robot_name: &'a str,
    pub layout: &'a Layout,
    pub method: Method,
    pub kind: PlayKind,
    pub stream: &'a crate::formats::tickstream::TickStream,
    pub progress: Option<&'a indicatif::ProgressBar>,
}

fn wire_pose(p: Pose2) -> protocol::Pose {
    protocol::Pose::from_si(p.x, p.y, p.theta)
}

/// Play `req` to the boards on `link`.
pub fn play(link: &mut Link, req: &PlayRequest) -> Result<PlayOutcome> {
    // Without a tick the board computes nothing to compare: "0 of 0 updates bit-exact" is no
    // result (replay refuses such a stream too).
    if !req
        .stream
        .events
        .iter()
        .any(|e| matches!(e, crate::formats::tickstream::Event::Tick { .. }))
    {
        bail!("the stream has no tick rows: nothing to play, nothing scored");
    }
    let info = session::hello(link)?;
    let layout = req.layout;
    let stream = super::played_stream::encode(
        req.stream,
        layout.encoders(),
        layout.abs().is_some(),
        req.kind,
        info.period_us,
    )?;
    // Both sides start from the micrometre pose on the wire.
    let start_wire = wire_pose(stream.start());
    let start = FixedPose::from_micrometres(start_wire.x_um, start_wire.y_um, start_wire.heading.0);
    let expected = expected_reports(layout, req.method, &stream, start)?;
    let fingerprint = session::load_robot(link, layout)?;
    let source = match req.kind {
        PlayKind::Ticks => SensorSource::PlayedTicks,
        PlayKind::Counts => SensorSource::PlayedCounts,
    };
    session::set_method_and_source(link, req.method, source, Reports::Poses, start_wire)?;

    let wall = Instant::now();
    let clock = |w: Instant| w.elapsed().as_micros() as u64;
    let mut tx: GbnSender<SEND_BUFFER> = GbnSender::new(DEFAULT_TIMEOUT_US);
    let mut rx: GbnReceiver<4096> = GbnReceiver::new();
    let mut offered = 0usize;
    let mut report_bytes: Vec<u8> = Vec::new();
    let mut got: Vec<Report> = Vec::new();
    let mut mismatches = 0u64;
    let mut first_mismatch = None;
    let mut last_progress = Instant::now();
    if let Some(bar) = req.progress {
        bar.set_length(expected.len() as u64);
    }
    while got.len() < expected.len() {
        offered += tx.offer(&stream.bytes[offered..]);
        while let Some(frame) = tx.poll_transmit(clock(wall)) {
            link.send(&HostToMaster::Events(frame))?;
        }
        let Some(msg) = link.recv(Duration::from_millis(5))? else {
            if last_progress.elapsed() > STALL {
                bail!(
                    "the board stopped answering after {} of {} updates ({} of {} event bytes \
                     acknowledged)",
                    got.len(),
                    expected.len(),
                    offered - tx.unacked(),
                    stream.bytes.len()
                );
            }
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
                "the slave reset after {} of {} updates: it started again from power-on, so \
                 this play is void (play it again)",
                got.len(),
                expected.len()
            ),
            _ => {}
        }
        if let Some(a) = rx.poll_ack() {
            link.send(&HostToMaster::ReportsAck(a))?;
        }
        // Whole records only; a partial one waits for its remaining bytes.
        let mut rest: &[u8] = &report_bytes;
        while let Ok((r, tail)) = postcard::take_from_bytes::<Report>(rest) {
            rest = tail;
            match r {
                Report::Pose { .. } => {
                    let i = got.len();
                    if expected.get(i) != Some(&r) {
                        mismatches += 1;
                        first_mismatch.get_or_insert_with(|| Mismatch {
                            update: i as u64 + 1,
                            board: format!("{r:?}"),
                            host: format!("{:?}", expected.get(i)),
                        });
                    }
                    got.push(r);
                    last_progress = Instant::now();
                }
                Report::BadEvents { offset } => {
                    bail!("the slave could not decode the event stream at byte {offset}")
                }
                _ => {}
            }
        }
        let consumed = report_bytes.len() - rest.len();
        report_bytes.drain(..consumed);
        if let Some(bar) = req.progress {
            bar.set_position(got.len() as u64);
        }
    }
    let wall_seconds = wall.elapsed().as_secs_f64();
    // Leave the board as it was: its power-on robot back if it had it, its own sensors.
    let power_on = robot_math::odometry::Layout::SEED_004;
    if info.robot == firmware_slave::robot_wire::layout_fingerprint(&power_on) {
        let _ = session::load_robot(link, &power_on);
    }
    let _ = session::set_method_and_source(
        link,
        req.method,
        SensorSource::Ticks,
        Reports::Off,
        protocol::Pose::default(),
    );
    let (final_error_m, max_error_m) = score(&got, &stream, start.to_pose2());
    let played_seconds = got.len() as f64 * stream.period_us as f64 * 1e-6;
    Ok(PlayOutcome {
        port: link.name().to_string(),
        robot: req.robot_name.to_string(),
        robot_fingerprint: format!("{fingerprint:08x}"),
        algorithm: req.method.name().to_string(),
        integer_method: matches!(req.method, Method::Exact | Method::Lut),
        sensor: match req.kind {
            PlayKind::Ticks => "timestamps".into(),
            PlayKind::Counts => format!("counts@{}Hz", 1e6 / stream.period_us as f64),
        },
        events: stream.events,
        samples: stream.samples,
        board_updates: got.len() as u64,
        expected_updates: expected.len() as u64,
        mismatches,
        first_mismatch,
        wire_bytes: stream.bytes.len() as u64,
        bytes_per_event: stream.bytes.len() as f64 / stream.events.max(1) as f64,
        link_bytes_sent: link.stats.bytes_sent,
        link_bytes_received: link.stats.bytes_received,
        frames_corrupted: link.stats.events_frames_corrupted,
        frames_dropped: link.stats.events_frames_dropped,
        frames_rejected_by_host: link.stats.frames_rejected,
        played_seconds,
        wall_seconds,
        played_per_wall_second: played_seconds / wall_seconds.max(1e-9),
        truth_rows: stream.truth.len(),
        final_error_m,
        max_error_m,
    })
}

/// Error of the board's poses against the truth rows: the board's pose at a row's instant is
/// interpolated between the two updates around it (the start pose before the first).
fn score(reports: &[Report], stream: &PlayedStream, start: Pose2) -> (Option<f64>, Option<f64>) {
    let poses: Vec<Pose2> = std::iter::once(start)
        .chain(reports.iter().filter_map(|r| match *r {
            Report::Pose { pose, .. } => {
                let (x, y, th) = pose.to_si();
                Some(Pose2::new(x, y, th))
            }
            _ => None,
        }))
        .collect();
    let p_ns = stream.period_us as f64 * 1e3;
    let mut last = None;
    let mut max = 0.0f64;
    for &(t_ns, truth) in &stream.truth {
        let k = t_ns as f64 / p_ns;
        let i = k.floor() as usize;
        if i + 1 >= poses.len() && i >= poses.len() {
            continue; // past the last update
        }
        let a = poses[i.min(poses.len() - 1)];
        let b = poses[(i + 1).min(poses.len() - 1)];
        let f = k - k.floor();
        let est = Pose2::new(a.x + (b.x - a.x) * f, a.y + (b.y - a.y) * f, a.theta);
        let e = est.distance_to(truth);
        max = max.max(e);
        last = Some(e);
    }
    (last, last.map(|_| max))
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
