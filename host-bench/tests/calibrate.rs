//! `host-bench calibrate` as a user runs it: UMBmark's squares driven on the emulator with a
//! robot whose geometry is off its robot file, the correction, and the squares driven again.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn host_bench(args: &[&std::ffi::OsStr]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_host-bench"))
        .args(args)
        .output()
        .unwrap()
}

fn ok(args: &[&std::ffi::OsStr]) -> String {
    let out = host_bench(args);
    assert!(
        out.status.success(),
        "{:?}: {}",
        args,
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

fn repo(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(rel)
}

/// `emulate --sweep N --json` of UMBmark's square one way, into `out`.
fn squares(way: &str, seeds: u32, robot: Option<&Path>, out: &Path) {
    let scenario = repo(&format!("scenarios/umbmark-{way}.toml"));
    let truly = repo("robots/seed002-as-built.toml");
    let n = seeds.to_string();
    let mut args: Vec<&std::ffi::OsStr> = vec![
        "emulate".as_ref(),
        "--scenario".as_ref(),
        scenario.as_os_str(),
        "--true-robot".as_ref(),
        truly.as_os_str(),
        "--sweep".as_ref(),
        n.as_ref(),
        "--json".as_ref(),
    ];
    if let Some(r) = robot {
        args.extend(["--robot".as_ref(), r.as_os_str()]);
    }
    std::fs::write(out, ok(&args)).unwrap();
}

fn calibrate(robot: &Path, runs: &[&Path], out: Option<&Path>) -> serde_json::Value {
    let mut args: Vec<&std::ffi::OsStr> = vec![
        "calibrate".as_ref(),
        "--robot".as_ref(),
        robot.as_os_str(),
        "--json".as_ref(),
        "--runs".as_ref(),
    ];
    args.extend(runs.iter().map(|r| r.as_os_str()));
    if let Some(o) = out {
        args.extend(["--out".as_ref(), o.as_os_str()]);
    }
    serde_json::from_str(&ok(&args)).unwrap()
}

/// The robot is seed002-as-built (right wheel 1 % larger, wheels 3 % further apart) while the
/// boards are told of seed002: UMBmark finds both factors, and the squares driven again with
/// the corrected robot file come back far closer (the goal: at least 20x less E_max,syst).
#[test]
fn umbmark_on_emulated_squares_finds_the_geometry_and_the_correction_holds() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n);
    let nominal = repo("robots/seed002.toml");
    squares("cw", 2, None, &p("cw.json"));
    squares("ccw", 2, None, &p("ccw.json"));
    let fitted = p("fitted.toml");
    let before = calibrate(&nominal, &[&p("cw.json"), &p("ccw.json")], Some(&fitted));
    let u = &before["umbmark"];
    let f = |v: &serde_json::Value| v.as_f64().unwrap();
    assert!((f(&u["e_d"]) - 1.01).abs() < 1e-4, "{u}");
    assert!((f(&u["e_b"]) - 1.03).abs() < 1e-4, "{u}");
    assert_eq!(
        (u["runs_cw"].as_u64(), u["runs_ccw"].as_u64()),
        (Some(2), Some(2))
    );
    // Driven again, the boards told of the corrected file.
    squares("cw", 2, Some(&fitted), &p("cw2.json"));
    squares("ccw", 2, Some(&fitted), &p("ccw2.json"));
    let after = calibrate(&fitted, &[&p("cw2.json"), &p("ccw2.json")], None);
    let (e0, e1) = (f(&u["e_max_syst_m"]), f(&after["umbmark"]["e_max_syst_m"]));
    assert!(
        e0 > 1.0 && e1 < e0 / 20.0 && e1 < 0.002,
        "E_max,syst {e0} m before, {e1} m after"
    );
    // Runs driven with another robot than the one named are refused, not fitted.
    let out = host_bench(&[
        "calibrate".as_ref(),
        "--robot".as_ref(),
        nominal.as_os_str(),
        "--runs".as_ref(),
        p("cw2.json").as_os_str(),
        p("ccw2.json").as_os_str(),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("was driven with robot"),
        "{err}"
    );
}

/// A generated stream is a true square the odometry follows (the other way round from
/// UMBmark's): the same factors, and the streams replayed on the corrected robot.
fn generated(robot: &Path, way: &str, out: &Path) {
    ok(&[
        "generate".as_ref(),
        "--robot".as_ref(),
        robot.as_os_str(),
        "--trajectory".as_ref(),
        format!("umbmark-{way}").as_ref(),
        "--out".as_ref(),
        out.as_os_str(),
    ]);
}

#[test]
fn umbmark_on_generated_squares_and_a_wheel_counting_backwards() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n);
    let truly = repo("robots/seed002-as-built.toml");
    let nominal = repo("robots/seed002.toml");
    generated(&truly, "cw", &p("cw.csv"));
    generated(&truly, "ccw", &p("ccw.csv"));
    let c = calibrate(&nominal, &[&p("cw.csv"), &p("ccw.csv")], None);
    let f = |v: &serde_json::Value| v.as_f64().unwrap();
    assert!((f(&c["umbmark"]["e_d"]) - 1.01).abs() < 1e-4, "{c}");
    assert!((f(&c["umbmark"]["e_b"]) - 1.03).abs() < 2e-4, "{c}");
    assert!(f(&c["e_max_syst_after_m"]) < f(&c["umbmark"]["e_max_syst_m"]) / 100.0);

    // The left encoder wired backwards: every one of its steps the other way.
    let text = std::fs::read_to_string(p("cw.csv")).unwrap();
    let flipped: String = text
        .lines()
        .map(|l| match l.split(',').collect::<Vec<_>>()[..] {
            [t, "tick", "0", v, ..] => {
                let v = if v == "1" { "-1" } else { "1" };
                format!("{t},tick,0,{v},,,\n")
            }
            _ => format!("{l}\n"),
        })
        .collect();
    std::fs::write(p("backwards.csv"), flipped).unwrap();
    let out = host_bench(&[
        "calibrate".as_ref(),
        "--robot".as_ref(),
        nominal.as_os_str(),
        "--runs".as_ref(),
        p("backwards.csv").as_os_str(),
        p("ccw.csv").as_os_str(),
        "--out".as_ref(),
        p("never.toml").as_os_str(),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{err}");
    assert!(
        err.contains("encoder left counted backwards") && err.contains("no fit is made"),
        "{err}"
    );
    assert!(!p("never.toml").exists());
}

#[test]
fn bad_inputs_are_named_and_nothing_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n);
    let nominal = repo("robots/seed002.toml");
    generated(&repo("robots/seed002-as-built.toml"), "cw", &p("cw.csv"));
    let run = |runs: &[&Path], out: &Path| {
        let mut args: Vec<&std::ffi::OsStr> = vec![
            "calibrate".as_ref(),
            "--robot".as_ref(),
            nominal.as_os_str(),
            "--out".as_ref(),
            out.as_os_str(),
            "--runs".as_ref(),
        ];
        args.extend(runs.iter().map(|r| r.as_os_str()));
        let o = host_bench(&args);
        assert!(!o.status.success());
        String::from_utf8_lossy(&o.stderr).into_owned()
    };
    let out = p("fitted.toml");
    // One direction only.
    let e = run(&[&p("cw.csv")], &out);
    assert!(e.contains("squares both ways"), "{e}");
    // No such file; a robot file given as a run; the output over an input.
    let e = run(&[&p("nope.csv")], &out);
    assert!(e.contains("nope.csv"), "{e}");
    let e = run(&[&nominal], &out);
    assert!(e.contains("seed002.toml"), "{e}");
    let e = run(&[&p("cw.csv")], &nominal);
    assert!(e.contains("--out"), "{e}");
    assert!(!out.exists());
}
