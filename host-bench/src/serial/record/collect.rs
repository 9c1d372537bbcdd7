//! What `record` reads from the slave's report stream: its records into rows of the tick
//! stream, each board number checked before it is used, and why a recording ends early.

use protocol::events::{Event, EventDecoder};
use protocol::spi::Report;

use crate::serial::reports::{Frame, ReportReader};

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

/// Gaps a stream lists one by one; more are counted (a stream's size stays bounded).
pub(super) const MAX_GAPS_LISTED: usize = 50;

/// A stretch of the recording with events missing: from the last event before it to the
/// first after it (`None`: the recording ended in it), in the board's nanoseconds.
pub(super) struct Gap {
    pub from_ns: u64,
    pub to_ns: Option<u64>,
    pub what: String,
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
    /// Report records that did not decode, passed over.
    pub undecodable: u64,
    /// `Sensors` records passed over after one that did not decode, until the event code
    /// started again (the events in them cannot be placed in time).
    pub unplaced: u64,
    /// Whether the records read are being passed over until the event code starts again.
    resyncing: bool,
    /// The absolute code last written: the slave sends it again at each start of its event
    /// code (for a host that passed over a change), and a reading that did not change is no
    /// row.
    last_abs: Option<u16>,
    /// Where events are missing (the first [`MAX_GAPS_LISTED`]), and how many gaps there
    /// were in all.
    pub gaps: Vec<Gap>,
    pub gap_count: u64,
    /// The board's time of the last event placed.
    last_event_ns: u64,
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
            undecodable: 0,
            unplaced: 0,
            resyncing: false,
            last_abs: None,
            gaps: Vec::new(),
            gap_count: 0,
            last_event_ns: 0,
            has_abs,
        }
    }

    /// Events are missing from here on, until the next one placed.
    fn gap(&mut self, what: impl FnOnce() -> String) {
        if self.gaps.last().is_some_and(|g| g.to_ns.is_none()) {
            return; // one gap, however many reasons
        }
        self.gap_count += 1;
        if self.gaps.len() < MAX_GAPS_LISTED {
            self.gaps.push(Gap {
                from_ns: self.last_event_ns,
                to_ns: None,
                what: what(),
            });
        }
    }

    /// An event placed at `t_ns`: the end of a gap if one is open.
    fn placed(&mut self, t_ns: u64) {
        self.last_event_ns = t_ns;
        if let Some(g) = self.gaps.last_mut().filter(|g| g.to_ns.is_none()) {
            g.to_ns = Some(t_ns);
        }
    }

    /// Records passed over: the ones that did not decode and the ones after them.
    pub fn skipped(&self) -> u64 {
        self.undecodable + self.unplaced
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

/// The whole records the stream has brought, into the collection; how many were read. A
/// frame that is no record, or a `Sensors` record whose events do not decode, is counted and
/// passed over, and so is every `Sensors` record after it until the slave's event code starts
/// again (at the next board pose or `Lost` marker): its times are deltas from events that
/// were lost. The records are framed, so the next one reads on its own. A number out of range
/// ends the recording.
pub(super) fn take_reports(
    reader: &mut ReportReader,
    c: &mut Collected,
    edges: &mut EventDecoder,
) -> std::result::Result<usize, Early> {
    let mut n = 0;
    while let Some(frame) = reader.next_frame() {
        let r = match frame {
            Frame::Bad { .. } => {
                c.undecodable += 1;
                c.resyncing = true;
                c.gap(undecodable_gap);
                continue;
            }
            Frame::Record(r) => r,
        };
        match take_report(r, c, edges) {
            Ok(()) => n += 1,
            Err(("undecodable record", _)) => {
                c.undecodable += 1;
                c.resyncing = true;
                c.gap(undecodable_gap);
            }
            Err((by, e)) => return Err(Early::new(by, format!("a report record: {e}"))),
        }
    }
    Ok(n)
}

fn undecodable_gap() -> String {
    "a report record that did not decode, and the sensor records after it up to the slave's \
     next pose"
        .into()
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
        Report::Sensors(_) if c.resyncing => c.unplaced += 1,
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
                        c.placed(t_ns);
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
                Ok(Event::Abs { code, .. }) if c.last_abs == Some(code) => {}
                Ok(Event::Abs { t_us, code }) => {
                    match board_ns(t_us, "an absolute reading's time stamp (Sensors, Abs.t_us)") {
                        Ok(t_ns) => {
                            c.placed(t_ns);
                            c.abs += 1;
                            c.last_abs = Some(code);
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
        Report::PoseAt { t_us, pose } => {
            c.board.push((
                board_ns(t_us, "a board pose's time stamp (PoseAt.t_us)").map_err(bad)?,
                pose,
            ));
            // The slave's event code starts from time 0 again after each pose.
            *edges = EventDecoder::new();
            c.resyncing = false;
        }
        Report::Lost { events, updates } => {
            c.lost_events += events as u64;
            c.lost_updates += updates as u64;
            if events > 0 {
                c.gap(|| format!("the slave dropped {events} events (the link could not keep up)"));
            }
            // ... and at each marker.
            *edges = EventDecoder::new();
            c.resyncing = false;
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
            // (The second is long enough to fill a record: events wait staged until one is
            // full or a pose is due.)
            stream.open = !(140..160).contains(&update) && !(250..262).contains(&update);
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
        // Three places with events missing: two stretches of a full stream, one refused tick.
        assert_eq!((c.gap_count, c.gaps.len()), (3, 3));
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

    /// A record the host cannot read is passed over, and so are the sensor records after it
    /// until the slave's next pose, where its event code starts again: every tick read after
    /// that has the board's own time stamp, and every one before the bad record too.
    #[test]
    fn a_record_that_does_not_decode_costs_at_most_the_events_to_the_next_pose() {
        use protocol::spi::{frame_report, REPORT_FRAME_MAX};
        let mut rec = Recorder::new();
        let mut stream = Stream {
            open: true,
            records: Vec::new(),
        };
        let mut made = Vec::new();
        let mut t = 1_000u64;
        for update in 0..300u64 {
            for k in 0..3u64 {
                t += 40 + (update * 7 + k * 13) % 50;
                rec.tick(&mut stream, t, (k % 2) as u8, 1);
                made.push(t);
            }
            // An absolute code that changes twice: sent at each change and again after each
            // pose, written only when it changes.
            rec.abs(&mut stream, t, (update / 100) as u16);
            rec.update(&mut stream, t, protocol::Pose::default(), POSE_EVERY);
            t += 1;
        }
        // Spoil a sensor record between two poses: its bytes become no record.
        let poses: Vec<usize> = (0..stream.records.len())
            .filter(|&i| matches!(stream.records[i], Report::PoseAt { .. }))
            .collect();
        let spoilt = poses[2] + 10;
        assert!(matches!(stream.records[spoilt], Report::Sensors(_)));
        let mut bytes = Vec::new();
        for (i, r) in stream.records.iter().enumerate() {
            if i == spoilt {
                bytes.extend_from_slice(&[0xFF, 0x13, 0x37, 0]);
                continue;
            }
            let mut frame = [0u8; REPORT_FRAME_MAX];
            let n = frame_report(r, &mut frame).unwrap();
            bytes.extend_from_slice(&frame[..n]);
        }
        let mut reader = ReportReader::default();
        let mut c = Collected::new(true);
        let mut edges = EventDecoder::new();
        for piece in bytes.chunks(7) {
            reader.push(piece);
            take_reports(&mut reader, &mut c, &mut edges).unwrap();
        }
        let sensors_between =
            (spoilt + 1..poses[3]).filter(|&i| matches!(stream.records[i], Report::Sensors(_)));
        assert_eq!(
            (c.undecodable, c.unplaced),
            (1, sensors_between.count() as u64)
        );
        // The ticks read are the board's, in order, and none goes missing outside the gap.
        let codes: Vec<u32> = (c.rows.iter())
            .filter_map(|r| match r {
                Row::Abs { code, .. } => Some(*code),
                _ => None,
            })
            .collect();
        assert_eq!(codes, [0, 1, 2]);
        let got: Vec<u64> = (c.rows.iter())
            .filter(|r| matches!(r, Row::Tick { .. }))
            .map(|r| r.t_ns() / 1000)
            .collect();
        assert!(got.windows(2).all(|w| w[0] < w[1]));
        let lost: Vec<u64> = made.iter().copied().filter(|m| !got.contains(m)).collect();
        assert!(!lost.is_empty());
        let pose_t = |i: usize| match stream.records[i] {
            Report::PoseAt { t_us, .. } => t_us,
            _ => unreachable!(),
        };
        assert!(
            lost.iter()
                .all(|&m| m > pose_t(poses[2]) && m <= pose_t(poses[3])),
            "lost outside the spoilt record's pose interval: {lost:?}"
        );
        assert!(got.len() + lost.len() == made.len());
        // The gap is written where it is: from the last tick before it to the first after.
        let [gap] = &c.gaps[..] else {
            panic!("one gap")
        };
        let before = got.iter().filter(|&&g| g < lost[0]).max().unwrap();
        let after = got.iter().filter(|&&g| g > lost[0]).min().unwrap();
        assert_eq!(
            (gap.from_ns, gap.to_ns),
            (before * 1000, Some(after * 1000))
        );
    }
}
