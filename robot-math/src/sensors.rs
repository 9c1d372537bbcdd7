//! Sensor decoding: Gray-code absolute encoders and wrapping hardware counters.

/// Decode a reflected binary Gray code.
pub fn gray_to_binary(gray: u16) -> u16 {
    let mut b = gray;
    let mut shift = gray >> 1;
    while shift != 0 {
        b ^= shift;
        shift >>= 1;
    }
    b
}

/// Encode a value as reflected binary Gray code.
pub fn binary_to_gray(b: u16) -> u16 {
    b ^ (b >> 1)
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
