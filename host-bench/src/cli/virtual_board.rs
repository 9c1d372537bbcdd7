//! `host-bench virtual-board`: both boards emulated in real time (or at `--time-scale`) behind a
//! pseudo-terminal, for `play`, `record` and `calibrate` without boards.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use clap::Args;
use host_bench::sim::virtual_board;
use host_bench::viewer::{topics, Outputs, ViewArgs};

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
    /// Fault injection: the probability per SPI transaction, [0, 1), that the master is late
    /// to release chip select, by 3 ms (another of its tasks held the CPU).
    #[arg(
        long,
        value_name = "RATE",
        default_value_t = 0.0,
        allow_negative_numbers = true
    )]
    pub fault_spi_late: f64,
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
    /// Run the emulated boards X times as fast as real time (0.01 to 100; as fast as the
    /// emulation goes, if that is slower). The host's waits and paces are spans of the boards'
    /// time: off 1, give `play`, `record` and `calibrate` `--clock FILE`, the file this prints
    /// after `clock: `, so they take their time from it.
    #[arg(long, value_name = "X", default_value_t = 1.0)]
    pub time_scale: f64,
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
    if !(0.01..=100.0).contains(&a.time_scale) {
        bail!(
            "--time-scale is simulated seconds per wall second, 0.01 to 100: got {}",
            a.time_scale
        );
    }
    opts.time_scale = a.time_scale;
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
        ("--fault-spi-late", a.fault_spi_late),
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
    opts.faults.spi.late = a.fault_spi_late;
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
    let clock = host_bench::serial::clock::ClockFile::create()?;
    // The first line is the port, for scripts: `port: /dev/pts/N`; the second the clock file,
    // as the chip model's `serve` prints them.
    println!("port: {name}");
    println!("clock: {}", clock.path().display());
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
    let pace = if a.time_scale == 1.0 {
        "in real time".to_string()
    } else {
        format!(
            "at {}x real time (give the host --clock {})",
            a.time_scale,
            clock.path().display()
        )
    };
    eprintln!("virtual board (robot {robot_name}{truly}, {driven}) serving {pace}; Ctrl-C ends it");
    let view = outputs.view.borrow().is_on().then_some(&outputs.view);
    virtual_board::serve(
        pty,
        &opts,
        &|| stop.load(std::sync::atomic::Ordering::Relaxed),
        view,
        Some(&clock),
    )?;
    if let Some(p) = outputs.finish()? {
        eprintln!("wrote {}", p.display());
    }
    Ok(())
}
