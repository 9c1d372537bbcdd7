//! Noise on one direction of a serial line, frame by frame: the virtual board's fault knob.
//!
//! Frames end at a 0x00 byte (COBS). Each whole frame passes, is lost, or has one bit flipped
//! (which may also split it, if the flip makes a 0x00), at the given rates, drawn from its own
//! seeded generator so a run can be repeated. A frame's bytes are held until its end arrives,
//! so a noisy line adds at most one frame of latency; a quiet one passes bytes straight on.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

/// What the noise did to the frames.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct SerialInjected {
    pub corrupted: u64,
    pub dropped: u64,
}

pub struct SerialNoise {
    corrupt: f64,
    drop: f64,
    rng: ChaCha8Rng,
    frame: Vec<u8>,
    pub injected: SerialInjected,
}

impl SerialNoise {
    /// Rates per frame, each in [0, 1).
    pub fn new(corrupt: f64, drop: f64, seed: u64) -> Self {
        SerialNoise {
            corrupt,
            drop,
            rng: ChaCha8Rng::seed_from_u64(seed),
            frame: Vec::new(),
            injected: SerialInjected::default(),
        }
    }

    /// The bytes that come out of the line for `bytes` going in.
    pub fn pass(&mut self, bytes: &[u8]) -> Vec<u8> {
        if self.corrupt == 0.0 && self.drop == 0.0 {
            return bytes.to_vec();
        }
        let mut out = Vec::with_capacity(bytes.len());
        for &b in bytes {
            self.frame.push(b);
            // A frame is at most a few hundred bytes; a line of garbage without a delimiter
            // is passed on in pieces rather than held for ever.
            if b != 0 && self.frame.len() < 4096 {
                continue;
            }
            let r: f64 = self.rng.random();
            if r < self.drop {
                self.injected.dropped += 1;
            } else {
                if r < self.drop + self.corrupt && self.frame.len() > 1 {
                    let i = self.rng.random_range(0..self.frame.len() - 1);
                    self.frame[i] ^= 1 << self.rng.random_range(0..8);
                    self.injected.corrupted += 1;
                }
                out.extend_from_slice(&self.frame);
            }
            self.frame.clear();
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frames(n: usize) -> Vec<u8> {
        (0..n).flat_map(|_| [3, 7, 9, 0]).collect()
    }

    #[test]
    fn a_quiet_line_passes_every_byte_at_once() {
        let mut line = SerialNoise::new(0.0, 0.0, 1);
        assert_eq!(line.pass(&[5, 6]), [5, 6]);
    }

    #[test]
    fn frames_are_lost_or_damaged_whole_at_about_their_rates() {
        let input = frames(20_000);
        let mut line = SerialNoise::new(0.01, 0.05, 7);
        // In pieces that cut frames anywhere: a frame is judged once it is complete.
        let mut out = Vec::new();
        for piece in input.chunks(5) {
            out.extend(line.pass(piece));
        }
        let i = line.injected;
        assert!((800..1200).contains(&i.dropped), "{i:?}");
        assert!((140..260).contains(&i.corrupted), "{i:?}");
        assert_eq!(out.len(), input.len() - 4 * i.dropped as usize);
        // One bit of one byte of each damaged frame, never its end.
        let damaged = out.chunks(4).filter(|f| *f != [3, 7, 9, 0]).count();
        assert_eq!(damaged as u64, i.corrupted);
    }
}
