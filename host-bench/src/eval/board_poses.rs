//! The board's own poses from a recording (`STEM.board.csv`, written by `host-bench record`
//! beside `STEM.csv`), scored against the stream's truth rows: what the board computed live,
//! next to what `replay` computes from the same ticks.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
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
/// pose's instant). `None` when no pose falls inside the truth rows.
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
    for (i, rec) in reader.deserialize::<(u64, f64, f64, f64)>().enumerate() {
        let (t, x, y, _) = rec.with_context(|| format!("{}: row {}", file.display(), i + 2))?;
        let k = truth.partition_point(|(tt, _)| *tt <= t);
        if k == 0 || k == truth.len() {
            continue;
        }
        let ((ta, a), (tb, b)) = (truth[k - 1], truth[k]);
        let f = (t - ta) as f64 / (tb - ta).max(1) as f64;
        let (tx, ty) = (a.x + (b.x - a.x) * f, a.y + (b.y - a.y) * f);
        let e = (x - tx).hypot(y - ty);
        max = max.max(e);
        last = Some(e);
        rows += 1;
    }
    Ok(last.map(|final_error_m| BoardScore {
        file: file.display().to_string(),
        rows,
        final_error_m,
        max_error_m: max,
    }))
}
