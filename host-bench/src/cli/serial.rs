//! The serial-bench commands: `play` and `record` (`virtual-board` is in `virtual_board.rs`).

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use clap::Args;
use firmware_slave::played::PlayKind;
use host_bench::boards::bench_file;
use host_bench::formats::{robot::Robot, tickstream};
use host_bench::serial::{clock, link::Link, play, played_stream, record};
use host_bench::viewer::{topics, Outputs, ViewArgs};

/// Where the master's serial link is: --port/--baud, else bench.toml's `[link]`.
#[derive(Args, Clone, Debug)]
pub struct PortArgs {
    /// Serial port of the master's USART1 (a USB-serial adapter, or virtual-board's pty), or
    /// `uid:ID`: the own USB port of the master whose chip ID is ID (the image built with
    /// `--features usb`; `host-bench probes` lists it) [default: bench.toml's link.port].
    #[arg(long, value_name = "PORT")]
    pub port: Option<String>,
    /// Baud rate to switch the link to once the master answers at its power-on 115200 (up to
    /// 4500000; USB-serial adapters reach 2000000 to 3000000). If the master does not answer
    /// at the new rate, both go back to 115200 and the run goes on, saying so
    /// [default: bench.toml's link.baud, else 115200].
    #[arg(long, value_name = "N")]
    pub baud: Option<u32>,
    /// Bench description [default: ./bench.toml if present].
    #[arg(long, value_name = "FILE")]
    pub bench: Option<PathBuf>,
    /// Wait this many times longer for the board (1 to 100): the handshake's and each
    /// setting's 3 s, play's 5 s without progress, the 50 ms before unacknowledged events are
    /// sent again. For a board slower than real time that has no clock to give (the chip model
    /// and `virtual-board` have: `--clock`).
    #[arg(long, value_name = "FACTOR", default_value_t = 1)]
    pub patience: u32,
    /// Take the host's time from a board model's clock file (the `clock: FILE` line that
    /// `scripts/board-model serve` or `host-bench virtual-board` prints) instead of the wall
    /// clock: every wait, pace and duration is then in the modelled boards' own time, whatever
    /// speed the model runs at.
    #[arg(long, value_name = "FILE")]
    pub clock: Option<PathBuf>,
}

impl PortArgs {
    pub fn open(&self) -> Result<Link> {
        let bench = match &self.bench {
            Some(p) => Some(bench_file::load(p)?),
            None if Path::new("bench.toml").exists() => {
                Some(bench_file::load(Path::new("bench.toml"))?)
            }
            None => None,
        };
        let link = bench.as_ref().and_then(|b| b.link.clone());
        let Some(port) = self.port.clone().or(link.as_ref().map(|l| l.port.clone())) else {
            bail!(
                "no serial port: pass --port PORT (`host-bench probes` lists them) or set \
                 [link] port in bench.toml (docs/bench.md)"
            );
        };
        let baud = self.baud.or(link.map(|l| l.baud)).unwrap_or(115_200);
        if baud == 0 {
            bail!("--baud must be positive");
        }
        if !(1..=100).contains(&self.patience) {
            bail!(
                "--patience is a factor from 1 to 100: got {}",
                self.patience
            );
        }
        // `uid:ID`: the USB port of the master whose chip ID that is.
        let port = if port.starts_with("uid:") {
            let ports =
                host_bench::boards::discovery::serial_ports().map_err(anyhow::Error::msg)?;
            host_bench::boards::discovery::resolve_port(&port, &ports)
                .map_err(anyhow::Error::msg)?
        } else {
            port
        };
        if let Some(file) = &self.clock {
            clock::use_model_clock(file)?;
        }
        let link = Link::open(&port, baud)?.with_patience(self.patience);
        // What was done about the adapter's latency timer (ports that have one).
        if let Some(note) = &link.latency_note {
            eprintln!("note: {note}");
        }
        Ok(link)
    }
}

#[derive(Args, Debug)]
pub struct PlayArgs {
    #[command(flatten)]
    pub port: PortArgs,
    /// Tick stream to play (docs/tick-stream.md).
    #[arg(long, value_name = "FILE")]
    pub ticks: PathBuf,
    /// Robot description [default: the stream's `# robot:` line].
    #[arg(long, value_name = "FILE")]
    pub robot: Option<PathBuf>,
    /// What the slave is fed: every tick with its time stamp, or count samples at its update
    /// rate.
    #[arg(long, default_value = "timestamps", value_parser = ["timestamps", "counts"])]
    pub sensor: String,
    /// Odometry method the slave runs (exact, arc, lut, timing).
    #[arg(long, default_value = "exact")]
    pub algorithm: String,
    /// The board reports every N-th pose in full, and every pose of the last window; each
    /// report carries the running digest of every pose before it, so every update is still
    /// checked bit for bit. On a difference the window it lies in is played again with every
    /// pose reported, to name the first update that differs. 1: every pose in full.
    #[arg(long, value_name = "N", default_value_t = play::CHECK_EVERY,
          value_parser = clap::value_parser!(u16).range(1..))]
    pub check_every: u16,
    /// Print the outcome as one JSON object.
    #[arg(long)]
    pub json: bool,
    /// Fault injection: damage these Events frames (0-based indices, comma separated) on
    /// the way out; the link must recover them.
    #[arg(long, value_name = "K,..", value_delimiter = ',')]
    pub fault_corrupt_frames: Vec<u64>,
    /// Fault injection: do not send these Events frames at all.
    #[arg(long, value_name = "K,..", value_delimiter = ',')]
    pub fault_drop_frames: Vec<u64>,
    #[command(flatten)]
    pub view: ViewArgs,
}

pub fn run_play(a: PlayArgs) -> Result<()> {
    let method = play::method_from_name(&a.algorithm)?;
    let kind = if a.sensor == "counts" {
        PlayKind::Counts
    } else {
        PlayKind::Ticks
    };
    // A span play cannot take is refused at its line, before the board is asked.
    let stream = tickstream::read_checked(&a.ticks, &mut played_stream::span_check())?;
    let robot_path = match &a.robot {
        Some(p) => p.clone(),
        None => stream.robot_path(&a.ticks).with_context(|| {
            format!(
                "{}: no `# robot:` line; name the robot with --robot FILE",
                a.ticks.display()
            )
        })?,
    };
    let robot = Robot::load(&robot_path)?;
    robot
        .odometry_layout()
        .with_context(|| robot_path.display().to_string())?;
    // What is wrong with the rows is said before the port is opened (play checks again, for
    // its other callers).
    played_stream::check_rows(&stream, &robot)
        .map_err(|e| anyhow::anyhow!("{}: {e:#}", a.ticks.display()))?;
    // A file that cannot be written, a port taken: said before the board is asked.
    let mut outputs = Outputs::open(
        &a.view,
        topics::serial_channels(true),
        "host-bench play",
        &[&a.ticks, &robot_path],
    )?;
    let mut link = a.port.open()?;
    link.faults.corrupt = a.fault_corrupt_frames.clone();
    link.faults.drop = a.fault_drop_frames.clone();
    let bar = progress_bar("{bar:30} {pos}/{len} updates {elapsed}");
    let outcome = play::play(
        &mut link,
        &play::PlayRequest {
            ticks: &a.ticks,
            robot: &robot,
            method,
            kind,
            stream: &stream,
            check_every: a.check_every,
            progress: Some(&bar),
            view: Some(&outputs.view),
        },
    )?;
    bar.finish_and_clear();
    // A fault asked for a frame the play never sent was never injected: the run proves
    // nothing about it.
    let sent = link.stats.events_frames;
    for (flag, ks) in [
        ("--fault-corrupt-frames", &a.fault_corrupt_frames),
        ("--fault-drop-frames", &a.fault_drop_frames),
    ] {
        if let Some(k) = ks.iter().find(|&&k| k >= sent) {
            bail!(
                "{flag} {k}: this play sent {sent} Events frames (0 to {}), so frame {k} was \
                 never sent and nothing was injected",
                sent.saturating_sub(1)
            );
        }
    }
    if a.json {
        println!("{}", serde_json::to_string(&outcome)?);
    } else {
        let o = &outcome;
        println!(
            "{} on {} (robot {} {}), `{}` reading {}",
            a.ticks.display(),
            o.port,
            o.robot,
            o.robot_fingerprint,
            o.algorithm,
            o.sensor
        );
        println!(
            "board vs host  {} of {} updates bit-exact, {} mismatches{}",
            o.board_updates,
            o.expected_updates,
            o.mismatches,
            if o.integer_method {
                " (integer method)"
            } else {
                " (float method: same IEEE arithmetic, compared all the same)"
            }
        );
        println!(
            "checked        every update by its running digest; {} poses in full (every {}{})",
            o.poses_reported,
            o.check_every,
            if o.check_every > 1 {
                ", and the last window's"
            } else {
                ""
            }
        );
        if let Some(m) = &o.first_mismatch {
            println!(
                "first mismatch at update {}: board {} host {}",
                m.update, m.board, m.host
            );
        }
        println!(
            "stream         {} events, {} wire bytes ({:.2} bytes/event), link {} bytes out / {} in at {} baud",
            o.events,
            o.wire_bytes,
            o.bytes_per_event,
            o.link_bytes_sent,
            o.link_bytes_received,
            o.baud
        );
        println!(
            "speed          {:.3} s played in {:.3} s {} ({:.2}x {})",
            o.played_seconds,
            o.wall_seconds,
            if clock::is_model() {
                "on the model's clock"
            } else {
                "wall"
            },
            o.played_per_wall_second,
            if clock::is_model() {
                "the boards' time"
            } else {
                "real time"
            }
        );
        match (o.final_error_m, o.max_error_m) {
            (Some(f), Some(m)) => println!(
                "vs truth       final error {:.4} mm, max {:.4} mm over {} rows",
                f * 1e3,
                m * 1e3,
                o.scored_rows
            ),
            _ if o.truth_rows > 0 => {
                println!("vs truth       no truth row within the updates played")
            }
            _ => println!("vs truth       the stream has no truth rows"),
        }
    }
    let verdict = match &outcome.first_mismatch {
        Some(m) => format!("failed: the board differs from update {}", m.update),
        None => {
            if let Some(p) = outputs.finish()? {
                if !a.json {
                    println!("wrote          {}", p.display());
                }
            }
            format!(
                "done: {} of {} updates bit-exact",
                outcome.board_updates, outcome.expected_updates
            )
        }
    };
    // The port is let go before the holding: the next play can open it meanwhile.
    drop(link);
    outputs.hold(&verdict);
    if let Some(m) = &outcome.first_mismatch {
        bail!(
            "the board and the host differ from update {} of {} on",
            m.update,
            outcome.expected_updates
        );
    }
    Ok(())
}

#[derive(Args, Debug)]
pub struct RecordArgs {
    #[command(flatten)]
    pub port: PortArgs,
    /// Tick stream to write (.csv or .csv.gz); the robot file and the board's poses are
    /// written beside it (STEM.robot.toml, STEM.board.csv).
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
    /// Seconds to record [default: until Ctrl-C].
    #[arg(long, value_name = "S")]
    pub duration: Option<f64>,
    /// Record every edge with its time stamp, or the counts at the update rate.
    #[arg(long, default_value = "timestamps", value_parser = ["timestamps", "counts"])]
    pub sensor: String,
    /// Load this robot into the slave first [default: the slave's power-on robot, the carriage
    /// robot of Xu, Zhu and Hu (2015)].
    #[arg(long, value_name = "FILE")]
    pub robot: Option<PathBuf>,
    /// Print the outcome as one JSON object.
    #[arg(long)]
    pub json: bool,
    #[command(flatten)]
    pub view: ViewArgs,
}

pub fn run_record(a: RecordArgs) -> Result<()> {
    // The stream is CSV, gzipped by a .gz name: another name would hide what it is.
    let name = a.out.file_name().map(|n| n.to_string_lossy().into_owned());
    if !name.is_some_and(|n| n.ends_with(".csv") || n.ends_with(".csv.gz")) {
        bail!(
            "--out {}: a tick stream is written as .csv, or .csv.gz to compress it",
            a.out.display()
        );
    }
    if let Some(d) = a.duration {
        // A recording also stops at the stream's size limit (docs/limits.md).
        if !(d > 0.0 && d <= 604_800.0) {
            bail!("--duration must be a number of seconds in (0, 604800] (a week), got {d}");
        }
    }
    let (robot_out, board_out) = record::companion_files(&a.out);
    let mut files = vec![a.out.as_path(), &robot_out, &board_out];
    files.extend(a.robot.as_deref());
    let mut outputs = Outputs::open(
        &a.view,
        topics::serial_channels(false),
        "host-bench record",
        &files,
    )?;
    let mut link = a.port.open()?;
    let bar = progress_bar("{spinner} recording {elapsed} {msg}");
    let outcome = record::record(
        &mut link,
        &record::RecordRequest {
            out: &a.out,
            duration_s: a.duration,
            counts: a.sensor == "counts",
            robot: a.robot.as_deref(),
            progress: Some(&bar),
            view: Some(&outputs.view),
        },
    )?;
    bar.finish_and_clear();
    if a.json {
        println!("{}", serde_json::to_string(&outcome)?);
    } else {
        let o = &outcome;
        println!(
            "wrote {} ({} ticks, {} absolute readings, {} truth rows, {:.1} s, stopped by {})",
            o.out, o.ticks, o.abs_readings, o.truth_rows, o.seconds, o.stopped_by
        );
        println!(
            "      {} (robot), {} ({} board poses)",
            o.robot_file, o.board_poses_file, o.board_poses
        );
        if o.lost_events + o.lost_updates > 0 {
            println!(
                "GAPS: the slave dropped {} events and {} updates (the link could not keep up)",
                o.lost_events, o.lost_updates
            );
        }
        if o.records_undecodable > 0 {
            println!(
                "GAPS: report records passed over: {} that did not decode, and {} sensor records \
                 after them, up to the slave's next pose (the stream's comments say so)",
                o.records_undecodable, o.records_unplaced
            );
        }
    }
    // The MCAP file goes with a whole recording only (the stream itself is kept either way,
    // marked PARTIAL).
    if outcome.partial.is_none() {
        if let Some(p) = outputs.finish()? {
            if !a.json {
                println!("      {} (the run for the viewers)", p.display());
            }
        }
    }
    drop(link);
    outputs.hold(&match &outcome.partial {
        None => format!("done: {} ticks, {:.1} s", outcome.ticks, outcome.seconds),
        Some(why) => format!("ended early: {why}"),
    });
    // Written either way; but a recording that broke off, or a board left reading what it
    // recorded, is not a success.
    if let Some(why) = &outcome.partial {
        bail!(
            "the recording ended early after {:.1} s: {why}. {} keeps what came before, marked \
             PARTIAL in its header",
            outcome.seconds,
            outcome.out
        );
    }
    if let Some(e) = &outcome.switch_back_failed {
        bail!(
            "{} is whole, but the slave could not be switched back to its own sensors \
             afterwards: {e}",
            outcome.out
        );
    }
    Ok(())
}

pub fn progress_bar(template: &str) -> indicatif::ProgressBar {
    // indicatif draws only on a terminal: piped output stays clean.
    indicatif::ProgressBar::new(0).with_style(
        indicatif::ProgressStyle::with_template(template)
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    )
}
