//! Probe selection and flashing against probe-rs' fake probes: no USB device is opened.
//!
//! A custom `ProbeLister` hands out `DebugProbeInfo`s whose factory opens a
//! `probe_rs::integration::FakeProbe` with a mocked Cortex-M core, so the same code path as
//! `host-bench flash` runs: plan (selection, image checks), open, attach to the STM32F103C8,
//! load the real firmware ELF and let probe-rs plan the flash download in dry-run mode.

use std::fmt;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

use host_bench::boards::flashing::{flash_all, FlashSettings};
use host_bench::boards::identity::Verdict;
use host_bench::boards::plan::{plan, FlashRequest};
use host_bench::boards::selection::{assign, resolve, ProbeSpec, SelectError};
use host_bench::boards::Board;
use probe_rs::integration::{FakeProbe, ProbeLister};
use probe_rs::probe::list::{Accessibility, Lister, ProbeListItem};
use probe_rs::probe::{
    DebugProbe, DebugProbeError, DebugProbeInfo, DebugProbeSelector, ProbeFactory,
};

/// Opens every fake probe as a FakeProbe with a mocked core.
#[derive(Debug)]
struct FakeFactory;

impl fmt::Display for FakeFactory {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("fake")
    }
}

impl ProbeFactory for FakeFactory {
    fn open(&self, _: &DebugProbeSelector) -> Result<Box<dyn DebugProbe>, DebugProbeError> {
        Ok(Box::new(FakeProbe::with_mocked_core()))
    }

    fn list_probes(&self) -> Vec<ProbeListItem> {
        Vec::new()
    }
}

static FAKE_FACTORY: FakeFactory = FakeFactory;

#[derive(Debug)]
struct FakeLister(Vec<ProbeListItem>);

impl ProbeLister for FakeLister {
    fn open(
        &self,
        selector: &DebugProbeSelector,
    ) -> Result<probe_rs::probe::Probe, DebugProbeError> {
        let item = self
            .0
            .iter()
            .find(|i| selector.matches_probe(&i.info))
            .ok_or(DebugProbeError::ProbeCouldNotBeCreated(
                probe_rs::probe::ProbeCreationError::NotFound,
            ))?;
        item.info.open()
    }

    fn list_with_access(&self, selector: Option<&DebugProbeSelector>) -> Vec<ProbeListItem> {
        self.0
            .iter()
            .filter(|i| selector.is_none_or(|s| s.matches_probe(&i.info)))
            .cloned()
            .collect()
    }
}

fn fake(name: &str, vid: u16, pid: u16, serial: &str) -> ProbeListItem {
    ProbeListItem::accessible(DebugProbeInfo::new(
        name,
        vid,
        pid,
        Some(serial.to_string()),
        &FAKE_FACTORY,
        None,
        false,
    ))
}

fn stlink(serial: &str) -> ProbeListItem {
    fake("STLink V2", 0x0483, 0x3748, serial)
}

fn lister(items: Vec<ProbeListItem>) -> Lister {
    Lister::with_lister(Box::new(FakeLister(items)))
}

fn spec(s: &str) -> Option<ProbeSpec> {
    Some(s.parse().unwrap())
}

fn serial_of(item: &ProbeListItem) -> &str {
    item.info.serial_number.as_deref().unwrap()
}

#[test]
fn each_board_gets_the_probe_its_serial_names_among_several() {
    let attached = vec![
        stlink("AAA1"),
        stlink("BBB2"),
        fake("CMSIS-DAP", 0xc251, 0xf001, "CCC3"),
    ];
    let chosen = assign(
        &[
            (Board::Slave, spec("CCC3")),
            (Board::Master, spec("0483:3748:AAA1")),
        ],
        &attached,
    )
    .unwrap();
    assert_eq!(chosen[0].0, Board::Slave);
    assert_eq!(serial_of(&chosen[0].1), "CCC3");
    assert_eq!(serial_of(&chosen[1].1), "AAA1");
}

#[test]
fn a_bare_serial_resolves_to_vid_pid_serial() {
    let attached = vec![stlink("AAA1"), fake("CMSIS-DAP", 0xc251, 0xf001, "CCC3")];
    let item = resolve(Board::Slave, &"CCC3".parse().unwrap(), &attached).unwrap();
    assert_eq!(
        host_bench::boards::selection::selector_text(&item.info),
        "c251:f001:CCC3"
    );
    // And the resolved selector is one probe-rs itself opens exactly this probe with.
    let selector = host_bench::boards::selection::selector_of(&item.info);
    assert_eq!(lister(attached).list(Some(&selector)), vec![item.info]);
}

#[test]
fn one_probe_left_over_goes_to_the_board_without_a_selector() {
    let attached = vec![stlink("AAA1"), stlink("BBB2")];
    let chosen = assign(
        &[(Board::Slave, spec("BBB2")), (Board::Master, None)],
        &attached,
    )
    .unwrap();
    assert_eq!(serial_of(&chosen[1].1), "AAA1");
}

#[test]
fn two_probes_and_no_selector_is_refused_with_the_list_and_what_to_pass() {
    let attached = vec![stlink("AAA1"), stlink("BBB2")];
    let err = assign(&[(Board::Slave, None), (Board::Master, None)], &attached).unwrap_err();
    assert!(matches!(err, SelectError::Ambiguous { .. }), "{err:?}");
    let text = err.to_string();
    for needle in [
        "0483:3748:AAA1",
        "0483:3748:BBB2",
        "--slave-probe",
        "bench.toml",
    ] {
        assert!(text.contains(needle), "{needle:?} missing from: {text}");
    }
    // One board wanted, still two candidates: also refused, never guessed.
    let err = assign(&[(Board::Master, None)], &attached).unwrap_err();
    assert!(err.to_string().contains("--master-probe"), "{err}");
}

#[test]
fn a_serial_not_attached_lists_what_is() {
    let attached = vec![stlink("AAA1"), stlink("BBB2")];
    let err = assign(
        &[(Board::Slave, spec("ZZZ9")), (Board::Master, spec("AAA1"))],
        &attached,
    )
    .unwrap_err();
    let text = err.to_string();
    assert!(
        matches!(
            err,
            SelectError::NotFound {
                board: Board::Slave,
                ..
            }
        ),
        "{text}"
    );
    assert!(
        text.contains("ZZZ9") && text.contains("AAA1") && text.contains("BBB2"),
        "{text}"
    );
}

#[test]
fn clones_sharing_a_serial_are_reported_not_picked_at_random() {
    let attached = vec![stlink("CLONE"), stlink("CLONE")];
    let err = assign(&[(Board::Slave, spec("CLONE"))], &attached).unwrap_err();
    let text = err.to_string();
    assert!(matches!(err, SelectError::NotUnique { .. }), "{text}");
    assert!(
        text.contains("identical") && text.contains("VID:PID:SERIAL"),
        "{text}"
    );
    // Spelling out VID:PID:SERIAL does not help when those are identical too.
    let err = assign(&[(Board::Slave, spec("0483:3748:CLONE"))], &attached).unwrap_err();
    assert!(matches!(err, SelectError::NotUnique { .. }), "{err}");
}

#[test]
fn the_same_probe_for_both_boards_and_missing_probes_are_refused() {
    let attached = vec![stlink("AAA1"), stlink("BBB2")];
    let err = assign(
        &[
            (Board::Slave, spec("AAA1")),
            (Board::Master, spec("0483:3748:AAA1")),
        ],
        &attached,
    )
    .unwrap_err();
    assert!(matches!(err, SelectError::SameProbe { .. }), "{err}");
    let err = assign(
        &[(Board::Slave, None), (Board::Master, None)],
        &[stlink("AAA1")],
    )
    .unwrap_err();
    assert!(matches!(err, SelectError::TooFewProbes { .. }), "{err}");
    let err = assign(&[(Board::Slave, None)], &[]).unwrap_err();
    assert_eq!(
        err.to_string(),
        "no debug probe found; `host-bench probes` lists what is attached"
    );
}

#[test]
fn a_probe_this_user_may_not_open_names_the_udev_rule() {
    let mut item = stlink("AAA1");
    item.accessibility = Accessibility::PermissionDenied;
    let err = assign(&[(Board::Slave, None)], &[item]).unwrap_err();
    assert!(err.to_string().contains("69-probe-rs.rules"), "{err}");
}

/// The real firmware image of `board`: from `$OMNIBENCH_FIRMWARE_DIR` if set (a folder holding
/// already-built release images, as `.ci/run` does so as not to build them twice), otherwise
/// built once per test run into its own target folder (a build into the shared one would wait
/// forever on the lock `cargo test` itself holds).
fn firmware_image(board: Board) -> PathBuf {
    static BUILT: OnceLock<Result<PathBuf, String>> = OnceLock::new();
    let dir = BUILT.get_or_init(|| {
        if let Some(dir) = std::env::var_os("OMNIBENCH_FIRMWARE_DIR") {
            return Ok(PathBuf::from(dir));
        }
        let workspace = Path::new(env!("CARGO_MANIFEST_DIR")).parent().unwrap();
        let target = std::env::var_os("CARGO_TARGET_DIR")
            .map(PathBuf::from)
            .unwrap_or_else(|| workspace.join("target"))
            .join("fw-for-tests");
        let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
        let out = Command::new(cargo)
            .current_dir(workspace)
            .args([
                "build",
                "--locked",
                "--release",
                "--target",
                "thumbv7m-none-eabi",
            ])
            .args([
                "-p",
                "firmware-slave",
                "-p",
                "firmware-master",
                "--target-dir",
            ])
            .arg(&target)
            .output()
            .map_err(|e| format!("cannot run cargo: {e}"))?;
        if !out.status.success() {
            return Err(format!(
                "building the firmware failed:\n{}",
                String::from_utf8_lossy(&out.stderr)
            ));
        }
        Ok(target.join("thumbv7m-none-eabi/release"))
    });
    // No image means a failed test, never a skipped one.
    let path = dir.as_ref().unwrap().join(board.package());
    assert!(path.is_file(), "{} was not built", path.display());
    path
}

#[test]
fn a_dry_run_flashes_the_real_images_through_fake_probes() {
    let request = FlashRequest {
        boards: Board::BOTH.to_vec(),
        slave_probe: spec("SLAVE1"),
        master_probe: spec("0483:374b:MASTER2"),
        slave_elf: Some(firmware_image(Board::Slave)),
        master_elf: Some(firmware_image(Board::Master)),
        ..FlashRequest::default()
    };
    let attached = lister(vec![
        stlink("SLAVE1"),
        fake("STLink V2-1", 0x0483, 0x374b, "MASTER2"),
        stlink("SPARE"),
    ]);
    let jobs = plan(&request, &attached).unwrap();
    assert_eq!(jobs.len(), 2);
    assert_eq!(jobs[0].chip, "STM32F103C8");
    let settings = FlashSettings {
        verify: true,
        dry_run: true,
    };
    for (board, outcome) in flash_all(jobs, settings, Vec::new()) {
        let flashed = outcome.unwrap_or_else(|e| panic!("{board}: {e}"));
        // The mocked core reads every register as 0: the ID check must say it could not
        // judge, not claim the chip matched.
        assert!(
            matches!(flashed.identity, Verdict::Unchecked(_)),
            "{:?}",
            flashed.identity
        );
        // probe-rs loaded the ELF's flash sections: both images are tens of KiB, under 64.
        assert!(
            (8 * 1024..=64 * 1024).contains(&flashed.planned_bytes),
            "{board}: {} bytes planned",
            flashed.planned_bytes
        );
        assert_eq!(flashed.session.target().name, "STM32F103C8");
    }
}

#[test]
fn the_plan_reports_a_missing_image_and_a_missing_probe_together() {
    let dir = tempfile::tempdir().unwrap();
    let request = FlashRequest {
        boards: vec![Board::Slave],
        target_dir: Some(dir.path().to_path_buf()),
        ..FlashRequest::default()
    };
    let err = plan(&request, &lister(Vec::new())).unwrap_err();
    assert!(
        err.contains("cargo build --release --target thumbv7m-none-eabi -p firmware-slave"),
        "{err}"
    );
    assert!(err.contains("no debug probe found"), "{err}");
}

#[test]
fn the_real_images_carry_a_defmt_table_and_an_rtt_block() {
    for board in Board::BOTH {
        let source =
            host_bench::boards::rtt_log::log_source(board, &firmware_image(board)).unwrap();
        assert!(
            source.control_block.is_some(),
            "{board}: no _SEGGER_RTT symbol"
        );
        assert!(!source.table.is_empty(), "{board}: empty defmt table");
    }
}

#[test]
fn a_dry_run_refuses_an_image_larger_than_the_chips_flash() {
    // The master's image planned for the 32 KiB STM32F103C6: probe-rs' plan must not fit, which
    // shows the dry run really lays the ELF out against the chip's memory map. (The slave's
    // code and data fit 32 KiB of flash since issue 11; the master's do not.)
    let request = FlashRequest {
        boards: vec![Board::Master],
        master_elf: Some(firmware_image(Board::Master)),
        chip: Some("STM32F103C6".into()),
        ..FlashRequest::default()
    };
    let jobs = plan(&request, &lister(vec![stlink("ONLY")])).unwrap();
    let settings = FlashSettings {
        verify: true,
        dry_run: true,
    };
    let (board, outcome) = flash_all(jobs, settings, Vec::new()).pop().unwrap();
    let Err(err) = outcome else {
        panic!("the master's image was planned into 32 KiB");
    };
    // The cause, not only probe-rs' "an error with the flashing procedure has occurred".
    assert!(
        err.starts_with("master:") && err.contains("STM32F103C6") && err.contains("0x080"),
        "{board}: {err}"
    );
}
