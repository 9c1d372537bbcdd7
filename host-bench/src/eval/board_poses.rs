//! The board's own poses from a recording (`STEM.board.csv`, written by `host-bench record`
//! beside `STEM.csv`), scored against the stream's truth rows: what the board computed live,
//! next to what `replay` computes from the same ticks.
//!
//! The board starts its odometry when the slave takes the record command, which the host
//! can time only to a few tens of milliseconds; `replay` starts at the first truth row. So,
//! like `replay`, the board is judged on the motion it measured from a known start: its
//! track is laid onto the truth at its first scored pose (moved and turned as a whole, never
//! stretched), and every later pose is compared there.

use std::path::{Path, PathBuf};

use anyhow::{anyhow, bail, Context, Result};
use robot_math::se2::wrap_angle;
use robot_math::Pose2;
use serde::Serialize;

use crate::formats::bounded_file::read_bounded;
use crate::formats::tickstream::{
    Event, TickStream, MAX_TRUTH_COORDINATE_M, MAX_TRUTH_HEADING_RAD,
};

#[derive(Clone, Debug, Serialize)]
pub struct BoardScore {
    pub file: String,
    /// Board poses inside the truth rows' time span (the ones scored).
    pub rows: usize,
    pub final_error_m: f64,
    pub max_error_m: f64,
    pub final_heading_error_rad: f64,
}

/// `b` seen from `a`: the rigid motion from `a` to `b`, in `a`'s frame.
fn relative(a: Pose2, b: Pose2) -> Pose2 {
    let (s, c) = a.theta.sin_cos();
    let (dx, dy) = (b.x - a.x, b.y - a.y);
    Pose2::new(c * dx + s * dy, -s * dx + c * dy, b.theta - a.theta)
}

/// `rel` applied from `a` (the inverse of [`relative`]).
fn from(a: Pose2, rel: Pose2) -> Pose2 {
    let (s, c) = a.theta.sin_cos();
    Pose2::new(
        a.x + c * rel.x - s * rel.y,
        a.y + s * rel.x + c * rel.y,
        a.theta + rel.theta,
    )
}

/// Largest board pose file read, bytes: it is read whole, beside a stream that may hold
/// 160 MiB of events, so together they stay under 200 MB. [`MAX_ROWS`] rows of 84 bytes
/// (`record` writes about 50 a row).
pub const MAX_BYTES: u64 = 8 << 20;

/// Most board poses in one file. `record` keeps one every 50 updates and stops here: 83
/// minutes at the slave's 1 kHz (a stream's `tickstream::MAX_EVENTS` rows fill in about 23 at
/// 3000 edges/s), 8 at 10 kHz.
pub const MAX_ROWS: usize = 100_000;

/// `STEM.board.csv` beside a stream `STEM.csv` / `STEM.csv.gz`, if anything has that name
/// (a folder, device or FIFO is refused when read, not passed over in silence).
pub fn beside(ticks: &Path) -> Option<PathBuf> {
    let name = ticks.file_name()?.to_str()?;
    let stem = name.strip_suffix(".gz").unwrap_or(name);
    let stem = stem.strip_suffix(".csv").unwrap_or(stem);
    let p = ticks.with_file_name(format!("{stem}.board.csv"));
    std::fs::symlink_metadata(&p).is_ok().then_some(p)
}

/// One pose of `file` at `line`: `t_ns,x_m,y_m,theta_rad`, each value within what a truth
/// row of a tick stream may hold (so every error computed from it is finite).
fn pose(file: &Path, line: u64, row: &csv::StringRecord) -> Result<(u64, Pose2)> {
    let at = || format!("{}:{line}", file.display());
    if row.len() != 4 {
        bail!(
            "{}: expected 4 fields (t_ns,x_m,y_m,theta_rad), found {}",
            at(),
            row.len()
        );
    }
    let t = row[0].trim();
    let t_ns: u64 = t.parse().map_err(|_| {
        anyhow!(
            "{}: t_ns must be a whole number of nanoseconds, got {t:?}",
            at()
        )
    })?;
    let mut v = [0.0; 3];
    for (k, (name, limit, unit)) in [
        ("x_m", MAX_TRUTH_COORDINATE_M, "m"),
        ("y_m", MAX_TRUTH_COORDINATE_M, "m"),
        ("theta_rad", MAX_TRUTH_HEADING_RAD, "rad"),
    ]
    .into_iter()
    .enumerate()
    {
        let f = row[k + 1].trim();
        let x: f64 = f
            .parse()
            .map_err(|_| anyhow!("{}: {name} must be a number, got {f:?}", at()))?;
        if !(x.is_finite() && x.abs() <= limit) {
            bail!(
                "{}: {name} must be finite and within ±{limit:e} {unit}, got {f}",
                at()
            );
        }
        v[k] = x;
    }
    Ok((t_ns, Pose2::new(v[0], v[1], v[2])))
}

/// Every pose of `file`, checked: a regular file of at most [`MAX_BYTES`] and [`MAX_ROWS`]
/// rows under the header `t_ns,x_m,y_m,theta_rad`. Errors name the file and line.
pub fn read(file: &Path) -> Result<Vec<(u64, Pose2)>> {
    let bytes = read_bounded(file, MAX_BYTES, "a board pose file")
        .with_context(|| format!("reading {}", file.display()))?;
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .from_reader(bytes.as_slice());
    let mut poses = Vec::new();
    let mut row = csv::StringRecord::new();
    let mut header_seen = false;
    loop {
        let more = reader.read_record(&mut row).map_err(|e| {
            let line = e.position().map_or(reader.position().line(), |p| p.line());
            anyhow!("{}:{line}: {e}", file.display())
        })?;
        if !more {
            break;
        }
        let line = row.position().map_or(0, |p| p.line());
        if !header_seen {
            let header: Vec<&str> = row.iter().map(str::trim).collect();
            if header != ["t_ns", "x_m", "y_m", "theta_rad"] {
                bail!(
                    "{}:{line}: expected the header t_ns,x_m,y_m,theta_rad",
                    file.display()
                );
            }
            header_seen = true;
            continue;
        }
        if poses.len() == MAX_ROWS {
            bail!(
                "{}:{line}: more than {MAX_ROWS} board poses",
                file.display()
            );
        }
        poses.push(pose(file, line, &row)?);
    }
    Ok(poses)
}

/// Score the board poses in `file` against `stream`'s truth (linearly interpolated to each
/// pose's instant), the board's track laid onto the truth at its first pose inside the truth
/// rows. `None` when no pose falls inside them.
pub fn score(file: &Path, stream: &TickStream) -> Result<Option<BoardScore>> {
    let poses = read(file)?;
    // The truth rows by their place in the stream, 4 bytes each: a copy of each pose took 67 MB
    // beside a stream at its limit.
    let truth: Vec<u32> = (0..stream.events.len() as u32)
        .filter(|&i| matches!(stream.events[i as usize], Event::Truth { .. }))
        .collect();
    let truth_at = |k: usize| stream.events[truth[k] as usize].truth(); // only truth rows listed
    let (mut rows, mut last, mut max) = (0usize, None, 0.0f64);
    // The first scored pose: the board's and the truth's there.
    let mut anchor: Option<(Pose2, Pose2)> = None;
    for (t, board) in poses {
        let k = truth.partition_point(|&i| stream.events[i as usize].t_ns() <= t);
        if k == 0 || k == truth.len() {
            continue;
        }
        let (Some((ta, a)), Some((tb, b))) = (truth_at(k - 1), truth_at(k)) else {
            continue;
        };
        let f = (t - ta) as f64 / (tb - ta).max(1) as f64;
        let want = Pose2::new(
            a.x + (b.x - a.x) * f,
            a.y + (b.y - a.y) * f,
            a.theta + wrap_angle(b.theta - a.theta) * f,
        );
        let (board0, truth0) = *anchor.get_or_insert((board, want));
        let laid = from(truth0, relative(board0, board));
        let e = laid.distance_to(want);
        max = max.max(e);
        last = Some((e, wrap_angle(laid.theta - want.theta)));
        rows += 1;
    }
    Ok(
        last.map(|(final_error_m, final_heading_error_rad)| BoardScore {
            file: file.display().to_string(),
            rows,
            final_error_m,
            max_error_m: max,
            final_heading_error_rad,
        }),
    )
}
