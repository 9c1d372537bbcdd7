//! The `host-bench` binary as a user runs it.

use std::process::Command;

fn host_bench() -> Command {
    Command::new(env!("CARGO_BIN_EXE_host-bench"))
}

/// Runs `host-bench` with `args`, which must succeed; its stdout.
fn stdout_of<S: AsRef<std::ffi::OsStr>>(args: &[S]) -> String {
    let out = host_bench().args(args).output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

/// Runs `host-bench` with `args`, which must succeed; its stdout as JSON.
fn json_of(args: &[&std::ffi::OsStr]) -> serde_json::Value {
    serde_json::from_str(&stdout_of(args)).unwrap()
}

#[test]
fn emulate_json_prints_the_documented_keys() {
    let stdout = stdout_of(&["emulate", "--json", "--duration", "3"]);
    assert_eq!(
        stdout.lines().count(),
        1,
        "one JSON object on one line: {stdout}"
    );
    let v: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    for key in [
        "scenario",
        "sim_seconds",
        "wall_seconds",
        "path_length_m",
        "final_error_m",
        "max_error_m",
        "final_heading_error_rad",
        "spi_frames",
        "spi_frames_rejected",
        "serial_frames",
        "serial_frames_rejected",
    ] {
        assert!(v.get(key).is_some(), "missing {key} in {stdout}");
    }
    assert_eq!(v["scenario"], "seed004-pursuit");
    assert_eq!(v["sim_seconds"], 3.0);
}

#[test]
fn envelope_json_gives_seed_003s_top_speeds_and_the_svg_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let svg = dir.path().join("envelope.svg");
    let v = json_of(&[
        "envelope".as_ref(),
        "--json".as_ref(),
        "--out".as_ref(),
        svg.as_ref(),
    ]);
    let ratio = |k: &str| v[k].as_f64().unwrap_or_else(|| panic!("{k} missing"));
    // Within 2 % of 2/√3 and 4/3 (the check).
    assert!((ratio("translate_max_ratio") / (2.0 / 3f64.sqrt()) - 1.0).abs() < 0.02);
    assert!((ratio("spin_translate_max_ratio") / (4.0 / 3.0) - 1.0).abs() < 0.02);
    assert_eq!(v["directions"].as_array().map(Vec::len), Some(360));
    // Arc versus line, driven: a goal each side of the crossover, and where the times cross.
    let a = &v["arc_vs_line"];
    assert_eq!(a["driven"].as_array().map(Vec::len), Some(7));
    let x = a["measured_crossover_angle_rad"]
        .as_f64()
        .expect("crossover");
    assert!((x - 1.831).abs() < 0.1, "{x}");
    let svg = std::fs::read_to_string(&svg).unwrap();
    assert!(svg.contains("<svg") && svg.contains("arc with spin vs straight line"));
}

#[test]
fn pursuit_sweep_json_has_a_row_per_period_and_the_svg_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let svg = dir.path().join("pursuit.svg");
    let v = json_of(&[
        "pursuit-sweep".as_ref(),
        "--json".as_ref(),
        "--duration".as_ref(),
        "10".as_ref(),
        "--out".as_ref(),
        svg.as_ref(),
    ]);
    assert!(std::fs::read_to_string(&svg).unwrap().contains("<svg"));
    let rows = v["rows"].as_array().expect("rows");
    assert_eq!(rows.len(), 16);
    for (r, tau) in rows.iter().zip(host_bench::eval::pursuit_sweep::PERIODS_S) {
        assert_eq!(r["tau_s"].as_f64(), Some(tau));
        for key in ["jitter", "tracking_rms_m", "hold_rms_m", "hold_max_m"] {
            assert!(r[key].as_f64().is_some_and(f64::is_finite), "{key}: {r}");
        }
        // The paper's equations for every Euler period; none for our law (null, not NaN).
        let paper = r["paper_hold_max_m"].as_f64();
        assert_eq!(paper.is_some(), tau > 0.0, "{r}");
    }
    // Too short to see the target stop: refused, with the reason.
    let out = host_bench()
        .args(["pursuit-sweep", "--duration", "5"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--duration"));
}

#[test]
fn emulate_out_writes_csv_svg_and_json() {
    let dir = std::env::temp_dir().join(format!("omnibench-cli-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let out = host_bench()
        .args(["emulate", "--duration", "2", "--out"])
        .arg(&dir)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let csv = std::fs::read_to_string(dir.join("run.csv")).unwrap();
    let header = csv.lines().next().unwrap();
    for col in [
        "t_s",
        "true_x_m",
        "slave_x_m",
        "master_x_m",
        "wheel_cmd_1_m_s",
        "duty_3_permille",
    ] {
        assert!(
            header.split(',').any(|c| c == col),
            "missing column {col}: {header}"
        );
    }
    // 2 s at 100 rows per second.
    assert!((195..=205).contains(&(csv.lines().count() - 1)));
    let svg = std::fs::read_to_string(dir.join("path.svg")).unwrap();
    assert!(svg.starts_with("<svg") && svg.contains("ground truth"));
    assert!(dir.join("summary.json").exists());
    // Nothing half-written left behind.
    assert!(std::fs::read_dir(&dir).unwrap().all(|e| !e
        .unwrap()
        .file_name()
        .to_string_lossy()
        .ends_with(".partial")));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bad_arguments_fail_clearly_and_write_nothing() {
    let out = host_bench()
        .args(["emulate", "--duration", "-1"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("--duration"), "{err}");
    assert!(!err.contains("panicked"), "{err}");

    let file = std::env::temp_dir().join(format!("omnibench-not-a-dir-{}", std::process::id()));
    std::fs::write(&file, "x").unwrap();
    let out = host_bench()
        .args(["emulate", "--duration", "1", "--out"])
        .arg(&file)
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("not a directory"), "{err}");
    assert_eq!(std::fs::read_to_string(&file).unwrap(), "x");
    std::fs::remove_file(&file).unwrap();

    let out = host_bench()
        .args(["emulate", "--scenario", "nope"])
        .output()
        .unwrap();
    assert!(!out.status.success());

    for command in ["emulate", "accuracy", "generate"] {
        let out = host_bench()
            .args([command, "--edges", "typcial"])
            .args(
                ["--robot", "r.toml", "--trajectory", "t", "--out", "o.csv"]
                    .iter()
                    .filter(|_| command == "generate"),
            )
            .output()
            .unwrap();
        assert!(!out.status.success(), "{command}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.contains("--edges: the encoder edges must be ideal, typical, max"),
            "{command}: {err}"
        );
    }
}

#[test]
fn emulate_runs_real_encoders_edges_and_says_so() {
    let text = stdout_of(&["emulate", "--duration", "3", "--edges", "typical"]);
    assert!(text.contains("edges HEDS-9040 typical"), "{text}");
}

fn tickstream_data(name: &str) -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/tickstreams")
        .join(name)
}

/// docs/tick-stream.md's Python example: 1 cm counts on a 0.2 m axle turn the body 0.05 rad a
/// count, which every estimator takes (they once all refused it and the run still exited 0).
#[test]
fn replay_scores_the_documented_python_example_with_every_method() {
    let out = host_bench()
        .args(["replay", "--json", "--ticks"])
        .arg(tickstream_data("python-circle.csv"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let names: Vec<&str> = v["algorithms"]
        .as_array()
        .unwrap()
        .iter()
        .map(|a| a["name"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["arc", "lut", "timing", "exact"], "{v}");
    assert!(v["skipped"].as_array().unwrap().is_empty(), "{v}");
    for a in v["algorithms"].as_array().unwrap() {
        // One lap of 3.14 m in 1 cm counts: every method ends within a count of the start.
        let e = a["final_error_m"].as_f64().unwrap();
        assert!(e < 0.01, "{a}");
    }
}

/// A robot no estimator can run fails naming its file, the key and the reason, rather than
/// printing an empty table and exiting 0.
#[test]
fn replay_that_scores_nothing_fails_with_the_reasons() {
    let dir = tempfile::tempdir().unwrap();
    let robot = std::fs::read_to_string(tickstream_data("diff-drive.toml"))
        .unwrap()
        .replace("metres_per_count = 0.01", "metres_per_count = 0.0625")
        .replace("y_m = 0.1\n", "y_m = 0.01\n")
        .replace("y_m = -0.1\n", "y_m = -0.01\n");
    // The longest count a robot file takes, on wheels 2 cm apart: 3 rad per count.
    let robot_path = dir.path().join("long-counts.toml");
    std::fs::write(&robot_path, robot).unwrap();
    let out = host_bench()
        .args(["replay", "--robot"])
        .arg(&robot_path)
        .arg("--ticks")
        .arg(tickstream_data("python-circle.csv"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("long-counts.toml: robot diff-drive: key `encoders`"),
        "{stderr}"
    );
    assert!(stderr.contains("per count"), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(out.stdout.is_empty());
}

#[test]
fn generate_takes_the_power_on_phase_and_its_seed() {
    let dir = tempfile::tempdir().unwrap();
    let robot = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../robots/seed001.toml");
    let run = |file: &str, extra: &[&str]| {
        let out = host_bench()
            .args(["generate", "--trajectory", "seed002-circle", "--robot"])
            .arg(&robot)
            .arg("--out")
            .arg(dir.path().join(file))
            .args(extra)
            .output()
            .unwrap();
        let text = std::fs::read_to_string(dir.path().join(file)).unwrap_or_default();
        (
            out.status.success(),
            String::from_utf8_lossy(&out.stderr).into_owned(),
            text,
        )
    };
    let phase_line = |text: &str| {
        text.lines()
            .find(|l| l.starts_with("# power-on phase:"))
            .unwrap_or_default()
            .to_string()
    };
    // The default is random with seed 0; the same seed writes the same file, another another.
    let (ok, err, default) = run("default.csv", &[]);
    assert!(ok, "{err}");
    assert!(
        phase_line(&default).starts_with("# power-on phase: random seed 0; encoder 0 (left) at ")
    );
    let (_, _, seed0) = run("seed0.csv", &["--phase", "random", "--seed", "0"]);
    let (_, _, seed5) = run("seed5.csv", &["--seed", "5"]);
    assert_eq!(default, seed0);
    assert!(phase_line(&seed5).starts_with("# power-on phase: random seed 5;"));
    assert_ne!(phase_line(&seed5), phase_line(&default));
    let (ok, err, quarter) = run("quarter.csv", &["--phase", "0.25"]);
    assert!(ok, "{err}");
    assert!(phase_line(&quarter).contains("encoder 1 (right) at 0.250000 of a count"));
    let (ok, err, zero) = run("zero.csv", &["--phase", "zero"]);
    assert!(ok, "{err}");
    assert!(phase_line(&zero).starts_with("# power-on phase: zero"));
    // Refused, and nothing written.
    for (file, extra, says) in [
        ("one.csv", &["--phase", "1"][..], "[0, 1)"),
        ("word.csv", &["--phase", "half"][..], "[0, 1)"),
        (
            "seeded.csv",
            &["--phase", "zero", "--seed", "3"][..],
            "--seed",
        ),
    ] {
        let (ok, err, text) = run(file, extra);
        assert!(!ok && err.contains(says), "{extra:?}: {err}");
        assert!(text.is_empty(), "{extra:?}");
    }
}

/// Issue 10's bad emulate options: each refused at once, naming the option, exit 1.
#[test]
fn bad_emulate_options_are_refused_naming_the_option() {
    let cases: [(&[&str], &str); 7] = [
        (&["--fault-slave-off-at", "nan"], "--fault-slave-off-at"),
        (&["--fault-slave-off-at", "-1"], "--fault-slave-off-at"),
        (
            &["--fault-host-silent-after", "inf"],
            "--fault-host-silent-after",
        ),
        (&["--duration", "1e-9"], "before the master answered"),
        (&["--duration", "1e12"], "--duration"),
        (
            &["--sweep", "3", "--seed", "18446744073709551615"],
            "--sweep 3",
        ),
        (&["--fault-spi-drop", "1"], "--fault-spi-drop"),
    ];
    for (args, says) in cases {
        let start = std::time::Instant::now();
        let out = host_bench().arg("emulate").args(args).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
        assert!(err.contains(says), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
        assert!(start.elapsed().as_secs() < 5, "{args:?}");
    }
}
