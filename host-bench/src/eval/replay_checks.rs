//! What a replay needs of its inputs, checked before any estimator runs: the counts rate, each
//! event against the robot, and a stream with something to score. The replay relies on the
//! same checks; `host-bench replay` makes them first, so a bad input is refused at its flag
//! or its line before anything is computed or written.

use anyhow::{bail, Result};
use robot_math::se2::wrap_angle;

use super::replay::Mode;
use crate::formats::robot::Robot;
use crate::formats::tickstream::{Event, TickStream};

/// Slowest counts sampling, Hz: a sample every 1000 s, slower than any odometry is read. (At
/// 10^-300 Hz the period saturated at 2^64 ns and the sampling clock wrapped.)
pub const MIN_COUNTS_RATE_HZ: f64 = 1e-3;

/// Fastest counts sampling, Hz: a sample every nanosecond, the streams' time unit.
pub const MAX_COUNTS_RATE_HZ: f64 = 1e9;

/// Less motion than this between the truth rows (and less turning than
/// [`MIN_TURN_RAD`]) scores nothing, as `emulate`'s "nothing scored" below 1 µm.
pub const MIN_PATH_M: f64 = 1e-6;

/// See [`MIN_PATH_M`]: a turn in place is motion to score.
pub const MIN_TURN_RAD: f64 = 1e-6;

/// `rate_hz` as `--counts-rate` may be: within [`MIN_COUNTS_RATE_HZ`, `MAX_COUNTS_RATE_HZ`].
pub fn check_counts_rate(rate_hz: f64) -> Result<()> {
    if !(MIN_COUNTS_RATE_HZ..=MAX_COUNTS_RATE_HZ).contains(&rate_hz) {
        bail!(
            "counts sampling rate must be {MIN_COUNTS_RATE_HZ:e} to {MAX_COUNTS_RATE_HZ:e} Hz \
             (a sample at least every 1000 s), got {rate_hz:?}"
        );
    }
    Ok(())
}

/// An event its robot cannot have produced: where it is in the stream, and why.
#[derive(Debug)]
pub struct BadEvent {
    /// Index into `TickStream::events` (`tickstream::Lines::of` gives its line).
    pub index: usize,
    pub message: String,
}

/// Every event of `stream` against `robot` ([`check_event`]), the first bad one returned.
pub fn check_events(robot: &Robot, stream: &TickStream) -> Result<(), BadEvent> {
    let n = robot.encoders.len();
    for (index, e) in stream.events.iter().enumerate() {
        check_event(robot, n, e).map_err(|message| BadEvent { index, message })?;
    }
    Ok(())
}

/// `event` against `robot` with `n` incremental encoders: a tick of an encoder it has, a
/// reading of an absolute encoder it has, within that encoder's bits.
pub fn check_event(robot: &Robot, n: usize, event: &Event) -> Result<(), String> {
    match *event {
        Event::Tick {
            t_ns: t, encoder, ..
        } if encoder as usize >= n => Err(format!(
            "tick for encoder {encoder} at t = {t} ns, but robot {} has {n} encoders",
            robot.name
        )),
        // The robot's own check, which `play` asks too.
        Event::Abs {
            t_ns: t,
            encoder,
            code,
        } => robot
            .abs_reading(encoder, code, t)
            .map(|_| ())
            .map_err(|e| e.to_string()),
        _ => Ok(()),
    }
}

/// Whether `stream`, read as `mode` says, has anything to score, whatever the method: two
/// truth rows or more, a tick between the first and the last (truth rows only before the
/// ticks scored "0.0000 mm" over no motion), motion between them (a path of 0 m scored a
/// perfect 0 mm), and with counts a sample before the last truth row (else every update is
/// one made for a truth row, not the counts rate).
pub fn check_scorable(stream: &TickStream, mode: Mode) -> Result<()> {
    let mut truth = stream.events.iter().filter_map(Event::truth);
    let Some((first_t, mut last)) = truth.next() else {
        bail!("the stream has no truth rows: nothing to score against");
    };
    let (mut rows, mut last_t, mut path, mut turned) = (1u64, first_t, 0.0, 0.0f64);
    for (t, p) in truth {
        path += last.distance_to(p);
        turned += wrap_angle(p.theta - last.theta).abs();
        (rows, last_t, last) = (rows + 1, t, p);
    }
    if rows < 2 {
        bail!("the stream has one truth row, the start pose: nothing to score against");
    }
    // Ticks at the first truth row's instant come before it: where the estimators start.
    let ticked = stream
        .events
        .iter()
        .any(|e| matches!(*e, Event::Tick { t_ns, .. } if t_ns > first_t && t_ns <= last_t));
    if !ticked {
        bail!(
            "no encoder tick between the first truth row and the last: the motion is not \
             scored (truth rows must come during the ticks, not only before or after them)"
        );
    }
    if path < MIN_PATH_M && turned < MIN_TURN_RAD {
        bail!(
            "nothing scored: the robot did not move in the {} s of its {rows} truth rows \
             (path {:.3} mm, turned {:.3} deg)",
            (last_t - first_t) as f64 * 1e-9,
            path * 1e3,
            turned.to_degrees()
        );
    }
    if let (Mode::Counts { rate_hz }, Some(p)) = (mode, mode.period_ns()) {
        let t0 = stream.events.first().map_or(0, |e| e.t_ns());
        if t0.checked_add(p).is_none_or(|first| first > last_t) {
            bail!(
                "nothing scored: read at {rate_hz} Hz the counters are first sampled {p} ns \
                 after the stream's start (t = {t0} ns), past its last truth row (t = {last_t} \
                 ns)"
            );
        }
    }
    Ok(())
}
