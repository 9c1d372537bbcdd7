//! The odometry computer's portable firmware: everything the slave board does, written
//! against the small traits in [`ports`] and `embassy_time`, so the same code runs on the
//! STM32F103 (board layer in `main.rs` + `board/`) and inside the host emulator.
//!
//! Two tasks, joined in [`run`]:
//! * the **odometry task** samples the counters and the absolute encoder on a fixed-rate
//!   ticker, extends the 16-bit counts to 64-bit totals, integrates the pose and publishes an
//!   [`protocol::spi::SlaveFrame`]. The integrator is `exact` in fixed point
//!   ([`robot_math::carriage::CarriageExact`]): integer-only on every update, as the FPU-less
//!   STM32F103 wants (`scripts/check-no-float.py` proves it from the disassembly);
//! * the **SPI task** arms the latest frame for the master's next poll, and checks and applies
//!   what the master sent back (commands such as set-pose, acknowledged by sequence number).
#![cfg_attr(not(test), no_std)]

mod estimator;
pub mod ports;
mod shared;

use embassy_futures::join::join;
use embassy_time::{Duration, Instant, Ticker};
use estimator::SlaveOdometry;
use protocol::spi::{self, slave_status, MasterFrame, SlaveCommand, SlaveFrame, SPI_FRAME_LEN};
use robot_math::carriage::CarriageGeometry;
use robot_math::exact::FixedPose;
use robot_math::sensors::{gray_to_binary, CounterExtender};

use estimator::Sample;
use ports::{AbsoluteEncoderPins, EncoderEdges, QuadratureCounters, SpiSlave, MEASURING_WHEELS};
use robot_math::sensors::{Quadrature, QuadratureDecoder};
use robot_math::ticks::TickTracker;
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
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SlaveConfig {
    pub geometry: CarriageGeometry,
    pub sensor: SensorMode,
    /// Odometry update period (fixed rate).
    pub update_period_us: u32,
    /// The absolute encoder pulls its outputs low for a 1 bit (open-collector, negative logic,
    /// as the E6CP-AG5C does): invert the pin levels before Gray decoding.
    pub abs_inverted: bool,
}

impl SlaveConfig {
    /// Seed 004's sensors at 1 kHz.
    pub const DEFAULT: SlaveConfig = SlaveConfig {
        geometry: CarriageGeometry::SEED_004,
        sensor: SensorMode::Counts,
        update_period_us: 1_000,
        abs_inverted: true,
    };

    /// The absolute code (binary, `0..2^bits`) the pins stand for.
    pub fn abs_code(&self, levels: u8) -> u16 {
        let bits = if self.abs_inverted { !levels } else { levels };
        let mask = ((1u32 << self.geometry.abs_bits) - 1) as u16;
        gray_to_binary(bits as u16 & mask)
    }
}

/// Run the slave firmware forever.
pub async fn run(
    counters: impl QuadratureCounters,
    edges: impl EncoderEdges,
    abs: impl AbsoluteEncoderPins,
    spi: impl SpiSlave,
    shared: &SlaveShared,
    config: &SlaveConfig,
) -> ! {
    join(
        odometry_task(counters, edges, abs, shared, config),
        spi_task(spi, shared),
    )
    .await
    .0
}

/// Fixed-rate sampling and pose integration.
pub async fn odometry_task(
    mut counters: impl QuadratureCounters,
    mut edges: impl EncoderEdges,
    mut abs: impl AbsoluteEncoderPins,
    shared: &SlaveShared,
    config: &SlaveConfig,
) -> ! {
    let period = Duration::from_micros(config.update_period_us as u64);
    let timestamps = config.sensor == SensorMode::TickTimestamps;
    let mut extenders = counters.read_raw().map(CounterExtender::new);
    let mut decoders = edges.levels().map(QuadratureDecoder::new);
    let mut ticks = [TickTracker::new(); MEASURING_WHEELS];
    let start = Sample {
        counts: [0; MEASURING_WHEELS],
        q16: [0; MEASURING_WHEELS],
        t_ns: Instant::now().as_micros() * 1000,
        code: config.abs_code(abs.read_levels()),
    };
    // The integer constants are derived once, here, with (soft) floats; every update after
    // this is integer-only.
    let Some(mut odometry) = SlaveOdometry::new(config.geometry, &start, timestamps) else {
        // An impossible geometry is a build mistake: publish nothing, so the master's
        // freshness watchdog sees a dead slave and keeps the motors off.
        loop {
            embassy_time::Timer::after_secs(3600).await;
        }
    };
    let mut ticker = Ticker::every(period);
    let mut next_due = Instant::now() + period;
    let mut seq: u16 = 0;
    // Sticky until the next successful switch: the host asked for something this slave lacks.
    let mut unsupported = false;
    loop {
        ticker.next().await;
        // Sample first, as close to the tick as possible; everything else can wait.
        let raw = counters.read_raw();
        let levels = abs.read_levels();
        let now = Instant::now();
        let t_ns = now.as_micros() * 1000;

        let mut status = slave_status::RUNNING;
        if now > next_due + period {
            status |= slave_status::OVERRUN;
        }
        next_due = now + period;
        let mut totals = [0i64; MEASURING_WHEELS];
        for (i, ext) in extenders.iter_mut().enumerate() {
            let (total, jumped) = ext.update(raw[i]);
            totals[i] = total;
            if jumped {
                status |= slave_status::COUNTER_JUMP;
            }
        }
        let code = config.abs_code(levels);

        // Tick-timestamp mode: every edge since the last update, decoded, into the trackers
        // (and to the methods that use single ticks), then each wheel interpolated to now.
        let sample = if timestamps {
            let complete = edges.drain(&mut |e| {
                let w = e.encoder as usize;
                let Some(decoder) = decoders.get_mut(w) else {
                    return;
                };
                match decoder.edge(e.levels) {
                    Quadrature::Step(step) => {
                        let t = e.t_us * 1000;
                        ticks[w].tick(t, step);
                        odometry.on_tick(t, w, step);
                    }
                    Quadrature::Missed => status |= slave_status::EDGES_LOST,
                    Quadrature::None => {}
                }
            });
            // The timers count the same edges in hardware: if the decoded count ever differs,
            // an edge was lost (or invented) on the interrupt path.
            if !complete || ticks.iter().zip(totals).any(|(t, c)| t.count() != c) {
                status |= slave_status::EDGES_LOST;
            }
            Sample {
                counts: ticks.map(|t| t.count()),
                q16: ticks.map(|t| t.position_q16(t_ns)),
                t_ns,
                code,
            }
        } else {
            Sample {
                counts: totals,
                q16: totals.map(|c| c << 16),
                t_ns,
                code,
            }
        };

        if let Some((command_seq, command)) = shared.take_command() {
            match command {
                SlaveCommand::SetPose(p) => {
                    let pose = FixedPose::from_micrometres(p.x_um, p.y_um, p.heading.0);
                    odometry.set_pose(pose, &sample);
                }
                SlaveCommand::SetAlgorithm(a) => {
                    unsupported = !odometry.switch(a, &sample);
                }
                SlaveCommand::None => {}
            }
            shared.acknowledge(command_seq);
        }
        let pose = odometry.update(&sample);
        if unsupported {
            status |= slave_status::ALGORITHM_UNSUPPORTED;
        }

        seq = seq.wrapping_add(1);
        let mut counts = [0i32; spi::ENCODER_SLOTS];
        for (slot, total) in counts.iter_mut().zip(totals) {
            // The wire carries the low 32 bits; the master only ever needs differences.
            *slot = total as i32;
        }
        let (x_um, y_um) = pose.micrometres();
        let update = SlaveFrame {
            seq,
            time_us: now.as_micros() as u32,
            counts,
            abs_code: code,
            pose: protocol::Pose {
                x_um,
                y_um,
                heading: protocol::BinaryAngle(pose.heading_bam()),
            },
            status,
            algorithm: odometry.algorithm(),
            ..SlaveFrame::default()
        };
        shared.publish(&update, pose);
    }
}

/// Answer the master's polls: arm the latest frame, check what came back.
pub async fn spi_task(mut spi: impl SpiSlave, shared: &SlaveShared) -> ! {
    let mut rx = [0u8; SPI_FRAME_LEN];
    loop {
        let mut frame = shared.frame();
        frame.armed_us = Instant::now().as_micros() as u32;
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
    use protocol::spi::MasterFrame;
    use robot_math::sensors::binary_to_gray;

    #[test]
    fn absolute_code_is_inverted_gray_on_the_pins() {
        let cfg = SlaveConfig::DEFAULT;
        for code in 0..256u16 {
            let levels = !(binary_to_gray(code) as u8);
            assert_eq!(cfg.abs_code(levels), code);
        }
        let plain = SlaveConfig {
            abs_inverted: false,
            ..cfg
        };
        assert_eq!(plain.abs_code(binary_to_gray(77) as u8), 77);
    }

    #[test]
    fn commands_are_applied_once_and_acknowledged() {
        let shared = SlaveShared::new();
        let set = SlaveCommand::SetPose(protocol::Pose::from_si(1.0, 2.0, 0.5));
        let frame = MasterFrame {
            seq: 1,
            command_seq: 4,
            command: set,
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
