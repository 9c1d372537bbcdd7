//! Where a real quadrature encoder puts its edges: not one count apart.
//!
//! An ideal incremental encoder changes its count each time the wheel rolls one step. A real
//! one decodes two channels, A and B, each high for about half of a cycle (one bar and window
//! of the code wheel, four counts), B about a quarter cycle after A; its four edges per cycle
//! (A↑, B↑, A↓, B↓) are where the states begin. A datasheet gives the errors in electrical
//! degrees (°e: a cycle is 360 °e, a count 90 °e). Broadcom's HEDS-9040/9140 (with the
//! HEDS-5140/6140 code wheels), typical / maximum:
//!
//! | error | symbol | typical | maximum |
//! |---|---|---|---|
//! | pulse width (each channel's high time against 180 °e) | ΔP | 7 °e | 30 °e |
//! | logic state width (each state against 90 °e) | ΔS | 5 °e | 30 °e |
//! | phase (A's high centre to B's, against 90 °e) | Δφ | 2 °e | 15 °e |
//! | cycle (one cycle's length against 360 °e) | ΔC | 3 °e | 5.5 °e |
//! | position (over a revolution) | ΔΘ | 10 arcmin | 40 arcmin |
//!
//! The model, per encoder, drawn once from a seed (a part is made once):
//! - **The four edges of a cycle.** Channel A high from 0 to `180 + p_A`, B's high centred
//!   `90 + φ` after A's, `180 + p_B` wide; `p_A`, `p_B` between ΔP/2 and ΔP and `φ` between
//!   Δφ/2 and Δφ, random signs, scaled down together until no state is more than ΔS off
//!   90 °e. So the edges of a cycle sit at 0, `90 + φ + (p_A − p_B)/2`, `180 + p_A`,
//!   `270 + φ + (p_A + p_B)/2` °e. (The state that ends on the next line also takes that
//!   line's placement, below: up to ΔC more.)
//! - **Cycle error**: each line of the code wheel (one per cycle, `counts_per_rev / 4` of them)
//!   placed up to ΔC/2 off, uniform, the same line every revolution: a cycle is then within ΔC
//!   of 360 °e.
//! - **Position error over a revolution** (the code wheel's and the measuring wheel's
//!   eccentricity): a sinusoid of one period per wheel revolution, ΔΘ/2 of shaft angle in
//!   amplitude, plus the wheel's runout (`wheel_runout_m`, ours: not a datasheet figure) as
//!   travel, random phase.
//! - **Capture latency**: each edge's time stamp late by a uniform `[0, capture_jitter_ns]`
//!   (the interrupt's entry, another handler in front of it), never before the encoder's
//!   previous stamp.
//! - **Slip**: the wheel rolls `1 − slip` of the ground's travel (0 in the datasheet presets).
//!
//! Which edge of the cycle a count's edge is depends on where in its cycle the encoder powered
//! on: the quadrature state at power-on (0..3), random per encoder.

use std::fmt;

use anyhow::bail;

use super::phase::{splitmix64, unit, GOLDEN};

/// An encoder's errors, as a datasheet states them (magnitudes; the signs and each line's
/// placement are drawn per encoder).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EdgeErrors {
    /// What these numbers are (a datasheet and a column, or "ideal").
    pub name: &'static str,
    pub pulse_width_error_deg_e: f64,
    pub state_width_error_deg_e: f64,
    pub phase_error_deg_e: f64,
    pub cycle_error_deg_e: f64,
    pub position_error_arcmin: f64,
    /// Counts (after ×4 decoding) per revolution of the code wheel, which turns with the
    /// measuring wheel: the period of the position error.
    pub counts_per_rev: u32,
    /// The measuring wheel's runout: travel error over its revolution, metres (amplitude).
    pub wheel_runout_m: f64,
    pub capture_jitter_ns: u64,
    pub slip: f64,
}

impl EdgeErrors {
    /// Every edge one count after the last, stamped when it happens.
    pub const IDEAL: EdgeErrors = EdgeErrors {
        name: "ideal",
        pulse_width_error_deg_e: 0.0,
        state_width_error_deg_e: 0.0,
        phase_error_deg_e: 0.0,
        cycle_error_deg_e: 0.0,
        position_error_arcmin: 0.0,
        counts_per_rev: 2000,
        wheel_runout_m: 0.0,
        capture_jitter_ns: 0,
        slip: 0.0,
    };

    /// Broadcom HEDS-9040/9140 with a HEDS-5140/6140 code wheel (500 lines: 2 000 counts a
    /// revolution), the datasheet's typical column; a 0.02 mm wheel runout and up to 1 µs of
    /// capture latency (ours).
    pub const HEDS_9040_TYPICAL: EdgeErrors = EdgeErrors {
        name: "HEDS-9040 typical",
        pulse_width_error_deg_e: 7.0,
        state_width_error_deg_e: 5.0,
        phase_error_deg_e: 2.0,
        cycle_error_deg_e: 3.0,
        position_error_arcmin: 10.0,
        counts_per_rev: 2000,
        wheel_runout_m: 0.02e-3,
        capture_jitter_ns: 1_000,
        slip: 0.0,
    };

    /// The same datasheet's maximum column; a 0.1 mm runout and up to 3 µs of latency (ours).
    pub const HEDS_9040_MAX: EdgeErrors = EdgeErrors {
        name: "HEDS-9040 maximum",
        pulse_width_error_deg_e: 30.0,
        state_width_error_deg_e: 30.0,
        phase_error_deg_e: 15.0,
        cycle_error_deg_e: 5.5,
        position_error_arcmin: 40.0,
        counts_per_rev: 2000,
        wheel_runout_m: 0.1e-3,
        capture_jitter_ns: 3_000,
        slip: 0.0,
    };

    /// `ideal`, `typical` or `max` (the HEDS-9040 columns), or `typical-cycle` / `max-cycle`:
    /// the same column's errors inside a revolution only (the four edges of each cycle and
    /// each line's placement), without the position error over a revolution, the runout or
    /// the capture latency.
    pub fn preset(name: &str) -> anyhow::Result<EdgeErrors> {
        Ok(match name {
            "ideal" => Self::IDEAL,
            "typical" => Self::HEDS_9040_TYPICAL,
            "max" => Self::HEDS_9040_MAX,
            "typical-cycle" => Self::HEDS_9040_TYPICAL.cycle_only("HEDS-9040 typical, cycle only"),
            "max-cycle" => Self::HEDS_9040_MAX.cycle_only("HEDS-9040 maximum, cycle only"),
            other => bail!(
                "the encoder edges must be ideal, typical, max, typical-cycle or max-cycle \
                 (Broadcom HEDS-9040's datasheet columns), got {other:?}"
            ),
        })
    }

    /// The errors inside a cycle and each line's placement only.
    const fn cycle_only(self, name: &'static str) -> EdgeErrors {
        EdgeErrors {
            name,
            position_error_arcmin: 0.0,
            wheel_runout_m: 0.0,
            capture_jitter_ns: 0,
            ..self
        }
    }

    pub fn is_ideal(&self) -> bool {
        *self == Self::IDEAL
    }
}

impl Default for EdgeErrors {
    fn default() -> Self {
        Self::IDEAL
    }
}

impl fmt::Display for EdgeErrors {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name)
    }
}

/// One encoder's edges, drawn from [`EdgeErrors`]: where (in counts of travel from the wheel's
/// power-on edge) its m-th edge is, and the count at a travel.
#[derive(Clone, Debug)]
pub struct EdgeMap {
    /// The power-on quadrature state: count m's edge is edge `(m + q0) mod 4` of its cycle.
    pub q0: u8,
    /// Edge k of a cycle, counts from its ideal place k (the four average 0).
    pub cycle_edges: [f64; 4],
    /// Each line's offset, counts (one per cycle of the code wheel).
    lines: Vec<f64>,
    /// Per-revolution term: amplitude (counts) and phase (rad).
    rev_amplitude: f64,
    rev_phase: f64,
    counts_per_rev: f64,
    /// Counts of the wheel's travel per metre of the ground's (1 − slip).
    pub scale: f64,
    pub capture_jitter_ns: u64,
    /// The capture latency's draws (a SplitMix64 state of the encoder's own).
    latency_draws: u64,
    ideal: bool,
}

/// Draws from a SplitMix64 stream.
struct Draws(u64);

impl Draws {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(GOLDEN);
        unit(splitmix64(self.0))
    }
    fn sign(&mut self) -> f64 {
        if self.next() < 0.5 {
            -1.0
        } else {
            1.0
        }
    }
}

impl EdgeMap {
    /// Encoder `index`'s edges from `errors`, reproducible from `seed`; `metres_per_count`
    /// turns the wheel's runout into counts.
    pub fn draw(errors: &EdgeErrors, seed: u64, index: usize, metres_per_count: f64) -> EdgeMap {
        let mut d = Draws(
            splitmix64(seed ^ 0x6564_6765_7300_0000).wrapping_add(index as u64 * 0x1_0000_0001),
        );
        let counts_per_rev = errors.counts_per_rev.max(4) as f64;
        let q0 = (d.next() * 4.0) as u8 & 3;
        // The four edges, °e.
        // Each error between half the column's figure and all of it, either sign.
        let mut magnitude = |figure: f64| d.sign() * figure * (0.5 + 0.5 * d.next());
        let (mut pa, mut pb, mut ph) = (
            magnitude(errors.pulse_width_error_deg_e),
            magnitude(errors.pulse_width_error_deg_e),
            magnitude(errors.phase_error_deg_e),
        );
        let edges = |pa: f64, pb: f64, ph: f64| {
            [
                0.0,
                90.0 + ph + (pa - pb) / 2.0,
                180.0 + pa,
                270.0 + ph + (pa + pb) / 2.0,
            ]
        };
        // Each state's error, °e: linear in (p_A, p_B, φ), so scaling them scales these. (The
        // last state ends on the next cycle's first edge, on the next line: the lines'
        // placement adds up to ΔC to it.)
        let e = edges(pa, pb, ph);
        let states: [f64; 4] = core::array::from_fn(|k| {
            let next = if k == 3 { 360.0 } else { e[k + 1] };
            (next - e[k] - 90.0).abs()
        });
        let worst = states.iter().cloned().fold(0.0, f64::max);
        if worst > errors.state_width_error_deg_e {
            let k = errors.state_width_error_deg_e / worst;
            (pa, pb, ph) = (pa * k, pb * k, ph * k);
        }
        let e = edges(pa, pb, ph);
        let mean = (0..4).map(|k| e[k] - 90.0 * k as f64).sum::<f64>() / 4.0;
        let cycle_edges = core::array::from_fn(|k| (e[k] - 90.0 * k as f64 - mean) / 90.0);
        let lines = (0..(counts_per_rev as usize / 4).max(1))
            .map(|_| (d.next() - 0.5) * errors.cycle_error_deg_e / 90.0)
            .collect();
        // ΔΘ is peak to peak over a revolution: half of it, in counts of the shaft's angle.
        let position = errors.position_error_arcmin / 2.0 / 60.0 / 360.0 * counts_per_rev;
        let runout = errors.wheel_runout_m / metres_per_count;
        let rev_phase = d.next() * std::f64::consts::TAU;
        EdgeMap {
            q0,
            cycle_edges,
            lines,
            rev_amplitude: position + runout,
            rev_phase,
            counts_per_rev,
            scale: 1.0 - errors.slip,
            capture_jitter_ns: errors.capture_jitter_ns,
            latency_draws: splitmix64(0x6c61_7465 ^ (index as u64).wrapping_mul(GOLDEN)),
            ideal: errors.is_ideal(),
        }
    }

    /// Every edge one count after the last.
    pub fn ideal() -> EdgeMap {
        EdgeMap::draw(&EdgeErrors::IDEAL, 0, 0, 1.0)
    }

    pub fn is_ideal(&self) -> bool {
        self.ideal
    }

    /// Where count `m`'s edge is: counts of travel from the power-on cycle's start (m itself
    /// for an ideal encoder).
    pub fn edge(&self, m: i64) -> f64 {
        if self.ideal {
            return m as f64;
        }
        let k = m + self.q0 as i64;
        let cycle = k.div_euclid(4);
        let line = self.lines[cycle.rem_euclid(self.lines.len() as i64) as usize];
        // Zero at count 0: it is where the wheel's travel is counted from.
        let angle = std::f64::consts::TAU * (m as f64 / self.counts_per_rev) + self.rev_phase;
        m as f64
            + self.cycle_edges[k.rem_euclid(4) as usize]
            + line
            + self.rev_amplitude * (angle.sin() - self.rev_phase.sin())
    }

    /// How late the next edge's time stamp is, ns: uniform in `[0, capture_jitter_ns]` (the
    /// caller keeps the stamps in order).
    pub fn latency_ns(&mut self) -> u64 {
        if self.capture_jitter_ns == 0 {
            return 0;
        }
        self.latency_draws = self.latency_draws.wrapping_add(GOLDEN);
        splitmix64(self.latency_draws) % (self.capture_jitter_ns + 1)
    }

    /// The count at `x` counts of travel: the last edge at or before it.
    pub fn count_at(&self, x: f64) -> i64 {
        let mut m = x.floor() as i64;
        if self.ideal {
            return m;
        }
        // The edges are within a few counts of their ideal places (the revolution term's
        // amplitude at most): step to the right one.
        while self.edge(m + 1) <= x {
            m += 1;
        }
        while self.edge(m) > x {
            m -= 1;
        }
        m
    }

    /// The smallest gap between consecutive edges over a revolution, counts (an encoder whose
    /// edges cross is no encoder: the draw must keep this well above 0).
    pub fn min_gap(&self) -> f64 {
        let n = self.counts_per_rev as i64 + 4;
        (0..n)
            .map(|m| self.edge(m + 1) - self.edge(m))
            .fold(f64::INFINITY, f64::min)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ideal_edges_are_whole_counts() {
        let e = EdgeMap::ideal();
        for m in -5..5 {
            assert_eq!(e.edge(m), m as f64);
            assert_eq!(e.count_at(m as f64 + 0.5), m);
        }
    }

    #[test]
    fn states_stay_within_the_datasheet_bound() {
        for (errors, bound) in [
            (EdgeErrors::HEDS_9040_TYPICAL, 5.0),
            (EdgeErrors::HEDS_9040_MAX, 30.0),
        ] {
            let mut worst: f64 = 0.0;
            for seed in 0..50 {
                let e = EdgeMap::draw(&errors, seed, 0, 1e-4);
                let edges: Vec<f64> = (0..5).map(|k| e.cycle_edges[k % 4] + k as f64).collect();
                for k in 0..4 {
                    let next = if k == 3 { edges[0] + 4.0 } else { edges[k + 1] };
                    worst = worst.max(((next - edges[k]) * 90.0 - 90.0).abs());
                }
                assert!(e.min_gap() > 0.5, "{}: gap {}", errors, e.min_gap());
            }
            // At the bound (the draw scales down to it), never past it.
            assert!(
                worst <= bound + 1e-9 && worst > 0.8 * bound,
                "{errors}: {worst}"
            );
        }
    }

    #[test]
    fn count_at_inverts_edge() {
        let e = EdgeMap::draw(&EdgeErrors::HEDS_9040_MAX, 7, 1, 1e-4);
        for m in -3000..3000 {
            let x = e.edge(m);
            assert_eq!(e.count_at(x), m, "on edge {m}");
            assert_eq!(e.count_at(x - 1e-9), m - 1, "before edge {m}");
        }
        assert_eq!(e.edge(0), e.cycle_edges[e.q0 as usize] + e.lines_at(0));
    }

    impl EdgeMap {
        fn lines_at(&self, m: i64) -> f64 {
            let k = m + self.q0 as i64;
            self.lines[k.div_euclid(4).rem_euclid(self.lines.len() as i64) as usize]
        }
    }

    #[test]
    fn a_cycle_spans_four_counts_give_or_take_the_cycle_error() {
        let e = EdgeMap::draw(&EdgeErrors::HEDS_9040_MAX, 3, 0, 1e-4);
        let e = EdgeMap {
            rev_amplitude: 0.0,
            ..e
        };
        for m in 0..2000 {
            let cycle = (e.edge(m + 4) - e.edge(m)) * 90.0;
            assert!((cycle - 360.0).abs() <= 5.5 + 1e-9, "{m}: {cycle}");
        }
    }
}
