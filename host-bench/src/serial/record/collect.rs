//! What `record` reads from the slave's report stream: its records into rows of the tick
//! stream, each board number checked before it is used, and why a recording ends early.

use protocol::events::{Event, EventDecoder};
use protocol::spi::Report;

use crate::formats::tickstream::Event as Row;

/// Latest time stamp a board may send, in microseconds (about 285 years): a larger one is no
/// clock reading, and in nanoseconds it would not fit the stream's 64 bits.
const MAX_T_US: u64 = u64::MAX / 1000 / 2;

/// A board's time stamp in nanoseconds, or why it is refused (`what` names the field).
pub(super) fn board_ns(t_us: u64, what: &str) -> std::result::Result<u64, String> {
    if t_us > MAX_T_US {
        return Err(format!(
            "the board sent {what} = {t_us} us, beyond any clock reading (at most {MAX_T_US})"
        ));
    }
    Ok(t_us * 1000)
}

/// What a recording has read from the report stream so far.
pub(super) struct Collected {
    pub rows: Vec<Row>,
    pub board: Vec<(u64, protocol::Pose)>,
    pub ticks: u64,
    pub abs: u64,
    pub lost_events: u64,
    pub lost_updates: u64,
    pub truth: u64,
    /// Whether the robot has an absolute encoder (else the slave's pins read nothing).
    pub has_abs: bool,
}

impl Collected {
    pub fn new(has_abs: bool) -> Self {
        Collected {
            rows: Vec::new(),
            board: Vec::new(),
            ticks: 0,
            abs: 0,
            lost_events: 0,
            lost_updates: 0,
            truth: 0,
            has_abs,
        }
    }
}

/// Why a recording ended before the user stopped it: a short name (`stopped_by`) and what
/// happened, for the stream's header and the error.
#[derive(Debug)]
pub(super) struct Early {
    pub by: &'static str,
    pub why: String,
}

impl Early {
    pub fn new(by: &'static str, why: impl Into<String>) -> Self {
        Early {
            by,
            why: why.into(),
        }
    }
}

/// The whole records at the front of `bytes` into the collection (a partial one waits for its
/// remaining bytes); how many. A record that does not decode ends the recording: records are
/// written back to back without framing, so nothing after it can be told apart.
pub(super) fn take_reports(
    bytes: &mut Vec<u8>,
    offset: &mut u64,
    c: &mut Collected,
    edges: &mut EventDecoder,
) -> std::result::Result<usize, Early> {
    let mut rest: &[u8] = bytes;
    let mut n = 0;
    let result = loop {
        match postcard::take_from_bytes::<Report>(rest) {
            Ok((r, tail)) => {
                let at = *offset + (bytes.len() - rest.len()) as u64;
                if let Err((by, e)) = take_report(r, c, edges) {
                    break Err(Early::new(
                        by,
                        format!("report record at byte {at} of the report stream: {e}"),
                    ));
                }
                rest = tail;
                n += 1;
            }
            Err(postcard::Error::DeserializeUnexpectedEnd) => break Ok(n),
            Err(e) => {
                let at = *offset + (bytes.len() - rest.len()) as u64;
                break Err(Early::new(
                    "undecodable record",
                    format!(
                        "the report record at byte {at} of the report stream does not decode \
                         ({e}): the records after it cannot be told apart"
                    ),
                ));
            }
        }
    };
    let used = bytes.len() - rest.len();
    *offset += used as u64;
    bytes.drain(..used);
    if result.is_err() {
        bytes.clear(); // nothing of it is read any more
    }
    result
}

/// One report record into the collection. In counts mode the slave reports each update's
/// count changes as that many ticks at the update instant, so both modes decode alike.
pub(super) fn take_report(
    r: Report,
    c: &mut Collected,
    edges: &mut EventDecoder,
) -> std::result::Result<(), (&'static str, String)> {
    let bad = |e: String| ("bad value", e);
    match r {
        Report::Sensors(b) => {
            let mut err = None;
            let mut undecodable = false;
            edges.feed(b.as_slice(), |e| match e {
                _ if err.is_some() => {}
                Ok(Event::Tick {
                    t_us,
                    encoder,
                    step,
                }) => match board_ns(t_us, "an edge's time stamp (Sensors, Tick.t_us)") {
                    Ok(t_ns) => {
                        c.ticks += 1;
                        c.rows.push(Row::Tick {
                            t_ns,
                            encoder: encoder as u16,
                            step: step.delta(),
                        });
                    }
                    Err(e) => err = Some(e),
                },
                Ok(Event::Abs { .. }) if !c.has_abs => {}
                Ok(Event::Abs { t_us, code }) => {
                    match board_ns(t_us, "an absolute reading's time stamp (Sensors, Abs.t_us)") {
                        Ok(t_ns) => {
                            c.abs += 1;
                            c.rows.push(Row::Abs {
                                t_ns,
                                encoder: 0,
                                code: code as u32,
                            });
                        }
                        Err(e) => err = Some(e),
                    }
                }
                Err(e) => {
                    undecodable = true;
                    err = Some(format!("the slave's sensor events do not decode: {e:?}"))
                }
            });
            if let Some(e) = err {
                let by = if undecodable {
                    "undecodable record"
                } else {
                    "bad value"
                };
                return Err((by, e));
            }
        }
        Report::PoseAt { t_us, pose } => c.board.push((
            board_ns(t_us, "a board pose's time stamp (PoseAt.t_us)").map_err(bad)?,
            pose,
        )),
        Report::Lost { events, updates } => {
            c.lost_events += events as u64;
            c.lost_updates += updates as u64;
            // The slave's event code starts from time 0 again at the marker.
            *edges = EventDecoder::new();
        }
        Report::Pose { .. } | Report::BadEvents { .. } => {}
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::serial::record::POSE_EVERY;
    use firmware_slave::recorder::{RecordSink, Recorder};

    /// The report stream, full (taking nothing) while `open` is false.
    struct Stream {
        open: bool,
        records: Vec<Report>,
    }

    impl RecordSink for Stream {
        fn put(&mut self, r: &Report) -> bool {
            if self.open {
                self.records.push(*r);
            }
            self.open
        }
    }

    /// The slave's recorder with its stream full for a while, read back as `record` reads it:
    /// every tick that arrives has the board's own time stamp, and the ones that do not are
    /// counted. (They did not: the slave starts its event code from time 0 again after a gap,
    /// and the host kept adding to the time before it, so every tick after the first gap was
    /// placed later by that much.)
    #[test]
    fn ticks_after_a_gap_keep_the_boards_time_stamps() {
        let mut rec = Recorder::new();
        let mut stream = Stream {
            open: true,
            records: Vec::new(),
        };
        let mut made = Vec::new();
        let mut t = 1_000u64;
        for update in 0..400u64 {
            // Full for two stretches: a gap of updates (with their poses), then another.
            stream.open = !(140..160).contains(&update) && !(250..252).contains(&update);
            for k in 0..3u64 {
                t += 40 + (update * 7 + k * 13) % 50;
                rec.tick(&mut stream, t, (k % 2) as u8, 1);
                made.push(t);
            }
            if update == 300 {
                // A time stamp before the last: the code cannot carry it, it is counted lost.
                rec.tick(&mut stream, t - 100, 0, 1);
                made.push(t - 100);
            }
            rec.update(&mut stream, t, protocol::Pose::default(), POSE_EVERY);
            t += 1;
        }
        let mut c = Collected::new(false);
        let mut edges = EventDecoder::new();
        for r in &stream.records {
            take_report(*r, &mut c, &mut edges).unwrap();
        }
        assert!(c.lost_events > 0 && c.lost_updates > 0, "the gaps happened");
        let got: Vec<u64> = c.rows.iter().map(|r| r.t_ns() / 1000).collect();
        assert_eq!(got.len() as u64 + c.lost_events, made.len() as u64);
        // Each one the board's, in order.
        let mut made_iter = made.iter();
        for g in &got {
            assert!(
                made_iter.any(|m| m == g),
                "tick at {g} us is none the board made (after a gap?)"
            );
        }
    }
}
