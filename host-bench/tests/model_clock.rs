//! `--clock FILE`: the host timing its waits by a board model's clock file instead of the
//! wall clock (host-bench/src/serial/clock.rs; the chip model writes the file,
//! board-model/f103/clock_file.py). Here a thread of the test stands in for the model's clock.

use std::os::unix::fs::FileExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use host_bench::serial::clock::clock_file_bytes;
use host_bench::sim::virtual_board;
use serialport::SerialPort;

#[path = "common/board.rs"]
mod board;
use board::Board;

const BIN: &str = env!("CARGO_BIN_EXE_host-bench");

fn data(p: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join("robots")
        .join(p)
        .display()
        .to_string()
}

fn line_stream(dir: &Path) -> PathBuf {
    let ticks = dir.join("line.csv");
    let gen = Command::new(BIN)
        .args(["generate", "--robot", &data("seed001.toml")])
        .args(["--trajectory", "seed000-line", "--out"])
        .arg(&ticks)
        .output()
        .unwrap();
    assert!(
        gen.status.success(),
        "{}",
        String::from_utf8_lossy(&gen.stderr)
    );
    ticks
}

/// A clock file kept running at `rate` times the wall's pace by a thread, until dropped.
struct FakeModelClock {
    path: PathBuf,
    stop: Arc<AtomicBool>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl FakeModelClock {
    fn start(dir: &Path, rate: f64) -> FakeModelClock {
        let path = dir.join("clock");
        std::fs::write(&path, clock_file_bytes(0)).unwrap();
        let stop = Arc::new(AtomicBool::new(false));
        let thread = {
            let (path, stop) = (path.clone(), stop.clone());
            std::thread::spawn(move || {
                // In place, as the model writes it: a file truncated and written again could
                // be read empty in between.
                let file = std::fs::OpenOptions::new().write(true).open(&path).unwrap();
                let t0 = Instant::now();
                while !stop.load(Ordering::Relaxed) {
                    let ns = (t0.elapsed().as_nanos() as f64 * rate) as u64;
                    file.write_all_at(&clock_file_bytes(ns), 0).unwrap();
                    std::thread::sleep(Duration::from_millis(2));
                }
            })
        };
        FakeModelClock {
            path,
            stop,
            thread: Some(thread),
        }
    }
}

impl Drop for FakeModelClock {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// `host-bench play --port PORT --clock CLOCK --ticks TICKS` and `more` options.
fn play(port: &str, clock: &Path, ticks: &Path, more: &[&str]) -> Output {
    Command::new(BIN)
        .args(["play", "--port", port, "--clock"])
        .arg(clock)
        .arg("--ticks")
        .arg(ticks)
        .args(more)
        .output()
        .unwrap()
}

#[test]
fn play_takes_its_time_from_the_clock_file() {
    let dir = tempfile::tempdir().unwrap();
    let ticks = line_stream(dir.path());
    let board = Board::start(virtual_board::Options::default());
    // A model at half of real time (the virtual board itself runs at real time: the play only
    // looks twice as fast to the host).
    let clock = FakeModelClock::start(dir.path(), 0.5);
    let wall = Instant::now();
    let out = play(&board.port, &clock.path, &ticks, &["--json"]);
    let wall = wall.elapsed().as_secs_f64();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["mismatches"], 0, "{v}");
    // The play's duration as the host measured it is the clock's: about half the wall time it
    // took (the process's start and the handshake lie outside the play's own span).
    let on_clock = v["wall_seconds"].as_f64().unwrap();
    assert!(
        on_clock > 0.0 && on_clock < 0.75 * wall,
        "{on_clock} s on the clock for {wall} s of wall time"
    );
}

#[test]
fn a_stopped_clock_ends_the_wait_for_an_answer_instead_of_hanging() {
    let dir = tempfile::tempdir().unwrap();
    let ticks = line_stream(dir.path());
    // A port with nothing behind it, and a model's clock that never moves.
    let (_silent, other_end) = serialport::TTYPort::pair().unwrap();
    let port = other_end.name().unwrap();
    let clock = dir.path().join("clock");
    std::fs::write(&clock, clock_file_bytes(42_000_000)).unwrap();
    let wall = Instant::now();
    let out = play(&port, &clock, &ticks, &[]);
    let wall = wall.elapsed();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{err}");
    assert!(
        err.contains("no answer") || err.contains("not answer"),
        "{err}"
    );
    // The handshake's 3 s, on the frozen clock: they start once it has not moved for 3 s of
    // wall time and then run at the wall's pace (on the wall clock, --clock ignored, they
    // would end after 3 s).
    assert!(
        wall > Duration::from_millis(5500) && wall < Duration::from_secs(30),
        "{wall:?}"
    );
}

#[test]
fn a_file_that_is_not_a_clock_is_refused_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let ticks = line_stream(dir.path());
    let not_a_clock = PathBuf::from(data("seed001.toml"));
    let out = play("/dev/null", &not_a_clock, &ticks, &[]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains("is not a board model's clock") && err.contains("seed001.toml"),
        "{err}"
    );
}
