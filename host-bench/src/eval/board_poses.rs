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

use anyhow::{Context, Result};
use robot_math::se2::wrap_angle;
use robot_math::Pose2;
use serde::Serialize;

use crate::formats::tickstream::{Event, TickStream};

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

/// `STEM.board.csv` beside a stream `STEM.csv` / `STEM.csv.gz`, if there is one.
pub fn beside(ticks: &Path) -> Option<PathBuf> {
    let name = ticks.file_name()?.to_str()?;
    let stem = name.strip_suffix(".gz").unwrap_or(name);
    let stem = stem.strip_suffix(".csv").unwrap_or(stem);
    let p = ticks.with_file_name(format!("{stem}.board.csv"));
    p.is_file().then_some(p)
}

/// Score the board poses in `file` against `stream`'s truth (linearly interpolated to each
/// pose's instant), the board's track laid onto the truth at its first pose inside the truth
/// rows. `None` when no pose falls inside them.
pub fn score(file: &Path, stream: &TickStream) -> Result<Option<BoardScore>> {
    let truth: Vec<(u64, Pose2)> = stream
        .events
        .iter()
        .filter_map(|e| match *e {
            Event::Truth {
                t_ns,
                x_m,
                y_m,
                theta_rad,
            } => Some((t_ns, Pose2::new(x_m, y_m, theta_rad))),
            _ => None,
        })
        .collect();
    let mut reader =
        csv::Reader::from_path(file).with_context(|| format!("reading {}", file.display()))?;
    let (mut rows, mut last, mut max) = (0usize, None, 0.0f64);
    // The first scored pose: the board's and the truth's there.
    let mut anchor: Option<(Pose2, Pose2)> = None;
    for (i, rec) in reader.deserialize::<(u64, f64, f64, f64)>().enumerate() {
        let (t, x, y, th) = rec.with_context(|| format!("{}: row {}", file.display(), i + 2))?;
        let k = truth.partition_point(|(tt, _)| *tt <= t);
        if k == 0 || k == truth.len() {
            continue;
        }
        let ((ta, a), (tb, b)) = (truth[k - 1], truth[k]);
        let f = (t - ta) as f64 / (tb - ta).max(1) as f64;
        let want = Pose2::new(
            a.x + (b.x - a.x) * f,
            a.y + (b.y - a.y) * f,
            a.theta + wrap_angle(b.theta - a.theta) * f,
        );
        let board = Pose2::new(x, y, th);
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
