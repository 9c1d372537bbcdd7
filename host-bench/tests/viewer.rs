//! Runs you can look at, end to end through the `host-bench` binary: the MCAP files of
//! `emulate`, `play` and `replay` read back with the `mcap` crate; `--live` from a WebSocket
//! client as Foxglove and Lichtblick connect; the bench page in a real headless Chromium.

#[path = "common/board.rs"]
mod board;
#[path = "viewer/browser.rs"]
mod browser;

use std::collections::BTreeMap;
use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use board::Board;
use browser::http_get;
use host_bench::sim::virtual_board;
use tungstenite::client::IntoClientRequest;
use tungstenite::Message;

const BIN: &str = env!("CARGO_BIN_EXE_host-bench");

/// `host-bench ARGS`, run to its end; its output, the run having succeeded.
fn succeeds(cmd: &mut Command) -> std::process::Output {
    let out = cmd.output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

fn circle() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/tickstreams/python-circle.csv")
}

/// One channel as read back: schema name, message encoding, messages (log time, JSON).
#[derive(Debug, Default)]
struct ReadChannel {
    schema: String,
    encoding: String,
    messages: Vec<(u64, serde_json::Value)>,
}

/// The file's channels by topic; panics unless every log time is at or after the one
/// before it in file order, and the summary's counts equal what was read.
fn read_mcap(path: &Path) -> BTreeMap<String, ReadChannel> {
    let bytes = std::fs::read(path).unwrap();
    let mut channels: BTreeMap<String, ReadChannel> = BTreeMap::new();
    let mut last = 0u64;
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        assert!(
            m.log_time >= last,
            "log time went back on {}",
            m.channel.topic
        );
        last = m.log_time;
        let c = channels.entry(m.channel.topic.clone()).or_default();
        c.schema = m.channel.schema.as_ref().unwrap().name.clone();
        assert_eq!(m.channel.schema.as_ref().unwrap().encoding, "jsonschema");
        c.encoding = m.channel.message_encoding.clone();
        c.messages
            .push((m.log_time, serde_json::from_slice(&m.data).unwrap()));
    }
    let summary = mcap::Summary::read(&bytes).unwrap().expect("a summary");
    let stats = summary.stats.expect("statistics");
    for (id, ch) in &summary.channels {
        let n = stats.channel_message_counts.get(id).copied().unwrap_or(0);
        let read = channels.get(&ch.topic).map_or(0, |c| c.messages.len());
        assert_eq!(n as usize, read, "{}: summary count", ch.topic);
        channels.entry(ch.topic.clone()).or_default();
    }
    channels
}

fn count(ch: &BTreeMap<String, ReadChannel>, topic: &str) -> usize {
    ch.get(topic).map_or(0, |c| c.messages.len())
}

#[test]
fn emulate_writes_an_mcap_file_the_viewers_read() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("run.mcap");
    succeeds(
        Command::new(BIN)
            .args(["emulate", "--duration", "2", "--mcap"])
            .arg(&file),
    );
    let ch = read_mcap(&file);
    let schema = |t: &str| ch[t].schema.as_str();
    assert_eq!(schema("/tf"), "foxglove.FrameTransform");
    for t in [
        "/truth/pose",
        "/slave/pose",
        "/master/estimate",
        "/master/target",
    ] {
        assert_eq!(schema(t), "foxglove.PoseInFrame", "{t}");
    }
    assert_eq!(schema("/slave/error"), "omnibench.PoseError");
    assert_eq!(schema("/master/wheels"), "omnibench.Wheels");
    assert_eq!(schema("/master/status"), "omnibench.Status");
    assert_eq!(schema("/encoders"), "omnibench.Encoders");
    assert_eq!(schema("/master/link"), "omnibench.Link");
    // The master takes a slave frame every 2 ms: its counter runs on.
    let link = &ch["/master/link"].messages;
    let ok = |i: usize| link[i].1["spi_frames_ok"].as_u64().unwrap();
    assert!(ok(199) > ok(100) + 400, "{} then {}", ok(100), ok(199));
    assert!(ch.values().all(|c| c.encoding == "json"));
    // A row every 10 ms of simulated time, logged at its own time.
    assert_eq!(count(&ch, "/truth/pose"), 200);
    assert_eq!(count(&ch, "/slave/pose"), 200);
    let truth = &ch["/truth/pose"].messages;
    assert!(truth[0].0 < 10_000_000, "first row at {} ns", truth[0].0);
    assert!(truth.windows(2).all(|w| w[1].0 == w[0].0 + 10_000_000));
    // The robot moves, and the slave follows it to well under a millimetre.
    let (_, last) = &truth[199];
    assert!(last["pose"]["position"]["x"].as_f64().unwrap().abs() > 0.01);
    let q = &last["pose"]["orientation"];
    let norm: f64 = ["x", "y", "z", "w"]
        .iter()
        .map(|k| q[*k].as_f64().unwrap().powi(2))
        .sum();
    assert!((norm - 1.0).abs() < 1e-9);
    let err = &ch["/slave/error"].messages;
    assert!(err
        .iter()
        .all(|(_, e)| e["position_mm"].as_f64().unwrap() < 1.0));
    assert!(ch["/master/status"].messages[100].1["set"]
        .as_array()
        .unwrap()
        .iter()
        .any(|f| f == "motors on"));
}

#[test]
fn a_run_that_fails_leaves_no_mcap_file() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("run.mcap");
    // The slave switched off from the start: nothing is scored.
    let out = Command::new(BIN)
        .args([
            "emulate",
            "--duration",
            "1",
            "--fault-slave-off-at",
            "0",
            "--mcap",
        ])
        .arg(&file)
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert_eq!(
        std::fs::read_dir(dir.path()).unwrap().count(),
        0,
        "left a file"
    );
    // A folder that does not exist: said before the run, naming the option.
    let out = Command::new(BIN)
        .args([
            "emulate",
            "--duration",
            "1",
            "--mcap",
            "/nonexistent/run.mcap",
        ])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("--mcap /nonexistent/run.mcap"),
        "{err}"
    );
}

#[test]
fn play_and_replay_write_mcap_files_the_viewers_read() {
    let dir = tempfile::tempdir().unwrap();
    let board = Board::start(virtual_board::Options::default());
    let file = dir.path().join("play.mcap");
    let out = succeeds(
        Command::new(BIN)
            .args(["play", "--json", "--port", &board.port, "--ticks"])
            .arg(circle())
            .arg("--mcap")
            .arg(&file),
    );
    let outcome: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let ch = read_mcap(&file);
    // Every update the host computed, every pose the board reported, every truth row scored.
    assert_eq!(
        count(&ch, "/host/pose") as u64,
        outcome["expected_updates"].as_u64().unwrap()
    );
    assert_eq!(
        count(&ch, "/board/pose") as u64,
        outcome["poses_reported"].as_u64().unwrap()
    );
    assert_eq!(
        count(&ch, "/truth/pose") as u64,
        outcome["scored_rows"].as_u64().unwrap()
    );
    assert_eq!(count(&ch, "/board/error"), count(&ch, "/truth/pose"));
    assert_eq!(count(&ch, "/link"), count(&ch, "/board/pose"));
    assert_eq!(ch["/board/pose"].schema, "foxglove.PoseInFrame");
    // Every message is logged at its own time.
    for topic in ["/host/pose", "/board/pose", "/truth/pose"] {
        for (t, m) in &ch[topic].messages {
            let stamp = m["timestamp"]["sec"].as_u64().unwrap() * 1_000_000_000
                + m["timestamp"]["nsec"].as_u64().unwrap();
            assert_eq!(*t, stamp, "{topic}");
        }
    }
    // The board's reported poses are the host's at the same updates.
    let host: BTreeMap<u64, &serde_json::Value> = ch["/host/pose"]
        .messages
        .iter()
        .map(|(t, m)| (*t, m))
        .collect();
    for (t, m) in &ch["/board/pose"].messages {
        assert_eq!(m["pose"], host[t]["pose"], "at {t} ns");
    }

    // The MCAP file may not be the stream played: refused before the board is asked, the
    // stream untouched.
    let copy = dir.path().join("circle.csv");
    std::fs::copy(circle(), &copy).unwrap();
    let out = Command::new(BIN)
        .args(["play", "--port", &board.port, "--robot"])
        .arg(circle().with_file_name("diff-drive.toml"))
        .arg("--ticks")
        .arg(&copy)
        .arg("--mcap")
        .arg(&copy)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("that is"), "{err}");
    assert_eq!(
        std::fs::read(&copy).unwrap(),
        std::fs::read(circle()).unwrap()
    );

    let file = dir.path().join("replay.mcap");
    succeeds(
        Command::new(BIN)
            .args(["replay", "--algorithm", "all", "--ticks"])
            .arg(circle())
            .arg("--mcap")
            .arg(&file),
    );
    let ch = read_mcap(&file);
    let rows = count(&ch, "/truth/pose");
    assert!(rows > 50, "{rows} truth rows");
    for m in ["arc", "lut", "timing", "exact"] {
        assert_eq!(count(&ch, &format!("/odometry/{m}/pose")), rows, "{m}");
        assert_eq!(count(&ch, &format!("/odometry/{m}/error")), rows, "{m}");
    }
}

/// `host-bench ARGS --live 127.0.0.1:0 ...`, and the port it serves on (from its stderr).
fn start_live(args: &[&str]) -> (Child, u16) {
    let mut child = Command::new(BIN)
        .args(args)
        .args(["--live", "127.0.0.1:0"])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut lines = BufReader::new(child.stderr.take().unwrap()).lines();
    let first = lines.next().unwrap().unwrap();
    let port = first
        .split("ws://127.0.0.1:")
        .nth(1)
        .and_then(|s| s.split(|c: char| !c.is_ascii_digit()).next())
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("no address in {first:?}"));
    // The rest of stderr is passed on (shown with a failing test), so the child never blocks.
    std::thread::spawn(move || lines.map_while(Result::ok).for_each(|l| eprintln!("{l}")));
    (child, port)
}

fn ws_connect(
    port: u16,
    subprotocol: &str,
) -> tungstenite::Result<(
    tungstenite::WebSocket<tungstenite::stream::MaybeTlsStream<TcpStream>>,
    tungstenite::handshake::client::Response,
)> {
    let mut req = format!("ws://127.0.0.1:{port}/")
        .into_client_request()
        .unwrap();
    req.headers_mut()
        .insert("sec-websocket-protocol", subprotocol.parse().unwrap());
    tungstenite::connect(req)
}

/// The next JSON control message with `op`.
fn next_op<S: Read + Write>(ws: &mut tungstenite::WebSocket<S>, op: &str) -> serde_json::Value {
    loop {
        if let Message::Text(t) = ws.read().unwrap() {
            let v: serde_json::Value = serde_json::from_str(t.as_str()).unwrap();
            if v["op"] == op {
                return v;
            }
        }
    }
}

#[test]
fn the_live_view_serves_poses_in_order_under_both_subprotocols() {
    let (mut child, port) = start_live(&[
        "emulate",
        "--duration",
        "2",
        "--live-speed",
        "2",
        "--live-hold",
        "2",
    ]);
    let (mut ws, resp) = ws_connect(port, "foxglove.websocket.v1").unwrap();
    assert_eq!(
        resp.headers()["sec-websocket-protocol"],
        "foxglove.websocket.v1"
    );
    assert!(next_op(&mut ws, "serverInfo")["name"]
        .as_str()
        .unwrap()
        .contains("omnibench"));
    let adv = next_op(&mut ws, "advertise");
    let slave = adv["channels"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["topic"] == "/slave/pose")
        .expect("/slave/pose advertised");
    assert_eq!(slave["schemaName"], "foxglove.PoseInFrame");
    assert_eq!(slave["encoding"], "json");
    ws.send(Message::text(
        serde_json::json!({"op": "subscribe", "subscriptions": [{"id": 7, "channelId": slave["id"]}]})
            .to_string(),
    ))
    .unwrap();
    // The other name in use is accepted too; one of neither is refused.
    let (_, resp) = ws_connect(port, "foxglove.sdk.v1").unwrap();
    assert_eq!(resp.headers()["sec-websocket-protocol"], "foxglove.sdk.v1");
    match ws_connect(port, "something.else") {
        Err(tungstenite::Error::Http(r)) => assert_eq!(r.status(), 400),
        other => panic!("not refused: {:?}", other.map(|(_, r)| r.status())),
    }
    // A client that floods a subscribe of a megabyte and never reads what it is sent: it is
    // let go, and holds up neither the run nor the other clients.
    let (mut lazy, _) = ws_connect(port, "foxglove.websocket.v1").unwrap();
    let flood: Vec<_> = (0..40_000)
        .map(|i| serde_json::json!({"id": i, "channelId": 0}))
        .collect();
    let _ = lazy.send(Message::text(
        serde_json::json!({"op": "subscribe", "subscriptions": flood}).to_string(),
    ));
    let mut poses = Vec::new();
    let deadline = Instant::now() + Duration::from_secs(20);
    while poses
        .last()
        .is_none_or(|p: &(u64, f64)| p.0 < 1_990_000_000)
        && Instant::now() < deadline
    {
        // Until the run's last pose (at 1.991 s), or the server going away.
        let Ok(m) = ws.read() else {
            break;
        };
        match m {
            Message::Binary(b) => {
                assert_eq!(b[0], 1, "message data");
                assert_eq!(u32::from_le_bytes(b[1..5].try_into().unwrap()), 7);
                let t = u64::from_le_bytes(b[5..13].try_into().unwrap());
                let m: serde_json::Value = serde_json::from_slice(&b[13..]).unwrap();
                poses.push((t, m["pose"]["position"]["x"].as_f64().unwrap()));
            }
            _ => continue,
        }
    }
    // The page's history: every channel's messages so far, in time order.
    let history: serde_json::Value =
        serde_json::from_str(&http_get(port, "/history").unwrap()).unwrap();
    let _ = child.kill();
    let _ = child.wait();
    drop(lazy);
    let kept = history["messages"].as_array().unwrap();
    let times: Vec<u64> = kept.iter().map(|m| m[1].as_u64().unwrap()).collect();
    assert!(
        times.windows(2).all(|w| w[0] <= w[1]),
        "history out of order"
    );
    let slave_id = slave["id"].as_u64().unwrap();
    let kept_slave = kept
        .iter()
        .filter(|m| m[0].as_u64() == Some(slave_id))
        .count();
    assert_eq!(
        kept_slave, 200,
        "the history keeps every /slave/pose of the run"
    );
    // Live from the subscription on (the run's first rows may come before it), in order, none
    // lost, to the run's last.
    assert!(poses.len() >= 190, "{} poses", poses.len());
    assert!(
        poses.windows(2).all(|w| w[1].0 == w[0].0 + 10_000_000),
        "in order, none lost"
    );
    assert_eq!(
        poses.last().unwrap().0,
        1_991_000_000,
        "to the end of the run"
    );
    assert!(
        (poses.last().unwrap().1 - poses[0].1).abs() > 0.01,
        "the robot moved"
    );
}

/// The points of the longest line an SVG plot draws (plotters writes each as a `polyline`).
fn longest_line(svg: &str) -> usize {
    svg.split("<polyline")
        .skip(1)
        .map(|p| {
            let points = p.split("points=\"").nth(1).unwrap_or("");
            points.split('"').next().unwrap_or("").split(' ').count()
        })
        .max()
        .unwrap_or(0)
}

/// Every plot comes as SVG and PNG, and draws its data: `accuracy --out` drew empty axes for
/// four days when the tracks it plots were let go before the pictures.
#[test]
fn plots_are_drawn_as_svg_and_png_with_their_data() {
    let dir = tempfile::tempdir().unwrap();
    let acc = dir.path().join("acc");
    succeeds(
        Command::new(BIN)
            .args(["accuracy", "--seeds", "1", "--out"])
            .arg(&acc),
    );
    let run = dir.path().join("run");
    succeeds(
        Command::new(BIN)
            .args(["emulate", "--duration", "2", "--out"])
            .arg(&run),
    );
    let mut svgs: Vec<PathBuf> = std::fs::read_dir(&acc)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "svg"))
        .collect();
    svgs.push(run.join("path.svg"));
    assert!(svgs.len() > 20, "{} plots", svgs.len());
    for svg in &svgs {
        let text = std::fs::read_to_string(svg).unwrap();
        assert!(
            longest_line(&text) > 100,
            "{}: no line drawn",
            svg.display()
        );
        let png = std::fs::read(svg.with_extension("png")).unwrap();
        assert_eq!(&png[1..4], b"PNG", "{}", svg.display());
        assert!(png.len() > 20_000, "{}: a blank PNG", svg.display());
    }
}
