//! What the host expects of the slave during `play`, made in step with the board's reports:
//! the slave's own played-sensors code ([`PlayedSensors`]) on the same bytes, a few reports
//! ahead, so that memory stays the same however many updates a stream takes (made all at
//! once, a span of 10¹⁴ ns asked for 3 GB before the board heard a byte).

use std::collections::VecDeque;

use anyhow::{bail, Result};
use firmware_slave::played::{PlayKind, PlayedSensors, ReportSink};
use protocol::spi::{PoseChecks, Report};
use robot_math::exact::FixedPose;
use robot_math::odometry::{Layout, Method};

use super::played_stream::{PlayedStream, WireBytes};

/// Reports made ahead of the board's.
const AHEAD: usize = 64;
/// Stream bytes made at a time for the host's decoder.
const CHUNK: usize = 4096;

struct Queue(VecDeque<Report>);

impl ReportSink for Queue {
    fn has_room(&self) -> bool {
        self.0.len() < AHEAD
    }
    fn push(&mut self, r: Report) {
        self.0.push_back(r)
    }
}

pub struct Expected<'s, 'a> {
    engine: PlayedSensors,
    bytes: WireBytes<'s, 'a>,
    /// Bytes made, `buf[used..]` not yet taken by the decoder.
    buf: Vec<u8>,
    used: usize,
    queue: Queue,
}

impl<'s, 'a> Expected<'s, 'a> {
    /// The reports of `stream` played from `start` with `method`, one for every update (the
    /// board reports some of them: [`report_of`](Self::report_of) passes over the rest).
    pub fn new(
        layout: &Layout,
        method: Method,
        stream: &'s PlayedStream<'a>,
        start: FixedPose,
    ) -> Result<Self> {
        let engine = PlayedSensors::new(
            layout,
            method,
            stream.kind,
            stream.period_us,
            start,
            PoseChecks::ALL,
        )
        .map_err(|e| {
            anyhow::anyhow!(
                "--algorithm {} with --sensor {}: {e}",
                method.name(),
                match stream.kind {
                    PlayKind::Ticks => "timestamps",
                    PlayKind::Counts => "counts",
                }
            )
        })?;
        Ok(Expected {
            engine,
            bytes: stream.bytes(),
            buf: Vec::with_capacity(CHUNK),
            used: 0,
            queue: Queue(VecDeque::with_capacity(AHEAD)),
        })
    }

    /// Update `update`'s report, each pose up to it handed to `seen` in order; `None` when
    /// the stream ends before it (or it was passed already).
    pub fn report_of(
        &mut self,
        update: u64,
        mut seen: impl FnMut(u64, &protocol::Pose),
    ) -> Result<Option<Report>> {
        while let Some(r) = self.next_report()? {
            let Report::Pose {
                update: u, pose, ..
            } = r
            else {
                continue;
            };
            seen(u64::from(u), &pose);
            match u64::from(u).cmp(&update) {
                std::cmp::Ordering::Less => {}
                std::cmp::Ordering::Equal => return Ok(Some(r)),
                std::cmp::Ordering::Greater => return Ok(None),
            }
        }
        Ok(None)
    }

    /// The next update's report; `None` after the last.
    pub fn next_report(&mut self) -> Result<Option<Report>> {
        loop {
            if let Some(r) = self.queue.0.pop_front() {
                return Ok(Some(r));
            }
            if self.used == self.buf.len() {
                self.buf.clear();
                self.used = 0;
                self.bytes.fill(&mut self.buf, CHUNK)?;
            }
            // With room for a report, the decoder takes a byte or reports (or, with no bytes
            // left, finishes what it holds): each turn moves on.
            let left = self.buf.len() - self.used;
            self.used += self.engine.feed(&self.buf[self.used..], &mut self.queue);
            if self.engine.failed() {
                bail!(
                    "the host's own decoder refused the stream near byte {}: an encoder bug",
                    self.used
                );
            }
            if left == 0 && self.queue.0.is_empty() {
                return Ok(None);
            }
        }
    }
}
