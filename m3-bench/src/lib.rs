//! The measured calls of the Cortex-M3 instruction-count benchmark (`scripts/m3-bench`; the
//! image that runs them under QEMU is `src/main.rs` and `src/chip.rs`).
//!
//! The calls are the slave's own code paths ([`SlaveEstimator`], as the odometry task
//! calls it), on the board's default layout (seed 004's swivel carriage) and on a body-fixed
//! 3-omni triangle. Portable: on the chip each call runs between two markers (`chip.rs`), on the
//! host a test runs every case once.
#![no_std]

use firmware_slave::ports::EncoderEdge;
use firmware_slave::{SensorMode, SlaveConfig, SlaveEstimator};
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
}

impl Case {
    pub const ALL: [Case; 8] = [
        Case::Empty,
        Case::ExactEdge,
        Case::ExactEdgePlacing,
        Case::ExactTicksUpdate,
        Case::ExactCountsUpdate,
        Case::Omni3Edge,
        Case::Omni3TicksUpdate,
        Case::Omni3CountsUpdate,
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
        &seed004.layout,
        abs_levels,
        edges,
        Case::ExactTicksUpdate,
    );
    counts_updates(meter, &seed004.layout, abs_levels, Case::ExactCountsUpdate);
    let omni = omni3();
    run_layout(
        meter,
        &omni,
        0,
        [Case::ExactEdgePlacing, Case::Omni3Edge],
        Case::Omni3TicksUpdate,
    );
    counts_updates(meter, &omni, 0, Case::Omni3CountsUpdate);
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
