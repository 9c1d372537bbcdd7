//! A tick stream turned into the bytes `play` sends: the event code of `protocol::events`
//! (time-stamped ticks) or one count sample per update period (counts mode), on the stream's
//! own clock starting at its first row, in whole microseconds (the board's time-stamp unit).
//!
//! Sampled counts: sample `k` (k = 1, 2, ...) holds every tick in `((k-1)·P, k·P]` (ticks at
//! time 0 go into sample 1) and the last absolute reading in it, so the board sees the counts
//! a timer read at `k·P` would show.
//!
//! With time stamps, the stream's start reading of the absolute encoder goes first, so that the
//! slave starts its odometry there (`firmware_slave::played`), as `replay` does.
//!
//! The bytes are made as they are sent ([`PlayedStream::bytes`]), never held whole: in counts
//! mode they grow with the span (a byte for every sample in which nothing moved), not with the
//! rows, and five rows a week apart are 6·10⁸ of them. What grows with the span is bounded
//! instead: at most [`MAX_UPDATES`] updates, each one report the host waits for.

use anyhow::{anyhow, bail, Result};
use protocol::events::{encode_sample, Event, EventEncoder, Sample, Step};
use robot_math::Pose2;

use crate::eval::replay_checks::check_event;
use crate::formats::robot::Robot;
use crate::formats::tickstream::{Event as Row, TickStream};
use firmware_slave::played::PlayKind;

/// Most updates one play asks of the slave: a week of its 1 kHz updates, as long as
/// `record --duration` records. Each is a pose report on the serial line, about 0.6 kHz at
/// 115 200 baud, so this bounds a play's time (a week's updates take 12 days); its memory does
/// not grow with them.
pub const MAX_UPDATES: u64 = 604_800_000;

/// The span of rows that takes [`MAX_UPDATES`] at the firmware's 1 ms period, checked on every
/// row before the board is asked ([`span_check`]); a slave that runs faster is checked again
/// once its period is known ([`PlayedStream::new`]).
pub const MAX_SPAN_NS: u64 = MAX_UPDATES * 1_000_000;

/// The code of a sample in which nothing moved and nothing was read.
const EMPTY_SAMPLE: u8 = 0;

/// A check of each row's distance from the first, for rows as they come (also as
/// `tickstream::read_checked`'s check, which names the line).
pub fn span_check() -> impl FnMut(&Row) -> Result<(), String> {
    let mut t0 = None;
    move |row| {
        let t = row.t_ns();
        let span = t.saturating_sub(*t0.get_or_insert(t));
        if span > MAX_SPAN_NS {
            return Err(format!(
                "t_ns {t} is {:.0} s after the first row; play takes at most {} s (a week: \
                 {MAX_UPDATES} updates of the slave's 1 ms, each a report the host waits for)",
                span as f64 * 1e-9,
                MAX_SPAN_NS / 1_000_000_000
            ));
        }
        Ok(())
    }
}

/// What needs no board: every tick of an encoder the robot has, every absolute reading one the
/// robot has within its bits (as `replay` checks it), a span [`span_check`] takes, a tick.
pub fn check_rows(stream: &TickStream, robot: &Robot) -> Result<()> {
    let encoders = robot.encoders.len();
    let mut span = span_check();
    for (i, row) in stream.events.iter().enumerate() {
        span(row).map_err(|m| anyhow!("event {}: {m}", i + 1))?;
        // `replay`'s own check of what the robot can have made.
        check_event(robot, encoders, row).map_err(|m| anyhow!("event {}: {m}", i + 1))?;
    }
    if !stream.events.iter().any(|e| matches!(e, Row::Tick { .. })) {
        // The board would compute nothing: "0 of 0 updates bit-exact" is no result (replay
        // refuses such a stream too).
        bail!("the stream has no tick rows: nothing to play, nothing scored");
    }
    Ok(())
}

/// A stream's rows as `play` sends them to a slave updating every `period_us`.
pub struct PlayedStream<'a> {
    rows: &'a [Row],
    t0: u64,
    /// The absolute encoder the odometry reads: the rows of others are not sent.
    abs_index: Option<usize>,
    /// With time stamps, the start reading's row, sent first.
    first: Option<usize>,
    pub kind: PlayKind,
    pub period_us: u32,
    /// Tick and absolute-encoder rows sent.
    pub events: u64,
    /// Count samples sent (counts mode).
    pub samples: u64,
    /// Updates the slave makes of them, one report each.
    pub updates: u64,
    /// Bytes of the event stream.
    pub wire_bytes: u64,
    /// Played time the stream spans, seconds.
    pub duration_s: f64,
}

impl<'a> PlayedStream<'a> {
    /// `stream`'s rows for `robot` (checked as [`check_rows`] does) played at `period_us`:
    /// refused if they need more than [`MAX_UPDATES`] updates, or none.
    pub fn new(
        stream: &'a TickStream,
        robot: &Robot,
        kind: PlayKind,
        period_us: u32,
    ) -> Result<Self> {
        check_rows(stream, robot)?;
        if period_us == 0 {
            bail!("the slave reports an update period of 0 µs");
        }
        let rows = &stream.events[..];
        let mut s = PlayedStream {
            rows,
            t0: rows.first().map_or(0, |e| e.t_ns()),
            abs_index: robot.odometry_abs_index(),
            first: None,
            kind,
            period_us,
            events: 0,
            samples: 0,
            updates: 0,
            wire_bytes: 0,
            duration_s: 0.0,
        };
        if kind == PlayKind::Ticks {
            s.first = robot.start_reading(rows).map(|(i, _)| i);
        }
        let p = period_us as u64;
        let sent = (0..rows.len()).filter_map(|i| s.event(i));
        let events = sent.clone().count() as u64;
        let last_sent = sent.clone().next_back().map_or(0, |e| e.t_us());
        s.events = events;
        let last_row = rows.last().map_or(0, |r| s.t_us(r.t_ns()));
        s.duration_s = last_row as f64 * 1e-6;
        // Update k comes at k·P and takes in every event up to it: with time stamps the
        // updates before the last event (nothing after it makes the next one); in counts mode
        // one a sample, up to the sample that covers the last row.
        s.updates = match kind {
            PlayKind::Ticks => last_sent.saturating_sub(1) / p,
            PlayKind::Counts => {
                s.samples = last_row.div_ceil(p).max(1);
                s.samples
            }
        };
        if s.updates > MAX_UPDATES {
            let i = (0..rows.len())
                .find(|&i| s.t_us(rows[i].t_ns()) > MAX_UPDATES * p)
                .unwrap_or(rows.len() - 1);
            bail!(
                "event {} (t = {} ns): at the slave's {period_us} µs an update, the stream needs \
                 {} updates by here, more than the {MAX_UPDATES} a play may take",
                i + 1,
                rows[i].t_ns(),
                s.t_us(rows[i].t_ns()).div_ceil(p)
            );
        }
        if s.updates == 0 {
            bail!(
                "nothing scored: the rows the slave is sent end {last_sent} µs after the first, \
                 within its first update (every {period_us} µs), so it would compute no update \
                 to compare (a stream must go on past one update period)"
            );
        }
        let mut wire_bytes = 0;
        let mut w = s.bytes();
        while w.make()? {
            wire_bytes += w.len as u64 + w.zeros;
        }
        s.wire_bytes = wire_bytes;
        Ok(s)
    }

    /// Played time of a row at `t_ns`, rounded to the nearest microsecond (monotonic, so the
    /// order of the rows is kept; rows out of order, which no reader makes, fail to encode).
    fn t_us(&self, t_ns: u64) -> u64 {
        t_ns.saturating_sub(self.t0).saturating_add(500) / 1000
    }

    /// What row `i` sends: nothing for a truth row or a reading of an absolute encoder the
    /// odometry does not read.
    fn event(&self, i: usize) -> Option<Event> {
        let t_us = self.t_us(self.rows[i].t_ns());
        match self.rows[i] {
            Row::Tick { encoder, step, .. } => Some(Event::Tick {
                t_us,
                encoder: encoder as u8,
                step: if step > 0 {
                    Step::Forward
                } else {
                    Step::Backward
                },
            }),
            Row::Abs { encoder, code, .. } if Some(encoder as usize) == self.abs_index => {
                Some(Event::Abs {
                    t_us,
                    code: code as u16,
                })
            }
            _ => None,
        }
    }

    /// The first truth row's pose (where odometry starts), or the origin.
    pub fn start(&self) -> Pose2 {
        self.truth().next().map_or(Pose2::default(), |t| t.1)
    }

    /// The truth rows, time in ns from the stream's start.
    pub fn truth(&self) -> impl Iterator<Item = (u64, Pose2)> + '_ {
        self.rows
            .iter()
            .filter_map(Row::truth)
            .map(|(t_ns, pose)| (t_ns.saturating_sub(self.t0), pose))
    }

    /// The bytes, from the first.
    pub fn bytes(&self) -> WireBytes<'_, 'a> {
        WireBytes {
            s: self,
            row: 0,
            first_sent: false,
            enc: EventEncoder::new(),
            sample: Sample::default(),
            sample_k: 1,
            code: [0; 32],
            at: 0,
            len: 0,
            zeros: 0,
            ended: false,
        }
    }
}

/// The bytes of a [`PlayedStream`], made as they are taken, a piece at a time: one event's
/// or sample's code, then (counts mode) the empty samples up to the next one.
pub struct WireBytes<'s, 'a> {
    s: &'s PlayedStream<'a>,
    /// Rows before this one are taken in.
    row: usize,
    first_sent: bool,
    enc: EventEncoder,
    /// The sample being filled, number `sample_k`.
    sample: Sample,
    sample_k: u64,
    /// The piece made and not yet taken: `code[at..len]`, then `zeros` empty samples.
    code: [u8; 32],
    at: usize,
    len: usize,
    zeros: u64,
    /// The samples after the last row are made.
    ended: bool,
}

impl WireBytes<'_, '_> {
    /// Append up to `max` bytes to `out` (none once all are taken).
    pub fn fill(&mut self, out: &mut Vec<u8>, max: usize) -> Result<()> {
        let end = out.len() + max;
        while out.len() < end {
            if self.at < self.len {
                let n = (self.len - self.at).min(end - out.len());
                out.extend_from_slice(&self.code[self.at..self.at + n]);
                self.at += n;
            } else if self.zeros > 0 {
                let n = self.zeros.min((end - out.len()) as u64);
                out.resize(out.len() + n as usize, EMPTY_SAMPLE);
                self.zeros -= n;
            } else if !self.make()? {
                break;
            }
        }
        Ok(())
    }

    /// Make the next piece; false after the last.
    fn make(&mut self) -> Result<bool> {
        let s = self.s;
        self.at = 0;
        self.len = 0;
        self.zeros = 0;
        if s.kind == PlayKind::Ticks {
            let first = if self.first_sent { None } else { s.first };
            self.first_sent = true;
            let next = first.or_else(|| {
                let i = (self.row..s.rows.len())
                    .find(|&i| Some(i) != s.first && s.event(i).is_some())?;
                self.row = i + 1;
                Some(i)
            });
            let Some(event) = next.and_then(|i| s.event(i)) else {
                return Ok(false);
            };
            self.len = self
                .enc
                .encode(&event, &mut self.code)
                .map_err(|e| anyhow!("cannot encode {event:?}: {e:?}"))?;
            return Ok(true);
        }
        let p = s.period_us as u64;
        while self.row < s.rows.len() {
            let i = self.row;
            self.row += 1;
            let Some(event) = s.event(i) else { continue };
            let k = event.t_us().div_ceil(p).max(1);
            let done = k > self.sample_k;
            if done {
                self.flush(k - self.sample_k - 1)?;
                self.sample_k = k;
            }
            match event {
                Event::Tick { encoder, step, .. } => {
                    self.sample.counts_delta[encoder as usize] += i32::from(step.delta())
                }
                Event::Abs { code, .. } => self.sample.abs = Some(code),
            }
            if done {
                return Ok(true);
            }
        }
        if self.ended {
            return Ok(false);
        }
        self.ended = true;
        // The last sample holding a row, then empty ones up to the one covering the last row.
        self.flush(s.samples - self.sample_k)?;
        Ok(true)
    }

    /// The sample being filled as the piece, followed by `zeros` empty ones.
    fn flush(&mut self, zeros: u64) -> Result<()> {
        self.len = encode_sample(&self.sample, &mut self.code)
            .map_err(|e| anyhow!("cannot encode a count sample: {e:?}"))?;
        self.zeros = zeros;
        self.sample = Sample::default();
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_empty_sample_is_one_byte_of_empty_sample() {
        let mut b = [0xffu8; 32];
        let n = encode_sample(&Sample::default(), &mut b).unwrap();
        assert_eq!(&b[..n], &[EMPTY_SAMPLE]);
    }
}
