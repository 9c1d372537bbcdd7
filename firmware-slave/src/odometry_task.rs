//! The odometry task: every update period, read the sensors (the board's, or the events the
//! host plays), apply the master's command, integrate, report, publish.
//!
//! Sources ([`SensorSource`]): the board's own encoders, every edge time-stamped (`Ticks`,
//! the default) or the timers' counts (`Counts`); or played events (`PlayedTicks`,
//! `PlayedCounts`) run through [`PlayedSensors`] in played time, as fast as they arrive. The
//! robot can be replaced at run time (an upload of [`protocol::robot`] parts).

use core::mem::MaybeUninit;

use embassy_time::{Duration, Instant, Ticker};
use postcard::experimental::max_size::MaxSize;
use protocol::spi::{
    frame_report, slave_status, PoseChecks, Report, Reports, SensorSource, SlaveCommand, SlaveFrame,
};
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
    fn bytes(&self) -> &[u8] {
        &self.buf[..self.len]
    }
}

/// Playing: records back to back. `play` compares every update in order and stops at a record
/// it cannot read, so framing would cost 2 bytes an update for nothing.
impl ReportSink for Staged {
    fn has_room(&self) -> bool {
        self.len + Report::POSTCARD_MAX_SIZE <= self.limit
    }
    fn push(&mut self, r: Report) {
        if let Ok(b) = protocol::to_slice(&r, &mut self.buf[self.len..self.limit]) {
            self.len += b.len();
        }
    }
}

/// Recording: each record framed, so `record` can pass over one it cannot read and read on.
impl RecordSink for Staged {
    fn put(&mut self, r: &Report) -> bool {
        match frame_report(r, &mut self.buf[self.len..self.limit]) {
            Some(n) => {
                self.len += n;
                true
            }
            None => false,
        }
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

/// Everything the odometry task keeps from one update to the next: kilobytes (two
/// estimators with their robot layouts), so it is built in place where the task keeps it
/// (on the board the task's static cell, see [`odometry_task`]) and changed in place: a
/// value this size built on a 20 KiB board's stack, or inlined into the task's poll function,
/// is what once overflowed it.
pub struct Odometer {
    estimator: SlaveEstimator,
    /// The played sensors, meaningful while `playing`.
    played: PlayedSensors,
    playing: bool,
    recorder: Recorder,
    upload: Upload,
    /// The robot the estimator runs, and its fingerprint.
    layout: Layout,
    robot: u32,
    /// A robot just committed, until the estimator takes it.
    uploaded: Layout,
    source: SensorSource,
    reports: Reports,
    sticky: u16,
    extenders: [CounterExtender; MEASURING_WHEELS],
    seq: u16,
    next_due: Instant,
    measured: crate::ports::UpdateCycles,
}

/// The board's readings at one update, and the flags they raised.
struct Readings {
    levels: u8,
    now: Instant,
    t_ns: u64,
    t_us: u64,
    status: u16,
    totals: [i64; MEASURING_WHEELS],
    /// The counters were read together with the edges handed over (no edge in between).
    matched: bool,
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
    // The task's state lives in the task's own storage (a static cell on the board: the
    // future is built there before its first poll), built in place: nothing of it passes
    // through the stack.
    let mut slot = MaybeUninit::uninit();
    let Some(odometer) = Odometer::start(&mut slot, &mut counters, &mut edges, &mut abs, config)
    else {
        // A layout the slave cannot run is a build mistake: publish nothing, so the master's
        // freshness watchdog sees a dead slave and keeps the motors off.
        loop {
            embassy_time::Timer::after_secs(3600).await;
        }
    };
    let mut ticker = Ticker::every(period);
    odometer.next_due = Instant::now() + period;
    loop {
        ticker.next().await;
        odometer.update(
            &mut counters,
            &mut edges,
            &mut abs,
            shared,
            config,
            clock,
            &mut cycles,
        );
    }
}

impl Odometer {
    /// Build the state in `slot`, the estimator started on the board's readings; `None` if
    /// the estimator cannot run the configured robot.
    #[inline(never)]
    fn start<'a>(
        slot: &'a mut MaybeUninit<Odometer>,
        counters: &mut impl QuadratureCounters,
        edges: &mut impl EncoderEdges,
        abs: &mut impl AbsoluteEncoderPins,
        config: &SlaveConfig,
    ) -> Option<&'a mut Odometer> {
        let (raw, edge_levels) = if config.sensor == SensorMode::TickTimestamps {
            start_edges(edges, counters)
        } else {
            (counters.read_raw(), edges.levels())
        };
        let o = Odometer::init(slot, config);
        o.extenders = raw.map(CounterExtender::new);
        let totals = o.extenders.map(|e| e.total());
        let started = o.estimator.restart(
            config.layout(),
            config.sensor,
            Instant::now().as_micros() * 1000,
            &totals,
            &edge_levels,
            abs.read_levels() as u16,
        );
        started.ok().map(|()| o)
    }

    /// Every field written in place; the estimators at rest on the configured robot.
    fn init<'a>(slot: &'a mut MaybeUninit<Odometer>, config: &SlaveConfig) -> &'a mut Odometer {
        let layout = config.layout();
        robot_math::init_in_place!(
            slot,
            Odometer {
                playing: false,
                recorder: Recorder::new(),
                upload: Upload::default(),
                layout: *layout,
                robot: config.power_on_fingerprint(),
                uploaded: *layout,
                source: match config.sensor {
                    SensorMode::Counts => SensorSource::Counts,
                    SensorMode::TickTimestamps => SensorSource::Ticks,
                },
                reports: Reports::Off,
                sticky: 0,
                extenders: [CounterExtender::new(0); MEASURING_WHEELS],
                seq: 0,
                next_due: Instant::from_ticks(0),
                measured: Default::default(),
            } in_place {
                estimator: SlaveEstimator::init(layout),
                played: PlayedSensors::init(layout),
            }
        )
    }

    /// One fixed-rate update: sample, apply the master's command, integrate, report, publish.
    // Out of line: its locals (a report stage, the readings) are this function's frame, which
    // the stack holds only while it runs, not the task's poll function's.
    #[allow(clippy::too_many_arguments)]
    #[inline(never)]
    fn update(
        &mut self,
        counters: &mut impl QuadratureCounters,
        edges: &mut impl EncoderEdges,
        abs: &mut impl AbsoluteEncoderPins,
        shared: &SlaveShared,
        config: &SlaveConfig,
        clock: crate::FrameClock,
        cycles: &mut impl crate::ports::CycleCounter,
    ) {
        let started = cycles.cycles();
        let recording = match self.reports {
            Reports::Record { pose_every } => Some(pose_every),
            _ => None,
        };
        let mut staged = Staged::new(shared.report_room());
        let mut r = self.read(
            counters,
            edges,
            abs,
            config,
            recording.is_some(),
            &mut staged,
        );

        // Commands: robot uploads and sources here, the rest to the estimator.
        let command = shared.take_command();
        let (for_estimator, new_streams) =
            self.apply_command(command.map(|(_, c)| c), shared, config, &r, edges);
        if new_streams {
            // After the estimator's restart, which reads the edge levels as close to the
            // drain as it can (an edge in between would leave its decoder a step out).
            self.recorder = Recorder::new();
            staged = Staged::new(shared.report_room());
            if let Reports::Record { .. } = self.reports {
                // The absolute encoder first: a recording must say where it starts.
                self.recorder.abs(&mut staged, r.t_us, r.levels as u16);
            }
        }
        if let Some((command_seq, _)) = command {
            shared.acknowledge(command_seq);
        }

        let (pose, algorithm) =
            self.integrate(shared, &mut staged, &mut r, recording, for_estimator);
        shared.push_reports(staged.bytes());

        self.seq = self.seq.wrapping_add(1);
        let frame = SlaveFrame {
            seq: self.seq,
            time_us: clock.us(r.now),
            pose: wire_pose(pose),
            status: r.status | self.sticky,
            algorithm,
            robot: self.robot,
            source: self.source,
            period_us: config.update_period_us,
            ..SlaveFrame::default()
        };
        shared.publish(&frame, pose);
        if let (Some(a), Some(b)) = (started, cycles.cycles()) {
            self.measured.add(b.wrapping_sub(a));
            if self.measured.updates as u64 * config.update_period_us as u64 >= 1_000_000 {
                cycles.report(&self.measured);
                self.measured = Default::default();
            }
        }
    }

    /// Sample the board: the absolute encoder first, as close to the tick as possible; then
    /// the edges, into the estimator when it reads them (and to the recorder), else drained
    /// and dropped so the queue never overflows, with the timers as they stood when the last
    /// edge was handed over.
    fn read(
        &mut self,
        counters: &mut impl QuadratureCounters,
        edges: &mut impl EncoderEdges,
        abs: &mut impl AbsoluteEncoderPins,
        config: &SlaveConfig,
        recording: bool,
        staged: &mut Staged,
    ) -> Readings {
        let levels = abs.read_levels();
        let now = Instant::now();
        let period = Duration::from_micros(config.update_period_us as u64);
        // This update's own flags; the sticky ones join them when the frame is made, as the
        // commands leave them (an installed robot's frame must not still say rejected).
        let mut status = slave_status::RUNNING;
        if now > self.next_due + period {
            status |= slave_status::OVERRUN;
        }
        self.next_due = now + period;
        let ticks_live = self.source == SensorSource::Ticks;
        let (estimator, recorder) = (&mut self.estimator, &mut self.recorder);
        let batch = edges.drain(|e| {
            if !ticks_live {
                return;
            }
            if let Some(step) = estimator.on_edge(e) {
                if recording {
                    recorder.tick(staged, e.t_us, e.encoder, step);
                }
            }
        });
        if ticks_live && !batch.complete {
            self.estimator.edges_lost();
        }
        let (raw, matched) = match batch.counters {
            Some(c) => (c, ticks_live),
            None => (counters.read_raw(), false),
        };
        let mut totals = [0i64; MEASURING_WHEELS];
        for ((total, ext), raw) in totals.iter_mut().zip(&mut self.extenders).zip(raw) {
            let (t, jumped) = ext.update(raw);
            *total = t;
            if jumped {
                status |= slave_status::COUNTER_JUMP;
            }
        }
        Readings {
            levels,
            now,
            t_ns: now.as_micros() * 1000,
            t_us: now.as_micros(),
            status,
            totals,
            matched,
        }
    }

    /// The master's command: robot uploads and sensor sources are the task's, the rest is the
    /// estimator's (returned, with a set-pose after a live source's restart). Also says
    /// whether the report streams restarted.
    #[inline(never)]
    fn apply_command(
        &mut self,
        command: Option<SlaveCommand>,
        shared: &SlaveShared,
        config: &SlaveConfig,
        r: &Readings,
        edges: &mut impl EncoderEdges,
    ) -> (Option<SlaveCommand>, bool) {
        // A committed robot, or a live source, restarts the estimator; in one place below
        // (each place the slave built one took ~0.3 KB of flash).
        let (restart, new_streams) = match command {
            Some(SlaveCommand::RobotWheel(p)) => {
                self.upload.wheel(p);
                (None, false)
            }
            Some(SlaveCommand::RobotExact(p)) => {
                self.upload.exact(p);
                (None, false)
            }
            Some(SlaveCommand::RobotCommit(h)) => {
                match self.upload.commit(&h, &mut self.uploaded) {
                    Ok(()) => {
                        let mode = live_mode(self.source);
                        (
                            self.restart(mode, Some(h.fingerprint), None, r, edges),
                            false,
                        )
                    }
                    Err(_) => {
                        self.sticky |= slave_status::ROBOT_REJECTED;
                        (None, false)
                    }
                }
            }
            Some(SlaveCommand::SetSource {
                source,
                reports,
                start,
            }) => {
                self.reports = reports;
                let for_estimator = self.set_source(source, start, shared, config, r, edges);
                (for_estimator, true)
            }
            other => return (other, false),
        };
        (restart, new_streams)
    }

    /// A new sensor source (and report stream, `self.reports`): played sensors restarted in
    /// place, or the estimator on a live source, from `start` with the method that ran before.
    fn set_source(
        &mut self,
        source: SensorSource,
        start: protocol::Pose,
        shared: &SlaveShared,
        config: &SlaveConfig,
        r: &Readings,
        edges: &mut impl EncoderEdges,
    ) -> Option<SlaveCommand> {
        // Both streams restart before the master learns (by the ack) that they did.
        shared.restart_streams(source.is_played());
        let method = method_of(self.estimator.algorithm());
        self.playing = false;
        self.sticky &= !slave_status::EVENTS_BAD;
        self.source = source;
        if !source.is_played() {
            return self.restart(live_mode(source), None, Some((start, method)), r, edges);
        }
        let kind = if source == SensorSource::PlayedTicks {
            PlayKind::Ticks
        } else {
            PlayKind::Counts
        };
        let start = FixedPose::from_micrometres(start.x_um, start.y_um, start.heading.0);
        let period = config.update_period_us;
        let checks = match self.reports {
            Reports::Poses(checks) => checks,
            _ => PoseChecks::ALL,
        };
        match self
            .played
            .restart(&self.layout, method, kind, period, start, checks)
        {
            Ok(()) => self.playing = true,
            Err(_) => self.sticky |= slave_status::ALGORITHM_UNSUPPORTED,
        }
        None
    }

    /// The estimator started again in place on the board's readings: on the robot just
    /// committed (`robot`: its fingerprint), or from a live source's start pose with the
    /// method that ran before (returned as the set-pose command for this update).
    fn restart(
        &mut self,
        mode: SensorMode,
        robot: Option<u32>,
        start: Option<(protocol::Pose, robot_math::odometry::Method)>,
        r: &Readings,
        edges: &mut impl EncoderEdges,
    ) -> Option<SlaveCommand> {
        let layout = if robot.is_some() {
            &self.uploaded
        } else {
            &self.layout
        };
        let abs = r.levels as u16;
        let levels = edges.levels();
        let started = self
            .estimator
            .restart(layout, mode, r.t_ns, &r.totals, &levels, abs);
        if started.is_err() {
            // `exact` runs every checked layout, so this is not expected; the robot that ran
            // runs on, from the origin.
            if robot.is_some() {
                self.sticky |= slave_status::ROBOT_REJECTED;
                let _ =
                    (self.estimator).restart(&self.layout, mode, r.t_ns, &r.totals, &levels, abs);
            }
            return None;
        }
        if let Some(fingerprint) = robot {
            self.layout = self.uploaded;
            self.robot = fingerprint;
            self.sticky &= !slave_status::ROBOT_REJECTED;
        }
        let (start, method) = start?;
        // Keep the method the host chose (refused: flagged, as a switch is). Only a build
        // with the float methods can be running another: the default image refuses every
        // switch away from `exact`, and leaves this out (216 B of its flash).
        if robot_math::odometry::FLOAT_METHODS && method != robot_math::odometry::Method::Exact {
            let switch = SlaveCommand::SetAlgorithm(crate::algorithm_of(method));
            let _ = self
                .estimator
                .sample(r.t_ns, &r.totals, false, abs, Some(switch));
        }
        Some(SlaveCommand::SetPose(start))
    }

    /// This update's pose: from the played sensors (as far as the played events go), or from
    /// the estimator on the board's readings (recorded when recording).
    fn integrate(
        &mut self,
        shared: &SlaveShared,
        staged: &mut Staged,
        r: &mut Readings,
        recording: Option<u16>,
        for_estimator: Option<SlaveCommand>,
    ) -> (FixedPose, protocol::spi::OdometryAlgorithm) {
        if self.playing {
            let p = &mut self.played;
            play_pass(p, shared, staged);
            if p.failed() {
                self.sticky |= slave_status::EVENTS_BAD;
            }
            let odometry = p.odometry();
            return (odometry.pose(), crate::algorithm_of(odometry.method()));
        }
        let levels = r.levels as u16;
        let update = (self.estimator).sample(r.t_ns, &r.totals, r.matched, levels, for_estimator);
        r.status |= update.status;
        if let Some(pose_every) = recording {
            if self.source == SensorSource::Counts {
                // Counts mode: each update's count changes as ticks at its instant.
                record_counts(&mut self.recorder, staged, r.t_us, &self.estimator);
            }
            self.recorder.abs(staged, r.t_us, levels);
            let pose = wire_pose(update.pose);
            self.recorder.update(staged, r.t_us, pose, pose_every);
        }
        (update.pose, update.algorithm)
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
