//! Record mode: the slave's raw readings into its report stream, for `host-bench record`.
//!
//! Every decoded tick (with its time stamp), each update's count changes in counts mode (as
//! that many ticks at the update instant), the absolute encoder's raw code when it changes,
//! all in the edge code of `protocol::events`, cut into [`Report::Sensors`] records; and the
//! pose every `pose_every` updates. The event code's times are deltas; it starts again from
//! time 0 after every [`Report::PoseAt`] and at every [`Report::Lost`] marker, so the host
//! can start its decoder again at the same places: after a record it could not read, it
//! reads on from the next of them (at most `pose_every` updates later). When the stream has
//! no room, events are dropped and counted, and a `Lost` marker goes ahead of what follows.

use protocol::events::{Event, EventEncoder, Step, MAX_EVENT_LEN};
use protocol::spi::{Report, REPORT_SENSOR_BYTES};
use protocol::Bytes;

/// Where records go: the report stream (bounded).
pub trait RecordSink {
    /// Append one record if it fits whole; false if it was dropped.
    fn put(&mut self, r: &Report) -> bool;
}

pub struct Recorder {
    encoder: EventEncoder,
    staged: [u8; REPORT_SENSOR_BYTES],
    len: usize,
    /// Events in `staged`.
    staged_events: u32,
    /// Events and updates dropped since the last `Lost` record went out.
    lost_events: u32,
    lost_updates: u32,
    last_abs: Option<u16>,
    updates: u32,
    /// Counts at the last recorded update (counts mode).
    counts: Option<[i64; 4]>,
}

impl Default for Recorder {
    fn default() -> Self {
        Self::new()
    }
}

impl Recorder {
    pub const fn new() -> Self {
        Recorder {
            encoder: EventEncoder::new(),
            staged: [0; REPORT_SENSOR_BYTES],
            len: 0,
            staged_events: 0,
            lost_events: 0,
            lost_updates: 0,
            last_abs: None,
            updates: 0,
            counts: None,
        }
    }

    /// The counts at the previous update (the same counts the first time), remembering
    /// `now` for the next.
    pub fn last_counts(&mut self, now: [i64; 4]) -> [i64; 4] {
        self.counts.replace(now).unwrap_or(now)
    }

    /// One decoded tick.
    pub fn tick(&mut self, sink: &mut dyn RecordSink, t_us: u64, encoder: u8, step: i8) {
        let step = if step > 0 {
            Step::Forward
        } else {
            Step::Backward
        };
        self.event(
            sink,
            Event::Tick {
                t_us,
                encoder,
                step,
            },
        );
    }

    /// The absolute encoder's raw code at an update (recorded when it changes).
    pub fn abs(&mut self, sink: &mut dyn RecordSink, t_us: u64, code: u16) {
        if self.last_abs != Some(code) {
            self.last_abs = Some(code);
            self.event(sink, Event::Abs { t_us, code });
        }
    }

    fn event(&mut self, sink: &mut dyn RecordSink, e: Event) {
        if self.len + MAX_EVENT_LEN > REPORT_SENSOR_BYTES {
            self.flush(sink);
        }
        match self.encoder.encode(&e, &mut self.staged[self.len..]) {
            Ok(n) => {
                self.len += n;
                self.staged_events += 1;
            }
            // Out of order or out of range: not representable, counted as lost. The `Lost`
            // marker it brings is where the host starts decoding from time 0 again, so the
            // code does too, after what is staged has gone out on the old one.
            Err(_) => {
                self.flush(sink);
                self.lost_events = self.lost_events.saturating_add(1);
                self.restart();
            }
        }
    }

    /// End of an update: every `pose_every` updates, what is staged and then the pose. Events
    /// stay staged across updates until a record is full or a pose is due: a record's 4
    /// bytes of tag, length and framing are then spent on 40 bytes of events, not on the 2 or
    /// 3 events of one update.
    pub fn update(
        &mut self,
        sink: &mut dyn RecordSink,
        t_us: u64,
        pose: protocol::Pose,
        pose_every: u16,
    ) {
        self.updates = self.updates.wrapping_add(1);
        if pose_every > 0 && self.updates.is_multiple_of(u32::from(pose_every)) {
            self.flush(sink);
            let r = Report::PoseAt { t_us, pose };
            if !self.put(sink, &r) {
                self.lost_updates = self.lost_updates.saturating_add(1);
            }
            // The host starts its decoder again at this pose, or at the `Lost` marker that
            // stands for it: so does the code. The absolute code goes out again too, for a
            // host that had to pass over the records before.
            self.restart();
        }
    }

    fn restart(&mut self) {
        self.encoder = EventEncoder::new();
        self.last_abs = None;
    }

    fn flush(&mut self, sink: &mut dyn RecordSink) {
        if self.len == 0 {
            return;
        }
        let r = Report::Sensors(Bytes::from_slice_truncating(&self.staged[..self.len]));
        if !self.put(sink, &r) {
            // Dropped: count what it held, and restart the delta code from time 0 so the
            // next record decodes on its own after the `Lost` marker.
            self.lost_events = self.lost_events.saturating_add(self.staged_events);
            self.restart();
        }
        self.len = 0;
        self.staged_events = 0;
    }

    /// Put a record, preceded by the `Lost` marker if anything was dropped before it.
    fn put(&mut self, sink: &mut dyn RecordSink, r: &Report) -> bool {
        if self.lost_events > 0 || self.lost_updates > 0 {
            let lost = Report::Lost {
                events: self.lost_events,
                updates: self.lost_updates,
            };
            if !sink.put(&lost) {
                return false;
            }
            self.lost_events = 0;
            self.lost_updates = 0;
        }
        sink.put(r)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use protocol::events::EventDecoder;

    /// The report stream: takes records while `open`.
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

    /// Records dropped while the stream is full are counted event by event in the `Lost`
    /// record that goes ahead of the next one, and the code restarts so that record decodes
    /// on its own.
    #[test]
    fn dropped_records_are_counted_event_by_event() {
        let mut rec = Recorder::new();
        let mut stream = Stream {
            open: false,
            records: Vec::new(),
        };
        let mut t = 0;
        // Enough ticks for several records, with time gaps of every size, and two codes.
        for k in 0..40u64 {
            t += 1 + k * k * 97;
            let step = if k % 3 == 0 { -1 } else { 1 };
            rec.tick(&mut stream, t, (k % 2) as u8, step);
        }
        rec.abs(&mut stream, t + 1, 6);
        rec.update(&mut stream, t + 1, protocol::Pose::default(), 1);
        assert!(stream.records.is_empty());

        stream.open = true;
        rec.tick(&mut stream, t + 10, 1, 1);
        rec.update(&mut stream, t + 10, protocol::Pose::default(), 1);
        let [lost, Report::Sensors(bytes), Report::PoseAt { .. }] = &stream.records[..] else {
            panic!("{:?}", stream.records);
        };
        assert_eq!(
            *lost,
            Report::Lost {
                events: 41,
                updates: 1
            }
        );
        let mut decoded = Vec::new();
        EventDecoder::new().feed(bytes.as_slice(), |e| decoded.push(e));
        assert_eq!(
            decoded,
            [Ok(Event::Tick {
                t_us: t + 10,
                encoder: 1,
                step: Step::Forward
            })]
        );
    }
}
