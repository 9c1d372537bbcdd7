//! A tick stream turned into the bytes `play` sends: the event code of `protocol::events`
//! (time-stamped ticks) or one count sample per update period (counts mode), on the stream's
//! own clock starting at its first row, in whole microseconds (the board's time-stamp unit).
//!
//! Sampled counts: sample `k` (k = 1, 2, ...) holds every tick in `((k-1)·P, k·P]` (ticks at
//! time 0 go into sample 1) and the last absolute reading in it, so the board sees the counts
//! a timer read at `k·P` would show.

use anyhow::{bail, Result};
use protocol::events::{encode_sample, Event, EventEncoder, Sample, Step, MAX_SAMPLE_LEN};
use robot_math::Pose2;

use crate::formats::tickstream::{Event as Row, TickStream};
use firmware_slave::played::PlayKind;

pub struct PlayedStream {
    pub kind: PlayKind,
    pub period_us: u32,
    pub bytes: Vec<u8>,
    /// Tick and absolute-encoder rows sent.
    pub events: u64,
    /// Count samples sent (counts mode).
    pub samples: u64,
    /// Truth rows, time in ns from the stream's start.
    pub truth: Vec<(u64, Pose2)>,
    /// Played time the stream spans, seconds.
    pub duration_s: f64,
}

impl PlayedStream {
    /// The first truth row's pose (where odometry starts), or the origin.
    pub fn start(&self) -> Pose2 {
        self.truth.first().map_or(Pose2::default(), |t| t.1)
    }
}

/// Encode `stream` for a robot with `encoders` incremental encoders (and an absolute one if
/// `has_abs`).
pub fn encode(
    stream: &TickStream,
    encoders: usize,
    has_abs: bool,
    kind: PlayKind,
    period_us: u32,
) -> Result<PlayedStream> {
    if period_us == 0 {
        bail!("the slave reports an update period of 0 µs");
    }
    let t0 = stream.events.first().map_or(0, |e| e.t_ns());
    // Rounded to the nearest microsecond: monotonic, so the order of the rows is kept.
    let rel_us = |t_ns: u64| (t_ns - t0).saturating_add(500) / 1000;
    let mut out = PlayedStream {
        kind,
        period_us,
        bytes: Vec::new(),
        events: 0,
        samples: 0,
        truth: Vec::new(),
        duration_s: 0.0,
    };
    let mut enc = EventEncoder::new();
    let mut sample = Sample::default();
    let mut sample_k: u64 = 1;
    let p = period_us as u64;
    let mut buf = [0u8; 32];
    let flush = |out: &mut PlayedStream, s: &Sample, buf: &mut [u8; 32]| -> Result<()> {
        let n = encode_sample(s, &mut buf[..MAX_SAMPLE_LEN])
            .map_err(|e| anyhow::anyhow!("cannot encode a count sample: {e:?}"))?;
        out.bytes.extend_from_slice(&buf[..n]);
        out.samples += 1;
        Ok(())
    };
    for (i, row) in stream.events.iter().enumerate() {
        let t_us = rel_us(row.t_ns());
        let event = match *row {
            Row::Truth {
                t_ns,
                x_m,
                y_m,
                theta_rad,
                ..
            } => {
                out.truth.push((t_ns - t0, Pose2::new(x_m, y_m, theta_rad)));
                continue;
            }
            Row::Tick {
                encoder,
                step,
                t_ns,
                ..
            } => {
                if encoder as usize >= encoders {
                    bail!(
                        "event {} (t = {t_ns} ns): a tick of encoder {encoder}, but the robot has \
                         {encoders} encoders",
                        i + 1
                    );
                }
                let step = if step > 0 {
                    Step::Forward
                } else {
                    Step::Backward
                };
                Event::Tick {
                    t_us,
                    encoder: encoder as u8,
                    step,
                }
            }
            Row::Abs {
                encoder,
                code,
                t_ns,
            } => {
                if !has_abs || encoder != 0 {
                    bail!(
                        "event {} (t = {t_ns} ns): a reading of absolute encoder {encoder}, but \
                         the robot has {}",
                        i + 1,
                        if has_abs { "one (number 0)" } else { "none" }
                    );
                }
                let Ok(code) = u16::try_from(code) else {
                    bail!(
                        "event {} (t = {t_ns} ns): absolute code {code} is over 16 bits",
                        i + 1
                    );
                };
                Event::Abs { t_us, code }
            }
        };
        out.events += 1;
        match kind {
            PlayKind::Ticks => {
                let n = enc
                    .encode(&event, &mut buf)
                    .map_err(|e| anyhow::anyhow!("event {}: cannot encode: {e:?}", i + 1))?;
                out.bytes.extend_from_slice(&buf[..n]);
            }
            PlayKind::Counts => {
                let k = t_us.div_ceil(p).max(1);
                while sample_k < k {
                    flush(&mut out, &sample, &mut buf)?;
                    sample = Sample::default();
                    sample_k += 1;
                }
                match event {
                    Event::Tick { encoder, step, .. } => {
                        sample.counts_delta[encoder as usize] += i32::from(step.delta())
                    }
                    Event::Abs { code, .. } => sample.abs = Some(code),
                }
            }
        }
    }
    let last_us = stream.events.last().map_or(0, |e| rel_us(e.t_ns()));
    if kind == PlayKind::Counts {
        // Up to the sample that covers the last row.
        let k_end = last_us.div_ceil(p).max(1);
        while sample_k <= k_end {
            flush(&mut out, &sample, &mut buf)?;
            sample = Sample::default();
            sample_k += 1;
        }
    }
    out.duration_s = last_us as f64 * 1e-6;
    if out.events == 0 {
        bail!("the stream has no tick or absolute-encoder rows: nothing to play");
    }
    Ok(out)
}
