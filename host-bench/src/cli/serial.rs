//! The serial-bench commands: `play`, `record`, `virtual-board`.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use clap::Args;
use firmware_slave::played::PlayKind;
use host_bench::boards::bench_file;
use host_bench::formats::{robot::Robot, tickstream};
use host_bench::serial::{link::Link, play, played_stream, record};
use host_bench::sim::virtual_board;
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
    /// sent again. For a board slower than real time, such as the chip model
    /// (`scripts/board-model play-check` passes 10).
    #[arg(long, value_name = "FACTOR", default_value_t = 1)]
    pub patience: u32,
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
            "speed          {:.3} s played in {:.3} s wall ({:.2}x real time)",
            o.played_seconds, o.wall_seconds, o.played_per_wall_second
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

#[derive(Args, Debug)]
pub struct VirtualBoardArgs {
    /// Seed for the encoders' power-on phase.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// The simulated robot (docs/robot-format.md; two encoders, as the slave board reads),
    /// loaded in the slave as if `play`/`record --robot` had sent it [default: the carriage
    /// robot of Xu, Zhu and Hu (2015), the slave's power-on robot].
    #[arg(long, value_name = "FILE")]
    pub robot: Option<std::path::PathBuf>,
    /// Fault injection: answer the handshake with this schema fingerprint (hex) instead of
    /// the real one, as a board flashed from another version would.
    #[arg(long, value_name = "HEX")]
    pub fault_schema: Option<String>,
    /// Fault injection: the probability per serial frame, [0, 1), that it has a bit flipped
    /// (each direction on its own).
    #[arg(
        long,
        value_name = "RATE",
        default_value_t = 0.0,
        allow_negative_numbers = true
    )]
    pub fault_serial_corrupt: f64,
    /// Fault injection: the probability per serial frame, [0, 1), that it is lost.
    #[arg(
        long,
        value_name = "RATE",
        default_value_t = 0.0,
        allow_negative_numbers = true
    )]
    pub fault_serial_drop: f64,
    /// Fault injection: the probability per serial frame, [0, 1), that it arrives twice.
    #[arg(
        long,
        value_name = "RATE",
        default_value_t = 0.0,
        allow_negative_numbers = true
    )]
    pub fault_serial_duplicate: f64,
    /// Fault injection: the probability per serial frame, [0, 1), that it arrives after the
    /// next one.
    #[arg(
        long,
        value_name = "RATE",
        default_value_t = 0.0,
        allow_negative_numbers = true
    )]
    pub fault_serial_delay: f64,
    /// Fault injection: the probability per serial frame, [0, 1), that it is torn: a piece
    /// arrives without its end and runs into the next frame.
    #[arg(
        long,
        value_name = "RATE",
        default_value_t = 0.0,
        allow_negative_numbers = true
    )]
    pub fault_serial_torn: f64,
    /// Fault injection: the probability per SPI transaction, [0, 1), that a frame has a bit
    /// flipped (each direction on its own).
    #[arg(
        long,
        value_name = "RATE",
        default_value_t = 0.0,
        allow_negative_numbers = true
    )]
    pub fault_spi_corrupt: f64,
    /// Fault injection: the probability per SPI transaction, [0, 1), that it is lost whole.
    #[arg(
        long,
        value_name = "RATE",
        default_value_t = 0.0,
        allow_negative_numbers = true
    )]
    pub fault_spi_drop: f64,
    /// Fault injection: the probability per SPI transaction, [0, 1), that it is torn.
    #[arg(
        long,
        value_name = "RATE",
        default_value_t = 0.0,
        allow_negative_numbers = true
    )]
    pub fault_spi_torn: f64,
    /// Fault injection: the probability per SPI transaction, [0, 1), that the slave is late
    /// to re-arm and sends its previous frame again.
    #[arg(
        long,
        value_name = "RATE",
        default_value_t = 0.0,
        allow_negative_numbers = true
    )]
    pub fault_spi_duplicate: f64,
    /// Fault injection: reset the slave this many seconds after the board started; it runs
    /// again from power-on 5 ms later (a `play` or `record` then stops and says so).
    #[arg(long, value_name = "SECS", allow_negative_numbers = true)]
    pub fault_slave_reset_at: Option<f64>,
    /// Where the simulated robot's measuring encoders put their edges: `ideal` (one count
    /// apart), or Broadcom HEDS-9040's datasheet errors, `typical` or `max`, each encoder's
    /// drawn from --seed (docs/tick-stream.md, "Encoder edges"): what `record` then records.
    #[arg(long, value_name = "ideal|typical|max", default_value = "ideal")]
    pub edges: String,
    /// Fault injection: one deliberate failure of the board on its line to the host, once N
    /// report frames have reached it (default 20): `stall` (silent), `flood` (only telemetry,
    /// fast), `repeat-ack` (stale acknowledgements, no reports), `bad-record` (a report that
    /// does not decode, in a good frame), `huge-time` (time stamps near 2^62 µs), `truncate`
    /// (a frame cut short, then silent), `close` (hangs up), `slow` (one frame in ten).
    #[arg(long, value_name = "ACT[@N]")]
    pub misbehave: Option<String>,
    /// How fast the robot drives round its course, in m/s (at most 1). By default the speed
    /// at which a 115 200-baud link carries every time-stamped edge: 0.05 m/s for the
    /// carriage robot's counts, scaled to a robot file's finer or coarser ones.
    #[arg(long, value_name = "M_S")]
    pub course_speed: Option<f64>,
    /// The robot as it really is, when it is not as the slave is told (--robot, or its
    /// power-on robot): the simulated measuring wheels follow this file, so a recording shows
    /// what wrong geometry does and `calibrate` can find it. Two encoders, on the body or a
    /// carriage as the slave's.
    #[arg(long, value_name = "FILE")]
    pub true_robot: Option<PathBuf>,
    /// The master drives the robot: its motor outputs turn the wheels of the robot's drive
    /// (--true-robot's, else --robot's, else the carriage robot's), as on a robot on the floor,
    /// and the robot stands still until the host drives it (`calibrate --drive-squares` does;
    /// the host sends the drive first). Without it the board pushes the robot round its own
    /// square course.
    #[arg(long)]
    pub master_drives: bool,
    /// Send no truth, as a real board: a recording then has no truth rows, and `calibrate
    /// --drive-squares` asks for each square's measured end pose, as of a robot on the floor.
    #[arg(long)]
    pub no_truth: bool,
    /// The fastest rate the USB-serial adapter carries (CH340: 2000000, CP2102N and FT232R:
    /// 3000000): a switch to a faster one garbles every byte, and the host and the master
    /// go back to 115200 [default: 4500000, the master's own limit].
    #[arg(long, value_name = "BAUD")]
    pub max_baud: Option<u32>,
    /// The adapter's latency timer: bytes for the host wait this long for a USB packet to
    /// fill (FTDI's default is 16 ms; Linux lets it be lowered to 1).
    #[arg(long, value_name = "MS", default_value_t = 0)]
    pub link_latency_ms: u32,
    /// Fault injection, for the checks of `play`: the master's frames to the slave carry
    /// played-event byte OFFSET with its lowest bit flipped under a valid check (a bug, not
    /// noise: every time that byte passes).
    #[arg(long, value_name = "OFFSET")]
    pub fault_spi_event_bit: Option<u32>,
    #[command(flatten)]
    pub view: ViewArgs,
}

pub fn run_virtual_board(a: VirtualBoardArgs) -> Result<()> {
    let (layout, robot_name) = match &a.robot {
        Some(path) => {
            let robot = host_bench::formats::robot::Robot::load(path)?;
            let layout = robot
                .odometry_layout()
                .with_context(|| format!("--robot {}", path.display()))?;
            (layout, robot.name)
        }
        None => (
            robot_math::odometry::Layout::SEED_004,
            "seed004, the carriage robot of Xu, Zhu and Hu 2015".to_string(),
        ),
    };
    let mut opts = virtual_board::Options {
        seed: a.seed,
        edges: host_bench::sim::generate::EdgeErrors::preset(&a.edges).context("--edges")?,
        ..virtual_board::Options::for_robot(layout)
    };
    if let Some(path) = &a.true_robot {
        let what = || format!("--true-robot {}", path.display());
        let robot = host_bench::formats::robot::Robot::load(path).with_context(what)?;
        let truly = robot.odometry_layout().with_context(what)?;
        let carriage = |l: &robot_math::odometry::Layout| l.carriage_geometry().is_some();
        if truly.encoders() != layout.encoders() || carriage(&truly) != carriage(&layout) {
            bail!(
                "{}: it must be the kind of robot the slave is told of ({} encoders, {}); it \
                 has {} encoders, {}",
                what(),
                layout.encoders(),
                if carriage(&layout) {
                    "on a carriage"
                } else {
                    "on the body"
                },
                truly.encoders(),
                if carriage(&truly) {
                    "on a carriage"
                } else {
                    "on the body"
                },
            );
        }
        opts.true_layout = Some(truly);
    }
    if a.master_drives {
        let model = match a.true_robot.as_ref().or(a.robot.as_ref()) {
            Some(path) => {
                let robot = host_bench::formats::robot::Robot::load(path)?;
                host_bench::formats::run_robot::robot_model(robot)
                    .with_context(|| format!("--master-drives: the drive of {}", path.display()))?
            }
            None => host_bench::formats::run_robot::power_on_robot(),
        };
        opts.master_drives = Some(virtual_board::Drivetrain {
            drive: model.drive,
            motor: model.motor,
        });
    }
    opts.send_truth = !a.no_truth;
    if let Some(b) = a.max_baud {
        if b < 9_600 {
            bail!("--max-baud is the adapter's fastest rate, at least 9600: got {b}");
        }
        opts.adapter.max_baud = b;
    }
    if a.link_latency_ms > 1_000 {
        bail!(
            "--link-latency-ms is the adapter's latency timer, 0 to 1000 ms (FTDI: 16): got {}",
            a.link_latency_ms
        );
    }
    opts.adapter.latency = embassy_time::Duration::from_millis(a.link_latency_ms.into());
    opts.faults.spi.event_bit = a.fault_spi_event_bit;
    if let Some(v) = a.course_speed {
        if !(v > 0.0 && v <= 1.0) {
            bail!("--course-speed is the robot's speed round its course, over 0 and at most 1 m/s: got {v}");
        }
        opts.course_speed = v;
    }
    for (name, rate) in [
        ("--fault-serial-corrupt", a.fault_serial_corrupt),
        ("--fault-serial-drop", a.fault_serial_drop),
        ("--fault-serial-duplicate", a.fault_serial_duplicate),
        ("--fault-serial-delay", a.fault_serial_delay),
        ("--fault-serial-torn", a.fault_serial_torn),
        ("--fault-spi-corrupt", a.fault_spi_corrupt),
        ("--fault-spi-drop", a.fault_spi_drop),
        ("--fault-spi-torn", a.fault_spi_torn),
        ("--fault-spi-duplicate", a.fault_spi_duplicate),
    ] {
        if !(0.0..1.0).contains(&rate) {
            bail!("{name} is a probability per frame, in [0, 1): got {rate}");
        }
    }
    opts.faults.serial = host_bench::sim::serial_noise::SerialFaults {
        corrupt: a.fault_serial_corrupt,
        drop: a.fault_serial_drop,
        duplicate: a.fault_serial_duplicate,
        delay: a.fault_serial_delay,
        torn: a.fault_serial_torn,
    };
    let f = opts.faults.serial;
    if f.total() >= 1.0 {
        bail!("the --fault-serial-* rates must add up to under 1");
    }
    opts.faults.spi.corrupt = a.fault_spi_corrupt;
    opts.faults.spi.drop = a.fault_spi_drop;
    opts.faults.spi.torn = a.fault_spi_torn;
    opts.faults.spi.duplicate = a.fault_spi_duplicate;
    if let Some(t) = a.fault_slave_reset_at {
        if !(0.0..=host_bench::sim::emulator::MAX_DURATION_S).contains(&t) {
            bail!(
                "--fault-slave-reset-at is seconds after the board started, 0 to {}: got {t}",
                host_bench::sim::emulator::MAX_DURATION_S
            );
        }
        opts.faults.slave_reset_at = Some(t);
    }
    if let Some(m) = &a.misbehave {
        opts.faults.misbehave = Some(
            host_bench::sim::misbehaving::Misbehaviour::parse(m)
                .map_err(|e| anyhow::anyhow!("--misbehave {e}"))?,
        );
    }
    if let Some(s) = &a.fault_schema {
        let fp = u32::from_str_radix(s.trim_start_matches("0x"), 16)
            .with_context(|| format!("--fault-schema {s:?} is not a hex number"))?;
        opts.faults.schema = Some(fp);
    }
    // Refuse a robot the board cannot simulate before printing a port.
    host_bench::sim::plant::MeasuringSensors::from_layout(opts.slave.layout()).map_err(|e| {
        anyhow::anyhow!(
            "{}: the virtual board cannot simulate robot {robot_name}: {e}",
            a.robot
                .as_deref()
                .unwrap_or(std::path::Path::new("the slave's power-on robot"))
                .display()
        )
    })?;
    if let Some(truly) = &opts.true_layout {
        host_bench::sim::plant::MeasuringSensors::from_layout(truly).map_err(|e| {
            anyhow::anyhow!("--true-robot: the virtual board cannot simulate it: {e}")
        })?;
    }
    if a.view.live_hold.is_some() {
        bail!("--live-hold: a virtual board serves until it is stopped; its view with it");
    }
    let mut channels = topics::emulate_channels(true);
    channels.retain(|c| c.topic != "/master/target");
    let inputs: Vec<&Path> = [&a.robot, &a.true_robot]
        .into_iter()
        .flatten()
        .map(PathBuf::as_path)
        .collect();
    let mut outputs = Outputs::open(&a.view, channels, "host-bench virtual-board", &inputs)?;
    // With --mcap, Ctrl-C ends the serving and the file is finished (SIGTERM leaves none).
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let _own_ctrl_c = a
        .view
        .mcap
        .is_some()
        .then(host_bench::formats::atomic::OwnCtrlC::take);
    if a.view.mcap.is_some() {
        signal_hook::flag::register(signal_hook::consts::SIGINT, stop.clone())
            .context("installing the Ctrl-C handler")?;
    }
    let (pty, _slave_end, name) = virtual_board::open_pty()?;
    // The first line is the port, for scripts: `port: /dev/pts/N`.
    println!("port: {name}");
    use std::io::Write;
    std::io::stdout().flush()?;
    let truly = a.true_robot.as_ref().map_or(String::new(), |p| {
        format!("; its wheels really as {}", p.display())
    });
    let driven = if opts.master_drives.is_some() {
        "driven by the master".to_string()
    } else {
        format!(
            "driven round a {} m square at {:.3} m/s",
            opts.course_side, opts.course_speed
        )
    };
    eprintln!("virtual board (robot {robot_name}{truly}, {driven}) serving; Ctrl-C ends it");
    let view = outputs.view.borrow().is_on().then_some(&outputs.view);
    virtual_board::serve(
        pty,
        &opts,
        &|| stop.load(std::sync::atomic::Ordering::Relaxed),
        view,
    )?;
    if let Some(p) = outputs.finish()? {
        eprintln!("wrote {}", p.display());
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
