//! The odometry task: every update period, read the sensors (the board's, or the events the
//! host plays), apply the master's command, integrate, report, publish.
//!
//! Sources ([`SensorSource`]): the board's own encoders, every edge time-stamped (`Ticks`,
//! the default) or the timers' counts (`Counts`); or played events (`PlayedTicks`,
//! `PlayedCounts`) run through [`PlayedSensors`] in played time, as fast as they arrive. The
//! robot can be replaced at run time (an upload of [`protocol::robot`] parts).

use embassy_time::{Duration, Instant, Ticker};
use postcard::experimental::max_size::MaxSize;
use protocol::spi::{slave_status, Report, Reports, SensorSource, SlaveCommand, SlaveFrame};
use robot_math::exact::FixedPose;
use robot_math::odometry::Layout;
use robot_math::sensors::CounterExtender;

use crate::played::{PlayKind, PlayedSensors, ReportSink};
use crate::ports::{AbsoluteEncoderPins, EncoderEdges, QuadratureCounters, MEASURING_WHEELS};
use crate::recorder::{RecordSink, Recorder};
use crate::robot_wire::Upload;
use crate::{method_of, SensorMode, SlaveConfig, SlaveEstimator, SlaveShared};

/// Report bytes staged per pass before they go to the shared stream.
const STAGE: usize = 256;

/// Reports staged locally (outside the shared state's critical section), bounded by the room
/// the shared report stream had when the pass began.
struct Staged {
    buf: [u8; STAGE],
    len: usize,
    limit: usize,
}

impl Staged {
    fn new(room: usize) -> Self {
        Staged {
            buf: [0; STAGE],
            len: 0,
            limit: room.min(STAGE),
        }
    }
    fn put(&mut self, r: &Report) -> bool {
        if self.len + Report::POSTCARD_MAX_SIZE > self.limit {
            return false;
        }
        match protocol::to_slice(r, &mut self.buf[self.len..self.limit]) {
            Ok(b) => {
                self.len += b.len();
                true
            }
            Err(_) => false,
        }
    }
    fn bytes(&self) -> &[u8] {
        &self.buf[..self.len]
    }
}

impl ReportSink for Staged {
    fn has_room(&self) -> bool {
        self.len + Report::POSTCARD_MAX_SIZE <= self.limit
    }
    fn push(&mut self, r: Report) {
        self.put(&r);
    }
}

impl RecordSink for Staged {
    fn put(&mut self, r: &Report) -> bool {
        Staged::put(self, r)
    }
}

fn live_mode(source: SensorSource) -> SensorMode {
    match source {
        SensorSource::Counts | SensorSource::PlayedCounts => SensorMode::Counts,
        _ => SensorMode::TickTimestamps,
    }
}

// Called at two places and kept out of line: on the board the tasks are one function the
// executor polls, and inlined there it cost more flash than a call (docs/performance.md,
// "Images, eleventh round").
#[inline(never)]
fn wire_pose(p: FixedPose) -> protocol::Pose {
    let (x_um, y_um) = p.micrometres();
    protocol::Pose {
        x_um,
        y_um,
        heading: protocol::BinaryAngle(p.heading_bam()),
    }
}

/// How the estimator restarts after a command: in which mode, with a committed robot (its
/// layout and fingerprint, installed only if the estimator takes it), from a source's start
/// pose with the method that ran before.
struct Restart {
    mode: SensorMode,
    robot: Option<(Layout, u32)>,
    start: Option<(protocol::Pose, robot_math::odometry::Method)>,
}

/// Fixed-rate sampling and pose integration.
pub async fn odometry_task(
    mut counters: impl QuadratureCounters,
    mut edges: impl EncoderEdges,
    mut abs: impl AbsoluteEncoderPins,
    shared: &SlaveShared,
    config: &SlaveConfig,
    clock: crate::FrameClock,
    mut cycles: impl crate::ports::CycleCounter,
) -> ! {
    let period = Duration::from_micros(config.update_period_us as u64);
    let (raw, edge_levels) = if config.sensor == SensorMode::TickTimestamps {
        start_edges(&mut edges, &mut counters)
    } else {
        (counters.read_raw(), edges.levels())
    };
    let mut extenders = raw.map(CounterExtender::new);
    let mut layout: Layout = *config.layout();
    let mut robot = config.power_on_fingerprint();
    let mut source = match config.sensor {
        SensorMode::Counts => SensorSource::Counts,
        SensorMode::TickTimestamps => SensorSource::Ticks,
    };
    let start = SlaveEstimator::new(
        &layout,
        config.sensor,
        Instant::now().as_micros() * 1000,
        &extenders.map(|e| e.total()),
        &edge_levels,
        abs.read_levels() as u16,
    );
    let Ok(mut estimator) = start else {
        // A layout the slave cannot run is a build mistake: publish nothing, so the master's
        // freshness watchdog sees a dead slave and keeps the motors off.
        loop {
            embassy_time::Timer::after_secs(3600).await;
        }
    };
    let mut reports = Reports::Off;
    let mut played: Option<PlayedSensors> = None;
    let mut recorder = Recorder::new();
    let mut upload = Upload::default();
    let mut sticky = 0u16;
    let mut ticker = Ticker::every(period);
    let mut next_due = Instant::now() + period;
    let mut seq: u16 = 0;
    let mut measured = crate::ports::UpdateCycles::default();
    loop {
        ticker.next().await;
        let started = cycles.cycles();
        // Sample first, as close to the tick as possible; everything else can wait.
        let levels = abs.read_levels();
        let now = Instant::now();
        let t_ns = now.as_micros() * 1000;
        let t_us = now.as_micros();
        // This update's own flags; the sticky ones join them when the frame is made, as the
        // commands below leave them (an installed robot's frame must not still say rejected).
        let mut status = slave_status::RUNNING;
        if now > next_due + period {
            status |= slave_status::OVERRUN;
        }
        next_due = now + period;
        let recording = match reports {
            Reports::Record { pose_every } => Some(pose_every),
            _ => None,
        };
        let mut staged = Staged::new(shared.report_room());

        // The board's edges: into the estimator when it reads them (and to the recorder),
        // else drained and dropped so the queue never overflows; with the timers as they
        // stood when the last edge was handed over.
        let ticks_live = source == SensorSource::Ticks;
        let batch = edges.drain(|e| {
            if !ticks_live {
                return;
            }
            if let Some(step) = estimator.on_edge(e) {
                if recording.is_some() {
                    recorder.tick(&mut staged, e.t_us, e.encoder, step);
                }
            }
        });
        if ticks_live && !batch.complete {
            estimator.edges_lost();
        }
        let (raw, matched) = match batch.counters {
            Some(c) => (c, ticks_live),
            None => (counters.read_raw(), false),
        };
        let mut totals = [0i64; MEASURING_WHEELS];
        for ((total, ext), raw) in totals.iter_mut().zip(&mut extenders).zip(raw) {
            let (t, jumped) = ext.update(raw);
            *total = t;
            if jumped {
                status |= slave_status::COUNTER_JUMP;
            }
        }

        // Commands: robot uploads and sources here, the rest to the estimator.
        let command = shared.take_command();
        let mut for_estimator = None;
        // A committed robot, or a live source, restarts the estimator; in one place below
        // (each place the slave built one took ~0.3 KB of flash).
        let mut restart: Option<Restart> = None;
        let mut new_streams = false;
        match command.map(|(_, c)| c) {
            Some(SlaveCommand::RobotWheel(p)) => upload.wheel(p),
            Some(SlaveCommand::RobotExact(p)) => upload.exact(p),
            Some(SlaveCommand::RobotCommit(h)) => match upload.commit(&h) {
                Ok(l) => {
                    restart = Some(Restart {
                        mode: live_mode(source),
                        robot: Some((l, h.fingerprint)),
                        start: None,
                    })
                }
                Err(_) => sticky |= slave_status::ROBOT_REJECTED,
            },
            Some(SlaveCommand::SetSource {
                source: s,
                reports: r,
                start,
            }) => {
                // Both streams restart before the master learns (by the ack below) that they did.
                shared.restart_streams(s.is_played());
                let start_pose =
                    FixedPose::from_micrometres(start.x_um, start.y_um, start.heading.0);
                let method = method_of(estimator.algorithm());
                played = None;
                sticky &= !slave_status::EVENTS_BAD;
                if s.is_played() {
                    let kind = if s == SensorSource::PlayedTicks {
                        PlayKind::Ticks
                    } else {
                        PlayKind::Counts
                    };
                    match PlayedSensors::new(
                        &layout,
                        method,
                        kind,
                        config.update_period_us,
                        start_pose,
                    ) {
                        Ok(p) => played = Some(p),
                        Err(_) => sticky |= slave_status::ALGORITHM_UNSUPPORTED,
                    }
                } else {
                    restart = Some(Restart {
                        mode: live_mode(s),
                        robot: None,
                        start: Some((start, method)),
                    });
                }
                source = s;
                reports = r;
                new_streams = true;
            }
            other => for_estimator = other,
        }
        if let Some(r) = restart {
            let fresh = SlaveEstimator::new(
                r.robot.as_ref().map_or(&layout, |(l, _)| l),
                r.mode,
                t_ns,
                &totals,
                &edges.levels(),
                levels as u16,
            );
            match fresh {
                Ok(e) => {
                    estimator = e;
                    if let Some((l, fingerprint)) = r.robot {
                        layout = l;
                        robot = fingerprint;
                        sticky &= !slave_status::ROBOT_REJECTED;
                    }
                    if let Some((start, method)) = r.start {
                        for_estimator = Some(SlaveCommand::SetPose(start));
                        // Keep the method the host chose (refused: flagged, as a switch is).
                        // Only a build with the float methods can be running another: the
                        // default image refuses every switch away from `exact`, and leaves this
                        // out (216 B of its flash).
                        if robot_math::odometry::FLOAT_METHODS
                            && method != robot_math::odometry::Method::Exact
                        {
                            let _ = estimator.sample(
                                t_ns,
                                &totals,
                                false,
                                levels as u16,
                                Some(SlaveCommand::SetAlgorithm(crate::algorithm_of(method))),
                            );
                        }
                    }
                }
                Err(_) => {
                    if r.robot.is_some() {
                        sticky |= slave_status::ROBOT_REJECTED;
                    }
                }
            }
        }
        if new_streams {
            // After the estimator's restart, which reads the edge levels as close to the
            // drain above as it can (an edge in between would leave its decoder a step out).
            recorder = Recorder::new();
            staged = Staged::new(shared.report_room());
            if let Reports::Record { .. } = reports {
                // The absolute encoder first: a recording must say where it starts.
                recorder.abs(&mut staged, t_us, levels as u16);
            }
        }
        if let Some((command_seq, _)) = command {
            shared.acknowledge(command_seq);
        }

        let (pose, algorithm) = if let Some(p) = played.as_mut() {
            play_pass(p, shared, &mut staged);
            if p.failed() {
                sticky |= slave_status::EVENTS_BAD;
            }
            (
                p.odometry().pose(),
                crate::algorithm_of(p.odometry().method()),
            )
        } else {
            let update = estimator.sample(t_ns, &totals, matched, levels as u16, for_estimator);
            status |= update.status;
            if let Some(pose_every) = recording {
                if source == SensorSource::Counts {
                    // Counts mode: each update's count changes as ticks at its instant.
                    record_counts(&mut recorder, &mut staged, t_us, &estimator);
                }
                recorder.abs(&mut staged, t_us, levels as u16);
                recorder.update(&mut staged, t_us, wire_pose(update.pose), pose_every);
            }
            (update.pose, update.algorithm)
        };
        shared.push_reports(staged.bytes());

        seq = seq.wrapping_add(1);
        let frame = SlaveFrame {
            seq,
            time_us: clock.us(now),
            pose: wire_pose(pose),
            status: status | sticky,
            algorithm,
            robot,
            source,
            period_us: config.update_period_us,
            ..SlaveFrame::default()
        };
        shared.publish(&frame, pose);
        if let (Some(a), Some(b)) = (started, cycles.cycles()) {
            measured.add(b.wrapping_sub(a));
            if measured.updates as u64 * config.update_period_us as u64 >= 1_000_000 {
                cycles.report(&measured);
                measured = Default::default();
            }
        }
    }
}

/// Counts since the last recorded update, per encoder.
fn record_counts(
    recorder: &mut Recorder,
    staged: &mut Staged,
    t_us: u64,
    estimator: &SlaveEstimator,
) {
    let counts = estimator.counts();
    let last = recorder.last_counts(counts);
    for (j, (&c, &l)) in counts.iter().zip(last.iter()).enumerate() {
        let d = c - l;
        let step = if d > 0 { 1 } else { -1 };
        for _ in 0..d.unsigned_abs().min(10_000) {
            recorder.tick(staged, t_us, j as u8, step);
        }
    }
}

/// Feed the played events that arrived, as far as report room allows.
fn play_pass(p: &mut PlayedSensors, shared: &SlaveShared, staged: &mut Staged) {
    let mut buf = [0u8; 64];
    loop {
        // Fed even with no new bytes: an event held back for report room finishes then.
        let n = shared.peek_events(&mut buf);
        let used = p.feed(&buf[..n], staged);
        shared.consume_events(used);
        if n == 0 || used < n || p.failed() {
            return;
        }
    }
}

/// Where edge decoding starts: the A/B levels and the timer counts at one instant. An edge
/// between reading the levels and the counters would leave the decoded count one off the
/// timers for good (a false lost edge at every update), so read the levels between two
/// drains and accept them only when no edge came in between (the second drain is empty and
/// the timers did not move). Edges drained here happened before the start: discarded.
fn start_edges(
    edges: &mut impl EncoderEdges,
    counters: &mut impl QuadratureCounters,
) -> ([u16; MEASURING_WHEELS], [u8; MEASURING_WHEELS]) {
    for _ in 0..8 {
        let before = edges.drain(|_| {}).counters;
        let levels = edges.levels();
        let mut quiet = true;
        let after = edges.drain(|_| quiet = false).counters;
        if let (true, Some(b), Some(a)) = (quiet, before, after) {
            if a == b {
                return (a, levels);
            }
        }
    }
    // Edges never stopped for a moment: start anyway; a one-off shows as EDGES_LOST.
    (counters.read_raw(), edges.levels())
}
