//! State shared between the slave's tasks.

use core::cell::RefCell;
/// The odometry and SPI tasks share this state, and they are one task on the board (joined
/// in [`crate::run`]) as in an emulation; no interrupt handler touches it. So nothing can
/// come between a task's reads and writes of it, and it takes no lock: a critical section
/// (interrupts off) around each access cost 228 B of the slave's flash (384 B of the master's)
/// and held the edge interrupts back; on the host, where it is an atomic instruction, it was
/// 9 % of an emulated run.
/// `NoopRawMutex` makes the state `!Sync`, so the compiler keeps it on its one thread.
use embassy_sync::blocking_mutex::raw::NoopRawMutex as SharedLock;
use embassy_sync::blocking_mutex::Mutex;
use protocol::chunks::{ChunkReceiver, ChunkSender};
use protocol::spi::{MasterFrame, SensorSource, SlaveCommand, SlaveFrame};
use protocol::Pose;
use robot_math::exact::FixedPose;
use robot_math::Pose2;

struct State {
    frame: SlaveFrame,
    /// A command received from the master and not yet applied by the odometry task.
    pending: Option<(u8, SlaveCommand)>,
    /// The pose at full precision (the frame rounds it to micrometres), for the emulator's scoring.
    pose: FixedPose,
    /// Played events from the master: where the stream is, and the bytes not consumed yet.
    events_rx: ChunkReceiver,
    events: Ring<EVENTS_BUFFER>,
    /// Whether events are taken at all (only while playing).
    events_open: bool,
    /// The report stream to the master.
    reports: ChunkSender<REPORTS_BUFFER>,
}

/// Played event bytes held for the odometry task.
pub const EVENTS_BUFFER: usize = 512;
/// Report bytes held for the master.
pub const REPORTS_BUFFER: usize = 1024;

/// A byte ring (consumed from the front).
struct Ring<const N: usize> {
    buf: [u8; N],
    head: usize,
    len: usize,
}

impl<const N: usize> Ring<N> {
    const fn new() -> Self {
        Ring {
            buf: [0; N],
            head: 0,
            len: 0,
        }
    }
    /// Empty, in place (a new ring built on the stack to be copied over this one would be
    /// half a kilobyte of the board's stack).
    fn clear(&mut self) {
        self.head = 0;
        self.len = 0;
    }
    fn push(&mut self, bytes: &[u8]) {
        for &b in bytes.iter().take(N - self.len) {
            self.buf[(self.head + self.len) % N] = b;
            self.len += 1;
        }
    }
    fn peek(&self, out: &mut [u8]) -> usize {
        let n = out.len().min(self.len);
        for (i, slot) in out[..n].iter_mut().enumerate() {
            *slot = self.buf[(self.head + i) % N];
        }
        n
    }
    fn consume(&mut self, n: usize) {
        let n = n.min(self.len);
        self.head = (self.head + n) % N;
        self.len -= n;
    }
}

/// The slave's shared state. `const`-constructible so the board can keep it in a `static`.
pub struct SlaveShared {
    state: Mutex<SharedLock, RefCell<State>>,
}

impl Default for SlaveShared {
    fn default() -> Self {
        Self::new()
    }
}

impl SlaveShared {
    pub const fn new() -> Self {
        SlaveShared {
            state: Mutex::new(RefCell::new(State {
                frame: SlaveFrame {
                    seq: 0,
                    time_us: 0,
                    armed_us: 0,
                    pose: Pose {
                        x_um: 0,
                        y_um: 0,
                        heading: protocol::BinaryAngle(0),
                    },
                    status: 0,
                    command_ack: 0,
                    rx_rejected: 0,
                    algorithm: protocol::spi::OdometryAlgorithm::Exact,
                    robot: 0,
                    source: SensorSource::Ticks,
                    period_us: 0,
                    events_next: 0,
                    reports: protocol::spi::Chunk {
                        offset: 0,
                        bytes: protocol::Bytes::new(),
                    },
                },
                pending: None,
                pose: FixedPose {
                    x: 0,
                    y: 0,
                    theta: 0,
                },
                events_rx: ChunkReceiver::new(),
                events: Ring::new(),
                events_open: false,
                reports: ChunkSender::new(),
            })),
        }
    }

    /// Back to the power-on state: what a reset leaves of RAM (the emulator's slave reset;
    /// on the board the `static` starts this way).
    pub fn restart(&self) {
        let fresh = SlaveShared::new().state.into_inner().into_inner();
        self.with(|s| *s = fresh);
    }

    fn with<R>(&self, f: impl FnOnce(&mut State) -> R) -> R {
        self.state.lock(|s| f(&mut s.borrow_mut()))
    }

    /// The frame the master will read next (without a report chunk: see
    /// [`SlaveShared::frame_to_arm`]).
    pub fn frame(&self) -> SlaveFrame {
        self.with(|s| s.frame)
    }

    /// The frame to arm for the master's next transaction: the odometry fields, the stream
    /// positions and the next report chunk.
    pub(crate) fn frame_to_arm(&self) -> SlaveFrame {
        self.with(|s| SlaveFrame {
            events_next: s.events_rx.next,
            reports: s.reports.next_chunk(),
            ..s.frame
        })
    }

    /// Restart both streams at offset 0; `played` opens the event stream. Called by the
    /// odometry task when it applies a new sensor source, before acknowledging it.
    pub(crate) fn restart_streams(&self, played: bool) {
        self.with(|s| {
            s.events_rx = ChunkReceiver::new();
            s.events.clear();
            s.events_open = played;
            s.reports.reset();
        });
    }

    /// Copy up to `out.len()` played event bytes, oldest first, without consuming them.
    pub(crate) fn peek_events(&self, out: &mut [u8]) -> usize {
        self.with(|s| s.events.peek(out))
    }

    pub(crate) fn consume_events(&self, n: usize) {
        self.with(|s| s.events.consume(n));
    }

    /// Room in the report stream.
    pub(crate) fn report_room(&self) -> usize {
        self.with(|s| s.reports.free())
    }

    /// Append report bytes (the caller checked the room; what does not fit is dropped).
    // Out of line for the image's size, as `odometry_task`'s `wire_pose`.
    #[inline(never)]
    pub(crate) fn push_reports(&self, bytes: &[u8]) -> usize {
        self.with(|s| s.reports.push(bytes))
    }

    /// The latest pose at full precision (the frame rounds to micrometres), in SI units.
    /// For the host (emulator, tests): the conversion uses floats.
    pub fn pose(&self) -> Pose2 {
        self.with(|s| s.pose).to_pose2()
    }

    /// Publish an odometry update. `update` carries the odometry fields; the link fields
    /// (`command_ack`, `rx_rejected`, `armed_us`) stay as this state keeps them.
    pub(crate) fn publish(&self, update: &SlaveFrame, pose: FixedPose) {
        self.with(|s| {
            s.frame = SlaveFrame {
                command_ack: s.frame.command_ack,
                rx_rejected: s.frame.rx_rejected,
                armed_us: s.frame.armed_us,
                ..*update
            };
            s.pose = pose;
        });
    }

    /// A valid frame from the master: queue its command unless it was already applied, take
    /// the played events that continue the stream, and drop the reports it acknowledged.
    pub(crate) fn receive(&self, f: &MasterFrame) {
        self.with(|s| {
            s.reports.on_ack(f.reports_next);
            if s.events_open {
                let room = EVENTS_BUFFER - s.events.len;
                let fresh = s.events_rx.accept(&f.events, room);
                s.events.push(fresh);
            }
            if f.command_seq == s.frame.command_ack {
                return;
            }
            match f.command {
                // Nothing to apply: acknowledge at once so the master's sequence moves on.
                SlaveCommand::None => s.frame.command_ack = f.command_seq,
                c => s.pending = Some((f.command_seq, c)),
            }
        });
    }

    // Out of line for the image's size, as `odometry_task`'s `wire_pose`.
    #[inline(never)]
    pub(crate) fn take_command(&self) -> Option<(u8, SlaveCommand)> {
        self.with(|s| s.pending.take())
    }

    pub(crate) fn acknowledge(&self, command_seq: u8) {
        self.with(|s| s.frame.command_ack = command_seq);
    }

    pub(crate) fn count_rejected(&self) {
        self.with(|s| s.frame.rx_rejected = s.frame.rx_rejected.wrapping_add(1));
    }
}
