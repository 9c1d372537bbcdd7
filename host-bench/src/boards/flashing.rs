//! Flashing the boards: for each, open its probe, attach to the chip, check the chip's
//! identity, download the ELF (erase, program, verify), then reset and run — each board on its
//! own thread, so two boards take as long as the slower one.
//!
//! Probes are opened through the [`DebugProbeInfo`] a probe-rs `Lister` returned, so the probe-rs
//! driver that found a probe is the one that opens it, and tests hand in fake probes through a
//! custom lister.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use probe_rs::flashing::{DownloadOptions, ElfLoader, ElfOptions, FlashProgress, ProgressEvent};
use probe_rs::probe::DebugProbeInfo;
use probe_rs::{MemoryInterface, Permissions, Session};

use super::identity::{self, Verdict};
use super::selection::{selector_text, UDEV_HELP};
use super::Board;

/// One board to flash: its probe (as listed), its image and its chip.
#[derive(Clone, Debug)]
pub struct FlashJob {
    pub board: Board,
    pub probe: DebugProbeInfo,
    pub image: PathBuf,
    pub chip: String,
}

/// How to flash.
#[derive(Clone, Copy, Debug)]
pub struct FlashSettings {
    /// Read the flash back after programming and compare.
    pub verify: bool,
    /// Attach, identify and plan the download (which sectors, which flash algorithm) but write
    /// nothing and leave the board running as it was.
    pub dry_run: bool,
}

/// A board flashed (or planned, in a dry run), with the session still attached for RTT.
pub struct Flashed {
    pub board: Board,
    pub session: Session,
    pub identity: Verdict,
    /// Bytes of the image's loadable sections (what is written, before sector padding).
    pub planned_bytes: u64,
    pub elapsed: Duration,
}

/// Receives probe-rs' flashing progress for one board (drawn as progress bars by the CLI).
pub type ProgressSink = Box<dyn FnMut(ProgressEvent) + Send>;

/// Checks a chip name against probe-rs' built-in chip list; the error suggests close names.
pub fn check_chip_name(chip: &str) -> Result<(), String> {
    let registry = probe_rs::config::Registry::from_builtin_families();
    match registry.get_target_by_name(chip) {
        Ok(_) => Ok(()),
        Err(e) => {
            let stem: String = chip.chars().take(7).collect();
            let mut close = registry.search_chips(&stem);
            close.truncate(8);
            let hint = if close.is_empty() {
                String::new()
            } else {
                format!(
                    "; chips probe-rs knows that start alike: {}",
                    close.join(", ")
                )
            };
            Err(format!("chip {chip:?} is not usable: {e}{hint}"))
        }
    }
}

/// Flashes every job, one thread per board, and returns each board's outcome in job order.
/// One board failing does not stop the other.
pub fn flash_all(
    jobs: Vec<FlashJob>,
    settings: FlashSettings,
    mut sinks: Vec<ProgressSink>,
) -> Vec<(Board, Result<Flashed, String>)> {
    std::thread::scope(|scope| {
        let handles: Vec<_> = jobs
            .into_iter()
            .map(|job| {
                let sink = if sinks.is_empty() {
                    Box::new(|_| {}) as ProgressSink
                } else {
                    sinks.remove(0)
                };
                let board = job.board;
                (board, scope.spawn(move || flash_one(&job, settings, sink)))
            })
            .collect();
        handles
            .into_iter()
            .map(|(board, handle)| {
                let outcome = handle.join().unwrap_or_else(|panic| {
                    // probe-rs drivers are not supposed to panic; if one does, report it as
                    // this board's failure rather than take the other board down with it.
                    let what = panic
                        .downcast_ref::<String>()
                        .cloned()
                        .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
                        .unwrap_or_default();
                    Err(format!("the {board}'s flashing thread panicked: {what}"))
                });
                (board, outcome)
            })
            .collect()
    })
}

/// Flashes one board; the error names the board, the probe and what to check.
pub fn flash_one(
    job: &FlashJob,
    settings: FlashSettings,
    progress: ProgressSink,
) -> Result<Flashed, String> {
    let started = Instant::now();
    let board = job.board;
    let probe_name = format!("{} ({})", selector_text(&job.probe), job.probe.identifier);
    let probe = job
        .probe
        .open()
        .map_err(|e| explain_open_error(board, &probe_name, &e))?;
    let mut session = probe
        .attach(job.chip.as_str(), Permissions::default())
        .map_err(|e| {
            format!(
                "{board}: cannot attach to the {} through {probe_name}: {}; check the SWD \
                 wiring (SWDIO, SWCLK, GND) and that the board is powered",
                job.chip,
                error_chain(&e)
            )
        })?;
    let identity = read_identity(&mut session, &job.chip);
    if let Verdict::Mismatch(what) = &identity {
        return Err(format!(
            "{board}: the board on {probe_name} is not a {}: {what}",
            job.chip
        ));
    }
    let elf = ElfLoader(ElfOptions::default());
    let loader =
        probe_rs::flashing::build_loader(&mut session, &job.image, elf, None).map_err(|e| {
            format!(
                "{board}: cannot prepare {} for the {}: {}",
                job.image.display(),
                job.chip,
                error_chain(&e)
            )
        })?;
    let planned_bytes = loader.data().map(|(_, data)| data.len() as u64).sum();
    let mut options = DownloadOptions::new();
    options.verify = settings.verify;
    options.dry_run = settings.dry_run;
    options.progress = FlashProgress::new(progress);
    loader.commit(&mut session, options).map_err(|e| {
        format!(
            "{board}: flashing {} through {probe_name} failed: {}",
            job.image.display(),
            error_chain(&e)
        )
    })?;
    if !settings.dry_run {
        session
            .core(0)
            .and_then(|mut core| core.reset())
            .map_err(|e| {
                format!(
                    "{board}: flashed, but resetting it failed: {}",
                    error_chain(&e)
                )
            })?;
    }
    Ok(Flashed {
        board,
        session,
        identity,
        planned_bytes,
        elapsed: started.elapsed(),
    })
}

// CPUID and DBGMCU_IDCODE, judged. A register that cannot be read leaves the chip unchecked
// (with the reason) rather than stopping the flash: the IDs are a safety net, not a gate.
fn read_identity(session: &mut Session, chip: &str) -> Verdict {
    if identity::expected_for(chip).is_none() {
        return identity::judge(chip, 0, 0);
    }
    let mut core = match session.core(0) {
        Ok(core) => core,
        Err(e) => {
            return Verdict::Unchecked(format!("could not reach the core to identify it: {e}"))
        }
    };
    let cpuid = core.read_word_32(identity::CPUID_ADDR);
    let idcode = core.read_word_32(identity::DBGMCU_IDCODE_ADDR);
    match (cpuid, idcode) {
        (Ok(cpuid), Ok(idcode)) => identity::judge(chip, cpuid, idcode),
        (Err(e), _) | (_, Err(e)) => {
            Verdict::Unchecked(format!("could not read the chip's ID registers: {e}"))
        }
    }
}

fn explain_open_error(
    board: Board,
    probe_name: &str,
    error: &probe_rs::probe::DebugProbeError,
) -> String {
    let mut denied = false;
    let mut source: Option<&(dyn std::error::Error + 'static)> = Some(error);
    while let Some(e) = source {
        if let Some(io) = e.downcast_ref::<std::io::Error>() {
            denied |= io.kind() == std::io::ErrorKind::PermissionDenied;
        }
        denied |= e
            .to_string()
            .to_ascii_lowercase()
            .contains("permission denied");
        source = e.source();
    }
    if denied {
        format!("{board}: permission denied opening {probe_name}; {UDEV_HELP}")
    } else {
        format!(
            "{board}: cannot open {probe_name}: {} (is another program, e.g. a debugger \
             or `probe-rs run`, using it?)",
            error_chain(error)
        )
    }
}

/// An error and its sources on one line: probe-rs' top-level messages ("An error with the
/// flashing procedure has occurred") say little; the cause is in the chain.
pub fn error_chain(error: &(dyn std::error::Error + 'static)) -> String {
    let mut text = error.to_string();
    let mut source = error.source();
    while let Some(e) = source {
        let part = e.to_string();
        // Some wrappers repeat their source's text; print each message once.
        if !text.contains(&part) {
            text.truncate(text.trim_end_matches('.').len());
            text.push_str(": ");
            text.push_str(&part);
        }
        source = e.source();
    }
    text
}
