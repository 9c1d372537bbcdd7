//! Scenario files (`docs/scenario-format.md`): every mistake is refused with the file, line
//! and key, before anything runs.

use std::path::Path;

use host_bench::formats::scenario::load;
use host_bench::sim::emulator::Motion;

const GOOD: &str = r#"format = "omnibench scenario v1"
name = "t"
robot = "ROBOTS/seed002.toml"
duration_s = 5.0

[start]
x_m = -0.15
y_m = 0.0
heading_deg = 0.0

[trajectory]
name = "seed002-circle"

[controller]
k_lateral = 6.0
speed_ki = 4.5
speed_kd = 0.002
"#;

/// Write `text` (with the robots folder filled in) to a temporary file and load it.
fn load_text(text: &str) -> anyhow::Result<host_bench::sim::emulator::Scenario> {
    let robots = Path::new(env!("CARGO_MANIFEST_DIR")).join("../robots");
    let dir = tempfile::tempdir()?;
    let path = dir.path().join("s.toml");
    std::fs::write(&path, text.replace("ROBOTS", robots.to_str().unwrap()))?;
    load(&path)
}

fn error(text: &str) -> String {
    match load_text(text) {
        Ok(s) => panic!("accepted: {s:?}"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn a_good_file_reads_into_the_run() {
    let s = load_text(GOOD).unwrap();
    assert_eq!(s.robot, "seed002");
    assert!(
        matches!(s.motion, Motion::Track { ref trajectory, .. } if trajectory == "seed002-circle")
    );
    assert_eq!(s.drive.k_lateral_milli, 6000);
    assert_eq!(s.drive.k_forward_milli, 8000, "the default");
    assert_eq!(s.drive.speed_ki_micro, 4_500_000);
    assert_eq!(s.drive.speed_kd_micro, 2_000);
    assert_eq!(s.drive.speed_kp_micro, 1_000_000, "the default");
    assert_eq!(s.start, (-0.15, 0.0, 0.0));
}

#[test]
fn mistakes_are_named_by_line_and_key() {
    let cases = [
        (GOOD.replace("seed002-circle", "seed002-circl"), ":12:8: key `trajectory.name`", "no trajectory"),
        (GOOD.replace("k_lateral = 6.0", "k_lateral = 0"), ":15:13: key `controller.k_lateral`", "must be > 0"),
        (GOOD.replace("x_m = -0.15", "x_m = \"a\""), ":7:7: key `start.x_m`", "expected a number"),
        (GOOD.replace("duration_s = 5.0", "duration_s = -1"), ":4:14: key `duration_s`", "must be in [0.1, 604800] s"),
        (GOOD.replace("duration_s = 5.0", "duration_s = 1e12"), ":4:14: key `duration_s`", "got 1e12"),
        (GOOD.replace("x_m = -0.15", "x_m = 1e9"), ":7:7: key `start.x_m`", "must be in [-1000, 1000] m"),
        (GOOD.replace("heading_deg = 0.0", "heading_deg = nan"), ":9:15: key `start.heading_deg`", "finite"),
        (GOOD.replace("seed002.toml", "nope.toml"), ":3:9: key `robot`", "cannot read the robot file"),
        (GOOD.replace("heading_deg = 0.0", "heading_deg = 0.0\nswivel_deg = 90"), ":10:14: key `start.swivel_deg`", "no swivel carriage"),
        (GOOD.replace("[trajectory]\nname = \"seed002-circle\"\n", ""), ":1:1: key `target`", "missing"),
        (GOOD.replace("k_lateral", "k_sideways"), ":15:1: key `controller.k_sideways`", "unknown field"),
        (GOOD.replace("speed_ki = 4.5", "speed_ki = -1"), ":16:12: key `controller.speed_ki`", "must be >= 0"),
        (GOOD.replace("speed_kd = 0.002", "speed_kd = 1e6"), ":17:12: key `controller.speed_kd`", "at most 1000"),
        (format!("{GOOD}[faults]\nspi_drop = 1.0\n"), ":19:12: key `faults.spi_drop`", "below 1"),
        (GOOD.replace("v1", "v2"), ":1:10: key `format`", "unsupported format"),
        (GOOD.replace("[start]", "[[start]]"), "key `start`", "write [start]"),
        (format!("{GOOD}[noise]\nencoder_phase = [0.5, 1.0]\n"), ":19:17: key `noise.encoder_phase`", "[0, 1)"),
        (format!("{GOOD}[noise]\nencoder_edges = \"typcal\"\n"), ":19:17: key `noise.encoder_edges`", "must be ideal, typical, max"),
        (format!("{GOOD}[target]\nfrom_m = [0, 0]\nto_m = [1, 0]\nspeed_m_s = 0.1\nrobot_speed_m_s = 0.2\n"), ":11:1: key `trajectory`", "not both"),
    ];
    for (text, place, what) in cases {
        let e = error(&text);
        assert!(
            e.contains(place) && e.contains(what),
            "wanted {place} {what}, got: {e}"
        );
    }
}

/// The robot must be one the master can drive: two wheels with a tracked point, or seed 003's.
#[test]
fn a_robot_the_master_cannot_drive_is_refused_at_its_line() {
    let e = error(&GOOD.replace("seed002.toml", "seed001.toml"));
    assert!(
        e.contains(":3:9: key `robot`") && e.contains("[tracked_point]"),
        "{e}"
    );
}

/// `noise.encoder_edges` puts a datasheet's edges on the plant's encoders.
#[test]
fn a_scenario_takes_the_encoders_edges() {
    let s = load_text(&format!("{GOOD}[noise]\nencoder_edges = \"max\"\n")).unwrap();
    assert_eq!(
        s.encoder_edges,
        host_bench::sim::generate::EdgeErrors::HEDS_9040_MAX
    );
    let s = load_text(GOOD).unwrap();
    assert!(s.encoder_edges.is_ideal());
}
