//! Played sensors: the slave's odometry fed from a stream of recorded events instead of its
//! timers and edge interrupts, in played time (SPEC §1 `play`).
//!
//! Sans-IO and shared: the slave runs it on the bytes the master forwards, and `host-bench
//! play` runs this very code on the bytes it sends, so the two must produce the same poses,
//! bit for bit (a difference is a bug, never a tolerance).
//!
//! Played time: update `k` (k = 1, 2, ...) happens at `k · period` of the stream's clock and
//! takes in every event up to and including that instant; each update reports its pose. In
//! counts mode every sample is one update.
//!
//! The start: odometry starts at the given pose with every count zero and the absolute encoder
//! at position 0, until the stream says where it stands: an absolute reading at played time 0
//! that comes before anything else (the player sends the stream's start reading first), or in
//! counts mode the first sample's reading, starts it again there, as `replay` starts at the
//! stream's first reading. (Started at position 0, a carriage whose swivel stood elsewhere
//! rolled its whole track turned by the difference.)

use core::mem::MaybeUninit;

use protocol::events::{Event, EventDecoder, Sample, SampleDecoder, Step};
use protocol::spi::{pose_digest, PoseChecks, Report};
use robot_math::exact::{FixedPose, MAX_ENCODERS};
use robot_math::odometry::{Layout, Method, Odometry, SensorKind, Unsupported};

/// Where the reports go: a bounded buffer (the slave's report stream) or a host-side list.
pub trait ReportSink {
    /// Room for one more report of any kind.
    fn has_room(&self) -> bool;
    fn push(&mut self, report: Report);
}

/// What the played stream holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PlayKind {
    /// Time-stamped ticks and absolute readings ([`protocol::events`] edge code).
    Ticks,
    /// One count sample per update ([`protocol::events`] counts code).
    Counts,
}

enum Decoder {
    Ticks(EventDecoder),
    Counts(SampleDecoder),
}

enum Pending {
    Event(Event),
    Sample(Sample),
}

pub struct PlayedSensors {
    odometry: Odometry,
    decoder: Decoder,
    period_ns: u64,
    /// Played time of the next update.
    next_update_ns: u64,
    /// Cumulative counts (counts mode).
    counts: [i64; MAX_ENCODERS],
    /// A decoded event or sample that could not be finished for lack of report room.
    pending: Option<Pending>,
    /// Stream bytes consumed so far.
    offset: u32,
    /// Set when the stream failed to decode; nothing more is taken.
    failed: bool,
    updates: u32,
    /// Nothing taken in yet: a reading now is where the absolute encoder starts.
    at_start: bool,
    /// Which updates are reported.
    checks: PoseChecks,
    /// The running digest of every update's pose so far.
    digest: u32,
}

/// The played-sensor kind an odometry method needs.
fn sensor_kind(kind: PlayKind) -> SensorKind {
    match kind {
        PlayKind::Ticks => SensorKind::Ticks,
        PlayKind::Counts => SensorKind::Counts,
    }
}

impl PlayedSensors {
    /// Start at `start` at played time 0, all counts zero, reporting the updates `checks`
    /// picks.
    ///
    /// By value, for the host; the board builds its played sensors in place
    /// ([`init`](Self::init) and [`restart`](Self::restart)).
    pub fn new(
        layout: &Layout,
        method: Method,
        kind: PlayKind,
        period_us: u32,
        start: FixedPose,
        checks: PoseChecks,
    ) -> Result<Self, Unsupported> {
        let mut slot = MaybeUninit::uninit();
        PlayedSensors::init(&mut slot, layout)
            .restart(layout, method, kind, period_us, start, checks)?;
        // SAFETY: `init` wrote every field.
        Ok(unsafe { slot.assume_init() })
    }

    /// Build played sensors in place in `slot` (the board's static cell), as a start for
    /// [`restart`](Self::restart): `exact` over `layout` reading counts, nothing played,
    /// failed (so nothing is taken in before a restart). Cannot fail.
    pub fn init<'a>(slot: &'a mut MaybeUninit<Self>, layout: &Layout) -> &'a mut Self {
        robot_math::init_in_place!(
            slot,
            PlayedSensors {
                decoder: Decoder::Counts(SampleDecoder::new()),
                period_ns: 1000,
                next_update_ns: 1000,
                counts: [0; MAX_ENCODERS],
                pending: None,
                offset: 0,
                failed: true,
                updates: 0,
                at_start: true,
                checks: PoseChecks::ALL,
                digest: 0,
            } in_place {
                odometry: Odometry::init(layout),
            }
        )
    }

    /// Start again in place, as [`new`](Self::new) would have started. On `Err` (a method
    /// this build lacks) the sensors are failed: they take nothing in until the next restart.
    pub fn restart(
        &mut self,
        layout: &Layout,
        method: Method,
        kind: PlayKind,
        period_us: u32,
        start: FixedPose,
        checks: PoseChecks,
    ) -> Result<(), Unsupported> {
        let started = self.odometry.restart(
            layout,
            method,
            sensor_kind(kind),
            start,
            0,
            &[0; MAX_ENCODERS],
            None,
        );
        let period_ns = (period_us.max(1) as u64) * 1000;
        self.decoder = match kind {
            PlayKind::Ticks => Decoder::Ticks(EventDecoder::new()),
            PlayKind::Counts => Decoder::Counts(SampleDecoder::new()),
        };
        self.period_ns = period_ns;
        self.next_update_ns = period_ns;
        self.counts = [0; MAX_ENCODERS];
        self.pending = None;
        self.offset = 0;
        self.failed = started.is_err();
        self.updates = 0;
        self.at_start = true;
        self.checks = checks;
        self.digest = 0;
        started
    }

    /// Start again as [`PlayedSensors::restart`] did, but with the absolute encoder at
    /// `code`: the odometry restarted in place from its own settings.
    fn start_at_abs(&mut self, code: u16) {
        let o = &mut self.odometry;
        let (method, sensors, pose) = (o.method(), o.sensors(), o.pose());
        // What `restart` started from these same settings; it cannot fail now.
        let zeros = [0; MAX_ENCODERS];
        let _ = o.restart_on_own_layout(method, sensors, pose, 0, &zeros, Some(code));
    }

    pub fn odometry(&self) -> &Odometry {
        &self.odometry
    }

    /// Updates done so far.
    pub fn updates(&self) -> u32 {
        self.updates
    }

    /// Played time of the last update, microseconds.
    pub fn played_us(&self) -> u64 {
        (self.next_update_ns - self.period_ns) / 1000
    }

    pub fn failed(&self) -> bool {
        self.failed
    }

    /// Take in stream bytes, reporting into `sink`. Room is checked before each update, so a
    /// report is never lost: when the sink is full, feeding stops and the bytes not consumed
    /// must be offered again. Returns the bytes consumed.
    pub fn feed(&mut self, bytes: &[u8], emit: &mut dyn ReportSink) -> usize {
        if !self.finish_pending(emit) {
            return 0;
        }
        let mut used = 0;
        for &b in bytes {
            if self.failed {
                break;
            }
            used += 1;
            self.offset = self.offset.wrapping_add(1);
            let decoded = match &mut self.decoder {
                Decoder::Ticks(d) => d.push(b).map(|r| r.map(Pending::Event)),
                Decoder::Counts(d) => d.push(b).map(|r| r.map(Pending::Sample)),
            };
            match decoded {
                None => {}
                Some(Ok(p)) => {
                    self.pending = Some(p);
                    if !self.finish_pending(emit) {
                        break;
                    }
                }
                Some(Err(_)) => {
                    // Reported when there is room; play is over either way.
                    self.failed = true;
                    if emit.has_room() {
                        emit.push(Report::BadEvents {
                            offset: self.offset.wrapping_sub(1),
                        });
                    }
                }
            }
        }
        used
    }

    /// Apply the pending event or sample, doing the updates before it as report room allows.
    fn finish_pending(&mut self, emit: &mut dyn ReportSink) -> bool {
        match self.pending.take() {
            None => true,
            Some(Pending::Event(e)) => {
                let t_ns = e.t_us().saturating_mul(1000);
                if let (true, Event::Abs { t_us: 0, code }) = (self.at_start, e) {
                    self.start_at_abs(code);
                }
                self.at_start = false;
                // Every update strictly before the event sees the stream as it was.
                while t_ns > self.next_update_ns {
                    if !emit.has_room() {
                        self.pending = Some(Pending::Event(e));
                        return false;
                    }
                    self.update(emit);
                }
                match e {
                    Event::Tick { encoder, step, .. } => {
                        let step = match step {
                            Step::Forward => 1,
                            Step::Backward => -1,
                        };
                        self.odometry.tick(t_ns, encoder as usize, step);
                    }
                    Event::Abs { code, .. } => self.odometry.set_abs(code),
                }
                true
            }
            Some(Pending::Sample(s)) => {
                if !emit.has_room() {
                    self.pending = Some(Pending::Sample(s));
                    return false;
                }
                if let (true, Some(code)) = (self.at_start, s.abs) {
                    self.start_at_abs(code);
                }
                self.at_start = false;
                for (c, d) in self.counts.iter_mut().zip(s.counts_delta) {
                    *c += d as i64;
                }
                self.odometry.set_counts(&self.counts);
                if let Some(code) = s.abs {
                    self.odometry.set_abs(code);
                }
                self.update(emit);
                true
            }
        }
    }

    /// One update at the next instant; the caller checked the sink has room.
    fn update(&mut self, emit: &mut dyn ReportSink) {
        let pose = self.odometry.update(self.next_update_ns);
        self.digest = pose_digest(self.digest, pose.x, pose.y, pose.theta);
        self.next_update_ns += self.period_ns;
        self.updates = self.updates.wrapping_add(1);
        if self.checks.reports(self.updates) {
            let (x_um, y_um) = pose.micrometres();
            emit.push(Report::Pose {
                update: self.updates,
                pose: protocol::Pose {
                    x_um,
                    y_um,
                    heading: protocol::BinaryAngle(pose.heading_bam()),
                },
                digest: self.digest,
            });
        }
    }
}
