//! The bench commands as a user runs them: `host-bench virtual-board` in the background, then
//! `play --json` and `record` + `replay --json` against the port it prints.

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Command, Stdio};

const BIN: &str = env!("CARGO_BIN_EXE_host-bench");

struct VirtualBoard {
    child: Child,
    port: String,
}

impl VirtualBoard {
    fn start(args: &[&str]) -> VirtualBoard {
        let mut child = Command::new(BIN)
            .arg("virtual-board")
            .args(args)
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("spawn virtual-board");
        let mut first = String::new();
        BufReader::new(child.stdout.take().unwrap())
            .read_line(&mut first)
            .unwrap();
        let port = first
            .trim()
            .strip_prefix("port: ")
            .unwrap_or_else(|| panic!("first line {first:?}"))
            .to_string();
        VirtualBoard { child, port }
    }
}

impl Drop for VirtualBoard {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Held by the tests whose figures a busy machine could spoil: a recording (its virtual board
/// runs in real time, and starved of the CPU it drops edges) and the signal test, which runs
/// a board and a hundred processes of its own.
static REAL_TIME: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn data(p: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../robots")
        .join(p)
        .display()
        .to_string()
}

#[test]
fn play_prints_the_verdict_as_json_and_a_wrong_robot_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let ticks = dir.path().join("line.csv");
    let gen = Command::new(BIN)
        .args([
            "generate",
            "--robot",
            &data("seed001.toml"),
            "--trajectory",
            "seed000-line",
        ])
        .arg("--out")
        .arg(&ticks)
        .output()
        .unwrap();
    assert!(
        gen.status.success(),
        "{}",
        String::from_utf8_lossy(&gen.stderr)
    );
    let board = VirtualBoard::start(&[]);
    let out = Command::new(BIN)
        .args([
            "play",
            "--port",
            &board.port,
            "--json",
            "--sensor",
            "counts",
        ])
        .arg("--ticks")
        .arg(&ticks)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    for key in [
        "events",
        "board_updates",
        "mismatches",
        "wire_bytes",
        "bytes_per_event",
        "played_seconds",
        "wall_seconds",
        "final_error_m",
    ] {
        assert!(v.get(key).is_some(), "{key} missing in {v}");
    }
    assert_eq!(v["mismatches"], 0);
    assert!(v["board_updates"].as_u64().unwrap() > 100);

    // A stream without a tick row gives the board nothing to compute: refused, not "0 of 0
    // updates bit-exact" and exit 0.
    let no_ticks = dir.path().join("no-ticks.csv");
    std::fs::write(
        &no_ticks,
        "# omnibench tick stream v1\nt_ns,kind,id,value,x_m,y_m,theta_rad\n0,truth,,,0,0,0\n1000000,truth,,,0.05,0,0\n",
    )
    .unwrap();
    let out = Command::new(BIN)
        .args([
            "play",
            "--port",
            &board.port,
            "--robot",
            &data("seed001.toml"),
        ])
        .arg("--ticks")
        .arg(&no_ticks)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("no tick rows"), "{err}");

    // A fault on a frame the play never sends injects nothing: the run is refused, not passed.
    let out = Command::new(BIN)
        .args([
            "play",
            "--port",
            &board.port,
            "--sensor",
            "counts",
            "--fault-drop-frames",
            "99999999999999",
        ])
        .arg("--ticks")
        .arg(&ticks)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("--fault-drop-frames 99999999999999: this play sent"),
        "{err}"
    );

    // The wrong robot for a stream (a triangle's ticks, a two-wheel robot): refused, and the
    // error names the row.
    let omni = dir.path().join("omni.csv");
    let gen = Command::new(BIN)
        .args([
            "generate",
            "--robot",
            &data("seed000-0.4mm.toml"),
            "--trajectory",
            "seed000-line",
        ])
        .arg("--out")
        .arg(&omni)
        .output()
        .unwrap();
    assert!(gen.status.success());
    let out = Command::new(BIN)
        .args([
            "play",
            "--port",
            &board.port,
            "--robot",
            &data("seed001.toml"),
        ])
        .arg("--ticks")
        .arg(&omni)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{err}");
    assert!(
        err.contains("encoder 2") && err.contains("2 encoders"),
        "{err}"
    );
}

#[test]
fn another_schema_makes_play_exit_non_zero() {
    let dir = tempfile::tempdir().unwrap();
    let ticks = dir.path().join("line.csv");
    let gen = Command::new(BIN)
        .args([
            "generate",
            "--robot",
            &data("seed001.toml"),
            "--trajectory",
            "seed000-line",
        ])
        .arg("--out")
        .arg(&ticks)
        .output()
        .unwrap();
    assert!(gen.status.success());
    let board = VirtualBoard::start(&["--fault-schema", "0badc0de"]);
    let out = Command::new(BIN)
        .args(["play", "--port", &board.port])
        .arg("--ticks")
        .arg(&ticks)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(err.contains("0badc0de") && err.contains("schema"), "{err}");
}

#[test]
fn record_writes_a_stream_that_replay_scores() {
    let _alone = REAL_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let dir = tempfile::tempdir().unwrap();
    let rec = dir.path().join("rec.csv");
    let board = VirtualBoard::start(&[]);
    let out = Command::new(BIN)
        .args(["record", "--port", &board.port, "--duration", "2"])
        .arg("--out")
        .arg(&rec)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let out = Command::new(BIN)
        .args(["replay", "--json", "--algorithm", "exact"])
        .arg("--ticks")
        .arg(&rec)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let err = v["algorithms"][0]["final_error_m"].as_f64().unwrap();
    assert!(err < 5e-3, "{v}");
    // The board's own poses, beside the stream, scored too.
    assert!(v["board"]["rows"].as_u64().unwrap() > 10, "{v}");
    assert!(v["board"]["final_error_m"].as_f64().unwrap() < 5e-3, "{v}");
}

#[test]
fn virtual_board_refuses_a_robot_the_slave_board_cannot_read() {
    // Seed 000's three encoders: the slave board has two quadrature inputs.
    let out = Command::new(BIN)
        .args(["virtual-board", "--robot", &data("seed000-0.1mm.toml")])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("seed000-0.1mm.toml") && err.contains("2 quadrature encoders"),
        "{err}"
    );
    assert!(out.stdout.is_empty(), "no port is offered");
}

#[test]
fn a_patience_out_of_range_is_refused_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let ticks = dir.path().join("line.csv");
    let gen = Command::new(BIN)
        .args(["generate", "--robot", &data("seed001.toml")])
        .args(["--trajectory", "seed000-line", "--out"])
        .arg(&ticks)
        .output()
        .unwrap();
    assert!(gen.status.success());
    for patience in ["0", "101"] {
        let out = Command::new(BIN)
            .args([
                "play",
                "--port",
                "/dev/null",
                "--patience",
                patience,
                "--ticks",
            ])
            .arg(&ticks)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success());
        assert!(
            err.contains("--patience") && err.contains(patience),
            "{err}"
        );
    }
}

/// `record` stopped by Ctrl-C and then, before it is done, by SIGTERM, at random moments
/// around its final write: each time either the previous recording of that name (stream,
/// robot file, board poses) is there as it was, or the new one is there whole; never a mix,
/// never a `.partial` or `.previous` file left. (Before: the three files were renamed one by
/// one, so a SIGTERM between them left a stream without its robot file or board poses: with
/// the same pauses, that left a mixed set at the first trial.)
/// `OMNIBENCH_SIGNAL_TRIALS` sets how many (default 10).
#[test]
fn record_stopped_by_signals_at_random_moments_leaves_one_whole_set() {
    let _alone = REAL_TIME.lock().unwrap_or_else(|e| e.into_inner());
    use rand::{Rng, SeedableRng};
    let trials: u32 = std::env::var("OMNIBENCH_SIGNAL_TRIALS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(10);
    let dir = tempfile::tempdir().unwrap();
    let names = ["rec.csv", "rec.robot.toml", "rec.board.csv"];
    let set = || -> Vec<Option<Vec<u8>>> {
        names
            .iter()
            .map(|n| std::fs::read(dir.path().join(n)).ok())
            .collect()
    };
    let board = VirtualBoard::start(&[]);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(35);
    let (mut kept, mut replaced) = (0, 0);
    let mut statuses = std::collections::BTreeMap::new();
    for trial in 0..trials {
        let before = set();
        let mut child = Command::new(BIN)
            .args(["record", "--port", &board.port])
            // 40 ms between one file and the next: the signals below land inside the write.
            .env("OMNIBENCH_RECORD_WRITE_PAUSE_MS", "40")
            .arg("--out")
            .arg(dir.path().join("rec.csv"))
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        let pid = child.id() as libc::pid_t;
        // Ctrl-C once it records (its set-up takes about half a second), then SIGTERM while
        // it switches the slave back, stages its files or renames them.
        std::thread::sleep(std::time::Duration::from_millis(
            rng.random_range(600..1200),
        ));
        unsafe { libc::kill(pid, libc::SIGINT) };
        std::thread::sleep(std::time::Duration::from_millis(rng.random_range(0..250)));
        unsafe { libc::kill(pid, libc::SIGTERM) };
        let status = child.wait().unwrap();
        let after = set();
        // The stream and the board poses differ from one recording to the next; the robot
        // file (the slave's power-on robot each time) does not.
        let changed = [0, 2].iter().filter(|&&i| before[i] != after[i]).count();
        *statuses.entry(status.code().unwrap_or(-1)).or_insert(0) += 1;
        let mut left: Vec<String> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| n.ends_with(".partial") || n.ends_with(".previous"))
            .collect();
        left.sort();
        assert!(left.is_empty(), "trial {trial} ({status}): left {left:?}");
        if changed == 0 {
            kept += 1;
            continue;
        }
        assert_eq!(
            changed, 2,
            "trial {trial} ({status}): a mix of old and new files"
        );
        let stream = host_bench::formats::tickstream::read(&dir.path().join("rec.csv")).unwrap();
        assert_eq!(
            stream.robot.as_deref(),
            Some("rec.robot.toml"),
            "trial {trial}"
        );
        host_bench::formats::robot::Robot::load(&dir.path().join("rec.robot.toml")).unwrap();
        let poses = String::from_utf8(after[2].clone().unwrap()).unwrap();
        assert!(
            poses.starts_with("t_ns,x_m,y_m,theta_rad\n"),
            "trial {trial}"
        );
        replaced += 1;
    }
    eprintln!(
        "{trials} trials: previous set kept {kept} times, new set whole {replaced} times; \
         exit codes {statuses:?} (143: SIGTERM ended it, 0: it had finished)"
    );
    // Both outcomes happen: the signals land before and after the renames (at 10 trials
    // the split seen, 53 to 47 in 100, would leave one out about one run in 500).
    if trials >= 30 {
        assert!(kept > 0 && replaced > 0, "kept {kept}, replaced {replaced}");
    }
}
