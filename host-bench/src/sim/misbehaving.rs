//! A board that misbehaves on purpose on its serial line to the host: the virtual board's
//! `--misbehave` knob, for tests of what `play` and `record` do when a board talks without
//! progress, goes silent, sends what does not decode or numbers out of range, or hangs up.
//!
//! Unlike the line noise of [`super::serial_noise`] (random, per frame, which the links
//! recover from), each behaviour here is one deliberate failure of the board, starting once
//! the host has been sent a given number of report frames (so a test can place it mid-play or
//! mid-recording whatever the host's set-up took). The frames are decoded, changed and encoded
//! again with a good check: what the host sees is a board that says wrong things well.

use protocol::serial::{self, FrameDecoder, MasterToHost};

/// What the board does wrong once triggered.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Act {
    /// Nothing more reaches the host: the board went silent.
    Stall,
    /// Only telemetry reaches the host, the line kept full of it: a board that talks and does
    /// nothing else.
    Flood,
    /// The last acknowledgement sent before the trigger, again and again (in place of the
    /// master's own, the line kept full as by `flood`), and no more reports; telemetry passes:
    /// stale acknowledgements, no progress.
    RepeatAck,
    /// The triggering report frame's bytes are replaced by bytes that are no report record
    /// (a good frame with a good check: the stream inside it is what is wrong); later frames
    /// pass as they are.
    BadRecord,
    /// From the trigger on, the true pose's time stamp is near 2^62 µs.
    HugeTime,
    /// The triggering frame is cut short (no end), and the board sends nothing more.
    Truncate,
    /// The board hangs up: the virtual board stops serving and its end of the port closes.
    Close,
    /// From the trigger on, one frame in ten reaches the host.
    Slow,
}

/// One deliberate failure: `act` once `after_reports` report frames have reached the host.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Misbehaviour {
    pub act: Act,
    pub after_reports: u32,
}

impl Misbehaviour {
    pub const NAMES: &'static str =
        "stall, flood, repeat-ack, bad-record, huge-time, truncate, close, slow";

    /// `ACT` or `ACT@N` (after N report frames; default 20).
    pub fn parse(s: &str) -> Result<Misbehaviour, String> {
        let (name, after) = match s.split_once('@') {
            Some((n, a)) => (
                n,
                a.parse::<u32>()
                    .map_err(|_| format!("{s:?}: after `@` a count of report frames, got {a:?}"))?,
            ),
            None => (s, 20),
        };
        let act = match name {
            "stall" => Act::Stall,
            "flood" => Act::Flood,
            "repeat-ack" => Act::RepeatAck,
            "bad-record" => Act::BadRecord,
            "huge-time" => Act::HugeTime,
            "truncate" => Act::Truncate,
            "close" => Act::Close,
            "slow" => Act::Slow,
            _ => return Err(format!("{name:?} is no misbehaviour: {}", Self::NAMES)),
        };
        Ok(Misbehaviour {
            act,
            after_reports: after,
        })
    }
}

/// The master-to-host line with one misbehaviour on it.
pub struct MisbehavingLine {
    what: Misbehaviour,
    decoder: FrameDecoder,
    reports_passed: u32,
    triggered: bool,
    last_ack: Option<MasterToHost>,
    last_telemetry: Option<MasterToHost>,
    frames_since: u32,
    closed: bool,
    /// When the last round's repeated frames went out (`flood`, `repeat-ack`).
    flooded_at: Option<std::time::Instant>,
}

/// What 115 200 baud carries, bytes a second (10 bits a byte).
const LINE_BYTES_PER_S: f64 = 11_520.0;

impl MisbehavingLine {
    pub fn new(what: Misbehaviour) -> Self {
        MisbehavingLine {
            what,
            decoder: FrameDecoder::new(),
            reports_passed: 0,
            triggered: false,
            last_ack: None,
            last_telemetry: None,
            frames_since: 0,
            closed: false,
            flooded_at: None,
        }
    }

    /// Whether the board has hung up (`close`): the caller stops serving.
    pub fn hung_up(&self) -> bool {
        self.closed && self.what.act == Act::Close
    }

    /// What reaches the host for the master's `bytes` (whole frames are judged; a frame's
    /// start waits in the decoder for its end).
    pub fn pass(&mut self, bytes: &[u8]) -> Vec<u8> {
        let mut out = Vec::new();
        for &b in bytes {
            let Some(Ok(msg)) = self.decoder.push::<MasterToHost>(b) else {
                continue;
            };
            if let Some(m) = self.judge(msg) {
                let mut f = [0u8; serial::MAX_FRAME];
                if let Ok(frame) = serial::encode(&m, &mut f) {
                    if self.triggered && self.what.act == Act::Truncate && !self.closed {
                        out.extend_from_slice(&frame[..frame.len() / 2]);
                        self.closed = true; // nothing more after the torn frame
                        continue;
                    }
                    out.extend_from_slice(frame);
                }
            }
        }
        let again = match self.what.act {
            Act::Flood => &self.last_telemetry,
            Act::RepeatAck => &self.last_ack,
            _ => &None,
        };
        if self.triggered {
            if let Some(t) = again {
                // The line kept full: as many frames as 115 200 baud carries in the time
                // since the last round (at least one), so the host never waits for a byte.
                let mut f = [0u8; serial::MAX_FRAME];
                if let Ok(frame) = serial::encode(t, &mut f) {
                    let now = std::time::Instant::now();
                    let since = self.flooded_at.map_or(0.0, |t| (now - t).as_secs_f64());
                    self.flooded_at = Some(now);
                    let n = ((since * LINE_BYTES_PER_S) as usize / frame.len()).clamp(1, 64);
                    for _ in 0..n {
                        out.extend_from_slice(frame);
                    }
                }
            }
        }
        out
    }

    /// The frame the host gets for `msg`, if any.
    fn judge(&mut self, msg: MasterToHost) -> Option<MasterToHost> {
        if self.closed && self.what.act != Act::Close {
            return None;
        }
        let is_report = matches!(&msg, MasterToHost::Reports(d) if !d.bytes.is_empty());
        if !self.triggered {
            match &msg {
                MasterToHost::EventsAck(_) => self.last_ack = Some(msg.clone()),
                MasterToHost::Telemetry(_) => self.last_telemetry = Some(msg.clone()),
                _ => {}
            }
            if is_report {
                self.reports_passed += 1;
                if self.reports_passed > self.what.after_reports {
                    self.triggered = true;
                } else {
                    return Some(msg);
                }
            } else {
                return Some(msg);
            }
        }
        // Triggered: `msg` is the triggering report frame or any frame after it.
        match self.what.act {
            Act::Stall => None,
            Act::Flood => match msg {
                MasterToHost::Telemetry(_) => {
                    self.last_telemetry = Some(msg.clone());
                    Some(msg)
                }
                _ => None,
            },
            Act::RepeatAck => match msg {
                MasterToHost::EventsAck(_) => self.last_ack.clone(),
                MasterToHost::Telemetry(_) => Some(msg),
                _ => None,
            },
            Act::BadRecord => match msg {
                MasterToHost::Reports(mut d) if self.frames_since == 0 => {
                    self.frames_since += 1;
                    // 0xFF is no report variant's tag: the record cannot decode.
                    for b in d.bytes.iter_mut() {
                        *b = 0xFF;
                    }
                    Some(MasterToHost::Reports(d))
                }
                m => Some(m),
            },
            Act::HugeTime => match msg {
                MasterToHost::SimTruth { t_us, pose } => Some(MasterToHost::SimTruth {
                    t_us: t_us | (1 << 62),
                    pose,
                }),
                m => Some(m),
            },
            Act::Truncate => Some(msg),
            Act::Close => {
                self.closed = true;
                None
            }
            Act::Slow => {
                self.frames_since += 1;
                (self.frames_since % 10 == 1).then_some(msg)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use protocol::link::{Ack, DataFrame};

    fn frame(msg: &MasterToHost) -> Vec<u8> {
        let mut f = [0u8; serial::MAX_FRAME];
        serial::encode(msg, &mut f).unwrap().to_vec()
    }

    fn report(seq: u16) -> MasterToHost {
        MasterToHost::Reports(DataFrame {
            seq,
            bytes: [1u8, 2, 3][..].try_into().unwrap(),
        })
    }

    fn ack(next: u16) -> MasterToHost {
        MasterToHost::EventsAck(Ack {
            next,
            credit: 100,
            gap: false,
        })
    }

    fn decode(bytes: &[u8]) -> Vec<MasterToHost> {
        let mut d = FrameDecoder::new();
        bytes
            .iter()
            .filter_map(|&b| d.push::<MasterToHost>(b).and_then(Result::ok))
            .collect()
    }

    #[test]
    fn names_parse_with_and_without_a_count_and_a_wrong_one_lists_them() {
        assert_eq!(
            Misbehaviour::parse("stall@3").unwrap(),
            Misbehaviour {
                act: Act::Stall,
                after_reports: 3
            }
        );
        assert_eq!(Misbehaviour::parse("flood").unwrap().after_reports, 20);
        let e = Misbehaviour::parse("sulk").unwrap_err();
        assert!(e.contains("repeat-ack"), "{e}");
        assert!(Misbehaviour::parse("stall@x").is_err());
    }

    #[test]
    fn repeat_ack_sends_the_old_acknowledgement_and_no_more_reports() {
        let mut line = MisbehavingLine::new(Misbehaviour::parse("repeat-ack@1").unwrap());
        let mut input = frame(&ack(5));
        input.extend(frame(&report(0)));
        input.extend(frame(&report(1))); // the trigger
        input.extend(frame(&ack(9)));
        input.extend(frame(&report(2)));
        let got = decode(&line.pass(&input));
        // The master's ack 9 replaced by 5, and 5 again at the end of the round.
        assert_eq!(got, vec![ack(5), report(0), ack(5), ack(5)]);
        // Every round of the board's loop, with nothing from the master.
        assert_eq!(decode(&line.pass(&[])), vec![ack(5)]);
    }

    #[test]
    fn stall_passes_everything_before_the_trigger_and_nothing_after() {
        let mut line = MisbehavingLine::new(Misbehaviour::parse("stall@2").unwrap());
        let input: Vec<u8> = (0..5).flat_map(|i| frame(&report(i))).collect();
        // Bytes cut anywhere: frames are judged whole.
        let mut out = Vec::new();
        for piece in input.chunks(3) {
            out.extend(line.pass(piece));
        }
        assert_eq!(decode(&out), vec![report(0), report(1)]);
    }

    #[test]
    fn a_bad_record_is_a_good_frame_whose_bytes_are_no_record() {
        let mut line = MisbehavingLine::new(Misbehaviour::parse("bad-record@0").unwrap());
        let got = decode(&line.pass(&[frame(&report(0)), frame(&report(1))].concat()));
        let MasterToHost::Reports(d) = &got[0] else {
            panic!("{got:?}")
        };
        assert!(d.bytes.iter().all(|&b| b == 0xFF));
        assert!(postcard::from_bytes::<protocol::spi::Report>(&d.bytes).is_err());
        assert_eq!(got[1], report(1));
    }
}
