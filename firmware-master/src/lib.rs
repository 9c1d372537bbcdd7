//! The motion controller's portable firmware: everything the master board does, written
//! against the small traits in [`ports`], `embedded_io_async` and `embassy_time`, so the same
//! code runs on the STM32F103 (board layer in `main.rs` + `board/`) and inside the emulator.
//!
//! The decisions live in one sans-IO state machine, [`controller::Controller`]; four thin
//! async tasks feed it and carry out what it decides, each a task of its own ([`tasks`]):
//! * **host rx**: reassemble serial frames, hand messages to the controller;
//! * **host tx**: send replies at once and telemetry at a fixed rate;
//! * **slave poll**: one SPI transaction per period; command out, odometry in;
//! * **control**: at a fixed rate, watchdogs, pursuit, inverse kinematics, motor duties.
#![cfg_attr(not(test), no_std)]

mod baud;
pub mod controller;
pub mod drive_setup;
pub mod ports;
mod relay;
pub mod tasks;

/// The master's tasks run in one thread-mode executor, on the board as in an emulation, so
/// none preempts another, and no interrupt handler touches their shared state: it takes no
/// lock (see firmware-slave's `shared.rs`).
use embassy_sync::blocking_mutex::raw::NoopRawMutex as SharedLock;
use embassy_sync::blocking_mutex::Mutex;
use embassy_sync::channel::Channel;
use protocol::serial::DriveGeometry;
use robot_math::pursuit::PursuitParams;

use controller::Controller;
use core::mem::MaybeUninit;

/// Robot geometry, rates and safety limits of the master.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MasterConfig {
    /// The drive at power-on: wheel layout, limits, motor constant and tracking gains. A host
    /// may send another (`HostToMaster::SetDrive`), so one image serves every robot.
    pub drive: DriveGeometry,
    pub pursuit: PursuitParams,
    /// Within this distance of a stopped target, and `arrive_heading_tolerance` of its
    /// heading, the robot has arrived: the motors switch off and it holds, metres.
    pub arrive_tolerance: f64,
    /// Radians. Above half the pose's heading step (seed 004's 8-bit swivel encoder: 1.4°
    /// steps, so up to 0.7° off), or the heading loop would chase the sensor's steps.
    pub arrive_heading_tolerance: f64,
    /// Holding at the goal, the motors stay off until the robot is this far from it (pushed
    /// away), metres: a band wider than `arrive_tolerance`, so a robot that coasts a little
    /// after switching off does not switch back on.
    pub hold_release: f64,
    /// ...or turned this far from the goal's heading, radians (over two of the swivel
    /// encoder's 1.4° steps).
    pub hold_heading_release: f64,
    /// Standing inside those release bands of a stopped goal without moving a quarter of
    /// `arrive_tolerance` for this long also arrives, µs: motors that cannot close the last
    /// millimetres (stiction with no integrator, a wheel against an obstacle) are switched off
    /// rather than left humming. Creeping in must not be cut short: at the arrival band's edge
    /// the speed loops' integrators take up to 1.9 s to break seed 004's wheels away (measured:
    /// 1.33 s at 1.5 mm, 1.82-1.86 s at 1.02-1.05 mm), so 5 s leaves a motor with 2.5 times
    /// that friction room.
    pub hold_settle_us: u32,
    pub control_period_us: u32,
    pub poll_period_us: u32,
    pub telemetry_period_us: u32,
    /// Motors stop when no fresh slave frame arrived for this long.
    pub slave_timeout_us: u32,
    /// Motors stop when the host sent nothing for this long while a target was followed.
    pub host_timeout_us: u32,
    /// Poll period while play/record streams are moving (a 128-byte frame takes 228 µs).
    pub stream_poll_period_us: u32,
    /// The serial link's power-on baud rate (USART1): where every host meets the master
    /// before it asks for a faster one (`HostToMaster::SetBaud`), and where the master goes
    /// back when a switch fails or the host falls silent.
    pub baud: u32,
    /// This chip's 96-bit unique ID (the board layer reads it; zero in the emulator).
    pub uid: [u8; 12],
}

/// The master firmware's version, from Cargo.toml.
pub const FIRMWARE_VERSION: [u8; 3] = [
    parse_u8(env!("CARGO_PKG_VERSION_MAJOR")),
    parse_u8(env!("CARGO_PKG_VERSION_MINOR")),
    parse_u8(env!("CARGO_PKG_VERSION_PATCH")),
];

const fn parse_u8(s: &str) -> u8 {
    let b = s.as_bytes();
    let mut i = 0;
    let mut v: u32 = 0;
    while i < b.len() {
        v = v * 10 + (b[i] - b'0') as u32;
        i += 1;
    }
    if v > 255 {
        255
    } else {
        v as u8
    }
}

impl MasterConfig {
    pub const DEFAULT: MasterConfig = MasterConfig {
        drive: drive_setup::SEED_004_DRIVE,
        pursuit: PursuitParams {
            heading_gain: 4.0,
            slow_radius: 0.15,
            max_spin: 2.0,
            period_s: 0.0,
        },
        arrive_tolerance: 0.001,
        arrive_heading_tolerance: 0.02,
        hold_release: 0.005,
        hold_heading_release: 0.06,
        hold_settle_us: 5_000_000,
        control_period_us: 10_000,
        poll_period_us: 2_000,
        telemetry_period_us: 20_000,
        slave_timeout_us: 50_000,
        host_timeout_us: 500_000,
        stream_poll_period_us: 500,
        baud: 115_200,
        uid: [0; 12],
    };
}

/// State shared by the master's tasks. `const`-constructible for a `static` on the board.
pub struct MasterShared {
    controller: Mutex<SharedLock, core::cell::RefCell<ControllerCell>>,
    /// Replies for the host (hello, rejections), sent ahead of telemetry.
    replies: Channel<SharedLock, protocol::serial::MasterToHost, 4>,
}

impl Default for MasterShared {
    fn default() -> Self {
        Self::new()
    }
}

impl MasterShared {
    pub const fn new() -> Self {
        MasterShared {
            controller: Mutex::new(core::cell::RefCell::new(ControllerCell {
                started: false,
                controller: MaybeUninit::uninit(),
            })),
            replies: Channel::new(),
        }
    }

    /// Run `f` on the controller (None before `run` has started it).
    pub fn with<R>(&self, f: impl FnOnce(&mut Controller) -> R) -> Option<R> {
        self.controller.lock(|c| {
            let mut cell = c.borrow_mut();
            // SAFETY: `started` is set only once `Controller::init` has written the slot.
            cell.started
                .then(|| f(unsafe { cell.controller.assume_init_mut() }))
        })
    }

    /// Start the controller in place in its cell (it is kilobytes: never on the stack);
    /// false, and none started, for a drive geometry it cannot run. Out of line: what it
    /// builds is then on the stack only while it runs, not in the tasks' poll function.
    #[inline(never)]
    pub(crate) fn start(&self, config: &MasterConfig) -> bool {
        self.controller.lock(|c| {
            let mut cell = c.borrow_mut();
            cell.started = false;
            cell.started = Controller::init(&mut cell.controller, *config).is_some();
            cell.started
        })
    }
}

/// Where the controller lives: built in place by [`MasterShared::start`].
struct ControllerCell {
    started: bool,
    controller: MaybeUninit<Controller>,
}
