//! The runs a calibration takes, each reduced to what it needs: where the robot started, where
//! its odometry (on the nominal robot) says it ended, where it was measured to end, and each
//! measuring encoder's count change.
//!
//! A run is a tick stream (any mode; `record`, `generate` or a writer of your own), whose end
//! pose is its last truth row or a line of `--measured`, replayed here with `exact` on the
//! nominal robot; or what `emulate --json` printed (one run, or `--sweep`'s `runs`), whose
//! odometry is the slave's own, run on the robot the boards were told of.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use robot_math::Pose2;
use serde::Deserialize;

use crate::eval::replay::{self, Mode};
use crate::formats::robot::Robot;
use crate::formats::tickstream::{self, Event};

/// One run, as a calibration sees it.
#[derive(Clone, Debug)]
pub struct RunEnd {
    /// The file, and the seed for an emulated run of a sweep.
    pub name: String,
    pub start: Pose2,
    /// Where the odometry on the nominal robot says it ended.
    pub odometry_end: Pose2,
    /// Where it really ended (truth, or measured by hand).
    pub measured_end: Pose2,
    /// Whether `measured_end` was measured by hand (`--measured`), not a truth row.
    pub by_hand: bool,
    /// Each measuring encoder's count change over the run.
    pub counts: Vec<i64>,
    /// The same in short bins (`counts.len()` a bin; [`BIN_NS`], [`BIN_COUNTS`]), for a fit
    /// that dead-reckons the run again; empty for an emulated run (its ticks are not kept).
    pub bins: Vec<i32>,
    /// How each encoder's counts agree with the rolling the truth gives each wheel
    /// ([`super::wiring::agreement`]); none without a track of truth.
    pub agreement: Option<Vec<Vec<f64>>>,
    /// The tick stream it came from, to be replayed again on a corrected robot (none for an
    /// emulated run: drive it again instead).
    pub stream: Option<PathBuf>,
    /// A carriage's swivel as its absolute encoder read it at the start and at the end,
    /// radians (none for body-fixed encoders, and for an emulated run).
    pub swivel: Option<(f64, f64)>,
}

impl RunEnd {
    /// True end minus odometry's, in the frame the run started in (x ahead, y left).
    pub fn error_in_start_frame(&self) -> (f64, f64) {
        let (dx, dy) = (
            self.measured_end.x - self.odometry_end.x,
            self.measured_end.y - self.odometry_end.y,
        );
        let (s, c) = self.start.theta.sin_cos();
        (c * dx + s * dy, -s * dx + c * dy)
    }
}

/// End poses measured by hand: `run,x_m,y_m,heading_deg`, one line a run, `run` being the
/// run's file as given on the command line or its file name.
pub fn read_measured(path: &Path) -> Result<BTreeMap<String, Pose2>> {
    let bytes =
        crate::formats::bounded_file::read_bounded(path, 1 << 20, "a file of measured end poses")
            .with_context(|| format!("--measured {}", path.display()))?;
    let text = String::from_utf8(bytes)
        .map_err(|_| anyhow::anyhow!("--measured {}: not text", path.display()))?;
    let mut rd = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .from_reader(text.as_bytes());
    let header: Vec<String> = rd.headers()?.iter().map(str::to_string).collect();
    if header != ["run", "x_m", "y_m", "heading_deg"] {
        bail!(
            "{}:1: the header must be run,x_m,y_m,heading_deg (got {})",
            path.display(),
            header.join(",")
        );
    }
    let mut out = BTreeMap::new();
    for (i, rec) in rd.records().enumerate() {
        let line = i + 2;
        let rec = rec.with_context(|| format!("{}:{line}", path.display()))?;
        let num = |k: usize, what: &str| -> Result<f64> {
            let v: f64 = rec[k].parse().map_err(|_| {
                anyhow::anyhow!(
                    "{}:{line}: {what} is not a number: {:?}",
                    path.display(),
                    &rec[k]
                )
            })?;
            if !v.is_finite() || v.abs() > 1e4 {
                bail!(
                    "{}:{line}: {what} = {v} is no measured position",
                    path.display()
                );
            }
            Ok(v)
        };
        let pose = Pose2::new(
            num(1, "x_m")?,
            num(2, "y_m")?,
            num(3, "heading_deg")?.to_radians(),
        );
        if out.insert(rec[0].to_string(), pose).is_some() {
            bail!(
                "{}:{line}: run {} is measured twice",
                path.display(),
                &rec[0]
            );
        }
    }
    Ok(out)
}

/// The runs in `path`: a tick stream, or `emulate --json`'s output.
pub fn read_runs(
    path: &Path,
    robot: &Robot,
    measured: &BTreeMap<String, Pose2>,
) -> Result<Vec<RunEnd>> {
    let head = {
        use std::io::Read;
        let mut buf = [0u8; 64];
        let n = crate::formats::bounded_file::open_regular(path)
            .and_then(|mut f| f.read(&mut buf))
            .with_context(|| format!("--runs {}", path.display()))?;
        String::from_utf8_lossy(&buf[..n]).trim_start().to_string()
    };
    if head.starts_with('{') {
        emulated_runs(path, robot)
    } else {
        let pose = measured_pose(path, measured);
        Ok(vec![stream_run(path, robot, pose)?])
    }
}

fn measured_pose(path: &Path, measured: &BTreeMap<String, Pose2>) -> Option<Pose2> {
    let as_given = path.display().to_string();
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned());
    measured
        .get(&as_given)
        .or_else(|| name.and_then(|n| measured.get(&n)))
        .copied()
}

/// A tick stream replayed with `exact` on `robot`; its end the last truth row, or `measured`
/// (then the end is the last event's instant, every tick counted).
pub fn stream_run(path: &Path, robot: &Robot, measured: Option<Pose2>) -> Result<RunEnd> {
    let mut stream = tickstream::read(path)?;
    let truth: Vec<(u64, Pose2)> = stream.events.iter().filter_map(Event::truth).collect();
    let last_t = stream.events.iter().map(Event::t_ns).max().unwrap_or(0);
    let first_t = stream.events.iter().map(Event::t_ns).min().unwrap_or(0);
    let push_truth = |events: &mut Vec<Event>, t_ns: u64, p: Pose2| {
        events.push(Event::Truth {
            t_ns,
            x_m: p.x,
            y_m: p.y,
            theta_rad: p.theta,
        })
    };
    let (start_t, start) = match (truth.first(), measured) {
        (Some(&first), _) => first,
        // A run on a real robot, measured by hand: it started at the origin facing +x.
        (None, Some(_)) => {
            let t = first_t.saturating_sub(1);
            push_truth(&mut stream.events, t, Pose2::default());
            (t, Pose2::default())
        }
        (None, None) => bail!(
            "{}: no truth rows and no --measured end pose: nothing to calibrate against",
            path.display()
        ),
    };
    let (end_t, measured_end) = match measured {
        Some(p) => {
            push_truth(&mut stream.events, last_t.max(start_t + 1), p);
            (last_t.max(start_t + 1), p)
        }
        None if truth.len() >= 2 => *truth.last().expect("two rows"),
        None => bail!(
            "{}: one truth row, the start: give its end pose in --measured",
            path.display()
        ),
    };
    stream.events.sort_by_key(Event::t_ns);
    let n = robot.encoders.len();
    let mut counts = vec![0i64; n];
    for e in &stream.events {
        if let Event::Tick {
            t_ns,
            encoder,
            step,
        } = *e
        {
            if t_ns > start_t && t_ns <= end_t && (encoder as usize) < n {
                counts[encoder as usize] += step as i64;
            }
        }
    }
    let bins = bins(&stream.events, n, start_t, end_t);
    let swivel = swivel_readings(robot, &stream.events, start_t, end_t)
        .with_context(|| path.display().to_string())?;
    let agreement = super::wiring::agreement(robot, &stream.events);
    let score = replay::replay(robot, &stream, "exact", Mode::Timestamps)
        .with_context(|| format!("{}: replaying it on robot {}", path.display(), robot.name))?;
    let &(_, odometry_end, _) = score.track.last().context("no truth row scored")?;
    Ok(RunEnd {
        name: path.display().to_string(),
        start,
        odometry_end,
        measured_end,
        by_hand: measured.is_some(),
        counts,
        bins,
        agreement,
        stream: Some(path.to_path_buf()),
        swivel,
    })
}

/// The runs as the fit reads them: their counts binned, which only a tick stream keeps.
pub fn binned(runs: &[RunEnd]) -> Result<Vec<super::fit::BinnedRun>> {
    (runs.iter())
        .map(|r| {
            if r.stream.is_none() {
                bail!(
                    "{}: an emulated run keeps no ticks, and this calibration dead-reckons the \
                     runs' counts again: record it (virtual-board and record, or generate)",
                    r.name
                );
            }
            Ok(super::fit::BinnedRun {
                name: r.name.clone(),
                start: r.start,
                measured_end: r.measured_end,
                bins: r.bins.clone(),
                swivel: r.swivel,
            })
        })
        .collect()
}

/// A carriage's swivel angle as its absolute encoder read it last at or before `start` (or
/// first, when it was first read later) and last at or before `end`, radians; none without a
/// carriage.
fn swivel_readings(
    robot: &Robot,
    events: &[Event],
    start: u64,
    end: u64,
) -> Result<Option<(f64, f64)>> {
    let layout = robot.odometry_layout()?;
    let (Some(geom), Some(abs)) = (layout.carriage_geometry(), layout.abs()) else {
        return Ok(None);
    };
    let (mut first, mut at_start, mut at_end) = (None, None, None);
    for e in events {
        let Event::Abs {
            t_ns,
            encoder,
            code,
        } = *e
        else {
            continue;
        };
        let Some(code) = robot.abs_reading(encoder, code, t_ns)? else {
            continue;
        };
        let angle = geom.swivel_angle(abs.decode(code));
        first = first.or(Some(angle));
        if t_ns <= start {
            at_start = Some(angle);
        }
        if t_ns <= end {
            at_end = Some(angle);
        }
    }
    match (at_start.or(first), at_end) {
        (Some(a), Some(b)) => Ok(Some((a, b))),
        _ => bail!("no reading of the carriage's swivel (its absolute encoder) by the run's end"),
    }
}

/// A bin of a run's counts ends after this long ...
pub const BIN_NS: u64 = 10_000_000;
/// ... or once an encoder has counted this many.
pub const BIN_COUNTS: i32 = 64;

/// The ticks of `events` (sorted) in `(from, to]` as count changes in bins.
fn bins(events: &[Event], n: usize, from: u64, to: u64) -> Vec<i32> {
    let mut out = Vec::new();
    let mut bin = vec![0i32; n];
    let mut bin_start = from;
    let flush = |bin: &mut Vec<i32>, out: &mut Vec<i32>| {
        if bin.iter().any(|&c| c != 0) {
            out.extend_from_slice(bin);
            bin.iter_mut().for_each(|c| *c = 0);
        }
    };
    for e in events {
        let Event::Tick {
            t_ns,
            encoder,
            step,
        } = *e
        else {
            continue;
        };
        if t_ns <= from || t_ns > to || encoder as usize >= n {
            continue;
        }
        if t_ns - bin_start >= BIN_NS {
            flush(&mut bin, &mut out);
            bin_start = t_ns;
        }
        bin[encoder as usize] += step as i32;
        if bin[encoder as usize].abs() >= BIN_COUNTS {
            flush(&mut bin, &mut out);
            bin_start = t_ns;
        }
    }
    flush(&mut bin, &mut out);
    out
}

/// What `calibrate` reads of an `emulate` summary.
#[derive(Deserialize)]
struct EmulatedRun {
    scenario: String,
    seed: u64,
    robot_fingerprint: u32,
    robot: String,
    start_pose: (f64, f64, f64),
    final_estimate_m: (f64, f64),
    final_estimate_heading_rad: f64,
    final_position_m: (f64, f64),
    final_heading_rad: f64,
    measuring_counts: [i64; 2],
}

fn emulated_runs(path: &Path, robot: &Robot) -> Result<Vec<RunEnd>> {
    let bytes = crate::formats::bounded_file::read_bounded(path, 64 << 20, "emulate's output")
        .with_context(|| format!("--runs {}", path.display()))?;
    let text = String::from_utf8(bytes)
        .map_err(|_| anyhow::anyhow!("{}: not text: not emulate's output", path.display()))?;
    let not_emulate = || {
        format!(
            "{}: not what `emulate --json` prints (one run, or a --sweep's runs)",
            path.display()
        )
    };
    let value: serde_json::Value = serde_json::from_str(&text).with_context(not_emulate)?;
    let values = match value.get("runs") {
        Some(serde_json::Value::Array(runs)) => runs.clone(),
        _ => vec![value],
    };
    let runs = (values.into_iter().enumerate())
        .map(|(i, v)| {
            serde_json::from_value::<EmulatedRun>(v)
                .with_context(|| format!("{} (run {})", not_emulate(), i + 1))
        })
        .collect::<Result<Vec<_>>>()?;
    let layout = robot.odometry_layout()?;
    let ours = firmware_slave::robot_wire::layout_fingerprint(&layout);
    runs.into_iter()
        .map(|r| {
            // The slave's odometry ran on the robot the boards were told of: it must be this
            // one, or the corrections would be of another robot's numbers.
            if r.robot_fingerprint != ours {
                bail!(
                    "{}: seed {} of {} was driven with robot {} (encoders {:08x}), not with \
                     robot {} (encoders {ours:08x}) that is being calibrated",
                    path.display(),
                    r.seed,
                    r.scenario,
                    r.robot,
                    r.robot_fingerprint,
                    robot.name
                );
            }
            let (x, y, th) = r.start_pose;
            Ok(RunEnd {
                name: format!("{} seed {}", path.display(), r.seed),
                start: Pose2::new(x, y, th),
                odometry_end: Pose2::new(
                    r.final_estimate_m.0,
                    r.final_estimate_m.1,
                    r.final_estimate_heading_rad,
                ),
                measured_end: Pose2::new(
                    r.final_position_m.0,
                    r.final_position_m.1,
                    r.final_heading_rad,
                ),
                by_hand: false,
                counts: r.measuring_counts.to_vec(),
                bins: Vec::new(),
                agreement: None,
                stream: None,
                swivel: None,
            })
        })
        .collect()
}
