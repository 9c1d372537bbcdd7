//! A bad-input hunt on `replay`, `accuracy --out` and the tick-stream reader: each finding is
//! refused with exit 1 and its place named (file and line, or flag), in under 5 s and 200 MB,
//! writing nothing and replacing nothing.

mod common;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use common::scratch;

const HEAD: &str = "# omnibench tick stream v1\n# robot: diff-drive.toml\n\
                    t_ns,kind,id,value,x_m,y_m,theta_rad\n";

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/tickstreams")
        .join(name)
}

/// The largest resident set of any finished child of this test binary, MB.
fn children_peak_rss_mb() -> f64 {
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    // SAFETY: getrusage writes one rusage into the struct it is given.
    let rc = unsafe { libc::getrusage(libc::RUSAGE_CHILDREN, &mut usage) };
    assert_eq!(rc, 0);
    usage.ru_maxrss as f64 / 1024.0 // KiB on Linux
}

/// What a file is: its inode, size and time, and its bytes if small (a huge input is not read
/// into this test: its children would inherit the memory).
type Seen = (u64, u64, Option<std::time::SystemTime>, Vec<u8>);

/// Every file and folder under `dir` (nothing at all if `dir` is missing).
fn snapshot(dir: &Path) -> BTreeMap<PathBuf, Seen> {
    use std::os::unix::fs::MetadataExt;
    let mut files = BTreeMap::new();
    let Ok(entries) = std::fs::read_dir(dir) else {
        return files;
    };
    for e in entries {
        let path = e.unwrap().path();
        let m = std::fs::symlink_metadata(&path).unwrap();
        let small = m.is_file() && m.len() < 1 << 20;
        let bytes = if small {
            std::fs::read(&path).unwrap()
        } else {
            Vec::new()
        };
        files.insert(path.clone(), (m.ino(), m.len(), m.modified().ok(), bytes));
        if m.is_dir() {
            files.extend(snapshot(&path));
        }
    }
    files
}

/// Runs host-bench with `args` in `dir` (the files under it compared before and after):
/// exit 1, `says` in the error, no panic, under 5 s and 200 MB, nothing written or replaced.
fn refused(dir: &Path, args: &[&str], says: &str) -> String {
    let before = snapshot(dir);
    let start = Instant::now();
    let o = Command::new(env!("CARGO_BIN_EXE_host-bench"))
        .current_dir(dir)
        .args(args)
        .output()
        .unwrap();
    let secs = start.elapsed().as_secs_f64();
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert_eq!(o.status.code(), Some(1), "{args:?}: {err}");
    assert!(err.contains(says), "{args:?}: wanted {says:?} in {err}");
    assert!(!err.contains("panicked"), "{args:?}: {err}");
    assert!(o.stdout.is_empty(), "{args:?} printed a result");
    assert!(secs < 5.0, "{args:?}: {secs} s");
    let peak_mb = children_peak_rss_mb();
    assert!(peak_mb < 200.0, "{args:?}: a child peaked at {peak_mb} MB");
    assert!(
        before == snapshot(dir),
        "{args:?} changed the files in {}",
        dir.display()
    );
    err
}

/// A folder for `test` with the documented Python example's stream and robot in it.
fn with_example(test: &str) -> PathBuf {
    let dir = scratch(&format!("replay-bad-inputs/{test}"));
    for name in ["python-circle.csv", "diff-drive.toml"] {
        std::fs::copy(data(name), dir.join(name)).unwrap();
    }
    dir
}

fn board(dir: &Path, rows: &str) {
    let text = format!("t_ns,x_m,y_m,theta_rad\n100000000,0,0,0\n200000000,0,0,0\n{rows}");
    std::fs::write(dir.join("python-circle.board.csv"), text).unwrap();
}

#[test]
fn rows_of_quoted_empty_cells_count_as_blank_lines() {
    let dir = scratch("replay-bad-inputs/quoted-blank");
    // As a spreadsheet writes blank rows with quotes: 3 MB here, a 1 MB gzip of 1 GB of them
    // took 20 s to refuse (`,` rows stopped at once).
    let mut text = String::from(HEAD);
    text.push_str(&"\"\"\n".repeat(600_000));
    text.push_str(&"\"\",\"\" ,\"\"\n".repeat(400_001));
    std::fs::write(dir.join("t.csv"), text).unwrap();
    std::fs::copy(data("diff-drive.toml"), dir.join("diff-drive.toml")).unwrap();
    refused(
        &dir,
        &["replay", "--ticks", "t.csv"],
        // The robot line is the first of them.
        "t.csv:1000003: more than 1000000 comment or blank lines",
    );
}

#[test]
fn cr_only_line_endings_are_refused_saying_so() {
    let dir = scratch("replay-bad-inputs/cr");
    std::fs::copy(data("diff-drive.toml"), dir.join("diff-drive.toml")).unwrap();
    // CR line endings alone (classic Mac OS): the whole file is one line.
    let text = std::fs::read_to_string(data("python-circle.csv")).unwrap();
    let cr = text.replace("\r\n", "\r").replace('\n', "\r");
    std::fs::write(dir.join("cr.csv"), cr).unwrap();
    refused(
        &dir,
        &["replay", "--ticks", "cr.csv"],
        "cr.csv:1: the line endings are CR alone",
    );
    // And past the longest line.
    let long = format!("{HEAD}{}", "0,truth,,,0,0,0\r".repeat(80_000)).replace('\n', "\r");
    std::fs::write(dir.join("long.csv"), long).unwrap();
    refused(
        &dir,
        &["replay", "--ticks", "long.csv"],
        "long.csv:1: the line endings are CR alone",
    );
}

#[test]
fn a_stream_one_row_over_the_limit_is_refused_under_200_mb() {
    use host_bench::formats::tickstream::MAX_EVENTS;
    use std::io::Write;
    let dir = scratch("replay-bad-inputs/rows");
    std::fs::copy(data("diff-drive.toml"), dir.join("diff-drive.toml")).unwrap();
    let file = std::fs::File::create(dir.join("t.csv.gz")).unwrap();
    let mut gz = flate2::write::GzEncoder::new(file, flate2::Compression::fast());
    gz.write_all(HEAD.as_bytes()).unwrap();
    let rows = "1,tick,0,1,,,\n".repeat(1 << 16);
    for _ in 0..MAX_EVENTS >> 16 {
        gz.write_all(rows.as_bytes()).unwrap();
    }
    gz.write_all(b"1,tick,1,1,,,\n").unwrap();
    gz.finish().unwrap();
    refused(
        &dir,
        &["replay", "--ticks", "t.csv.gz"],
        &format!("t.csv.gz:{}: more than {MAX_EVENTS} events", MAX_EVENTS + 4),
    );
}

#[test]
fn a_board_pose_file_that_is_huge_or_not_a_regular_file_is_refused_naming_it() {
    let dir = with_example("board-size");
    let ticks = ["replay", "--ticks", "python-circle.csv"];
    let path = dir.join("python-circle.board.csv");
    // 1 GiB of nothing (sparse): once read whole into 3 GB, then ignored, exit 0.
    std::fs::File::create(&path)
        .unwrap()
        .set_len(1 << 30)
        .unwrap();
    refused(
        &dir,
        &ticks,
        "python-circle.board.csv: larger than 8192 KiB",
    );
    std::fs::remove_file(&path).unwrap();
    // A folder and a FIFO by that name: refused unread (a FIFO's open does not wait).
    std::fs::create_dir(&path).unwrap();
    refused(&dir, &ticks, "python-circle.board.csv: not a regular file");
    std::fs::remove_dir(&path).unwrap();
    let made = Command::new("mkfifo").arg(&path).status().unwrap();
    assert!(made.success());
    refused(&dir, &ticks, "python-circle.board.csv: not a regular file");
    std::fs::remove_file(&path).unwrap();
    // Rows past the documented count.
    let mut rows = String::from("t_ns,x_m,y_m,theta_rad\n");
    for k in 0..=host_bench::eval::board_poses::MAX_ROWS {
        rows.push_str(&format!("{k},0,0,0\n"));
    }
    std::fs::write(&path, rows).unwrap();
    refused(
        &dir,
        &ticks,
        "python-circle.board.csv:100002: more than 100000 board poses",
    );
}

#[test]
fn board_poses_that_are_not_finite_or_out_of_range_are_refused_at_their_line() {
    let dir = with_example("board-values");
    let ticks = ["replay", "--ticks", "python-circle.csv"];
    for (row, says) in [
        (
            "300000000,0,0,NaN\n",
            "python-circle.board.csv:4: theta_rad must be finite",
        ),
        (
            "300000000,inf,0,0\n",
            "python-circle.board.csv:4: x_m must be finite",
        ),
        ("300000000,0,1e300,0\n", "within ±1e6 m, got 1e300"),
        ("300000000,0,0,2e6\n", "within ±1e6 rad, got 2e6"),
        (
            "xyz,0,0,0\n",
            "python-circle.board.csv:4: t_ns must be a whole number",
        ),
        (
            "300000000,0,0\n",
            "python-circle.board.csv:4: expected 4 fields",
        ),
    ] {
        board(&dir, row);
        refused(&dir, &ticks, says);
        let json = [&ticks[..], &["--json"]].concat();
        refused(&dir, &json, says);
    }
}

#[test]
fn errors_about_a_streams_content_name_its_line() {
    let dir = scratch("replay-bad-inputs/lines");
    std::fs::copy(data("diff-drive.toml"), dir.join("diff-drive.toml")).unwrap();
    let start = "0,truth,,,0,0,0\n# a comment\n\n";
    for (name, row, says) in [
        (
            "id.csv",
            "1,tick,65535,1,,,\n",
            "id.csv:7: tick for encoder 65535 at t = 1 ns",
        ),
        (
            "abs.csv",
            "1,abs,0,5,,,\n",
            "abs.csv:7: abs reading of absolute encoder 0",
        ),
    ] {
        let text = format!("{HEAD}{start}{row}1,tick,0,1,,,\n2,truth,,,0.01,0,0\n");
        std::fs::write(dir.join(name), text).unwrap();
        let err = refused(&dir, &["replay", "--ticks", name], says);
        assert!(!err.contains("no estimator can run"), "{err}");
    }
}

#[test]
fn counts_rates_below_the_documented_range_are_refused_at_the_flag() {
    let dir = scratch("replay-bad-inputs/counts-rate");
    std::fs::copy(data("diff-drive.toml"), dir.join("diff-drive.toml")).unwrap();
    let stream =
        format!("{HEAD}5,truth,,,0,0,0\n6,tick,0,1,,,\n6,tick,1,1,,,\n7,truth,,,0.01,0,0\n");
    std::fs::write(dir.join("t.csv"), stream).unwrap();
    let run = |rate: &'static str| ["replay", "--ticks", "t.csv", "--counts-rate", rate];
    for rate in ["1e-300", "5e-11", "0.0009"] {
        refused(
            &dir,
            &run(rate),
            "--counts-rate: counts sampling rate must be 1e-3 to 1e9 Hz",
        );
    }
    // The slowest rate, its first sample past the stream's end: nothing is sampled to score.
    refused(
        &dir,
        &run("1e-3"),
        "t.csv: nothing scored: read at 0.001 Hz",
    );
}

#[test]
fn truth_rows_that_never_move_score_nothing() {
    let dir = scratch("replay-bad-inputs/still");
    std::fs::copy(data("diff-drive.toml"), dir.join("diff-drive.toml")).unwrap();
    let text = format!("{HEAD}0,truth,,,0,0,0\n1,tick,0,1,,,\n1,tick,0,-1,,,\n2,truth,,,0,0,0\n");
    std::fs::write(dir.join("still.csv"), text).unwrap();
    let err = refused(
        &dir,
        &["replay", "--ticks", "still.csv"],
        "still.csv: nothing scored",
    );
    assert!(err.contains("did not move"), "{err}");
    // A turn in place is motion: scored.
    let text = format!("{HEAD}0,truth,,,0,0,0\n1,tick,0,1,,,\n1,tick,1,-1,,,\n2,truth,,,0,0,0.1\n");
    std::fs::write(dir.join("spin.csv"), text).unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_host-bench"))
        .current_dir(&dir)
        .args(["replay", "--ticks", "spin.csv", "--algorithm", "exact"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

#[test]
fn replay_out_checks_every_input_first_and_leaves_nothing_when_it_fails() {
    let dir = with_example("out-fails");
    // A folder of earlier tracks, to be left as it was.
    let old = dir.join("outA");
    std::fs::create_dir(&old).unwrap();
    for name in ["arc", "lut", "timing", "exact"] {
        std::fs::write(old.join(format!("{name}.csv")), "earlier run\n").unwrap();
    }
    board(&dir, "xyz,0,0,0\n");
    for out in ["outA", "outB", "new/deeper"] {
        let args = ["replay", "--ticks", "python-circle.csv", "--out", out];
        refused(&dir, &args, "python-circle.board.csv:4: t_ns");
    }
    assert!(!dir.join("outB").exists() && !dir.join("new").exists());
    // A bad event, at the end of the stream: found before any track is written.
    std::fs::remove_file(dir.join("python-circle.board.csv")).unwrap();
    let text = std::fs::read_to_string(dir.join("python-circle.csv")).unwrap();
    let lines = text.lines().count();
    std::fs::write(
        dir.join("late.csv"),
        format!("{text}99999999999,tick,2,1,,,\n"),
    )
    .unwrap();
    let args = ["replay", "--ticks", "late.csv", "--out", "outA"];
    refused(
        &dir,
        &args,
        &format!("late.csv:{}: tick for encoder 2", lines + 1),
    );
    // And a good run writes all four.
    let args = ["replay", "--ticks", "python-circle.csv", "--out", "outB"];
    let o = Command::new(env!("CARGO_BIN_EXE_host-bench"))
        .current_dir(&dir)
        .args(args)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let written: Vec<_> = snapshot(&dir.join("outB")).into_keys().collect();
    assert_eq!(written.len(), 4, "{written:?}");
}

#[test]
fn replay_out_refuses_to_write_over_its_own_inputs() {
    let dir = with_example("out-over-input");
    std::fs::create_dir(dir.join("r2")).unwrap();
    std::fs::copy(data("python-circle.csv"), dir.join("r2/exact.csv")).unwrap();
    std::fs::copy(data("diff-drive.toml"), dir.join("r2/diff-drive.toml")).unwrap();
    let args = ["replay", "--ticks", "r2/exact.csv", "--out", "r2"];
    refused(&dir, &args, "r2/exact.csv is the tick stream");
    // Named through another path to the same folder, and the robot file as a track's name.
    let args = ["replay", "--ticks", "r2/exact.csv", "--out", "r2/../r2/."];
    refused(&dir, &args, "is the tick stream");
    std::fs::copy(data("diff-drive.toml"), dir.join("lut.csv")).unwrap();
    let args = [
        "replay",
        "--ticks",
        "python-circle.csv",
        "--robot",
        "lut.csv",
        "--out",
        ".",
    ];
    refused(&dir, &args, "lut.csv is the robot file");
}

#[test]
fn accuracy_out_is_checked_before_the_work_and_leaves_nothing() {
    let dir = scratch("replay-bad-inputs/accuracy-out");
    refused(
        &dir,
        &["accuracy", "--seeds", "1", "--out", "/dev/null/x"],
        "--out /dev/null/x: cannot create directory",
    );
    // One name in the way: refused before the work, no other file written.
    std::fs::create_dir_all(dir.join("acc2/rest-then-arcs-seed001-counts-10000Hz.svg")).unwrap();
    refused(
        &dir,
        &["accuracy", "--seeds", "1", "--out", "acc2"],
        "acc2/rest-then-arcs-seed001-counts-10000Hz.svg: it exists and is not a regular file",
    );
    // A folder name too long for the file system: none of its parents made are left.
    let long = format!("acc3/sub/{}", "x".repeat(300));
    refused(
        &dir,
        &["accuracy", "--seeds", "1", "--out", &long],
        "--out acc3/sub/xxx",
    );
    assert!(!dir.join("acc3").exists());
}
