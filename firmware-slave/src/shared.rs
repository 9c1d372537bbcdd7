//! State shared between the slave's tasks.

use core::cell::RefCell;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::blocking_mutex::Mutex;
use protocol::spi::{MasterFrame, SlaveCommand, SlaveFrame, ENCODER_SLOTS};
use protocol::Pose;
use robot_math::exact::FixedPose;
use robot_math::Pose2;

struct State {
    frame: SlaveFrame,
    /// A command received from the master and not yet applied by the odometry task.
    pending: Option<(u8, SlaveCommand)>,
    /// The pose at full precision (the frame rounds it to micrometres), for the emulator's scoring.
    pose: FixedPose,
}

/// The slave's shared state. `const`-constructible so the board can keep it in a `static`.
pub struct SlaveShared {
    state: Mutex<CriticalSectionRawMutex, RefCell<State>>,
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
                    counts: [0; ENCODER_SLOTS],
                    abs_code: 0,
                    pose: Pose {
                        x_um: 0,
                        y_um: 0,
                        heading: protocol::BinaryAngle(0),
                    },
                    status: 0,
                    command_ack: 0,
                    rx_rejected: 0,
                    algorithm: protocol::spi::OdometryAlgorithm::Exact,
                },
                pending: None,
                pose: FixedPose {
                    x: 0,
                    y: 0,
                    theta: 0,
                },
            })),
        }
    }

    fn with<R>(&self, f: impl FnOnce(&mut State) -> R) -> R {
        self.state.lock(|s| f(&mut s.borrow_mut()))
    }

    /// The frame the master will read next.
    pub fn frame(&self) -> SlaveFrame {
        self.with(|s| s.frame)
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

    /// A valid frame from the master: queue its command unless it was already applied.
    pub(crate) fn receive(&self, f: &MasterFrame) {
        self.with(|s| {
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
