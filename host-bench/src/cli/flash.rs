//! `probes`, `init-bench` and `flash`: the real boards (docs/bench.md).

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::sync::Mutex;

use anyhow::{anyhow, bail};
use host_bench::boards::bench_file::{self, BenchDraft, DEFAULT_BAUD, DEFAULT_CHIP};
use host_bench::boards::discovery::{self, Inventory};
use host_bench::boards::flashing::{self, FlashSettings, Flashed, ProgressSink};
use host_bench::boards::identity::Verdict;
use host_bench::boards::plan::{self, FlashRequest};
use host_bench::boards::selection::{selector_text, ProbeSpec};
use host_bench::boards::{images, rtt_log, Board};
use indicatif::{MultiProgress, ProgressBar, ProgressDrawTarget, ProgressStyle};
use probe_rs::flashing::{ProgressEvent, ProgressOperation};
use probe_rs::probe::list::Lister;
use serde_json::json;

/// `host-bench probes`: what is attached.
pub fn run_probes(json: bool) -> anyhow::Result<()> {
    let inventory = discovery::inventory(&Lister::new());
    if json {
        println!("{}", serde_json::to_string(&inventory)?);
    } else {
        print!("{}", discovery::inventory_text(&inventory));
    }
    Ok(())
}

/// `host-bench init-bench`: a bench.toml from what is attached, with what was guessed.
pub fn run_init_bench(out: PathBuf, force: bool) -> anyhow::Result<()> {
    let inventory = discovery::inventory(&Lister::new());
    let draft = draft_from(&inventory);
    bench_file::write_atomically(&out, &bench_file::render(&draft), force)
        .map_err(|e| anyhow!(e))?;
    eprintln!("wrote {}", out.display());
    eprint!("{}", guesses_text(&inventory, &draft));
    Ok(())
}

// First probe listed → slave, second → master, first USB serial port → the master's link.
fn draft_from(inventory: &Inventory) -> BenchDraft {
    BenchDraft {
        chip: DEFAULT_CHIP.to_string(),
        slave_probe: inventory.probes.first().map(|p| p.selector.clone()),
        master_probe: inventory.probes.get(1).map(|p| p.selector.clone()),
        link_port: inventory
            .serial_ports
            .iter()
            .find(|s| s.is_usb())
            .map(|s| s.path.clone()),
        baud: DEFAULT_BAUD,
    }
}

fn guesses_text(inventory: &Inventory, draft: &BenchDraft) -> String {
    let mut out = String::new();
    for (board, probe) in [(Board::Slave, 0), (Board::Master, 1)] {
        match inventory.probes.get(probe) {
            Some(p) => out.push_str(&format!(
                "  {board:<6} probe {} ({}): guessed from the listing order; check that this \
                 probe is wired to the {board} (unplug it and see which one `host-bench \
                 probes` stops listing)\n",
                p.selector, p.name
            )),
            None => out.push_str(&format!(
                "  {board:<6} probe: none found; attach it and set [{board}] probe (see \
                 `host-bench probes`)\n"
            )),
        }
    }
    if inventory.probes.len() > 2 {
        out.push_str(&format!(
            "  {} probes attached: only the first two were used\n",
            inventory.probes.len()
        ));
    }
    match &draft.link_port {
        Some(port) => out.push_str(&format!(
            "  link   {port} at {} baud: the first USB serial port; check it is the adapter \
             wired to the master's USART1 (PA9 TX, PA10 RX)\n",
            draft.baud
        )),
        None => out.push_str("  link: no USB serial port found; [link] left commented out\n"),
    }
    out
}

/// The `flash` subcommand's arguments.
#[derive(clap::Args, Debug)]
pub struct FlashArgs {
    /// Flash the slave (default: both boards).
    #[arg(long)]
    pub slave: bool,
    /// Flash the master (default: both boards).
    #[arg(long)]
    pub master: bool,
    /// Bench description [default: ./bench.toml if present].
    #[arg(long, value_name = "FILE")]
    pub bench: Option<PathBuf>,
    /// The slave's probe: VID:PID[:SERIAL] (hex ids) or a serial number.
    #[arg(long, value_name = "SEL")]
    pub slave_probe: Option<ProbeSpec>,
    /// The master's probe: VID:PID[:SERIAL] (hex ids) or a serial number.
    #[arg(long, value_name = "SEL")]
    pub master_probe: Option<ProbeSpec>,
    /// The slave's image [default: <target>/thumbv7m-none-eabi/release/firmware-slave].
    #[arg(long, value_name = "ELF")]
    pub slave_elf: Option<PathBuf>,
    /// The master's image [default: <target>/thumbv7m-none-eabi/release/firmware-master].
    #[arg(long, value_name = "ELF")]
    pub master_elf: Option<PathBuf>,
    /// probe-rs chip name [default: bench.toml's, else STM32F103C8].
    #[arg(long, value_name = "NAME")]
    pub chip: Option<String>,
    /// Skip reading the flash back after programming.
    #[arg(long)]
    pub no_verify: bool,
    /// Attach and plan the download, write nothing, leave the boards running.
    #[arg(long, conflicts_with = "rtt")]
    pub dry_run: bool,
    /// Afterwards print both boards' defmt logs over RTT, prefixed [slave] / [master],
    /// until Ctrl-C.
    #[arg(long, conflicts_with = "json")]
    pub rtt: bool,
    /// Print {"boards":[{board, ok, chip, bytes, seconds, verified, dry_run, identity} or
    /// {board, ok:false, error}]}.
    #[arg(long)]
    pub json: bool,
}

/// `host-bench flash`: both boards (or one) through their probes, in parallel.
pub fn run_flash(args: FlashArgs) -> anyhow::Result<()> {
    let boards: Vec<Board> = match (args.slave, args.master) {
        (false, false) | (true, true) => Board::BOTH.to_vec(),
        (true, false) => vec![Board::Slave],
        (false, true) => vec![Board::Master],
    };
    let bench = match &args.bench {
        Some(path) => Some(bench_file::load(path)?),
        None if Path::new("bench.toml").is_file() => {
            if !args.json {
                eprintln!("using ./bench.toml");
            }
            Some(bench_file::load(Path::new("bench.toml"))?)
        }
        None => None,
    };
    let cwd = std::env::current_dir()?;
    let target_dir = std::env::var("CARGO_TARGET_DIR").ok();
    let request = FlashRequest {
        boards,
        bench,
        slave_probe: args.slave_probe,
        master_probe: args.master_probe,
        slave_elf: args.slave_elf,
        master_elf: args.master_elf,
        chip: args.chip,
        target_dir: images::target_dir(target_dir.as_deref(), &cwd),
    };
    let jobs = plan::plan(&request, &Lister::new()).map_err(|e| anyhow!(e))?;
    if !args.json {
        for job in &jobs {
            eprintln!(
                "{}: {} via {} ({}), image {}",
                job.board,
                job.chip,
                selector_text(&job.probe),
                job.probe.identifier,
                job.image.display()
            );
        }
    }
    let images: Vec<(Board, PathBuf)> = jobs.iter().map(|j| (j.board, j.image.clone())).collect();
    let bars = if args.json {
        MultiProgress::with_draw_target(ProgressDrawTarget::hidden())
    } else {
        // Drawn on stderr, and only when it is a terminal.
        MultiProgress::new()
    };
    let sinks = jobs.iter().map(|j| progress_sink(&bars, j.board)).collect();
    let settings = FlashSettings {
        verify: !args.no_verify,
        dry_run: args.dry_run,
    };
    let outcomes = flashing::flash_all(jobs, settings, sinks);
    bars.clear().ok();
    report(&outcomes, settings, args.json)?;
    let failures: Vec<&String> = outcomes
        .iter()
        .filter_map(|(_, o)| o.as_ref().err())
        .collect();
    if !failures.is_empty() {
        bail!(
            "{}",
            failures
                .iter()
                .map(|f| f.as_str())
                .collect::<Vec<_>>()
                .join("\n")
        );
    }
    if args.rtt {
        let flashed: Vec<Flashed> = outcomes.into_iter().filter_map(|(_, o)| o.ok()).collect();
        follow_logs(flashed, &images)?;
    }
    Ok(())
}

fn report(
    outcomes: &[(Board, Result<Flashed, String>)],
    settings: FlashSettings,
    json: bool,
) -> anyhow::Result<()> {
    if json {
        let boards: Vec<_> = outcomes
            .iter()
            .map(|(board, outcome)| match outcome {
                Ok(f) => json!({
                    "board": board.name(),
                    "ok": true,
                    "chip": f.session.target().name,
                    "bytes": f.planned_bytes,
                    "seconds": f.elapsed.as_secs_f64(),
                    "verified": settings.verify && !settings.dry_run,
                    "dry_run": settings.dry_run,
                    "identity": identity_text(&f.identity),
                }),
                Err(e) => json!({"board": board.name(), "ok": false, "error": e}),
            })
            .collect();
        println!("{}", json!({ "boards": boards }));
        return Ok(());
    }
    for (board, outcome) in outcomes {
        let Ok(f) = outcome else { continue };
        if let Verdict::Unchecked(why) = &f.identity {
            eprintln!("{board}: chip not identified ({why})");
        }
        if settings.dry_run {
            println!(
                "{board}: dry run: {} bytes planned for the {}, nothing written ({:.1} s)",
                f.planned_bytes,
                f.session.target().name,
                f.elapsed.as_secs_f64()
            );
        } else {
            println!(
                "{board}: flashed {} bytes{} in {:.1} s, reset and running",
                f.planned_bytes,
                if settings.verify { ", verified," } else { "" },
                f.elapsed.as_secs_f64()
            );
        }
    }
    Ok(())
}

fn identity_text(v: &Verdict) -> String {
    match v {
        Verdict::Matches => "matches".into(),
        Verdict::Unchecked(why) => format!("unchecked: {why}"),
        Verdict::Mismatch(what) => format!("mismatch: {what}"),
    }
}

// One bar per flashing phase and board, made when probe-rs announces the phase.
fn progress_sink(bars: &MultiProgress, board: Board) -> ProgressSink {
    let bars = bars.clone();
    let style = ProgressStyle::with_template(
        "{prefix:<16} {bar:30} {bytes:>9}/{total_bytes:<9} {elapsed:>4} {msg}",
    )
    .unwrap_or_else(|_| ProgressStyle::default_bar());
    let mut phases: [Option<ProgressBar>; 4] = Default::default();
    let index = |op: ProgressOperation| match op {
        ProgressOperation::Fill => 0,
        ProgressOperation::Erase => 1,
        ProgressOperation::Program => 2,
        ProgressOperation::Verify => 3,
    };
    let name = |op: ProgressOperation| match op {
        ProgressOperation::Fill => "fill",
        ProgressOperation::Erase => "erase",
        ProgressOperation::Program => "program",
        ProgressOperation::Verify => "verify",
    };
    Box::new(move |event| match event {
        ProgressEvent::AddProgressBar { operation, total } => {
            let bar = bars.add(ProgressBar::new(total.unwrap_or(0)).with_style(style.clone()));
            bar.set_prefix(format!("[{board}] {}", name(operation)));
            phases[index(operation)] = Some(bar);
        }
        ProgressEvent::Progress {
            operation, size, ..
        } => {
            if let Some(bar) = &phases[index(operation)] {
                bar.inc(size);
            }
        }
        ProgressEvent::Finished(operation) => {
            if let Some(bar) = &phases[index(operation)] {
                bar.finish();
            }
        }
        ProgressEvent::Failed(operation) => {
            if let Some(bar) = &phases[index(operation)] {
                bar.abandon_with_message("failed");
            }
        }
        _ => {}
    })
}

// Both boards' defmt logs, one thread each, until Ctrl-C ends the process.
fn follow_logs(flashed: Vec<Flashed>, images: &[(Board, PathBuf)]) -> anyhow::Result<()> {
    let mut sources = Vec::new();
    for f in &flashed {
        let image = images
            .iter()
            .find(|(b, _)| *b == f.board)
            .map(|(_, p)| p.clone())
            .ok_or_else(|| anyhow!("{}: no image recorded", f.board))?;
        sources.push(rtt_log::log_source(f.board, &image).map_err(|e| anyhow!(e))?);
    }
    eprintln!("reading the boards' defmt logs over RTT; Ctrl-C to stop");
    // Never set here: Ctrl-C ends the process (the boards keep running). The flag exists for
    // callers that stop the readers themselves.
    let stop = AtomicBool::new(false);
    let stdout = Mutex::new(());
    let emit = |line: String| {
        // One lock per line, so the two boards' lines never interleave mid-line.
        let _guard = stdout.lock();
        println!("{line}");
    };
    let errors: Vec<String> = std::thread::scope(|scope| {
        let handles: Vec<_> = flashed
            .into_iter()
            .zip(&sources)
            .map(|(mut f, source)| {
                let (stop, emit) = (&stop, &emit);
                scope.spawn(move || {
                    let result = rtt_log::follow(f.board, &mut f.session, source, stop, emit);
                    // Said at once: the other board's log goes on until Ctrl-C.
                    if let Err(e) = &result {
                        eprintln!("error: {e}");
                    }
                    result
                })
            })
            .collect();
        handles
            .into_iter()
            .filter_map(|h| match h.join() {
                Ok(Ok(())) => None,
                Ok(Err(e)) => Some(e),
                Err(_) => Some("an RTT reader panicked".to_string()),
            })
            .collect()
    });
    if !errors.is_empty() {
        bail!("{}", errors.join("\n"));
    }
    Ok(())
}
