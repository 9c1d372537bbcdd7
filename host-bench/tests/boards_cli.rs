//! `host-bench probes`, `init-bench` and `flash` as a user runs them, on a machine that may
//! have no debug probe attached (CI has none).

use std::path::Path;
use std::process::{Command, Output};

fn host_bench(cwd: &Path) -> Command {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_host-bench"));
    cmd.current_dir(cwd);
    cmd
}

fn text(out: &Output) -> (String, String) {
    (
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn attached_probes(cwd: &Path) -> Vec<serde_json::Value> {
    let out = host_bench(cwd).args(["probes", "--json"]).output().unwrap();
    let (stdout, stderr) = text(&out);
    assert!(out.status.success(), "{stderr}");
    let v: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert!(v["serial_ports"].is_array(), "{stdout}");
    v["probes"].as_array().unwrap().clone()
}

// A 32-bit little-endian ARM ELF header: enough for the image check, which runs before any
// probe is touched.
fn fake_arm_elf(path: &Path) {
    let mut header = vec![0u8; 52];
    header[..4].copy_from_slice(b"\x7fELF");
    header[4] = 1; // ELFCLASS32
    header[5] = 1; // little-endian
    header[18..20].copy_from_slice(&40u16.to_le_bytes()); // EM_ARM
    std::fs::write(path, header).unwrap();
}

#[test]
fn probes_lists_what_is_attached_or_says_there_is_none() {
    let dir = tempfile::tempdir().unwrap();
    let probes = attached_probes(dir.path());
    let out = host_bench(dir.path()).arg("probes").output().unwrap();
    let (stdout, stderr) = text(&out);
    assert!(out.status.success(), "{stderr}");
    if probes.is_empty() {
        assert!(stdout.contains("no probes"), "{stdout}");
    } else {
        for p in &probes {
            assert!(stdout.contains(p["selector"].as_str().unwrap()), "{stdout}");
        }
    }
    for p in &probes {
        for key in ["name", "vid", "pid", "serial", "selector"] {
            assert!(p.get(key).is_some(), "probe without {key}: {p}");
        }
    }
}

#[test]
fn flash_without_images_says_how_to_build_them_and_that_no_probe_is_there() {
    let dir = tempfile::tempdir().unwrap();
    let no_probe = attached_probes(dir.path()).is_empty();
    let out = host_bench(dir.path())
        .arg("flash")
        .env("CARGO_TARGET_DIR", dir.path())
        .output()
        .unwrap();
    let (_, stderr) = text(&out);
    assert!(!out.status.success(), "{stderr}");
    for board in ["slave", "master"] {
        let command =
            format!("cargo build --release --target thumbv7m-none-eabi -p firmware-{board}");
        assert!(stderr.contains(&command), "{command:?} missing: {stderr}");
    }
    if no_probe {
        // Both problems in one run: the user fixes everything before trying again.
        assert!(stderr.contains("no debug probe found"), "{stderr}");
    }
}

#[test]
fn flash_with_images_and_no_probe_says_only_that() {
    let dir = tempfile::tempdir().unwrap();
    if !attached_probes(dir.path()).is_empty() {
        eprintln!("a probe is attached: the no-probe error cannot be shown here");
        return;
    }
    fake_arm_elf(&dir.path().join("slave.elf"));
    fake_arm_elf(&dir.path().join("master.elf"));
    let out = host_bench(dir.path())
        .args([
            "flash",
            "--slave-elf",
            "slave.elf",
            "--master-elf",
            "master.elf",
        ])
        .output()
        .unwrap();
    let (_, stderr) = text(&out);
    assert!(!out.status.success());
    assert_eq!(
        stderr.trim(),
        "error: no debug probe found; `host-bench probes` lists what is attached"
    );
}

#[test]
fn init_bench_writes_a_loadable_file_and_will_not_overwrite_it_unasked() {
    let dir = tempfile::tempdir().unwrap();
    let out = host_bench(dir.path()).arg("init-bench").output().unwrap();
    let (_, stderr) = text(&out);
    assert!(out.status.success(), "{stderr}");
    assert!(
        stderr.contains("slave") && stderr.contains("master"),
        "{stderr}"
    );
    let path = dir.path().join("bench.toml");
    let bench = host_bench::boards::bench_file::load(&path).unwrap();
    assert_eq!(bench.chip, "STM32F103C8");

    std::fs::write(&path, "chip = \"mine\"\n").unwrap();
    let out = host_bench(dir.path()).arg("init-bench").output().unwrap();
    assert!(!out.status.success());
    assert!(text(&out).1.contains("--force"));
    assert_eq!(std::fs::read_to_string(&path).unwrap(), "chip = \"mine\"\n");

    let out = host_bench(dir.path())
        .args(["init-bench", "--force", "--out", "bench.toml"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", text(&out).1);
    assert!(host_bench::boards::bench_file::load(&path).is_ok());
    // Only bench.toml is left: the temporary file was renamed, not copied.
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
}

#[test]
fn flash_refuses_a_bench_file_with_an_unknown_key_naming_it_and_its_line() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("bench.toml"),
        "chip = \"STM32F103C8\"\n\n[slave]\nprobe = \"0483:3748\"\nelf = \"x\"\n",
    )
    .unwrap();
    let out = host_bench(dir.path()).arg("flash").output().unwrap();
    let (_, stderr) = text(&out);
    assert!(!out.status.success());
    assert!(
        stderr.contains("bench.toml:5") && stderr.contains("elf"),
        "{stderr}"
    );
}
