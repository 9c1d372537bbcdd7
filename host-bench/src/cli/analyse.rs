//! The analysis commands: `accuracy`, `replay` (`generate` is in `generate.rs`).

use std::path::{Path, PathBuf};

use anyhow::Context;
use host_bench::formats::atomic::{check_output, OutputDir, Staged};

/// Most power-on seeds per accuracy case (each case replays every method once per seed).
pub const MAX_ACCURACY_SEEDS: u64 = 1000;

pub fn run_accuracy(
    json: bool,
    out: Option<PathBuf>,
    seeds: u64,
    edges: &str,
    even_edges: bool,
) -> anyhow::Result<()> {
    use host_bench::eval::accuracy;
    let edges = host_bench::sim::generate::EdgeErrors::preset(edges).context("--edges")?;
    anyhow::ensure!(
        (1..=MAX_ACCURACY_SEEDS).contains(&seeds),
        "--seeds must be 1 to {MAX_ACCURACY_SEEDS}, got {seeds}"
    );
    // The folder and every name it may get, checked before the minutes of work: a name in
    // the way was found only after them, with hundreds of the other files already written.
    let made = match &out {
        Some(dir) => Some(output_dir(dir, &accuracy_files(dir)?, &[])?),
        None => None,
    };
    let total = accuracy::cases().len() as u64 * seeds;
    // indicatif draws only when stderr is a terminal: CI logs stay clean.
    let bar = indicatif::ProgressBar::new(total).with_style(
        indicatif::ProgressStyle::with_template("{bar:30} {pos}/{len} {elapsed} {msg}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let results = accuracy::run(seeds, edges, even_edges, |label| {
        bar.set_message(label.to_string());
        bar.inc(1);
    })?;
    bar.finish_and_clear();
    if let Some(dir) = &out {
        // Renamed into place together: a file that fails leaves none of the others.
        let mut staged = Staged::default();
        for r in &results {
            let stem = accuracy::file_stem(&r.case, &r.robot, &r.mode);
            // The tracks and the picture of seed 0; the figures cover every seed.
            let first: Vec<_> = r
                .algorithms
                .iter()
                .filter_map(|m| m.runs.first().cloned())
                .collect();
            for s in &first {
                let path = dir.join(format!("{stem}-{}.csv", s.name));
                staged.write(&path, |f| s.write_track_to(f))?;
            }
            let title = format!(
                "{} on {} ({}, seed 0): paths and error",
                r.case, r.robot, r.mode
            );
            let svg = host_bench::eval::report::case_svg(&title, &first)?;
            let path = dir.join(format!("{stem}.svg"));
            host_bench::eval::png::stage(&mut staged, &path, &svg)?;
        }
        staged.commit()?;
    }
    if let Some(made) = made {
        made.keep();
    }
    if json {
        println!("{}", serde_json::json!({ "cases": results }));
    } else {
        print!("{}", accuracy::table(&results));
    }
    Ok(())
}

/// Every file `accuracy --out DIR` may write: each case's picture and each method's track,
/// in every mode (a method that cannot run there writes none).
fn accuracy_files(dir: &Path) -> anyhow::Result<Vec<PathBuf>> {
    use host_bench::eval::{accuracy, replay};
    let mut files = Vec::new();
    for case in accuracy::cases() {
        let robot = accuracy::robot(&case)?;
        for mode in accuracy::modes() {
            let stem = accuracy::file_stem(case.trajectory, &robot.name, &mode.to_string());
            files.push(dir.join(format!("{stem}.svg")));
            files.push(dir.join(format!("{stem}.png")));
            for name in replay::ALGORITHMS {
                files.push(dir.join(format!("{stem}-{name}.csv")));
            }
        }
    }
    Ok(files)
}

/// `dir`, made with its parents for `files`, each checked before any work: a regular file or
/// a new name, and none of the run's `inputs` (what they are, and their paths; compared as
/// canonical paths, like `generate`'s guard for its robot file). Dropped without `keep` (the
/// run failed), the folders it made go again.
fn output_dir(
    dir: &Path,
    files: &[PathBuf],
    inputs: &[(&str, &Path)],
) -> anyhow::Result<OutputDir> {
    let flag = || format!("--out {}", dir.display());
    host_bench::formats::atomic::refuse_inputs(&flag(), files, inputs)?;
    let made = OutputDir::create(dir).with_context(flag)?;
    for file in files {
        check_output(file).with_context(flag)?;
    }
    Ok(made)
}

pub fn run_replay(
    robot: Option<PathBuf>,
    ticks: PathBuf,
    algorithm: String,
    counts_rate: Option<f64>,
    out: Option<PathBuf>,
    json: bool,
    view: &host_bench::viewer::ViewArgs,
) -> anyhow::Result<()> {
    use host_bench::eval::{board_poses, replay, replay_checks as checks};
    use host_bench::formats::{robot::Robot, tickstream};
    // The flag before any file is read.
    let mode = match counts_rate {
        Some(rate_hz) => {
            checks::check_counts_rate(rate_hz).context("--counts-rate")?;
            replay::Mode::Counts { rate_hz }
        }
        None => replay::Mode::Timestamps,
    };
    let (stream, lines) = tickstream::read_with_lines(&ticks)?;
    let robot_path = match robot {
        Some(p) => p,
        None => stream.robot_path(&ticks).ok_or_else(|| {
            anyhow::anyhow!(
                "{}: no `# robot:` line; name the robot with --robot FILE",
                ticks.display()
            )
        })?,
    };
    let robot = Robot::load(&robot_path)?;
    // A robot the odometry cannot run (5 encoders: `generate` takes it), named by its file.
    robot
        .odometry_layout()
        .with_context(|| robot_path.display().to_string())?;
    // Every input is read and checked before any method runs or any file is written: the
    // events against the robot (at their line), what there is to score, the board's poses.
    checks::check_events(&robot, &stream)
        .map_err(|e| anyhow::anyhow!("{}:{}: {}", ticks.display(), lines.of(e.index), e.message))?;
    checks::check_scorable(&stream, mode).with_context(|| ticks.display().to_string())?;
    // A recording's own poses, when `record` wrote them beside the stream.
    let board_file = board_poses::beside(&ticks);
    let board = match &board_file {
        Some(f) => board_poses::score(f, &stream)?,
        None => None,
    };
    let names: Vec<&str> = if algorithm == "all" {
        replay::ALGORITHMS.to_vec()
    } else {
        vec![algorithm.as_str()]
    };
    let made = match &out {
        Some(dir) => {
            let files: Vec<PathBuf> = names.iter().map(|n| dir.join(format!("{n}.csv"))).collect();
            let mut inputs = vec![
                ("the tick stream", ticks.as_path()),
                ("the robot file", robot_path.as_path()),
            ];
            inputs.extend(board_file.as_deref().map(|b| ("the board poses", b)));
            Some(output_dir(dir, &files, &inputs)?)
        }
        None => None,
    };
    let mut files = vec![ticks.as_path(), robot_path.as_path()];
    files.extend(board_file.as_deref());
    let track_files: Vec<PathBuf> = (out.iter())
        .flat_map(|dir| names.iter().map(move |n| dir.join(format!("{n}.csv"))))
        .collect();
    files.extend(track_files.iter().map(PathBuf::as_path));
    let mut outputs = host_bench::viewer::Outputs::open(
        view,
        host_bench::viewer::topics::replay_channels(&names),
        "host-bench replay",
        &files,
    )?;
    // Each method's track, kept for the view (shown together at the end, in time order).
    let mut tracks = Vec::new();
    // A named algorithm must run; with `all`, the ones that cannot apply to this robot or
    // mode (e.g. `timing` on sampled counts) are skipped with the reason.
    let mut scores = Vec::new();
    let mut skipped = Vec::new();
    let mut staged = Staged::default();
    for name in &names {
        let run = if out.is_some() || outputs.view.borrow().is_on() {
            replay::replay
        } else {
            replay::replay_untracked
        };
        match run(&robot, &stream, name, mode) {
            Ok(mut s) => {
                // Each track is written to its temporary file and let go at once (four of them
                // for a long stream would be most of the memory); all are renamed into place
                // at the end, so a run that fails replaces none.
                if let Some(dir) = &out {
                    let path = dir.join(format!("{}.csv", s.name));
                    staged.write(&path, |f| s.write_track_to(f))?;
                }
                let track = std::mem::take(&mut s.track);
                if outputs.view.borrow().is_on() {
                    tracks.push((s.name.clone(), track));
                }
                scores.push(s)
            }
            Err(e) if algorithm == "all" => {
                skipped.push(serde_json::json!({"name": name, "reason": format!("{e:#}")}))
            }
            Err(e) => return Err(e),
        }
    }
    // A run that scores nothing is a failure, not an empty table.
    if scores.is_empty() {
        let reason = |k: &serde_json::Value| k["reason"].as_str().unwrap_or("").to_string();
        let mut reasons: Vec<String> = skipped.iter().map(reason).collect();
        reasons.dedup();
        let why = if reasons.len() == 1 {
            reasons.remove(0)
        } else {
            let each = |k: &serde_json::Value| {
                format!("{}: {}", k["name"].as_str().unwrap_or(""), reason(k))
            };
            skipped.iter().map(each).collect::<Vec<_>>().join("; ")
        };
        anyhow::bail!("{}: no estimator can run: {why}", ticks.display());
    }
    host_bench::viewer::topics::replay_tracks(&mut outputs.view.borrow_mut(), &tracks)?;
    drop(tracks);
    // The MCAP file first, and gone again should the tracks fail to go in place.
    let mcap = outputs.finish()?;
    if let Err(e) = staged.commit() {
        if let Some(p) = &mcap {
            let _ = std::fs::remove_file(p);
        }
        return Err(e);
    }
    if let Some(made) = made {
        made.keep();
    }
    if json {
        println!(
            "{}",
            serde_json::json!({ "mode": mode.to_string(), "algorithms": scores, "skipped": skipped, "board": board })
        );
    } else {
        println!(
            "{} on {} ({} events), encoders read as {mode}",
            ticks.display(),
            robot.name,
            stream.events.len()
        );
        for s in &scores {
            println!(
                "{:<8} final error {:9.4} mm, max {:9.4} mm, final heading error {:+.5} deg, path {:.3} m",
                s.name,
                s.final_error_m * 1e3,
                s.max_error_m * 1e3,
                s.final_heading_error_rad.to_degrees(),
                s.path_length_m
            );
        }
        for k in &skipped {
            println!(
                "{:<8} skipped: {}",
                k["name"].as_str().unwrap_or(""),
                k["reason"].as_str().unwrap_or("")
            );
        }
        if let Some(b) = &board {
            println!(
                "{:<8} final error {:9.4} mm, max {:9.4} mm, final heading error {:+.5} deg \
                 ({} poses the board computed live, from its first: {})",
                "board",
                b.final_error_m * 1e3,
                b.max_error_m * 1e3,
                b.final_heading_error_rad.to_degrees(),
                b.rows,
                b.file
            );
        }
        if let Some(p) = &mcap {
            println!("wrote {}", p.display());
        }
    }
    outputs.hold(&format!("done: {} methods scored", scores.len()));
    Ok(())
}
