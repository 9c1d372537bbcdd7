//! Issue 10's corpus of bad inputs, one class a case: each gets exit 1, an error naming the
//! option or file, no panic, in under 5 s, under 200 MB resident, and nothing written.

use std::path::Path;
use std::process::Command;
use std::time::Instant;

fn repo(rel: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join(rel)
        .to_string_lossy()
        .into_owned()
}

/// Run host-bench with `args`; check the exit, the message, the time and that `out` (if any)
/// was not written.
fn refused(args: &[&str], says: &str, out: Option<&Path>) {
    let start = Instant::now();
    let o = Command::new(env!("CARGO_BIN_EXE_host-bench"))
        .args(args)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{args:?}: {err}");
    assert!(err.contains(says), "{args:?}: wanted {says:?} in {err}");
    assert!(!err.contains("panicked"), "{args:?}: {err}");
    assert!(start.elapsed().as_secs_f64() < 5.0, "{args:?}");
    let peak_mb = children_peak_rss_mb();
    assert!(
        peak_mb < 200.0,
        "{args:?}: a child of this test peaked at {peak_mb} MB"
    );
    if let Some(out) = out {
        assert!(!out.exists(), "{args:?} wrote {}", out.display());
        let dir = out.parent().unwrap();
        let left: Vec<_> = std::fs::read_dir(dir).unwrap().collect();
        assert!(left.is_empty(), "{args:?} left {left:?}");
    }
}

/// The largest resident set of any finished child of this test binary, MB (the kernel keeps
/// the maximum over every child waited for: one that grew past the bound fails every later
/// check too, never none).
fn children_peak_rss_mb() -> f64 {
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    // SAFETY: getrusage writes one rusage into the struct it is given.
    let rc = unsafe { libc::getrusage(libc::RUSAGE_CHILDREN, &mut usage) };
    assert_eq!(rc, 0);
    usage.ru_maxrss as f64 / 1024.0 // KiB on Linux
}

/// `text` as a file `name` in `dir`, its path as a string.
fn file(dir: &Path, name: &str, text: &str) -> String {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path.to_str().unwrap().to_owned()
}

const STREAM_HEAD: &str = "# omnibench tick stream v1\nt_ns,kind,id,value,x_m,y_m,theta_rad\n";

#[test]
fn tick_streams_that_cannot_be_scored_honestly_are_refused_at_their_line() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let seed001 = repo("robots/seed001.toml");
    let start = "0,truth,,,0,0,0\n";
    let cases = [
        // Beyond what the estimators' fixed point holds (it would score 10^9 km of "error").
        (
            "far.csv",
            format!("{STREAM_HEAD}0,truth,,,1e12,0,0\n"),
            "far.csv:3: truth x_m must be within ±1e6 m",
        ),
        (
            "spun.csv",
            format!("{STREAM_HEAD}0,truth,,,0,0,6.9e12\n"),
            "spun.csv:3: truth theta_rad must be within ±1e6 rad",
        ),
        // An absolute encoder the robot does not have, and a code wider than one it has.
        (
            "abs.csv",
            format!("{STREAM_HEAD}{start}5,abs,3,12,,,\n10,truth,,,0,0,0\n"),
            "absolute encoder 3 at t = 5 ns, but robot seed001 has 0",
        ),
        // Only the start pose: nothing to score.
        (
            "one.csv",
            format!("{STREAM_HEAD}{start}5,tick,0,1,,,\n"),
            "one truth row, the start pose",
        ),
        ("none.csv", STREAM_HEAD.to_string(), "no truth rows"),
        (
            "enc.csv",
            format!("{STREAM_HEAD}{start}5,tick,7,1,,,\n10,truth,,,0,0,0\n"),
            "tick for encoder 7",
        ),
    ];
    for (name, text, says) in cases {
        let ticks = file(d, name, &text);
        refused(
            &["replay", "--robot", &seed001, "--ticks", &ticks],
            says,
            None,
        );
    }
    // A FIFO nobody writes to: read as empty at once, not waited on for ever.
    let fifo = d.join("fifo.csv");
    assert!(Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .unwrap()
        .success());
    refused(
        &[
            "replay",
            "--robot",
            &seed001,
            "--ticks",
            fifo.to_str().unwrap(),
        ],
        "fifo.csv: empty file",
        None,
    );
    let seed004 = repo("robots/seed004.toml"); // one 8-bit absolute encoder
    let wide = file(
        d,
        "wide.csv",
        &format!("{STREAM_HEAD}{start}5,abs,0,256,,,\n10,truth,,,0,0,0\n"),
    );
    refused(
        &["replay", "--robot", &seed004, "--ticks", &wide],
        "does not fit its 8 bits",
        None,
    );
    for rate in ["-5", "nan", "0", "1e30"] {
        refused(
            &[
                "replay",
                "--robot",
                &seed001,
                "--ticks",
                &wide,
                "--counts-rate",
                rate,
            ],
            "counts sampling rate",
            None,
        );
    }
}

#[test]
fn a_gap_of_centuries_between_two_ticks_costs_no_time() {
    // 1.8·10^19 ns between ticks, sampled at 1 GHz: 1.8·10^19 samples if walked one by one.
    let dir = tempfile::tempdir().unwrap();
    let ticks = file(
        dir.path(),
        "gap.csv",
        &format!("{STREAM_HEAD}0,truth,,,0,0,0\n5,tick,0,1,,,\n18000000000000000000,tick,0,1,,,\n18000000000000000001,truth,,,0.0008,0,0\n"),
    );
    let start = Instant::now();
    let o = Command::new(env!("CARGO_BIN_EXE_host-bench"))
        .args([
            "replay",
            "--robot",
            &repo("robots/seed001.toml"),
            "--ticks",
            &ticks,
        ])
        .args(["--counts-rate", "1e9", "--json"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(start.elapsed().as_secs_f64() < 5.0);
}

#[test]
fn robot_values_outside_their_documented_ranges_are_refused_at_their_key() {
    let dir = tempfile::tempdir().unwrap();
    let seed001 = std::fs::read_to_string(repo("robots/seed001.toml")).unwrap();
    let ticks = file(
        dir.path(),
        "t.csv",
        &format!("{STREAM_HEAD}0,truth,,,0,0,0\n1,truth,,,0,0,0\n"),
    );
    let cases = [
        (
            "metres_per_count = 0.0004   # 0.04 cm per pulse",
            "metres_per_count = 1e308",
            "`encoders[0].metres_per_count`: a count must be 1e-7 to 0.0625 m",
        ),
        (
            "metres_per_count = 0.0004   # 0.04 cm per pulse",
            "metres_per_count = 1e-300",
            "got 1e-300 m",
        ),
        (
            "y_m = 0.15                  # L/2, assumed",
            "y_m = 1e300",
            "`encoders[0].y_m`: must be in [-10, 10] m, got 1e300",
        ),
        (
            "direction_deg = 0.0         # a positive",
            "direction_deg = 1e20 # a positive",
            "`encoders[0].direction_deg`: must be in [-360, 360] deg",
        ),
        (
            "v_max_m_s = 1.0",
            "v_max_m_s = 1e300",
            "`drive_wheels[0].v_max_m_s`: must be in [0.001, 100] m/s",
        ),
    ];
    for (i, (from, to, says)) in cases.into_iter().enumerate() {
        assert!(seed001.contains(from), "{from}");
        let robot = file(
            dir.path(),
            &format!("r{i}.toml"),
            &seed001.replacen(from, to, 1),
        );
        refused(
            &["replay", "--robot", &robot, "--ticks", &ticks],
            says,
            None,
        );
    }
}

#[test]
fn counts_of_work_a_typo_could_ask_for_are_refused() {
    for (args, says) in [
        (
            vec!["accuracy", "--seeds", "4000000000"],
            "--seeds must be 1 to 1000",
        ),
        (
            vec!["emulate", "--sweep", "100000000"],
            "--sweep must be 1 to 1000",
        ),
        (
            vec!["emulate", "--sweep", "1000", "--duration", "3600"],
            "a week",
        ),
        (vec!["emulate", "--duration", "inf"], "--duration"),
        (
            vec!["emulate", "--fault-slave-off-at", "nan"],
            "--fault-slave-off-at",
        ),
    ] {
        refused(&args, says, None);
    }
    // An image named by --slave-elf is checked on the open file before it is read.
    refused(
        &[
            "flash",
            "--dry-run",
            "--slave",
            "--slave-elf",
            "/dev/zero",
            "--slave-probe",
            "0483:3748",
        ],
        "not a regular file",
        None,
    );
}

/// Ctrl-C in the middle of writing a file leaves nothing behind: not the target, not the
/// `.partial` temporary, and the exit says it was interrupted (128 + SIGINT).
#[test]
fn ctrl_c_while_writing_leaves_nothing_half_written() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("big.csv.gz");
    // About 1.8·10^6 rows: a few seconds of writing, in the test profile's build.
    let mut child = Command::new(env!("CARGO_BIN_EXE_host-bench"))
        .args(["generate", "--robot", &repo("robots/seed000-0.1mm.toml")])
        .args([
            "--trajectory",
            "seed001-straight-40m",
            "--truth-rate",
            "10000",
            "--out",
        ])
        .arg(&out)
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let partial = || {
        std::fs::read_dir(dir.path())
            .unwrap()
            .filter_map(|e| e.ok())
            .any(|e| e.file_name().to_string_lossy().ends_with(".partial"))
    };
    let start = Instant::now();
    while !partial() {
        assert!(
            child.try_wait().unwrap().is_none(),
            "generate ended before writing"
        );
        assert!(start.elapsed().as_secs() < 20, "no .partial file appeared");
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
    // SAFETY: kill sends a signal to our own child, still running (not yet waited for).
    assert_eq!(unsafe { libc::kill(child.id() as i32, libc::SIGINT) }, 0);
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(128 + libc::SIGINT), "{status:?}");
    let left: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
    assert!(left.is_empty(), "left {left:?}");
}

#[test]
fn sampling_rates_that_would_exhaust_memory_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("t.csv");
    let o = out.to_str().unwrap();
    let seed001 = repo("robots/seed001.toml");
    let seed004 = repo("robots/seed004.toml");
    let gen = |robot: &str, traj: &'static str, flag: &'static str, v: &'static str| {
        vec![
            "generate",
            "--robot",
            robot,
            "--trajectory",
            traj,
            "--out",
            o,
            flag,
            v,
        ]
        .into_iter()
        .map(str::to_owned)
        .collect::<Vec<_>>()
    };
    for (args, says) in [
        (
            gen(&seed001, "seed001-curve", "--truth-rate", "1e12"),
            "--truth-rate",
        ),
        (
            gen(&seed004, "seed001-curve", "--abs-rate", "1e12"),
            "--abs-rate",
        ),
        (
            gen(&seed001, "seed001-curve", "--truth-rate", "nan"),
            "--truth-rate",
        ),
        // Within the rate, but 100 s of it: too many rows for one stream.
        (
            gen(&seed001, "seed001-straight-40m", "--truth-rate", "1e5"),
            "at most 2000000",
        ),
    ] {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        refused(&args, says, Some(&out));
    } // Counts of 0.1 µm: 6·10⁷ ticks along seed 001's curve (2.5 GB once made), refused
      // before any is made.
    let robots = tempfile::tempdir().unwrap();
    let fine = robots.path().join("fine.toml");
    let text = std::fs::read_to_string(&seed001).unwrap();
    std::fs::write(
        &fine,
        text.replace("metres_per_count = 0.0004", "metres_per_count = 1e-7"),
    )
    .unwrap();
    let fine = fine.to_str().unwrap().to_owned();
    let args = gen(&fine, "seed001-curve", "--truth-rate", "100");
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    refused(&args, "encoder ticks", Some(&out));
}

#[test]
fn description_files_that_are_devices_folders_or_huge_are_refused_unread() {
    let dir = tempfile::tempdir().unwrap();
    let big = dir.path().join("big.toml");
    std::fs::write(&big, vec![b'#'; 2 << 20]).unwrap();
    let big = big.to_str().unwrap();
    let ticks = dir.path().join("t.csv");
    std::fs::write(
        &ticks,
        "# omnibench tick stream v1\nt_ns,kind,id,value,x_m,y_m,theta_rad\n",
    )
    .unwrap();
    let ticks = ticks.to_str().unwrap();
    let folder = dir.path().to_str().unwrap();
    for (args, says) in [
        (
            vec!["replay", "--robot", "/dev/zero", "--ticks", ticks],
            "not a regular file",
        ),
        (
            vec!["replay", "--robot", folder, "--ticks", ticks],
            "not a regular file",
        ),
        (
            vec!["replay", "--robot", big, "--ticks", ticks],
            "larger than 1024 KiB",
        ),
        (
            vec!["emulate", "--scenario", "/dev/zero"],
            "not a regular file",
        ),
        (vec!["emulate", "--scenario", big], "larger than 1024 KiB"),
    ] {
        refused(&args, says, None);
    }
}

/// What an independent bad-input hunt found (issue 10), each refused now at its place.
#[test]
fn a_bad_input_hunts_findings_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let seed001 = repo("robots/seed001.toml");

    // A million empty comment lines (a 2 MB file, or a gzip of a few kB): each kept comment
    // cost a String whatever its bytes, 50 M of them 1.2 GB.
    let flood = d.join("flood.csv");
    let mut text = String::from(STREAM_HEAD);
    text.push_str(&"#\n".repeat(1_000_001));
    std::fs::write(&flood, text).unwrap();
    refused(
        &[
            "replay",
            "--robot",
            &seed001,
            "--ticks",
            flood.to_str().unwrap(),
        ],
        "more than 1000000 comment or blank lines",
        None,
    );

    // Truth rows only before the ticks: every method scored "0.0000 mm" over no motion.
    let before = file(
        d,
        "before.csv",
        &format!("{STREAM_HEAD}0,truth,,,0,0,0\n1000,truth,,,0,0,0\n2000,tick,0,1,,,\n3000,tick,0,1,,,\n"),
    );
    refused(
        &["replay", "--robot", &seed001, "--ticks", &before],
        "no encoder tick between the first truth row and the last",
        None,
    );

    // Faults that could never happen, or never be seen, in the run.
    for (args, says) in [
        (
            vec!["emulate", "--fault-slave-reset-at", "12"],
            "the fault would never happen",
        ),
        (
            vec!["emulate", "--fault-host-silent-after", "1e308"],
            "--fault-host-silent-after",
        ),
        (
            vec!["emulate", "--fault-slave-reset-at", "0.001"],
            "a late power-on",
        ),
        (
            vec!["emulate", "--fault-slave-reset-at", "11.99"],
            "before the end of the run",
        ),
        // A run that moves nothing scores nothing: not a perfect 0.00 mm and exit 0.
        (
            vec!["emulate", "--fault-slave-off-at", "0"],
            "nothing scored: the robot did not move",
        ),
        (
            vec!["emulate", "--fault-spi-drop", "0.999999"],
            "nothing scored",
        ),
    ] {
        refused(&args, says, None);
    }

    // Scenario keys: the serial rates' sum and a third encoder phase, at their line.
    let square = std::fs::read_to_string(repo("scenarios/seed002-square.toml")).unwrap();
    let square = square.replace("../robots/", &format!("{}/", repo("robots")));
    for (name, extra, says) in [
        (
            "sum.toml",
            "\n[faults]\nserial_drop = 0.6\nserial_corrupt = 0.4\n",
            "key `faults.serial_*`: the serial fault rates share one draw per frame",
        ),
        (
            "phase.toml",
            "\n[noise]\nencoder_phase = [0.25, 0.5, 0.75]\n",
            "key `noise.encoder_phase`: two fractions of a count, one per measuring wheel: got 3",
        ),
    ] {
        let path = file(d, name, &format!("{square}{extra}"));
        refused(&["emulate", "--scenario", &path], &format!("{name}:"), None);
        refused(&["emulate", "--scenario", &path], says, None);
    }

    // The stream written over the robot it is made for.
    let robot = file(d, "r.toml", &std::fs::read_to_string(&seed001).unwrap());
    refused(
        &[
            "generate",
            "--robot",
            &robot,
            "--trajectory",
            "twist-arcs",
            "--out",
            &robot,
        ],
        "is the robot file given with --robot",
        None,
    );
    assert!(std::fs::read_to_string(&robot)
        .unwrap()
        .starts_with("format = "));

    // A name that would print an escape sequence to the terminal, refused at its key.
    let seed001_text = std::fs::read_to_string(&seed001).unwrap();
    let escaped = file(
        d,
        "escaped.toml",
        &seed001_text.replacen(r#"name = "seed001""#, r#"name = "seed\u001b[31m""#, 1),
    );
    let ticks_out = d.join("escaped.csv");
    refused(
        &[
            "generate",
            "--robot",
            &escaped,
            "--trajectory",
            "twist-arcs",
            "--out",
            ticks_out.to_str().unwrap(),
        ],
        "escaped.toml:2:8: key `name`: must not hold control characters",
        None,
    );
    assert!(!ticks_out.exists());

    // An output path that is a FIFO (or a device: as root, `record --out /dev/null` replaced
    // /dev/null with a file) is refused, and left as it was.
    let fifo = d.join("out.fifo");
    assert!(Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .unwrap()
        .success());
    refused(
        &[
            "generate",
            "--robot",
            &seed001,
            "--trajectory",
            "twist-arcs",
            "--out",
            fifo.to_str().unwrap(),
        ],
        "it exists and is not a regular file",
        None,
    );
    use std::os::unix::fs::FileTypeExt;
    assert!(std::fs::metadata(&fifo).unwrap().file_type().is_fifo());

    // Output names that would hide what is in the file.
    refused(
        &["envelope", "--out", d.join("e.png").to_str().unwrap()],
        "drawn as SVG",
        None,
    );
    refused(
        &[
            "record",
            "--port",
            "/dev/null",
            "--out",
            d.join("r.txt").to_str().unwrap(),
        ],
        "a tick stream is written as .csv",
        None,
    );

    // Seed 001's `lut` holds 42.9 m: a run 1 km from the origin is refused for it, not scored
    // as 988 m of error.
    let far = file(
        d,
        "far-lut.csv",
        &format!(
            "{STREAM_HEAD}0,truth,,,1000,0,0\n1000,tick,0,1,,,\n1000,tick,1,1,,,\n2000,truth,,,1000.0001,0,0\n"
        ),
    );
    refused(
        &[
            "replay",
            "--robot",
            &seed001,
            "--ticks",
            &far,
            "--algorithm",
            "lut",
        ],
        "`lut` (Batbayar and Zoljargal 2013) keeps positions in 32-bit units of 10 nm",
        None,
    );

    // A run that fails leaves none of the folders --out would have made.
    let out = d.join("runs");
    refused(
        &[
            "emulate",
            "--fault-host-silent-after",
            "0",
            "--out",
            out.join("a/b").to_str().unwrap(),
        ],
        "the host fell silent",
        None,
    );
    assert!(!out.exists(), "a failed run left {}", out.display());
}

/// The third hunt's findings on the outputs: a failed run replaces nothing, and no output is
/// put where a device or FIFO is.
#[test]
fn a_failed_run_replaces_no_output_and_writes_over_no_device() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();

    // init-bench --force over a FIFO replaced it with a regular file (its own atomic write
    // skipped the check every other output has).
    let fifo = d.join("bench.fifo");
    let made = Command::new("mkfifo").arg(&fifo).status().unwrap();
    assert!(made.success());
    let o = Command::new(env!("CARGO_BIN_EXE_host-bench"))
        .args(["init-bench", "--force", "--out", fifo.to_str().unwrap()])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("is not a regular file"), "{err}");
    let kind = std::fs::symlink_metadata(&fifo).unwrap().file_type();
    assert!(std::os::unix::fs::FileTypeExt::is_fifo(&kind));
    std::fs::remove_file(&fifo).unwrap();

    // emulate --out: a blocked path.svg is found before the run, and run.csv is untouched;
    // a run that scores nothing puts none of its files in place.
    let out = d.join("out");
    std::fs::create_dir_all(out.join("path.svg")).unwrap();
    std::fs::write(out.join("run.csv"), "OLD").unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_host-bench"))
        .args(["emulate", "--duration", "1", "--out", out.to_str().unwrap()])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("path.svg"), "{err}");
    assert_eq!(std::fs::read_to_string(out.join("run.csv")).unwrap(), "OLD");
    std::fs::remove_dir(out.join("path.svg")).unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_host-bench"))
        .args(["emulate", "--duration", "2", "--fault-slave-off-at", "0"])
        .args(["--out", out.to_str().unwrap()])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("nothing scored") && err.contains("nothing written"),
        "{err}"
    );
    assert_eq!(std::fs::read_to_string(out.join("run.csv")).unwrap(), "OLD");
    let left: Vec<_> = std::fs::read_dir(&out).unwrap().collect();
    assert_eq!(left.len(), 1, "{left:?}");
    // A file name ending in `/` failed only at the rename, naming a temporary file.
    let slashed = format!("{}/", d.join("x.csv").display());
    refused(
        &[
            "generate",
            "--robot",
            &repo("robots/seed001.toml"),
            "--trajectory",
            "twist-arcs",
            "--out",
            &slashed,
        ],
        "the name ends in /, a folder's",
        None,
    );
    assert!(!d.join("x.csv").exists());
    // And a new folder for such a run is not left behind.
    let new = d.join("new/sub");
    refused(
        &[
            "emulate",
            "--duration",
            "2",
            "--fault-slave-off-at",
            "0",
            "--out",
            new.to_str().unwrap(),
        ],
        "nothing written",
        None,
    );
    assert!(!d.join("new").exists());
}

/// Scenario values inside their own ranges that the master would refuse (a gain that rounds
/// to zero on the wire, a speed or a path faster than the robot): refused when the file is
/// read, at the key, not as "the master refused the session" once the run has begun.
#[test]
fn what_the_master_would_refuse_is_refused_at_the_scenario_key() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let robots = format!("{}/", repo("robots"));
    let square = std::fs::read_to_string(repo("scenarios/seed002-square.toml"))
        .unwrap()
        .replace("../robots/", &robots);
    let pursuit = std::fs::read_to_string(repo("scenarios/seed004-pursuit.toml"))
        .unwrap()
        .replace("../robots/", &robots);
    let slow = std::fs::read_to_string(repo("robots/seed002.toml"))
        .unwrap()
        .replace("v_max_m_s = 0.8", "v_max_m_s = 0.2");
    file(d, "slow.toml", &slow);
    let slow_square = square.replace(&format!("{robots}seed002.toml"), "slow.toml");
    assert_ne!(slow_square, square);
    let pursuit_fast = {
        let line = pursuit
            .lines()
            .find(|l| l.starts_with("robot_speed_m_s"))
            .unwrap();
        pursuit.replace(line, "robot_speed_m_s = 100")
    };
    for (name, text, says) in [
        (
            "gain.toml",
            square.replacen("k_forward = 8.0", "k_forward = 0.0004", 1),
            "key `controller.k_forward`: must be at least 0.001",
        ),
        (
            "slow-square.toml",
            slow_square,
            "key `trajectory.name`: the path's peak speed, 0.400 m/s, is above the robot's top speed, 0.200 m/s",
        ),
        (
            "fast.toml",
            pursuit_fast,
            "key `target.robot_speed_m_s`: 100 m/s is above the robot's top speed",
        ),
    ] {
        let path = file(d, name, &text);
        refused(&["emulate", "--scenario", &path], &format!("{name}:"), None);
        refused(&["emulate", "--scenario", &path], says, None);
    }
}

/// Outputs that are inputs, outputs checked late, options that contradict each other: each
/// refused before any work, the inputs left as they were.
#[test]
fn outputs_are_checked_first_and_never_write_over_an_input() {
    let dir = tempfile::tempdir().unwrap();
    let bin = env!("CARGO_BIN_EXE_host-bench");
    let run = |args: &[&str]| {
        let t = Instant::now();
        let o = Command::new(bin).args(args).output().unwrap();
        (o, t.elapsed().as_secs_f64())
    };
    // A scenario kept as run.csv, its robot as summary.json, in the folder `--out` names:
    // the run's run.csv and summary.json would replace them.
    let robot = std::fs::read_to_string(repo("robots/seed002.toml")).unwrap();
    let scenario = std::fs::read_to_string(repo("scenarios/seed002-square.toml"))
        .unwrap()
        .replace("../robots/seed002.toml", "summary.json");
    let as_input = dir.path().join("as-input");
    std::fs::create_dir(&as_input).unwrap();
    let robot_path = file(&as_input, "summary.json", &robot);
    let out_dir = as_input.to_str().unwrap();
    // Kept as run.csv, the scenario is named; kept as scenario.toml, its robot file is.
    for (name, what) in [
        ("run.csv", "is the scenario file"),
        ("scenario.toml", "is the scenario's robot file"),
    ] {
        let scenario_path = file(&as_input, name, &scenario);
        let (o, _) = run(&[
            "emulate",
            "--scenario",
            &scenario_path,
            "--duration",
            "1",
            "--out",
            out_dir,
        ]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{err}");
        assert!(
            err.contains(what) && err.contains("would write over its own input"),
            "{name}: {err}"
        );
        assert_eq!(std::fs::read_to_string(&scenario_path).unwrap(), scenario);
    }
    assert_eq!(std::fs::read_to_string(&robot_path).unwrap(), robot);

    // pursuit-sweep's picture: a folder that is not there, or a name that is not .svg, is
    // refused at once, not after a sweep of minutes; the file of that name stays.
    let notes = file(dir.path(), "notes.txt", "mine\n");
    for (out, says) in [
        (dir.path().join("nodir/p.svg"), "does not exist"),
        (Path::new(&notes).to_path_buf(), "name a .svg file"),
    ] {
        let (o, took) = run(&[
            "pursuit-sweep",
            "--duration",
            "3600",
            "--out",
            out.to_str().unwrap(),
        ]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{err}");
        assert!(err.contains(says), "{out:?}: {err}");
        assert!(took < 5.0, "{out:?}: refused after {took} s");
    }
    assert_eq!(std::fs::read_to_string(&notes).unwrap(), "mine\n");

    // A slave switched off cannot reset: the two faults together are refused.
    refused(
        &[
            "emulate",
            "--duration",
            "5",
            "--fault-slave-off-at",
            "1",
            "--fault-slave-reset-at",
            "2",
        ],
        "contradict each other",
        None,
    );
}
