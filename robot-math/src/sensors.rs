//! Sensor decoding: Gray-code absolute encoders and wrapping hardware counters.

/// Decode a reflected binary Gray code.
///
/// Bit k of the result is the XOR of the Gray code's bits k and up: four shifted XORs make
/// that prefix for 16 bits (a loop over the bits cost the slave about 20 instructions an
/// update).
pub fn gray_to_binary(gray: u16) -> u16 {
    // In 32 bits: a `u16` is zero-extended again before each shift.
    let mut b = gray as u32;
    b ^= b >> 1;
    b ^= b >> 2;
    b ^= b >> 4;
    b ^= b >> 8;
    b as u16
}

/// Encode a value as reflected binary Gray code.
pub fn binary_to_gray(b: u16) -> u16 {
    b ^ (b >> 1)
}

/// Rim speeds (m/s) from two readings of free-running 16-bit encoder counters `dt` seconds
/// apart: the wrapped difference, so a counter passing 65535 → 0 reads as the one count it
/// moved (valid while a wheel moves under 32 768 counts between readings).
pub fn speeds_from_counts<const N: usize>(
    before: [u16; N],
    now: [u16; N],
    metres_per_count: f64,
    dt: f64,
) -> [f64; N] {
    core::array::from_fn(|i| now[i].wrapping_sub(before[i]) as i16 as f64 * metres_per_count / dt)
}

/// Extends a wrapping 16-bit hardware counter (a timer in encoder mode) to a 64-bit total.
///
/// Correct as long as the counter moves less than half its range (32 768 counts) between two
/// calls to [`CounterExtender::update`]; a larger step is reported so it can be flagged.
#[derive(Clone, Copy, Debug, Default)]
pub struct CounterExtender {
    last: u16,
    total: i64,
}

impl CounterExtender {
    /// Start from the counter's current raw value; the total starts at zero.
    pub const fn new(raw: u16) -> Self {
        CounterExtender {
            last: raw,
            total: 0,
        }
    }

    /// Feed the current raw value; returns the new total and whether the step was suspicious
    /// (|step| >= 16 384, a quarter of the range: a sign that reads are too far apart).
    pub fn update(&mut self, raw: u16) -> (i64, bool) {
        // Two's-complement difference: the wrap-around is exact for |step| < 32 768.
        let step = raw.wrapping_sub(self.last) as i16;
        self.last = raw;
        self.total += step as i64;
        (self.total, step.unsigned_abs() >= 1 << 14)
    }

    pub fn total(&self) -> i64 {
        self.total
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gray_round_trip_and_adjacency() {
        for v in 0..=u16::MAX {
            assert_eq!(gray_to_binary(binary_to_gray(v)), v);
        }
        for v in 0..255u16 {
            // Neighbouring codes differ in one bit: the point of Gray code.
            assert_eq!((binary_to_gray(v) ^ binary_to_gray(v + 1)).count_ones(), 1);
        }
    }

    #[test]
    fn counter_extends_across_wraps_both_ways() {
        let mut raw: u16 = 65_530;
        let mut c = CounterExtender::new(raw);
        let mut expect = 0i64;
        for step in [3i64, 7, 20_000, 20_000, -5, -30_000, -30_000, -30_000, 12] {
            raw = (raw as i64 + step).rem_euclid(65_536) as u16;
            expect += step;
            assert_eq!(c.update(raw).0, expect);
        }
    }
}

/// x4 quadrature decoding of edge events: the A/B levels after each edge give a step of ±1.
///
/// Levels are `bit 0 = A, bit 1 = B`. Forward is the sequence 00 → 01 → 11 → 10 → 00 (A leads
/// B), which is what a timer in encoder mode counts up. A change of both bits at once means an
/// edge was missed: it is reported, and no step is guessed.
#[derive(Clone, Copy, Debug)]
pub struct QuadratureDecoder {
    last: u8,
}

/// What one edge meant.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Quadrature {
    Step(i8),
    /// Levels unchanged (a bounce that came back, or a duplicate report).
    None,
    /// Both channels changed: at least one edge was lost.
    Missed,
}

impl QuadratureDecoder {
    /// Start from the current levels.
    pub const fn new(levels: u8) -> Self {
        QuadratureDecoder { last: levels & 3 }
    }

    /// Position of a level pair in the forward cycle 00, 01, 11, 10: the levels are its Gray
    /// code, so the position is `g ^ (g >> 1)` (branch-free: it runs on every edge).
    #[inline(always)]
    const fn phase(levels: u8) -> u8 {
        let g = levels & 3;
        g ^ (g >> 1)
    }

    /// The levels an encoder shows at cumulative count `c` (for emulation and tests).
    pub const fn levels_at(count: i64) -> u8 {
        [0b00, 0b01, 0b11, 0b10][count.rem_euclid(4) as usize]
    }

    pub fn edge(&mut self, levels: u8) -> Quadrature {
        let (from, to) = (Self::phase(self.last), Self::phase(levels));
        self.last = levels & 3;
        match to.wrapping_sub(from) & 3 {
            0 => Quadrature::None,
            1 => Quadrature::Step(1),
            3 => Quadrature::Step(-1),
            _ => Quadrature::Missed,
        }
    }
}

#[cfg(test)]
mod quadrature_tests {
    use super::*;

    #[test]
    fn decodes_both_directions_and_flags_missed_edges() {
        let mut d = QuadratureDecoder::new(QuadratureDecoder::levels_at(0));
        let mut count = 0i64;
        for c in (1..=9).chain((3..9).rev()) {
            match d.edge(QuadratureDecoder::levels_at(c)) {
                Quadrature::Step(s) => count += s as i64,
                other => panic!("{other:?} at {c}"),
            }
            assert_eq!(count, c);
        }
        // Skipping a level pair (two edges at once) is a missed edge, not a guess.
        assert_eq!(
            d.edge(QuadratureDecoder::levels_at(count + 2)),
            Quadrature::Missed
        );
        assert_eq!(
            d.edge(QuadratureDecoder::levels_at(count + 2)),
            Quadrature::None
        );
    }
}
