//! `host-bench`: the omnibench command line.

use std::path::PathBuf;
use std::process::ExitCode;

mod cli;

use clap::{Parser, Subcommand};
use host_bench::eval::report;
use host_bench::sim::emulator::{self, Scenario};

#[derive(Parser)]
#[command(
    name = "host-bench",
    version,
    about = "omnibench: hardware-in-the-loop bench for wheel-encoder localisation"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

// Parsed once per process: how large one variant is costs nothing.
#[allow(clippy::large_enum_variant)]
#[derive(Subcommand)]
enum Command {
    /// Run both boards' firmware in-process against a simulated robot (no hardware needed)
    /// and report odometry accuracy against ground truth.
    Emulate {
        /// The run: a scenario file (`scenarios/*.toml`, docs/scenario-format.md) or the
        /// built-in seed004-pursuit.
        #[arg(long, value_name = "FILE|NAME", default_value = "seed004-pursuit")]
        scenario: String,
        /// The robot file the boards are given instead of the scenario's: its encoders go to
        /// the slave, its drive to the master (with the scenario's controller gains).
        #[arg(long, value_name = "FILE")]
        robot: Option<PathBuf>,
        /// The robot as it really is, when it is not as the boards are told: the simulated
        /// wheels, encoders and carriage follow this file, so the run shows what wrong
        /// geometry does (`calibrate` finds it). The same kind of robot as the boards'.
        #[arg(long, value_name = "FILE")]
        true_robot: Option<PathBuf>,
        /// Simulated seconds to run [default: the scenario's own duration, 12 s for seed004-pursuit].
        #[arg(long, allow_negative_numbers = true)]
        duration: Option<f64>,
        /// Seed for everything random in the run (e.g. the encoders' phase at power-on).
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Odometry algorithm the slave runs (sent to it over the protocol): exact, arc, lut
        /// or timing.
        #[arg(long, default_value = "exact", value_parser = parse_method)]
        algorithm: robot_math::odometry::Method,
        /// How the slave reads its measuring wheels: hardware `counts` at its fixed rate, or
        /// every edge with its `timestamps` (edge interrupts) [default: the board's, timestamps].
        #[arg(long, value_parser = ["counts", "timestamps"])]
        sensor: Option<String>,
        /// The slave's odometry update rate, Hz [default: the board's own].
        #[arg(long, value_name = "HZ", value_parser = slave_rates())]
        slave_rate: Option<String>,
        /// Print the summary as one JSON object instead of text.
        #[arg(long)]
        json: bool,
        /// Run N times with seeds SEED, SEED+1, ... and report the spread of the errors
        /// (quantisation depends on where the encoders stood at power-on).
        #[arg(long, value_name = "N", conflicts_with_all = ["out", "mcap", "live"])]
        sweep: Option<u32>,
        /// Write run.csv (the log), path.svg and path.png (the paths plotted) and summary.json into
        /// this folder.
        #[arg(long, value_name = "DIR")]
        out: Option<PathBuf>,
        #[command(flatten)]
        view: host_bench::viewer::ViewArgs,
        /// With --live: the run paced to this many times real time (an emulation runs far
        /// faster than real time; paced, the page and the viewers can follow it).
        #[arg(long, value_name = "X", default_value_t = 1.0, requires = "live")]
        live_speed: f64,
        /// Where the two measuring-wheel encoders stand within their counts at power-on,
        /// fractions of a count in [0, 1) [default: drawn from the seed]. With time stamps the
        /// slave places each wheel from its first ticks; reading counters it cannot, and
        /// their difference tilts the carriage heading by (P1 - P0) counts over the wheel base
        /// (docs/odometry.md).
        #[arg(long, value_name = "P0,P1", value_parser = parse_phase)]
        encoder_phase: Option<[f64; 2]>,
        /// Where the measuring encoders put their edges: `ideal` (one count apart), or
        /// Broadcom HEDS-9040's datasheet errors, `typical` or `max` (and `typical-cycle`,
        /// `max-cycle`), each encoder's drawn from the seed (docs/tick-stream.md, "Encoder
        /// edges").
        /// [default: the scenario's `noise.encoder_edges`, else ideal]
        #[arg(long, value_name = "ideal|typical|max")]
        edges: Option<String>,
        /// Fault injection: cut the slave's power at this simulated time (seconds).
        #[arg(long, value_name = "SECS", allow_negative_numbers = true)]
        fault_slave_off_at: Option<f64>,
        /// Fault injection: reset the slave at this simulated time (seconds). It starts again
        /// 5 ms later from power-on (its pose, clock and settings as at power-on); the master
        /// must tell, stop the motors and report SLAVE_RESET to the host.
        #[arg(long, value_name = "SECS", allow_negative_numbers = true)]
        fault_slave_reset_at: Option<f64>,
        /// Fault injection: the host goes silent at this simulated time (seconds).
        #[arg(long, value_name = "SECS", allow_negative_numbers = true)]
        fault_host_silent_after: Option<f64>,
        /// Fault injection: the probability per SPI transaction, [0, 1), that a frame has a bit
        /// flipped (each direction on its own).
        #[arg(long, value_name = "RATE", allow_negative_numbers = true)]
        fault_spi_corrupt: Option<f64>,
        /// Fault injection: the probability per SPI transaction, [0, 1), that it is lost
        /// whole (the master reads an idle line, the slave sees nothing). With any SPI fault
        /// on, the run is also compared with the clean run, and made again driven through the
        /// clean run's duties: the slave's pose must then end bit for bit at the clean run's
        /// (`fault_check` in --json).
        #[arg(long, value_name = "RATE", allow_negative_numbers = true)]
        fault_spi_drop: Option<f64>,
        /// Fault injection: the probability per SPI transaction, [0, 1), that chip select rises
        /// part way through: both boards keep a torn frame.
        #[arg(long, value_name = "RATE", allow_negative_numbers = true)]
        fault_spi_torn: Option<f64>,
        /// Fault injection: the probability per SPI transaction, [0, 1), that the slave is late
        /// to re-arm: the master reads the slave's previous frame again and the slave misses
        /// the transaction (SPI has no other duplicate or delayed frame: the master clocks it).
        #[arg(long, value_name = "RATE", allow_negative_numbers = true)]
        fault_spi_duplicate: Option<f64>,
        /// Fault injection: the probability per SPI transaction, [0, 1), that the master is
        /// late to release chip select, by 3 ms (another of its tasks held the CPU when the
        /// last bit went); the slave re-arms on time, and no slave reset may be imagined.
        #[arg(long, value_name = "RATE", allow_negative_numbers = true)]
        fault_spi_late: Option<f64>,
        /// Fault injection: the probability per serial frame between host and master, each
        /// way, [0, 1), that it has a bit flipped; the four below that it is lost, arrives
        /// twice, arrives after the next one, or is torn (a piece without its end, run into the
        /// next frame). Together under 1. On a noisy line the host sends each setting
        /// and the goal again until the master's telemetry shows it.
        #[arg(long, value_name = "RATE", allow_negative_numbers = true)]
        fault_serial_corrupt: Option<f64>,
        #[arg(long, value_name = "RATE", allow_negative_numbers = true)]
        fault_serial_drop: Option<f64>,
        #[arg(long, value_name = "RATE", allow_negative_numbers = true)]
        fault_serial_duplicate: Option<f64>,
        #[arg(long, value_name = "RATE", allow_negative_numbers = true)]
        fault_serial_delay: Option<f64>,
        #[arg(long, value_name = "RATE", allow_negative_numbers = true)]
        fault_serial_torn: Option<f64>,
    },
    /// Every test case from the papers, every sensor mode, all four odometry methods side by
    /// side, with the papers' reported figures.
    Accuracy {
        /// Print {"cases":[{case, robot, mode, path_length_m, seeds, phase, algorithms:[{name,
        /// final_error_m, median_error_m, max_error_m: {median, p95, max}}...]}...]}.
        #[arg(long)]
        json: bool,
        /// Power-on seeds per case: each runs with every encoder at a random point inside
        /// its count; figures are median, p95 and max over the seeds.
        #[arg(long, default_value_t = host_bench::eval::accuracy::DEFAULT_SEEDS)]
        seeds: u64,
        /// Write an SVG per case and mode (true path and each method's path; error against
        /// distance) and each method's track (truth, estimate, error per truth row) as CSV.
        #[arg(long, value_name = "DIR")]
        out: Option<PathBuf>,
        /// Where the encoders put their edges: `ideal` (one count apart), or Broadcom
        /// HEDS-9040's datasheet errors, `typical` or `max`, each seed's encoders drawn from
        /// them (docs/odometry.md, "Encoders as they are"); `typical-cycle` and `max-cycle`
        /// without the errors over a revolution and the capture latency.
        #[arg(
            long,
            value_name = "ideal|typical|max|typical-cycle|max-cycle",
            default_value = "ideal"
        )]
        edges: String,
        /// `exact` takes every edge a whole count after the last, as before it learned where
        /// each encoder puts the four edges of its quadrature cycle (with time stamps; the
        /// slave always learns them): for a comparison. On `replay`: `--algorithm exact+even`.
        #[arg(long)]
        even_edges: bool,
    },
    /// Yan (2013)'s speed envelope of the three-omni drive: top translation speed in every
    /// direction and with spin, from the model and driven flat out on the simulated robot,
    /// and where an arc with spin beats a straight line.
    Envelope {
        /// Print {translate_max_ratio, spin_translate_max_ratio, directions:[...],
        /// spin_cases:[...], arc_vs_line:{...}, ...} instead of text.
        #[arg(long)]
        json: bool,
        /// Write the envelope as an SVG (polar: model, measured, with spin).
        #[arg(long, value_name = "FILE.svg")]
        out: Option<PathBuf>,
    },
    /// The pursuit period of Xu, Zhu and Hu (2015): the default scenario emulated with the
    /// master running the paper's Euler pursuit for τ = 0.1 ... 1.5 s (and our law as τ = 0),
    /// with the path's jitter and the tracking error of each.
    PursuitSweep {
        /// Print {"rows":[{tau_s, law, jitter, tracking_rms_m, hold_rms_m, hold_max_m, ...}]}.
        #[arg(long)]
        json: bool,
        /// Simulated seconds of each run, 10 to 3600 (the target stops after 7.1 s).
        #[arg(long, default_value_t = 12.0)]
        duration: f64,
        /// Write the plot as an SVG (paths for a few periods; overshoot and turning against τ,
        /// emulated and from the paper's equations).
        #[arg(long, value_name = "FILE.svg")]
        out: Option<PathBuf>,
    },
    /// Write the exact tick stream a robot's ideal encoders produce along a trajectory
    /// (docs/tick-stream.md).
    Generate(cli::generate::GenerateArgs),
    /// Run odometry estimators over a tick stream (docs/tick-stream.md) and score them
    /// against its truth rows.
    Replay {
        /// Robot description (docs/robot-format.md) [default: the stream's `# robot:` line].
        #[arg(long, value_name = "FILE")]
        robot: Option<PathBuf>,
        /// Tick stream file (.csv or .csv.gz).
        #[arg(long, value_name = "FILE")]
        ticks: PathBuf,
        /// Estimator to run (arc, lut, timing, exact; exact-f64, exact's float twin), or
        /// `all`. `exact+even` (or `exact-f64+even`): `exact` taking every edge a whole count
        /// after the last instead of learning where each encoder puts the four edges of its
        /// quadrature cycle (time stamps only), as the slave never does: for a comparison.
        #[arg(long, default_value = "all")]
        algorithm: String,
        /// Write each algorithm's track (truth, estimate, error at every truth row) as
        /// DIR/<algorithm>.csv.
        #[arg(long, value_name = "DIR")]
        out: Option<PathBuf>,
        /// Read the encoders as hardware counters sampled at this rate (Hz) instead of as
        /// time-stamped ticks.
        #[arg(long, value_name = "HZ", allow_negative_numbers = true)]
        counts_rate: Option<f64>,
        /// Print {"algorithms":[{name, final_error_m, max_error_m, final_heading_error_rad, path_length_m}...]}.
        #[arg(long)]
        json: bool,
        #[command(flatten)]
        view: host_bench::viewer::ViewArgs,
    },
    /// How far a robot's geometry is off its robot file, from runs whose true end pose is
    /// known (UMBmark's squares), and the robot file corrected (docs/calibration.md).
    Calibrate(cli::calibrate::CalibrateArgs),
    /// List the attached debug probes and serial ports (docs/bench.md).
    Probes {
        /// Print {"probes":[{name, vid, pid, serial, selector, accessible}],
        /// "serial_ports":[{path, kind, vid, pid, manufacturer, product, serial}]}.
        #[arg(long)]
        json: bool,
    },
    /// Write a bench.toml from what is attached: first probe → slave, second → master, first
    /// USB serial port → the master's link. Says what it guessed.
    InitBench {
        #[arg(long, value_name = "FILE", default_value = "bench.toml")]
        out: PathBuf,
        /// Replace an existing file.
        #[arg(long)]
        force: bool,
    },
    /// Flash the boards' release images through their debug probes, both in parallel, then
    /// verify, reset and run. Builds nothing (docs/bench.md).
    Flash(cli::flash::FlashArgs),
    /// Play a tick stream into the slave over the serial link and check, update by update,
    /// that it computes the same poses as the host (docs/bench.md).
    Play(cli::serial::PlayArgs),
    /// Record the slave's encoders (and poses) into a tick stream over the serial link.
    Record(cli::serial::RecordArgs),
    /// Both boards emulated behind a pseudo-terminal, in real time (or --time-scale X): prints
    /// `port: /dev/pts/N`, then `clock: FILE` (its time, for `--clock`), and serves `play`,
    /// `record` and `calibrate` until killed.
    VirtualBoard(cli::virtual_board::VirtualBoardArgs),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    if let Err(e) = host_bench::formats::atomic::remove_partials_on_signals() {
        eprintln!("error: {e:#}");
        return ExitCode::FAILURE;
    }
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

/// `--encoder-phase P0,P1`: two fractions of a count, each in [0, 1).
fn parse_phase(s: &str) -> Result<[f64; 2], String> {
    let bad = || format!("expected two fractions of a count in [0, 1), e.g. 0.25,0.5; got {s:?}");
    let (a, b) = s.split_once(',').ok_or_else(bad)?;
    let p = [a, b].map(|v| v.trim().parse::<f64>().ok());
    match p {
        [Some(a), Some(b)] if (0.0..1.0).contains(&a) && (0.0..1.0).contains(&b) => Ok([a, b]),
        _ => Err(bad()),
    }
}

/// An odometry method by name; unknown names are refused with the list.
/// `--slave-rate`'s values: the rates a slave board can be built for.
fn slave_rates() -> clap::builder::PossibleValuesParser {
    let rates = firmware_slave::board_rate::BOARD_RATES_HZ;
    clap::builder::PossibleValuesParser::new(
        rates.map(|hz| clap::builder::PossibleValue::new(hz.to_string())),
    )
}

fn parse_method(name: &str) -> Result<robot_math::odometry::Method, String> {
    robot_math::odometry::Method::from_name(name).ok_or_else(|| {
        format!(
            "unknown odometry method {name:?}; available: {}",
            robot_math::odometry::Method::NAMES
        )
    })
}

fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Emulate {
            scenario,
            robot,
            true_robot,
            duration,
            seed,
            algorithm,
            sensor,
            slave_rate,
            json,
            sweep,
            out,
            view,
            live_speed,
            encoder_phase,
            edges,
            fault_slave_off_at,
            fault_slave_reset_at,
            fault_host_silent_after,
            fault_spi_corrupt,
            fault_spi_drop,
            fault_spi_torn,
            fault_spi_duplicate,
            fault_spi_late,
            fault_serial_corrupt,
            fault_serial_drop,
            fault_serial_duplicate,
            fault_serial_delay,
            fault_serial_torn,
        } => {
            let mut scenario = match Scenario::builtin(&scenario) {
                Some(s) => s,
                None if !std::path::Path::new(&scenario).exists() => anyhow::bail!(
                    "--scenario {scenario}: no such file, and no built-in of that name (the \
                     built-ins: {}; the files: scenarios/*.toml)",
                    Scenario::BUILTIN_NAMES.join(", ")
                ),
                None => host_bench::formats::scenario::load(std::path::Path::new(&scenario))?,
            };
            if let Some(path) = &robot {
                scenario.set_robot(path)?;
            }
            if let Some(path) = &true_robot {
                scenario.set_true_robot(path)?;
            }
            let mut opts = emulator::Options::new(&scenario);
            if let Some(d) = duration {
                opts.duration = d;
            }
            opts.seed = seed;
            opts.algorithm = firmware_slave::algorithm_of(algorithm);
            match sensor.as_deref() {
                Some("counts") => opts.slave.sensor = firmware_slave::SensorMode::Counts,
                Some("timestamps") => {
                    opts.slave.sensor = firmware_slave::SensorMode::TickTimestamps
                }
                // The board's configuration.
                _ => {}
            }
            let rate = slave_rate.as_deref().and_then(|r| r.parse::<u32>().ok());
            if let Some(period_us) = rate.and_then(firmware_slave::board_rate::period_us) {
                opts.slave.update_period_us = period_us;
            }
            // The command line over the scenario's own settings.
            opts.encoder_phase = encoder_phase.or(opts.encoder_phase);
            if let Some(e) = &edges {
                opts.edges = host_bench::sim::generate::EdgeErrors::preset(e)
                    .map_err(|err| anyhow::anyhow!("--edges: {err:#}"))?;
            }
            let f = &mut opts.faults;
            f.slave_off_at = fault_slave_off_at.or(f.slave_off_at);
            f.slave_reset_at = fault_slave_reset_at.or(f.slave_reset_at);
            f.host_silent_after = fault_host_silent_after.or(f.host_silent_after);
            f.spi.corrupt = fault_spi_corrupt.unwrap_or(f.spi.corrupt);
            f.spi.drop = fault_spi_drop.unwrap_or(f.spi.drop);
            f.spi.torn = fault_spi_torn.unwrap_or(f.spi.torn);
            f.spi.duplicate = fault_spi_duplicate.unwrap_or(f.spi.duplicate);
            f.spi.late = fault_spi_late.unwrap_or(f.spi.late);
            f.serial.corrupt = fault_serial_corrupt.unwrap_or(f.serial.corrupt);
            f.serial.drop = fault_serial_drop.unwrap_or(f.serial.drop);
            f.serial.duplicate = fault_serial_duplicate.unwrap_or(f.serial.duplicate);
            f.serial.delay = fault_serial_delay.unwrap_or(f.serial.delay);
            f.serial.torn = fault_serial_torn.unwrap_or(f.serial.torn);
            // The log's rows only stream to the files of --out: a run of any length keeps
            // its summary alone (and a thinned copy for the plot).
            opts.keep_log = false;
            if let Some(n) = sweep {
                return cli::sweep::run_sweep(&scenario, &opts, n, json);
            }
            if !host_bench::viewer::LIVE_SPEEDS.contains(&live_speed) {
                let r = host_bench::viewer::LIVE_SPEEDS;
                anyhow::bail!(
                    "--live-speed {live_speed}: a factor of real time, {} to {}",
                    r.start(),
                    r.end()
                );
            }
            // The MCAP file may not be one of the run's inputs or --out files.
            let mut files: Vec<PathBuf> = (scenario.source_files.iter())
                .map(|(_, p)| p.clone())
                .collect();
            if let Some(dir) = &out {
                for f in ["run.csv", "path.svg", "path.png", "summary.json"] {
                    files.push(dir.join(f));
                }
            }
            let file_refs: Vec<&std::path::Path> = files.iter().map(PathBuf::as_path).collect();
            let mut outputs = host_bench::viewer::Outputs::open(
                &view,
                host_bench::viewer::topics::emulate_channels(false),
                "host-bench emulate",
                &file_refs,
            )?;
            let pacer = outputs
                .is_live()
                .then(|| host_bench::viewer::Pacer::new(live_speed));
            let mut see = |row: &emulator::LogRow| {
                if let Some(p) = &pacer {
                    p.wait_for(row.t_s);
                }
                host_bench::viewer::topics::emulate_row(&mut outputs.view.borrow_mut(), row)
            };
            // With --out, the files are written as the run goes but put in place only once
            // it has scored something and the fault check is in: all of them or none.
            let (mut run, files) = match &out {
                Some(dir) => {
                    let (run, files) = report::emulate_into(&scenario, &opts, dir, &mut see)?;
                    (run, Some(files))
                }
                None => {
                    let summary =
                        emulator::run_logged(&scenario, &opts, Some(&mut |row| see(&row)))?;
                    (
                        emulator::Run {
                            summary,
                            log: Vec::new(),
                        },
                        None,
                    )
                }
            };
            let spi = opts.faults.spi;
            if spi != Default::default() {
                let check = emulator::fault_check(&scenario, &opts, &run.summary)?;
                run.summary.fault_check = Some(check);
            }
            let nothing = emulator::nothing_scored(&run.summary);
            if nothing.is_none() {
                // The MCAP file first: should the --out files then fail to go in place, it
                // goes again, so the run leaves all of its files or none.
                let mcap = outputs.finish()?;
                if let Some(files) = files {
                    match files.commit(&run.summary) {
                        Ok(written) if !json => {
                            for p in written {
                                eprintln!("wrote {}", p.display());
                            }
                        }
                        Ok(_) => {}
                        Err(e) => {
                            if let Some(p) = &mcap {
                                let _ = std::fs::remove_file(p);
                            }
                            return Err(e);
                        }
                    }
                }
                if let Some(p) = mcap.filter(|_| !json) {
                    eprintln!("wrote {}", p.display());
                }
            }
            if json {
                println!("{}", serde_json::to_string(&run.summary)?);
            } else {
                print!("{}", report::summary_text(&run.summary));
            }
            outputs.hold(&match &nothing {
                None => format!(
                    "done: slave odometry final error {:.3} mm, max {:.3} mm",
                    run.summary.final_error_m * 1e3,
                    run.summary.max_error_m * 1e3
                ),
                Some(why) => format!("failed: {why}"),
            });
            if let Some(why) = nothing {
                match &out {
                    Some(dir) => anyhow::bail!("{why} (nothing written to {})", dir.display()),
                    None => anyhow::bail!("{why}"),
                }
            }
            Ok(())
        }
        Command::Accuracy {
            json,
            out,
            seeds,
            edges,
            even_edges,
        } => cli::analyse::run_accuracy(json, out, seeds, &edges, even_edges),
        Command::Envelope { json, out } => cli::envelope::run_envelope(json, out),
        Command::PursuitSweep {
            json,
            duration,
            out,
        } => cli::pursuit_sweep::run_pursuit_sweep(json, duration, out),
        Command::Generate(a) => cli::generate::run_generate(a),
        Command::Replay {
            robot,
            ticks,
            algorithm,
            out,
            counts_rate,
            json,
            view,
        } => cli::analyse::run_replay(robot, ticks, algorithm, counts_rate, out, json, &view),
        Command::Calibrate(a) => cli::calibrate::run_calibrate(a),
        Command::Probes { json } => cli::flash::run_probes(json),
        Command::InitBench { out, force } => cli::flash::run_init_bench(out, force),
        Command::Flash(a) => cli::flash::run_flash(a),
        Command::Play(a) => cli::serial::run_play(a),
        Command::Record(a) => cli::serial::run_record(a),
        Command::VirtualBoard(a) => cli::virtual_board::run_virtual_board(a),
    }
}
