//! Where a recording goes: the stream and the two files beside it, as one set.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::{bail, Result};

use super::collect::{Collected, Early};
use super::{RecordOutcome, RecordRequest};
use crate::formats::tickstream::{self, Event as Row, TickStream};

/// The files written beside a recording `out`: `STEM.robot.toml` and `STEM.board.csv`.
pub fn companion_files(out: &Path) -> (PathBuf, PathBuf) {
    let stem = out
        .file_name()
        .and_then(|n| n.to_str())
        .map(|n| {
            n.trim_end_matches(".gz")
                .trim_end_matches(".csv")
                .to_string()
        })
        .unwrap_or_else(|| "recording".into());
    let dir = out.parent().unwrap_or(Path::new(""));
    (
        dir.join(format!("{stem}.robot.toml")),
        dir.join(format!("{stem}.board.csv")),
    )
}

/// The signal test's lever (`tests/bench_cli.rs`): `OMNIBENCH_RECORD_WRITE_PAUSE_MS` widens
/// the final write, a few milliseconds on its own, so that signals sent at random moments land
/// inside it between one file and the next, where a set written file by file would be torn.
fn pause_for_signal_tests() {
    if let Some(ms) = std::env::var("OMNIBENCH_RECORD_WRITE_PAUSE_MS")
        .ok()
        .and_then(|v| v.parse::<u64>().ok())
    {
        std::thread::sleep(Duration::from_millis(ms.min(1000)));
    }
}

pub(super) fn write(
    req: &RecordRequest,
    robot_text: &str,
    robot_name: &str,
    mut c: Collected,
    seconds: f64,
    period_us: u64,
    stopped: &std::result::Result<&str, Early>,
) -> Result<RecordOutcome> {
    let (stopped_by, partial) = match stopped {
        Ok(by) => (by.to_string(), None),
        Err(early) => (early.by.to_string(), Some(early.why.clone())),
    };
    if c.rows.iter().all(|r| matches!(r, Row::Truth { .. })) {
        if let Err(early) = stopped {
            bail!(
                "nothing recorded: the recording ended after {seconds:.1} s, before any encoder \
                 event reached the host: {}",
                early.why
            );
        }
        bail!(
            "nothing recorded in {seconds:.1} s: no encoder event reached the host (is the \
             slave in a sensor mode that reports? {} truth rows, {} board poses)",
            c.truth,
            c.board.len()
        );
    }
    // The truth comes straight from the simulation, the sensors through the slave's report
    // stream, tens of milliseconds behind: truth past the slave's last pose may have no
    // ticks yet. The slave flushes its sensor records before each pose, so up to that pose
    // every tick is in; later truth rows go.
    if let Some(&(covered, _)) = c.board.last() {
        c.rows
            .retain(|r| !matches!(*r, Row::Truth { t_ns, .. } if t_ns > covered));
    }
    // One clock for everything (the slave's), starting at the first row.
    c.rows.sort_by_key(|r| r.t_ns());
    // With truth, the stream starts at the first truth row (replay starts from its pose):
    // ticks before it would move the robot twice; the absolute reading then is kept.
    if let Some(first) = c.rows.iter().position(|r| matches!(r, Row::Truth { .. })) {
        let t = c.rows[first].t_ns();
        let abs = c.rows[..first].iter().rev().find_map(|r| match *r {
            Row::Abs { encoder, code, .. } => Some(Row::Abs {
                t_ns: t,
                encoder,
                code,
            }),
            _ => None,
        });
        c.rows.drain(..first);
        if let Some(a) = abs {
            c.rows.insert(1, a);
        }
        c.board.retain(|b| b.0 >= t);
    }
    let t0 = c.rows[0]
        .t_ns()
        .min(c.board.first().map_or(u64::MAX, |b| b.0));
    for r in &mut c.rows {
        match r {
            Row::Tick { t_ns, .. } | Row::Abs { t_ns, .. } | Row::Truth { t_ns, .. } => *t_ns -= t0,
        }
    }
    let out = req.out;
    let (robot_path, board_file) = companion_files(out);
    let dir = out.parent().unwrap_or(Path::new(""));
    let robot_file = robot_path
        .file_name()
        .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
    let mut comments = Vec::new();
    if let Some(why) = &partial {
        // First, where a reader looks: this stream ends where the recording broke off.
        comments.push(format!(
            "PARTIAL: the recording ended early after {seconds:.3} s: {why}; the stream holds \
             what came before"
        ));
    }
    comments.extend([
        format!("recorded by host-bench record from robot {robot_name} ({stopped_by} after {seconds:.3} s)"),
        if req.counts {
            format!(
                "sensor: counts@{}Hz; each sample's count change is written as that many ticks \
                 at the sample instant (replay with --counts-rate {})",
                1_000_000 / period_us,
                1_000_000 / period_us
            )
        } else {
            "sensor: timestamps (every edge, time-stamped by the slave in microseconds)".into()
        },
    ]);
    if c.lost_events > 0 || c.lost_updates > 0 {
        comments.push(format!(
            "GAPS: the link could not keep up; the slave dropped {} encoder events and {} \
             updates (the counts after a gap are off by what was dropped)",
            c.lost_events, c.lost_updates
        ));
    }
    if c.skipped() > 0 {
        comments.push(format!(
            "GAPS: report records passed over: {} that did not decode, and {} sensor \
             records after them, up to where the slave's event code started again at its next \
             pose (the counts after a gap are off by what those records held)",
            c.undecodable, c.unplaced
        ));
    }
    // Each gap where it is, on the stream's clock.
    let at = |t_ns: u64| format!("{:.6} s", t_ns.saturating_sub(t0) as f64 * 1e-9);
    for g in &c.gaps {
        let to = g.to_ns.map_or_else(|| "the end".to_string(), at);
        comments.push(format!("GAP from {} to {to}: {}", at(g.from_ns), g.what));
    }
    if c.gap_count > c.gaps.len() as u64 {
        comments.push(format!(
            "GAP: {} more gaps, not listed",
            c.gap_count - c.gaps.len() as u64
        ));
    }
    // What is written (rows before the first truth row, or past the last pose, are not).
    let written = |f: fn(&Row) -> bool| c.rows.iter().filter(|r| f(r)).count() as u64;
    let ticks = written(|r| matches!(r, Row::Tick { .. }));
    let abs_readings = written(|r| matches!(r, Row::Abs { .. }));
    let truth_rows = written(|r| matches!(r, Row::Truth { .. }));
    let stream = TickStream {
        robot: Some(robot_file.clone()),
        comments,
        events: c.rows,
    };
    // The three files appear together or not at all, and until they do, a recording of the
    // same name from before stays whole (`atomic::Staged`).
    let mut staged = crate::formats::atomic::Staged::default();
    tickstream::stage(&mut staged, out, &stream)?;
    pause_for_signal_tests();
    staged.write(&dir.join(&robot_file), |f| {
        f.write_all(robot_text.as_bytes())?;
        Ok(())
    })?;
    pause_for_signal_tests();
    let mut poses = String::from("t_ns,x_m,y_m,theta_rad\n");
    for (t, p) in &c.board {
        let (x, y, th) = p.to_si();
        poses.push_str(&format!("{},{x},{y},{th}\n", t.saturating_sub(t0)));
    }
    staged.write(&board_file, |f| {
        f.write_all(poses.as_bytes())?;
        Ok(())
    })?;
    pause_for_signal_tests();
    staged.commit()?;
    Ok(RecordOutcome {
        out: out.display().to_string(),
        robot_file: dir.join(&robot_file).display().to_string(),
        board_poses_file: PathBuf::from(&board_file).display().to_string(),
        sensor: if req.counts { "counts" } else { "timestamps" }.into(),
        seconds,
        edges: ticks,
        ticks,
        abs_readings,
        truth_rows,
        board_poses: c.board.len() as u64,
        lost_events: c.lost_events,
        lost_updates: c.lost_updates,
        gaps: c.gap_count,
        baud: 0,
        baud_asked: 0,
        records_undecodable: c.undecodable,
        records_unplaced: c.unplaced,
        stopped_by,
        partial,
        switch_back_failed: None,
    })
}
