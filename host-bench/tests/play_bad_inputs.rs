//! `play`'s bad inputs and what a play can leave behind on a board: each bad stream refused
//! with its file (and line) named, exit 1, in under 5 s and 200 MB, before the board is asked
//! where that can be; a long span costs time, not memory; a play after an interrupted one runs
//! whole. (Found by a bad-input hunt against `host-bench virtual-board`.)

#[path = "common/board.rs"]
mod board;

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use board::Board;
use firmware_slave::played::PlayKind;
use host_bench::formats::robot::Robot;
use host_bench::formats::tickstream::{self, Event, TickStream};
use host_bench::serial::expected::Expected;
use host_bench::serial::played_stream::{PlayedStream, MAX_UPDATES};
use host_bench::serial::{play, record, session};
use host_bench::sim::virtual_board;
use protocol::link::{GbnSender, DEFAULT_TIMEOUT_US};
use protocol::serial::{HostToMaster, MasterToHost};
use protocol::spi::{PoseChecks, Reports, SensorSource};
use robot_math::exact::FixedPose;
use robot_math::odometry::Method;

const BIN: &str = env!("CARGO_BIN_EXE_host-bench");
const HEAD: &str =
    "# omnibench tick stream v1\n# robot: seed004.toml\nt_ns,kind,id,value,x_m,y_m,theta_rad\n";
/// Seed 004's swivel (8 bits) at code 159, then one tick a millisecond in.
const START: &str = "0,truth,,,0,0,0\n0,abs,0,159,,,\n1000000,tick,0,1,,,\n";

fn repo(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(rel)
}

/// A stream of seed 004 (`HEAD`, then `rows`) as `name` in `dir`, the robot file beside it.
fn stream(dir: &Path, name: &str, rows: &str) -> String {
    std::fs::copy(repo("robots/seed004.toml"), dir.join("seed004.toml")).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, format!("{HEAD}{rows}")).unwrap();
    path.to_str().unwrap().to_owned()
}

/// `play` with `args` must exit 1 within 5 s saying `says`, print nothing on stdout, and no
/// child of this test may have grown past 200 MB.
fn refused(args: &[&str], says: &str) {
    let start = Instant::now();
    let o = Command::new(BIN).arg("play").args(args).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{args:?}: {err}");
    assert!(err.contains(says), "{args:?}: wanted {says:?} in {err}");
    assert!(!err.contains("panicked"), "{args:?}: {err}");
    assert!(o.stdout.is_empty(), "{args:?} printed a result");
    assert!(start.elapsed() < Duration::from_secs(5), "{args:?}");
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    // SAFETY: getrusage writes one rusage into the struct it is given.
    assert_eq!(
        unsafe { libc::getrusage(libc::RUSAGE_CHILDREN, &mut usage) },
        0
    );
    assert!(
        usage.ru_maxrss < 200 * 1024,
        "a child peaked at {} KB",
        usage.ru_maxrss
    );
}

/// Before the fix, 5 rows whose span asked for 10^8 updates had the host make every expected
/// report first: 3 GB (an abort), or, at 10^7, 475 MB and then a board that stopped
/// answering. Now a span past a week (what `record` records at most) is refused at its line,
/// before the port is even opened; a week is taken.
#[test]
fn a_span_play_cannot_take_is_refused_at_its_line_before_the_board_is_asked() {
    let dir = tempfile::tempdir().unwrap();
    let week_ns = 604_800_000_000_000u64;
    let far = stream(
        dir.path(),
        "far.csv",
        &format!("{START}# the run goes on\n{},tick,1,1,,,\n", week_ns + 1),
    );
    refused(
        &["--port", "/nonexistent/tty", "--ticks", &far],
        "far.csv:8: t_ns 604800000000001 is 604800 s after the first row; play takes at most",
    );
    let week = stream(
        dir.path(),
        "week.csv",
        &format!("{START}{week_ns},tick,1,1,,,\n"),
    );
    refused(
        &["--port", "/nonexistent/tty", "--ticks", &week],
        "cannot open serial port /nonexistent/tty",
    );
}

/// A span of 28 hours (10^8 updates) plays, in either sensor mode, at the memory of any play:
/// nothing made ahead of the board but a few reports and a buffer of bytes.
#[test]
fn a_long_span_plays_in_bounded_memory() {
    let dir = tempfile::tempdir().unwrap();
    let long = stream(
        dir.path(),
        "long.csv",
        &format!("{START}100000000000000,tick,1,1,,,\n100000000000001,truth,,,0,0,0\n"),
    );
    let board = Board::start(virtual_board::Options::default());
    for sensor in ["timestamps", "counts"] {
        let mut child = Command::new(BIN)
            .args([
                "play",
                "--port",
                &board.port,
                "--ticks",
                &long,
                "--sensor",
                sensor,
            ])
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        std::thread::sleep(Duration::from_secs(3));
        if child.try_wait().unwrap().is_some() {
            let out = child.wait_with_output().unwrap();
            panic!("{sensor}: {}", String::from_utf8_lossy(&out.stderr));
        }
        let status = std::fs::read_to_string(format!("/proc/{}/status", child.id())).unwrap();
        let _ = child.kill();
        let _ = child.wait();
        let peak_kb: u64 = status
            .lines()
            .find_map(|l| l.strip_prefix("VmHWM:"))
            .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
            .unwrap();
        assert!(peak_kb < 200 * 1024, "{sensor}: {peak_kb} KB after 3 s");
    }
}

/// The same at the library: a week's span is counted, its bytes sized and its first reports
/// made at once, without walking its 6·10⁸ updates.
#[test]
fn a_week_long_stream_is_counted_without_being_walked() {
    let robot = Robot::load(&repo("robots/seed004.toml")).unwrap();
    let layout = robot.odometry_layout().unwrap();
    let week_ns = 604_800_000_000_000u64;
    let s = rows(&format!("{START}{week_ns},tick,1,1,,,\n"));
    let start = Instant::now();
    for kind in [PlayKind::Ticks, PlayKind::Counts] {
        let p = PlayedStream::new(&s, &robot, kind, 1000).unwrap();
        assert!(
            p.updates >= MAX_UPDATES - 1 && p.updates <= MAX_UPDATES,
            "{kind:?}"
        );
        let mut e = Expected::new(&layout, Method::Exact, &p, FixedPose::default()).unwrap();
        for _ in 0..1000 {
            assert!(e.next_report().unwrap().is_some());
        }
    }
    assert!(
        start.elapsed() < Duration::from_secs(2),
        "{:?}",
        start.elapsed()
    );
}

fn rows(rows: &str) -> TickStream {
    tickstream::read_from(format!("{HEAD}{rows}").as_bytes(), Path::new("t.csv")).unwrap()
}

/// The updates and bytes counted from the rows are what the slave's own code makes of the
/// bytes made for it, in every corner: rows at 0, an event on an update's instant, one just
/// past it, a run ending on a truth row, the start reading sent first.
#[test]
fn what_is_counted_from_the_rows_is_what_the_slaves_code_makes() {
    let robot = Robot::load(&repo("robots/seed004.toml")).unwrap();
    let layout = robot.odometry_layout().unwrap();
    let cases = [
        "0,tick,0,1,,,\n0,abs,0,17,,,\n2000000,tick,1,-1,,,\n",
        "0,truth,,,0,0,0\n0,abs,0,159,,,\n1000600,tick,0,1,,,\n",
        "0,truth,,,0,0,0\n499,abs,0,3,,,\n500,tick,0,1,,,\n3000000,abs,0,4,,,\n",
        "5,tick,0,1,,,\n1500000,tick,0,1,,,\n7000000,tick,1,1,,,\n9999999,truth,,,0,0,0\n",
    ];
    for text in cases {
        let s = rows(text);
        for kind in [PlayKind::Ticks, PlayKind::Counts] {
            for period in [1000, 700] {
                let p = PlayedStream::new(&s, &robot, kind, period).unwrap();
                let mut e =
                    Expected::new(&layout, Method::Exact, &p, FixedPose::default()).unwrap();
                let mut n = 0;
                while e.next_report().unwrap().is_some() {
                    n += 1;
                }
                assert_eq!(n, p.updates, "{text:?} {kind:?} {period}");
                let (mut whole, mut pieces) = (Vec::new(), Vec::new());
                p.bytes().fill(&mut whole, usize::MAX / 2).unwrap();
                let mut w = p.bytes();
                loop {
                    let before = pieces.len();
                    w.fill(&mut pieces, 3).unwrap();
                    if pieces.len() == before {
                        break;
                    }
                }
                assert_eq!(whole, pieces);
                assert_eq!(whole.len() as u64, p.wire_bytes);
            }
        }
    }
}

/// A code wider than seed 004's 8-bit swivel encoder played with exit 0 where `replay` refuses
/// it: both ask the same check now, and say the same.
#[test]
fn a_code_wider_than_its_encoder_is_refused_as_replay_refuses_it() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        ("wide.csv", "0,abs,0,65535,,,", "does not fit its 8 bits"),
        (
            "other.csv",
            "0,abs,1,3,,,",
            "but robot seed004 has 1 absolute encoders",
        ),
    ];
    for (name, abs, says) in cases {
        let rows = format!("0,truth,,,0,0,0\n{abs}\n1000000,tick,0,1,,,\n5000000,tick,1,1,,,\n");
        let ticks = stream(dir.path(), name, &rows);
        refused(&["--port", "/nonexistent/tty", "--ticks", &ticks], says);
        let replay = Command::new(BIN)
            .args(["replay", "--ticks", &ticks])
            .output()
            .unwrap();
        let replay_err = String::from_utf8_lossy(&replay.stderr);
        let play = Command::new(BIN)
            .args(["play", "--port", "/nonexistent/tty", "--ticks", &ticks])
            .output()
            .unwrap();
        let play_err = String::from_utf8_lossy(&play.stderr);
        let said = |e: &str| e.split(": ").last().unwrap_or("").trim().to_string();
        assert_eq!(said(&play_err), said(&replay_err), "{name}");
    }
}

/// "board vs host 0 of 0 updates bit-exact" exited 0: a stream whose rows end within the
/// slave's first update period gives it nothing to compute. Refused, before anything is sent.
#[test]
fn a_stream_that_gives_no_update_exits_1_nothing_scored() {
    let dir = tempfile::tempdir().unwrap();
    let one = stream(dir.path(), "one.csv", START);
    let mut same = String::from(START);
    for _ in 0..3000 {
        same.push_str("1000000,tick,0,1,,,\n");
    }
    same.push_str("2000000,truth,,,0,0,0\n");
    let same = stream(dir.path(), "same.csv", &same);
    let board = Board::start(virtual_board::Options::default());
    for ticks in [&one, &same] {
        refused(
            &["--port", &board.port, "--ticks", ticks],
            "nothing scored: the rows the slave is sent end 1000 µs after the first",
        );
        refused(
            &["--port", &board.port, "--ticks", ticks, "--json"],
            ".csv: nothing scored",
        );
    }
}

/// Played from a recording of seed 004's carriage, the board started its odometry at swivel
/// position 0, not where the recording's first reading put it: 139 mm off the truth where
/// `replay` was 0.0007 mm off. It starts at the stream's start reading now, as replay does.
#[test]
fn a_carriage_recording_plays_as_close_to_its_truth_as_it_replays() {
    let dir = tempfile::tempdir().unwrap();
    let board = Board::start(virtual_board::Options::default());
    let out = dir.path().join("rec.csv");
    record::record(&mut board.link(), &board::recording(&out, None, false)).unwrap();
    let stream = tickstream::read(&out).unwrap();
    let robot = Robot::load(&stream.robot_path(&out).unwrap()).unwrap();
    let replay = |s: &TickStream, rate: Option<f64>| {
        let mode = rate.map_or(host_bench::eval::replay::Mode::Timestamps, |rate_hz| {
            host_bench::eval::replay::Mode::Counts { rate_hz }
        });
        host_bench::eval::replay::replay(&robot, s, "exact", mode)
            .unwrap()
            .final_error_m
    };
    // The start reading matters in this recording: without it replay is far off too.
    let mut blind = stream.clone();
    let t0 = stream.events[0].t_ns();
    blind
        .events
        .retain(|e| !matches!(*e, Event::Abs { t_ns, .. } if t_ns == t0));
    assert!(replay(&blind, None) > 1e-3, "{}", replay(&blind, None));
    for (kind, rate) in [(PlayKind::Ticks, None), (PlayKind::Counts, Some(1000.0))] {
        let o = play::play(
            &mut board.link(),
            &play::PlayRequest {
                ticks: &out,
                robot: &robot,
                method: Method::Exact,
                kind,
                stream: &stream,
                check_every: play::CHECK_EVERY,
                progress: None,
                view: None,
            },
        )
        .unwrap();
        assert_eq!(o.mismatches, 0, "{:?}", o.first_mismatch);
        let (played, replayed) = (o.final_error_m.unwrap(), replay(&stream, rate));
        assert!(
            (played - replayed).abs() < 0.05e-3,
            "{kind:?}: play {played} m, replay {replayed} m"
        );
    }
}

/// A play stopped midway (Ctrl-C) left every later play of the same stream stalled: "the board
/// stopped answering after 0 of 5099 updates". The slave still read the old played stream, so
/// the new play's switch to it showed at once, before the slave had applied it; the report
/// bytes of the old stream the master took in meanwhile came first in the new session, and the
/// host could not read past them.
#[test]
fn a_play_after_an_interrupted_one_runs_whole() {
    let dir = tempfile::tempdir().unwrap();
    let name = "seed000-0.8mm.toml";
    std::fs::copy(repo(&format!("robots/{name}")), dir.path().join(name)).unwrap();
    let robot = Robot::load(&dir.path().join(name)).unwrap();
    let traj = host_bench::sim::trajectory::build("seed000-line").unwrap();
    let opts = host_bench::sim::generate::GenerateOptions::default();
    let s = host_bench::sim::generate::generate(&robot, Some(name), traj.as_ref(), &opts).unwrap();
    let ticks = dir.path().join("line.csv");
    tickstream::write(&ticks, &s).unwrap();
    let board = Board::start(virtual_board::Options::default());
    let play_it = || {
        play::play(
            &mut board.link(),
            &play::PlayRequest {
                ticks: &ticks,
                robot: &robot,
                method: Method::Exact,
                kind: PlayKind::Ticks,
                stream: &s,
                check_every: play::CHECK_EVERY,
                progress: None,
                view: None,
            },
        )
    };
    let clean = play_it().unwrap();
    interrupted_play(&board, &robot, &s);
    let o = play_it().unwrap_or_else(|e| panic!("after an interrupted play: {e:#}"));
    assert_eq!(o.mismatches, 0, "{:?}", o.first_mismatch);
    assert_eq!(o.board_updates, clean.board_updates);
    assert_eq!(o.final_error_m, clean.final_error_m);
}

/// What a play stopped by Ctrl-C leaves: the slave reading a played stream half sent, its
/// reports never acknowledged (the report buffers full), and no one on the line.
fn interrupted_play(board: &Board, robot: &Robot, s: &TickStream) {
    let mut link = board.link();
    let info = session::hello(&mut link).unwrap();
    let layout = robot.odometry_layout().unwrap();
    session::load_robot(&mut link, &layout).unwrap();
    let source = SensorSource::PlayedTicks;
    let start = protocol::Pose::default();
    session::set_method_and_source(
        &mut link,
        Method::Exact,
        source,
        Reports::Poses(PoseChecks::ALL),
        start,
    )
    .unwrap();
    let p = PlayedStream::new(s, robot, PlayKind::Ticks, info.period_us).unwrap();
    let mut bytes = Vec::new();
    p.bytes()
        .fill(&mut bytes, (p.wire_bytes / 2) as usize)
        .unwrap();
    let mut tx: GbnSender<4096> = GbnSender::new(DEFAULT_TIMEOUT_US);
    let (mut offered, wall) = (0, Instant::now());
    while wall.elapsed() < Duration::from_millis(1500) {
        offered += tx.offer(&bytes[offered..]);
        let now = wall.elapsed().as_micros() as u64;
        while let Some(frame) = tx.poll_transmit(now) {
            link.send(&HostToMaster::Events(frame)).unwrap();
        }
        if let Some(MasterToHost::EventsAck(a)) = link.recv(Duration::from_millis(5)).unwrap() {
            tx.on_ack(a, now);
        }
    }
    assert!(offered > 1000, "the interrupted play sent {offered} bytes");
}
