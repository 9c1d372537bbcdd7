//! The measured calls of the Cortex-M3 instruction-count benchmark (`scripts/m3-bench`; the
//! image that runs them under QEMU is `src/main.rs` and `src/chip.rs`).
//!
//! The calls are the boards' own code paths: the slave's odometry ([`SlaveEstimator`], as the
//! odometry task calls it) on the board's default layout (seed 004's swivel carriage) and on a
//! body-fixed 3-omni triangle; the SPI frames each side builds and checks; the master's
//! control step. Portable: on the chip each call runs between two markers (`chip.rs`), on the
//! host a test runs every case once.
#![no_std]

use embassy_time::Instant;
use firmware_master::controller::Controller;
use firmware_master::MasterConfig;
use firmware_slave::ports::EncoderEdge;
use firmware_slave::{SensorMode, SlaveConfig, SlaveEstimator};
use protocol::serial::{HostToMaster, MovingTarget};
use protocol::spi::{self, MasterFrame, SlaveFrame, SPI_FRAME_LEN};
use protocol::{BinaryAngle, Point, Pose};
use robot_math::odometry::Layout;
use robot_math::sensors::QuadratureDecoder;
use robot_math::ticks::PLACING_TICKS;
use robot_math::wheel::Wheel;

/// What is measured. The order is the report's.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Case {
    /// Nothing: the markers' own cost, taken off every other case.
    Empty,
    /// One edge in tick-timestamp mode once every wheel is placed: decode, time stamp, count.
    ExactEdge,
    /// One of each wheel's first edges, while the wheels are being placed (the start fit).
    ExactEdgePlacing,
    /// The fixed-rate update in tick-timestamp mode: every wheel interpolated to the instant.
    ExactTicksUpdate,
    /// The fixed-rate update with sampled counters.
    ExactCountsUpdate,
    /// The same three on a 3-omni triangle (body-fixed wheels, no absolute encoder).
    Omni3Edge,
    Omni3TicksUpdate,
    Omni3CountsUpdate,
    /// The slave builds its frame for the master (postcard, padding, CRC-32), and checks and
    /// decodes the master's; the master the same the other way. Frames as in a run: a pose,
    /// no command, empty streams.
    SpiSlaveBuild,
    SpiSlaveParse,
    SpiMasterBuild,
    SpiMasterParse,
    /// The CRC-32 of a frame's 124 checked bytes, each engine alone: the `crc` crate's table
    /// (this image's engine, which the SPI cases above count, and the boards' before they took
    /// their CRC unit), and the boards' word-by-word engine (`protocol::crc32::checksum_by_words`)
    /// with a RAM word standing in for the unit's data register: the instructions the board
    /// runs, less the busy flag's handful; the unit's own 4 cycles a word are not instructions.
    /// (The stand-in computes no CRC; the instructions do not depend on the data.)
    Crc32Table,
    Crc32Unit,
    /// The master's control step following a target (pursuit, kinematics, speed loops,
    /// duties), a fresh slave frame taken just before.
    MasterControlStep,
}

impl Case {
    pub const ALL: [Case; 15] = [
        Case::Empty,
        Case::ExactEdge,
        Case::ExactEdgePlacing,
        Case::ExactTicksUpdate,
        Case::ExactCountsUpdate,
        Case::Omni3Edge,
        Case::Omni3TicksUpdate,
        Case::Omni3CountsUpdate,
        Case::SpiSlaveBuild,
        Case::SpiSlaveParse,
        Case::SpiMasterBuild,
        Case::SpiMasterParse,
        Case::Crc32Table,
        Case::Crc32Unit,
        Case::MasterControlStep,
    ];
}

/// Runs a call as one measurement of a case.
pub trait Meter {
    fn measure(&mut self, case: Case, call: &mut dyn FnMut());
}

/// Calls measured per case (the placing case has as many as the wheels' first ticks).
pub const CALLS: usize = 32;

/// Every case, in [`Case::ALL`]'s order.
pub fn run(meter: &mut dyn Meter) {
    for _ in 0..CALLS {
        meter.measure(Case::Empty, &mut || {});
    }
    let seed004 = SlaveConfig::DEFAULT;
    // The swivel encoder's pins as they read at swivel 0 (active-low Gray: all high).
    let abs_levels = 0xFF;
    let edges = [Case::ExactEdgePlacing, Case::ExactEdge];
    run_layout(
        meter,
        seed004.layout(),
        abs_levels,
        edges,
        Case::ExactTicksUpdate,
    );
    counts_updates(meter, seed004.layout(), abs_levels, Case::ExactCountsUpdate);
    let omni = omni3();
    run_layout(
        meter,
        &omni,
        0,
        [Case::ExactEdgePlacing, Case::Omni3Edge],
        Case::Omni3TicksUpdate,
    );
    counts_updates(meter, &omni, 0, Case::Omni3CountsUpdate);
    spi_frames(meter);
    crc_engines(meter);
    control_steps(meter);
}

/// A slave frame as one arms it in a run, its pose moved by `k`.
fn slave_frame(k: u32) -> SlaveFrame {
    SlaveFrame {
        seq: k as u16,
        time_us: 1_000 * k,
        armed_us: 1_000 * k + 400,
        pose: Pose {
            x_um: 1_234_567 + 300 * k as i32,
            y_um: -765_432 + 200 * k as i32,
            heading: BinaryAngle(0x2345_6789u32.wrapping_add(k << 20)),
        },
        status: protocol::spi::slave_status::RUNNING,
        robot: 0xec1b_0d6a,
        period_us: 1_000,
        ..SlaveFrame::default()
    }
}

/// Each side's frame built and checked, [`CALLS`] times each.
fn spi_frames(meter: &mut dyn Meter) {
    for k in 0..CALLS as u32 {
        let slave = slave_frame(k);
        let master = MasterFrame {
            seq: k as u16,
            command_seq: 3,
            ..MasterFrame::default()
        };
        let mut wire = [0u8; SPI_FRAME_LEN];
        meter.measure(Case::SpiSlaveBuild, &mut || {
            wire = core::hint::black_box(spi::encode(core::hint::black_box(&slave)));
        });
        meter.measure(Case::SpiMasterParse, &mut || {
            core::hint::black_box(spi::decode::<SlaveFrame>(core::hint::black_box(&wire))).ok();
        });
        meter.measure(Case::SpiMasterBuild, &mut || {
            wire = core::hint::black_box(spi::encode(core::hint::black_box(&master)));
        });
        meter.measure(Case::SpiSlaveParse, &mut || {
            core::hint::black_box(spi::decode::<MasterFrame>(core::hint::black_box(&wire))).ok();
        });
    }
}

/// The CRC-32 of a frame's checked bytes, [`CALLS`] times by each engine.
fn crc_engines(meter: &mut dyn Meter) {
    /// The unit's data register, as the board's engine drives it: a volatile store per word,
    /// a volatile load for the result.
    struct StandIn(u32);
    impl protocol::crc32::WordCrcUnit for StandIn {
        fn reset(&mut self) {
            // SAFETY: a plain field, written through a valid `&mut`.
            unsafe { core::ptr::write_volatile(&mut self.0, u32::MAX) }
        }
        fn feed(&mut self, word: u32) {
            // SAFETY: as above.
            unsafe { core::ptr::write_volatile(&mut self.0, word) }
        }
        fn read(&mut self) -> u32 {
            // SAFETY: as above.
            unsafe { core::ptr::read_volatile(&self.0) }
        }
    }
    let mut unit = StandIn(0);
    for k in 0..CALLS {
        let wire = spi::encode(&slave_frame(k as u32));
        let body = &wire[..SPI_FRAME_LEN - 4];
        meter.measure(Case::Crc32Table, &mut || {
            core::hint::black_box(protocol::crc32::checksum(core::hint::black_box(body)));
        });
        meter.measure(Case::Crc32Unit, &mut || {
            core::hint::black_box(protocol::crc32::checksum_by_words(
                &mut unit,
                core::hint::black_box(body),
            ));
        });
    }
}

/// The master following a target 1 m ahead at 0.5 m/s, a fresh slave frame every 2 ms and a
/// control step every 10 ms, as it runs.
fn control_steps(meter: &mut dyn Meter) {
    let Some(mut c) = Controller::new(MasterConfig::DEFAULT) else {
        return;
    };
    let to = Point {
        x_um: 1_000_000,
        y_um: 300_000,
    };
    c.on_host_message(
        Instant::from_millis(0),
        HostToMaster::FollowTarget(MovingTarget {
            from: to,
            to,
            target_speed_um_s: 0,
            robot_speed_um_s: 500_000,
            heading: BinaryAngle(0),
        }),
    );
    for k in 1..=CALLS as u32 * 5 {
        let now = Instant::from_millis(2 * k as u64);
        c.on_slave_frame(now, Ok(slave_frame(k)));
        if k % 5 == 0 {
            c.on_host_message(now, HostToMaster::Heartbeat);
            meter.measure(Case::MasterControlStep, &mut || {
                core::hint::black_box(c.control(now));
            });
        }
    }
}

/// Seed 000's triangle: three omni wheels at 120° on a 0.13 m circle, 0.1 mm counts.
fn omni3() -> Layout {
    let (r, m) = (0.13, 0.0001);
    let at = |deg: f64| {
        let a = deg.to_radians();
        let (s, c) = (libm::sin(a), libm::cos(a));
        // Rolling along the tangent.
        (
            Wheel {
                x: r * c,
                y: r * s,
                ux: -s,
                uy: c,
            },
            m,
        )
    };
    Layout::from_geometry(&[at(0.0), at(120.0), at(240.0)], None, None)
        .expect("seed 000's triangle is a valid layout")
}

/// The slave's estimator at time 0, every encoder at count 0 (its A/B levels those of count
/// 0), the absolute encoder's pins at `abs_levels`.
fn at_rest(layout: &Layout, sensor: SensorMode, abs_levels: u16) -> SlaveEstimator {
    let n = layout.encoders();
    let levels = [QuadratureDecoder::levels_at(0); 4];
    SlaveEstimator::new(layout, sensor, 0, &[0; 4][..n], &levels[..n], abs_levels)
        .expect("a layout the slave takes")
}

/// Edges of every wheel rolling forward at its own steady rate (wheel j every 250 + 40·j µs),
/// in time order, with an update every millisecond: each wheel's first [`PLACING_TICKS`] edges
/// measured as `placing`, then [`CALLS`] edges as `edge` and [`CALLS`] updates as `update` once
/// every wheel is placed.
fn run_layout(
    meter: &mut dyn Meter,
    layout: &Layout,
    abs_levels: u16,
    [placing, edge]: [Case; 2],
    update: Case,
) {
    let n = layout.encoders();
    let mut est = at_rest(layout, SensorMode::TickTimestamps, abs_levels);
    let period_us = |j: usize| 250 + 40 * j as u64;
    let mut counts = [0i64; 4];
    let mut next_us: [u64; 4] = core::array::from_fn(|j| 100 + 17 * j as u64);
    let (mut edges, mut updates) = (0, 0);
    let mut next_update_us = 1000;
    let placed = |counts: &[i64; 4]| counts[..n].iter().all(|&c| c >= PLACING_TICKS as i64);
    while edges < CALLS || updates < CALLS {
        // The next edge of any wheel, or the next update if it comes first.
        let j = (0..n).min_by_key(|&j| next_us[j]).unwrap_or(0);
        if next_update_us <= next_us[j] {
            let t_ns = next_update_us * 1000;
            let c = counts;
            let mut call = || {
                core::hint::black_box(est.sample(t_ns, &c[..n], true, abs_levels, None));
            };
            if placed(&counts) && updates < CALLS {
                meter.measure(update, &mut call);
                updates += 1;
            } else {
                call();
            }
            next_update_us += 1000;
            continue;
        }
        let was_placed = placed(&counts);
        counts[j] += 1;
        let e = EncoderEdge {
            t_us: next_us[j],
            encoder: j as u8,
            levels: QuadratureDecoder::levels_at(counts[j]),
        };
        let mut call = || {
            core::hint::black_box(est.on_edge(e));
        };
        if counts[j] <= PLACING_TICKS as i64 {
            meter.measure(placing, &mut call);
        } else if was_placed && edges < CALLS {
            meter.measure(edge, &mut call);
            edges += 1;
        } else {
            call();
        }
        next_us[j] += period_us(j);
    }
}

/// Sampled counters, every wheel a few counts further at each update.
fn counts_updates(meter: &mut dyn Meter, layout: &Layout, abs_levels: u16, update: Case) {
    let n = layout.encoders();
    let mut est = at_rest(layout, SensorMode::Counts, abs_levels);
    let mut counts = [0i64; 4];
    for k in 1..=CALLS as u64 {
        for (j, c) in counts.iter_mut().enumerate().take(n) {
            *c += 3 + j as i64;
        }
        let c = counts;
        meter.measure(update, &mut || {
            core::hint::black_box(est.sample(k * 1_000_000, &c[..n], false, abs_levels, None));
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    struct Count([usize; Case::ALL.len()]);

    impl Meter for Count {
        fn measure(&mut self, case: Case, call: &mut dyn FnMut()) {
            let i = Case::ALL.iter().position(|&c| c == case).unwrap();
            self.0[i] += 1;
            call();
        }
    }

    #[test]
    fn every_case_is_measured_as_often_as_the_report_says() {
        let mut m = Count([0; Case::ALL.len()]);
        run(&mut m);
        for (case, &calls) in Case::ALL.iter().zip(&m.0) {
            let expected = match case {
                // Each wheel's first ticks: seed 004's two wheels and the triangle's three.
                Case::ExactEdgePlacing => 5 * PLACING_TICKS,
                _ => CALLS,
            };
            assert_eq!(calls, expected, "{case:?}");
        }
    }
}
