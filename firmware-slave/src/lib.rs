//! The odometry computer's portable firmware: everything the slave board does, written
//! against the small traits in [`ports`] and `embassy_time`, so the same code runs on the
//! STM32F103 (board layer in `main.rs` + `board/`) and inside the host emulator.
//!
//! Two tasks, run together in [`run`]:
//! * the **odometry task** samples the sensors on a fixed-rate ticker (the timers' counters,
//!   or every time-stamped encoder edge with the counters that match them, and the absolute
//!   encoder), extends the 16-bit counts to 64-bit totals and hands everything to the
//!   [`SlaveEstimator`] (robot-math's one odometry layer, `exact` by default: integer-only on
//!   every update, as the FPU-less STM32F103 wants, `scripts/check-no-float.py` proves it from
//!   the disassembly), then publishes an [`protocol::spi::SlaveFrame`];
//! * the **SPI task** arms the latest frame for the master's next poll, and checks and applies
//!   what the master sent back (commands such as set-pose, acknowledged by sequence number).
#![cfg_attr(not(test), no_std)]

mod estimator;
mod odometry_task;
pub mod played;
pub mod ports;
pub mod recorder;
pub mod robot_wire;
mod shared;

#[cfg(test)]
mod upload_tests;
// The board's update rates: a build setting, which the build script checks (see
// `board_rate.rs`), and the emulator's `--slave-rate`.
#[path = "../board_rate.rs"]
pub mod board_rate;
pub use odometry_task::odometry_task;

use embassy_futures::select::{select, Either};
use embassy_time::Instant;
use protocol::spi::{self, MasterFrame, SPI_FRAME_LEN};
use robot_math::odometry::Layout;

pub use estimator::{algorithm_of, method_of, SlaveEstimator, Update};
use ports::{AbsoluteEncoderPins, EncoderEdges, QuadratureCounters, SpiSlave};
pub use shared::SlaveShared;

/// How the slave sees its measuring wheels.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SensorMode {
    /// The timers' hardware quadrature counters, read at the fixed update rate.
    Counts,
    /// Every encoder edge with its time stamp ([`ports::EncoderEdges`]): `exact` interpolates
    /// each wheel to the update instant, and `timing` becomes available.
    TickTimestamps,
}

/// How the slave's sensors are built and how often it integrates.
#[derive(Clone, Debug, PartialEq)]
pub struct SlaveConfig {
    /// The robot the slave powers on with: its sensors' geometry and integer constants
    /// (robot-math's one layout type). Private, so that it always comes with its fingerprint.
    layout: Layout,
    /// `layout`'s fingerprint (`robot_wire::layout_fingerprint`), what the frames report
    /// until another robot is uploaded. The configuration carries it rather than the slave
    /// working it out at start: the board's robot's is a constant
    /// ([`SlaveConfig::SEED_004_FINGERPRINT`]), and the code that works one out (632 B) stays
    /// out of the image. The emulator's other robots have theirs worked out on the host
    /// ([`SlaveConfig::with_layout`]); the firmware reads it the same way in both.
    power_on_fingerprint: u32,
    pub sensor: SensorMode,
    /// Odometry update period (fixed rate).
    pub update_period_us: u32,
}

impl SlaveConfig {
    /// THE board configuration (the firmware image and the emulator both run it): seed 004's
    /// sensors ([`Layout::SEED_004`], the absolute encoder active-low Gray), every encoder
    /// edge time-stamped (EXTI; the timers still count in hardware and the slave cross-checks
    /// the two), 1 kHz updates.
    pub const DEFAULT: SlaveConfig = SlaveConfig {
        layout: Layout::SEED_004,
        power_on_fingerprint: Self::SEED_004_FINGERPRINT,
        sensor: SensorMode::TickTimestamps,
        update_period_us: 1_000_000 / board_rate::DEFAULT_RATE_HZ,
    };

    /// [`Layout::SEED_004`]'s fingerprint, as a constant: the test
    /// `the_default_robots_fingerprint_is_its_layouts` proves it equal to the one worked out
    /// from the layout, and fails (saying the new value) when the layout or the fingerprint's
    /// form changes.
    pub const SEED_004_FINGERPRINT: u32 = 0xe4f6_f88a;

    /// This configuration with `layout` as the robot the slave powers on with (the emulator's
    /// virtual boards), its fingerprint worked out here.
    pub fn with_layout(self, layout: Layout) -> SlaveConfig {
        SlaveConfig {
            layout,
            power_on_fingerprint: robot_wire::layout_fingerprint(&layout),
            ..self
        }
    }

    /// This configuration at another update period (the board's image: the rate it was
    /// built for).
    pub const fn with_update_period_us(self, update_period_us: u32) -> SlaveConfig {
        SlaveConfig {
            update_period_us,
            ..self
        }
    }

    /// The robot the slave powers on with.
    pub fn layout(&self) -> &Layout {
        &self.layout
    }

    /// [`layout`](Self::layout)'s fingerprint.
    pub fn power_on_fingerprint(&self) -> u32 {
        self.power_on_fingerprint
    }

    /// The absolute encoder position (`0..2^bits`) the pins stand for (0 without one).
    pub fn abs_code(&self, levels: u8) -> u16 {
        self.layout.abs().map_or(0, |a| a.decode(levels as u16))
    }
}

/// The slave's clock as its frames show it (`time_us`, `armed_us`): microseconds since this
/// firmware started, wrapping at 32 bits, as the board's timer counts from reset. The master
/// tells a restarted slave by this clock starting again. In emulation both boards share one
/// virtual clock, and counting from the start is what makes a restarted slave's clock restart.
#[derive(Clone, Copy, Debug)]
pub struct FrameClock {
    start: Instant,
}

impl FrameClock {
    /// The clock starting now.
    pub fn start() -> Self {
        FrameClock {
            start: Instant::now(),
        }
    }

    /// `t` on this clock.
    pub fn us(&self, t: Instant) -> u32 {
        t.as_micros().wrapping_sub(self.start.as_micros()) as u32
    }
}

/// Run the slave firmware forever.
pub async fn run(
    counters: impl QuadratureCounters,
    edges: impl EncoderEdges,
    abs: impl AbsoluteEncoderPins,
    spi: impl SpiSlave,
    cycles: impl ports::CycleCounter,
    shared: &SlaveShared,
    config: &SlaveConfig,
) -> ! {
    let clock = FrameClock::start();
    // `select`, not `join`: neither ever ends, and select polls them in the same order
    // without join's slots for their outputs (the slave's flash).
    match select(
        odometry_task(counters, edges, abs, shared, config, clock, cycles),
        spi_task(spi, shared, clock),
    )
    .await
    {
        Either::First(never) | Either::Second(never) => never,
    }
}

/// Answer the master's polls: arm the latest frame, check what came back.
pub async fn spi_task(mut spi: impl SpiSlave, shared: &SlaveShared, clock: FrameClock) -> ! {
    let mut rx = [0u8; SPI_FRAME_LEN];
    loop {
        let mut frame = shared.frame_to_arm();
        frame.armed_us = clock.us(Instant::now());
        let tx = spi::encode(&frame);
        match spi.exchange(&tx, &mut rx).await {
            Ok(()) => match spi::decode::<MasterFrame>(&rx) {
                Ok(frame) => shared.receive(&frame),
                Err(_) => shared.count_rejected(),
            },
            // A torn transaction carries nothing trustworthy; the master will see our reply
            // fail its CRC too and count it on its side.
            Err(_) => shared.count_rejected(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use protocol::spi::{MasterFrame, SlaveCommand};
    use robot_math::sensors::binary_to_gray;

    #[test]
    fn absolute_code_is_inverted_gray_on_the_pins() {
        let cfg = SlaveConfig::DEFAULT;
        for code in 0..256u16 {
            let levels = !(binary_to_gray(code) as u8);
            assert_eq!(cfg.abs_code(levels), code);
        }
        let abs = robot_math::odometry::AbsLayout {
            inverted: false,
            ..robot_math::odometry::AbsLayout::E6CP_AG5C
        };
        let layout = &cfg.layout;
        let plain = cfg.clone().with_layout(
            Layout::from_parts(
                2,
                *layout.wheels(),
                *layout.metres_per_count(),
                *layout.exact(),
                layout.carriage(),
                Some(abs),
            )
            .unwrap(),
        );
        assert_eq!(plain.abs_code(binary_to_gray(77) as u8), 77);
    }

    #[test]
    fn the_default_robots_fingerprint_is_its_layouts() {
        let worked_out = robot_wire::layout_fingerprint(&Layout::SEED_004);
        assert_eq!(
            SlaveConfig::DEFAULT.power_on_fingerprint(),
            worked_out,
            "SEED_004_FINGERPRINT is now {worked_out:#010x}"
        );
        // Another robot's (seed 004's with its absolute encoder active-high) is worked out
        // with it; the default's again, the same.
        let l = Layout::SEED_004;
        let abs = robot_math::odometry::AbsLayout {
            inverted: false,
            ..robot_math::odometry::AbsLayout::E6CP_AG5C
        };
        let other = Layout::from_parts(
            2,
            *l.wheels(),
            *l.metres_per_count(),
            *l.exact(),
            l.carriage(),
            Some(abs),
        )
        .unwrap();
        let config = SlaveConfig::DEFAULT.with_layout(other);
        assert_eq!(config.layout(), &other);
        assert_eq!(
            config.power_on_fingerprint(),
            robot_wire::layout_fingerprint(&other)
        );
        assert_ne!(config.power_on_fingerprint(), worked_out);
        assert_eq!(
            SlaveConfig::DEFAULT.with_layout(Layout::SEED_004),
            SlaveConfig::DEFAULT
        );
    }

    #[test]
    fn commands_are_applied_once_and_acknowledged() {
        let shared = SlaveShared::new();
        let set = SlaveCommand::SetPose(protocol::Pose::from_si(1.0, 2.0, 0.5));
        let frame = MasterFrame {
            seq: 1,
            command_seq: 4,
            command: set,
            ..MasterFrame::default()
        };
        shared.receive(&frame);
        assert_eq!(shared.take_command(), Some((4, set)));
        shared.acknowledge(4);
        assert_eq!(shared.frame().command_ack, 4);
        // The master repeats the command until it sees the ack: the repeat must not re-apply.
        shared.receive(&MasterFrame { seq: 2, ..frame });
        assert_eq!(shared.take_command(), None);
        // A "no command" frame with a new sequence number is acknowledged at once.
        shared.receive(&MasterFrame {
            seq: 3,
            command_seq: 5,
            command: SlaveCommand::None,
            ..MasterFrame::default()
        });
        assert_eq!(shared.frame().command_ack, 5);
        assert_eq!(shared.take_command(), None);
    }

    #[test]
    fn rejected_frames_are_counted_and_wrap() {
        let shared = SlaveShared::new();
        for _ in 0..70_000u32 {
            shared.count_rejected();
        }
        assert_eq!(shared.frame().rx_rejected, (70_000u32 % 65_536) as u16);
    }
}
