//! Noise on one direction of a serial line, frame by frame: the virtual board's fault knob.
//!
//! Frames end at a 0x00 byte (COBS). Each whole frame passes, is lost, has one bit flipped
//! (which may also split it, if the flip makes a 0x00), arrives twice, is held back and
//! arrives after the next frame, or is torn (the line drops out part way: a piece of the
//! frame arrives without its end, so the receiver reads it and the next frame as one bad
//! frame), at the given rates, drawn from its own seeded generator so a
//! run can be repeated. A frame's bytes are held until its end arrives,
//! so a noisy line adds at most one frame of latency; a quiet one passes bytes straight on.

use protocol::serial::{FrameDecoder, FrameError, HostToMaster, MasterToHost};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

/// The frames the receiving end's decoder refuses, by why (`protocol::serial::FrameError`),
/// as a copy of that decoder at the end of the line sees them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct SerialRejections {
    pub overflow: u64,
    pub cobs: u64,
    pub short: u64,
    pub crc: u64,
    pub decode: u64,
    pub non_canonical: u64,
}

impl SerialRejections {
    fn count(&mut self, e: FrameError) {
        let n = match e {
            FrameError::Overflow => &mut self.overflow,
            FrameError::Cobs => &mut self.cobs,
            FrameError::Short => &mut self.short,
            FrameError::Crc => &mut self.crc,
            FrameError::Decode => &mut self.decode,
            FrameError::NonCanonical => &mut self.non_canonical,
        };
        *n += 1;
    }

    pub fn total(&self) -> u64 {
        self.overflow + self.cobs + self.short + self.crc + self.decode + self.non_canonical
    }
}

/// Which end the line runs to: what its frames decode as.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Receiver {
    Master,
    Host,
}

/// What the noise did to the frames.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct SerialInjected {
    pub corrupted: u64,
    pub dropped: u64,
    pub duplicated: u64,
    pub delayed: u64,
    pub torn: u64,
}

/// Rates per frame, each in [0, 1) and together under 1.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SerialFaults {
    pub corrupt: f64,
    pub drop: f64,
    pub duplicate: f64,
    pub delay: f64,
    pub torn: f64,
}

impl SerialFaults {
    /// The chance that a frame is touched at all (the rates share one draw: under 1).
    pub fn total(&self) -> f64 {
        self.corrupt + self.drop + self.duplicate + self.delay + self.torn
    }
}

pub struct SerialNoise {
    faults: SerialFaults,
    rng: ChaCha8Rng,
    frame: Vec<u8>,
    /// A frame held back, to go out after the next one.
    held: Option<Vec<u8>>,
    pub injected: SerialInjected,
    /// The receiver's decoder, copied, and what it refused.
    receiver: (Receiver, FrameDecoder),
    pub rejected: SerialRejections,
}

impl SerialNoise {
    pub fn new(faults: SerialFaults, seed: u64, receiver: Receiver) -> Self {
        SerialNoise {
            faults,
            rng: ChaCha8Rng::seed_from_u64(seed),
            frame: Vec::new(),
            held: None,
            injected: SerialInjected::default(),
            receiver: (receiver, FrameDecoder::new()),
            rejected: SerialRejections::default(),
        }
    }

    /// What the receiver's decoder makes of `out`: each refusal counted by why. (Only on a
    /// noisy line: a quiet one passes the senders' own frames, which always decode.)
    fn tally(&mut self, out: &[u8]) {
        let (receiver, decoder) = &mut self.receiver;
        for &b in out {
            let refused = match receiver {
                Receiver::Master => decoder.push::<HostToMaster>(b).and_then(Result::err),
                Receiver::Host => decoder.push::<MasterToHost>(b).and_then(Result::err),
            };
            if let Some(e) = refused {
                self.rejected.count(e);
            }
        }
    }

    /// The bytes that come out of the line for `bytes` going in.
    pub fn pass(&mut self, bytes: &[u8]) -> Vec<u8> {
        if self.faults == SerialFaults::default() {
            return bytes.to_vec();
        }
        let SerialFaults {
            corrupt,
            drop,
            duplicate,
            delay,
            torn,
        } = self.faults;
        let mut out = Vec::with_capacity(bytes.len());
        for &b in bytes {
            self.frame.push(b);
            // A frame is at most a few hundred bytes; a line of garbage without a delimiter
            // is passed on in pieces rather than held for ever.
            if b != 0 && self.frame.len() < 4096 {
                continue;
            }
            let r: f64 = self.rng.random();
            let mut frame = std::mem::take(&mut self.frame);
            if r < drop {
                self.injected.dropped += 1;
                continue;
            }
            let r = r - drop;
            if r < corrupt && frame.len() > 1 {
                let i = self.rng.random_range(0..frame.len() - 1);
                frame[i] ^= 1 << self.rng.random_range(0..8);
                self.injected.corrupted += 1;
            } else if r >= corrupt && r < corrupt + duplicate {
                self.injected.duplicated += 1;
                out.extend_from_slice(&frame);
            } else if r >= corrupt + duplicate
                && r < corrupt + duplicate + delay
                && self.held.is_none()
            {
                self.injected.delayed += 1;
                self.held = Some(frame);
                continue;
            } else if r >= corrupt + duplicate + delay
                && r < corrupt + duplicate + delay + torn
                && frame.len() > 1
            {
                // A piece without the delimiter: the next frame's bytes run on after it.
                self.injected.torn += 1;
                let keep = self.rng.random_range(1..frame.len());
                out.extend_from_slice(&frame[..keep]);
                continue;
            }
            out.extend_from_slice(&frame);
            if let Some(held) = self.held.take() {
                out.extend_from_slice(&held);
            }
        }
        self.tally(&out);
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
        let mut line = SerialNoise::new(SerialFaults::default(), 1, Receiver::Master);
        assert_eq!(line.pass(&[5, 6]), [5, 6]);
    }

    #[test]
    fn frames_are_lost_or_damaged_whole_at_about_their_rates() {
        let input = frames(20_000);
        let faults = SerialFaults {
            corrupt: 0.01,
            drop: 0.05,
            ..Default::default()
        };
        let mut line = SerialNoise::new(faults, 7, Receiver::Master);
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

    #[test]
    fn a_torn_frame_arrives_as_a_piece_run_into_the_next() {
        let input = frames(2_000);
        let faults = SerialFaults {
            torn: 0.05,
            ..Default::default()
        };
        let mut line = SerialNoise::new(faults, 5, Receiver::Master);
        let out = line.pass(&input);
        let i = line.injected;
        assert!((60..140).contains(&i.torn), "{i:?}");
        // Each tear loses its frame's end: one delimiter fewer, and a piece of 1-3 bytes runs
        // into the frame after it.
        let ends = out.iter().filter(|&&b| b == 0).count() as u64;
        assert_eq!(ends, 2_000 - i.torn);
        let runs_on = out.split(|&b| b == 0).filter(|f| f.len() > 3).count() as u64;
        assert!(runs_on > 0 && runs_on <= i.torn, "{runs_on} {i:?}");
    }

    #[test]
    fn duplicated_and_delayed_frames_arrive_twice_or_one_frame_late() {
        let input: Vec<u8> = (1..=200u8).flat_map(|i| [i, 0]).collect();
        let faults = SerialFaults {
            duplicate: 0.05,
            delay: 0.05,
            ..Default::default()
        };
        let mut line = SerialNoise::new(faults, 3, Receiver::Master);
        let out = line.pass(&input);
        let i = line.injected;
        assert!(i.duplicated > 2 && i.delayed > 2, "{i:?}");
        let got: Vec<u8> = out.chunks(2).map(|f| f[0]).collect();
        // Every frame arrives; a held one at most one frame late.
        let mut seen: Vec<u8> = got.clone();
        seen.sort();
        seen.dedup();
        assert_eq!(seen.len(), 200 - usize::from(line.held.is_some()));
        assert_eq!(
            got.len() as u64,
            200 + i.duplicated - u64::from(line.held.is_some())
        );
        for (k, w) in got.windows(2).enumerate() {
            assert!(w[1] + 2 >= w[0], "frame {k}: {w:?}");
        }
    }
}
