//! Issue 10's corpus of bad inputs, one class a case: each gets exit 1, an error naming the
//! option or file, no panic, in under 5 s, and nothing written.

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
    if let Some(out) = out {
        assert!(!out.exists(), "{args:?} wrote {}", out.display());
        let dir = out.parent().unwrap();
        let left: Vec<_> = std::fs::read_dir(dir).unwrap().collect();
        assert!(left.is_empty(), "{args:?} left {left:?}");
    }
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
