//! `host-bench`: the omnibench command line.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};
use host_bench::emulator::{self, Scenario};
use host_bench::report;

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

#[derive(Subcommand)]
enum Command {
    /// Run both boards' firmware in-process against a simulated robot (no hardware needed)
    /// and report odometry accuracy against ground truth.
    Emulate {
        /// Built-in scenario to run.
        #[arg(long, default_value = "seed004-pursuit", value_parser = clap::builder::PossibleValuesParser::new(Scenario::BUILTIN_NAMES))]
        scenario: String,
        /// Simulated seconds to run [default: the scenario's own duration, 12 s for seed004-pursuit].
        #[arg(long, allow_negative_numbers = true)]
        duration: Option<f64>,
        /// Seed for everything random in the run (e.g. the encoders' phase at power-on).
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Odometry algorithm the slave runs (sent to it over the protocol).
        #[arg(long, default_value = "exact", value_parser = ["exact", "arc", "lut", "timing"])]
        algorithm: String,
        /// How the slave reads its measuring wheels: hardware `counts` at its fixed rate, or
        /// every edge with its `timestamps` (edge interrupts).
        #[arg(long, default_value = "counts", value_parser = ["counts", "timestamps"])]
        sensor: String,
        /// Print the summary as one JSON object instead of text.
        #[arg(long)]
        json: bool,
        /// Run N times with seeds SEED, SEED+1, ... and report the spread of the errors
        /// (quantisation depends on where the encoders stood at power-on).
        #[arg(long, value_name = "N", conflicts_with = "out")]
        sweep: Option<u32>,
        /// Write run.csv (the log), path.svg (paths plot) and summary.json into this folder.
        #[arg(long, value_name = "DIR")]
        out: Option<PathBuf>,
        /// Fault injection: cut the slave's power at this simulated time (seconds).
        #[arg(long, value_name = "SECS", allow_negative_numbers = true)]
        fault_slave_off_at: Option<f64>,
        /// Fault injection: the host goes silent at this simulated time (seconds).
        #[arg(long, value_name = "SECS", allow_negative_numbers = true)]
        fault_host_silent_after: Option<f64>,
    },
    /// Every seed case, every sensor mode, all four odometry methods side by side, with the
    /// papers' reported figures.
    Accuracy {
        /// Print {"cases":[{case, robot, mode, path_length_m, algorithms:[...]}...]}.
        #[arg(long)]
        json: bool,
        /// Write an SVG per case and mode (true path and each method's path; error against
        /// distance) and each method's track (truth, estimate, error per truth row) as CSV.
        #[arg(long, value_name = "DIR")]
        out: Option<PathBuf>,
    },
    /// Write the exact tick stream a robot's ideal encoders produce along a trajectory
    /// (docs/tick-stream.md).
    Generate {
        /// List the trajectories and exit.
        #[arg(long)]
        list: bool,
        /// Robot description (docs/robot-format.md).
        #[arg(long, value_name = "FILE", required_unless_present = "list")]
        robot: Option<PathBuf>,
        /// Trajectory name (see --list).
        #[arg(long, required_unless_present = "list")]
        trajectory: Option<String>,
        /// Output file (.csv, or .csv.gz to compress).
        #[arg(long, value_name = "FILE", required_unless_present = "list")]
        out: Option<PathBuf>,
        /// Ground-truth rows per second.
        #[arg(long, default_value_t = 100.0)]
        truth_rate: f64,
        /// Absolute-encoder readings per second (robots that have one).
        #[arg(long, default_value_t = 1000.0)]
        abs_rate: f64,
    },
    /// Run odometry estimators over a tick stream (docs/tick-stream.md) and score them
    /// against its truth rows.
    Replay {
        /// Robot description (docs/robot-format.md) [default: the stream's `# robot:` line].
        #[arg(long, value_name = "FILE")]
        robot: Option<PathBuf>,
        /// Tick stream file (.csv or .csv.gz).
        #[arg(long, value_name = "FILE")]
        ticks: PathBuf,
        /// Estimator to run, or `all`.
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
    },
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Emulate {
            scenario,
            duration,
            seed,
            algorithm,
            sensor,
            json,
            sweep,
            out,
            fault_slave_off_at,
            fault_host_silent_after,
        } => {
            let scenario = Scenario::builtin(&scenario)
                .ok_or_else(|| anyhow::anyhow!("unknown scenario {scenario:?}"))?;
            let mut opts = emulator::Options::new(&scenario);
            if let Some(d) = duration {
                opts.duration = d;
            }
            opts.seed = seed;
            opts.algorithm = match algorithm.as_str() {
                "arc" => protocol::spi::OdometryAlgorithm::Arc,
                "lut" => protocol::spi::OdometryAlgorithm::Lut,
                "timing" => protocol::spi::OdometryAlgorithm::Timing,
                _ => protocol::spi::OdometryAlgorithm::Exact,
            };
            if sensor == "timestamps" {
                opts.slave.sensor = firmware_slave::SensorMode::TickTimestamps;
            }
            opts.faults.slave_off_at = fault_slave_off_at;
            opts.faults.host_silent_after = fault_host_silent_after;
            if let Some(n) = sweep {
                return run_sweep(&scenario, &opts, n, json);
            }
            let run = emulator::run(&scenario, &opts)?;
            if let Some(dir) = &out {
                let written = report::write_outputs(&run, dir)?;
                if !json {
                    for p in written {
                        eprintln!("wrote {}", p.display());
                    }
                }
            }
            if json {
                println!("{}", serde_json::to_string(&run.summary)?);
            } else {
                print!("{}", report::summary_text(&run.summary));
            }
            Ok(())
        }
        Command::Accuracy { json, out } => run_accuracy(json, out),
        Command::Generate {
            list,
            robot,
            trajectory,
            out,
            truth_rate,
            abs_rate,
        } => run_generate(list, robot, trajectory, out, truth_rate, abs_rate),
        Command::Replay {
            robot,
            ticks,
            algorithm,
            out,
            counts_rate,
            json,
        } => run_replay(robot, ticks, algorithm, counts_rate, out, json),
    }
}

fn run_accuracy(json: bool, out: Option<PathBuf>) -> anyhow::Result<()> {
    use host_bench::accuracy;
    let total = (accuracy::cases().len() * accuracy::modes().len()) as u64;
    // indicatif draws only when stderr is a terminal: CI logs stay clean.
    let bar = indicatif::ProgressBar::new(total).with_style(
        indicatif::ProgressStyle::with_template("{bar:30} {pos}/{len} {elapsed} {msg}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let results = accuracy::run(|label| {
        bar.set_message(label.to_string());
        bar.inc(1);
    })?;
    bar.finish_and_clear();
    if let Some(dir) = &out {
        std::fs::create_dir_all(dir)
            .map_err(|e| anyhow::anyhow!("--out {}: {e}", dir.display()))?;
        for r in &results {
            let mode = r.mode.replace('@', "-");
            for s in &r.algorithms {
                s.write_track(&dir.join(format!("{}-{}-{mode}-{}.csv", r.case, r.robot, s.name)))?;
            }
            let title = format!("{} on {} ({}): paths and error", r.case, r.robot, r.mode);
            host_bench::report::write_case_svg(
                &dir.join(format!("{}-{}-{mode}.svg", r.case, r.robot)),
                &title,
                &r.algorithms,
            )?;
        }
    }
    if json {
        println!("{}", serde_json::json!({ "cases": results }));
    } else {
        print!("{}", accuracy::table(&results));
    }
    Ok(())
}

fn run_generate(
    list: bool,
    robot: Option<PathBuf>,
    trajectory: Option<String>,
    out: Option<PathBuf>,
    truth_rate_hz: f64,
    abs_rate_hz: f64,
) -> anyhow::Result<()> {
    use host_bench::{generate, robot::Robot, tickstream, trajectory as traj};
    if list {
        for t in traj::catalogue() {
            let drive = match t.drive {
                traj::Drive::Differential => "any robot",
                traj::Drive::Holonomic => "omni robots",
            };
            println!(
                "{:<24} {:<10} {:<11} {}",
                t.name, t.paper, drive, t.description
            );
        }
        return Ok(());
    }
    // clap guarantees these without --list.
    let (Some(robot_path), Some(name), Some(out)) = (robot, trajectory, out) else {
        anyhow::bail!("--robot, --trajectory and --out are required");
    };
    for (flag, v) in [("--truth-rate", truth_rate_hz), ("--abs-rate", abs_rate_hz)] {
        anyhow::ensure!(
            v.is_finite() && v > 0.0,
            "{flag} must be a positive number of Hz, got {v}"
        );
    }
    let robot = Robot::load(&robot_path)?;
    let named = traj::named(&name).ok_or_else(|| {
        anyhow::anyhow!("unknown trajectory {name:?}; `host-bench generate --list` names them")
    })?;
    generate::check_drive(&robot, named.drive)?;
    let t = traj::build(&name)
        .ok_or_else(|| anyhow::anyhow!("trajectory {name:?} could not be built"))?;
    // The stream names its robot relative to where the stream is written.
    let header = relative_path(
        &robot_path,
        out.parent().unwrap_or(std::path::Path::new(".")),
    );
    let stream = generate::generate(
        &robot,
        header.as_deref(),
        t.as_ref(),
        &generate::GenerateOptions {
            truth_rate_hz,
            abs_rate_hz,
        },
    )?;
    tickstream::write(&out, &stream)?;
    let ticks = stream
        .events
        .iter()
        .filter(|e| matches!(e, tickstream::Event::Tick { .. }))
        .count();
    eprintln!(
        "wrote {} ({} events, {} ticks, {:.3} s of {})",
        out.display(),
        stream.events.len(),
        ticks,
        t.duration(),
        name
    );
    Ok(())
}

/// `target` relative to the directory `from`, when both resolve (for the `# robot:` line).
fn relative_path(target: &std::path::Path, from: &std::path::Path) -> Option<String> {
    let target = std::fs::canonicalize(target).ok()?;
    let from = std::fs::canonicalize(if from.as_os_str().is_empty() {
        std::path::Path::new(".")
    } else {
        from
    })
    .ok()?;
    let common = target
        .components()
        .zip(from.components())
        .take_while(|(a, b)| a == b)
        .count();
    let mut rel = std::path::PathBuf::new();
    for _ in from.components().skip(common) {
        rel.push("..");
    }
    for c in target.components().skip(common) {
        rel.push(c);
    }
    rel.to_str().map(str::to_owned)
}

fn run_replay(
    robot: Option<PathBuf>,
    ticks: PathBuf,
    algorithm: String,
    counts_rate: Option<f64>,
    out: Option<PathBuf>,
    json: bool,
) -> anyhow::Result<()> {
    use host_bench::{replay, robot::Robot, tickstream};
    let mode = counts_rate.map_or(replay::Mode::Timestamps, |rate_hz| replay::Mode::Counts {
        rate_hz,
    });
    let stream = tickstream::read(&ticks)?;
    let robot_path = match robot {
        Some(p) => p,
        None => stream.robot_path(&ticks).ok_or_else(|| {
            anyhow::anyhow!(
                "{}: no `# robot:` line; name the robot with --robot FILE",
                ticks.display()
            )
        })?,
    };
    let robot = Robot::load(&robot_path)?;
    let names: Vec<&str> = if algorithm == "all" {
        replay::ALGORITHMS.to_vec()
    } else {
        vec![algorithm.as_str()]
    };
    // A named algorithm must run; with `all`, the ones that cannot apply to this robot or
    // mode (e.g. `timing` on sampled counts) are skipped with the reason.
    let mut scores = Vec::new();
    let mut skipped = Vec::new();
    for name in &names {
        match replay::replay(&robot, &stream, name, mode) {
            Ok(s) => scores.push(s),
            Err(e) if algorithm == "all" => {
                skipped.push(serde_json::json!({"name": name, "reason": format!("{e:#}")}))
            }
            Err(e) => return Err(e),
        }
    }
    if let Some(dir) = &out {
        std::fs::create_dir_all(dir)
            .map_err(|e| anyhow::anyhow!("--out {}: {e}", dir.display()))?;
        for s in &scores {
            s.write_track(&dir.join(format!("{}.csv", s.name)))?;
        }
    }
    if json {
        println!(
            "{}",
            serde_json::json!({ "mode": mode.to_string(), "algorithms": scores, "skipped": skipped })
        );
    } else {
        println!(
            "{} on {} ({} events), encoders read as {mode}",
            ticks.display(),
            robot.name,
            stream.events.len()
        );
        for s in &scores {
            println!(
                "{:<8} final error {:9.4} mm, max {:9.4} mm, final heading error {:+.5} deg, path {:.3} m",
                s.name,
                s.final_error_m * 1e3,
                s.max_error_m * 1e3,
                s.final_heading_error_rad.to_degrees(),
                s.path_length_m
            );
        }
        for k in &skipped {
            println!(
                "{:<8} skipped: {}",
                k["name"].as_str().unwrap_or(""),
                k["reason"].as_str().unwrap_or("")
            );
        }
    }
    Ok(())
}

fn run_sweep(
    scenario: &Scenario,
    opts: &emulator::Options,
    n: u32,
    json: bool,
) -> anyhow::Result<()> {
    anyhow::ensure!(n > 0, "--sweep needs at least one run");
    let mut summaries = Vec::new();
    for k in 0..n as u64 {
        let mut o = opts.clone();
        o.seed = opts.seed + k;
        let s = emulator::run(scenario, &o)?.summary;
        if !json {
            println!(
                "seed {:>4}: final error {:7.3} mm, max {:7.3} mm, heading {:+7.3} deg, {:5.1} mm from goal, rejected frames {}",
                s.seed,
                s.final_error_m * 1e3,
                s.max_error_m * 1e3,
                s.final_heading_error_rad.to_degrees(),
                s.distance_to_goal_m * 1e3,
                s.spi_frames_rejected + s.serial_frames_rejected
            );
        }
        summaries.push(s);
    }
    let stat = |f: fn(&emulator::Summary) -> f64| {
        let mut v: Vec<f64> = summaries.iter().map(f).collect();
        v.sort_by(f64::total_cmp);
        (v[0], v[v.len() / 2], v[v.len() - 1])
    };
    let fe = stat(|s| s.final_error_m);
    let me = stat(|s| s.max_error_m);
    let he = stat(|s| s.final_heading_error_rad.abs());
    if json {
        let spread = |(min, median, max): (f64, f64, f64)| serde_json::json!({"min": min, "median": median, "max": max});
        println!(
            "{}",
            serde_json::json!({
                "scenario": scenario.name,
                "runs": summaries,
                "final_error_m": spread(fe),
                "max_error_m": spread(me),
                "abs_final_heading_error_rad": spread(he),
            })
        );
    } else {
        println!(
            "{} runs of {}: final error min {:.3} / median {:.3} / max {:.3} mm; max error up to {:.3} mm; |heading error| up to {:.3} deg",
            n,
            scenario.name,
            fe.0 * 1e3,
            fe.1 * 1e3,
            fe.2 * 1e3,
            me.2 * 1e3,
            he.2.to_degrees()
        );
    }
    Ok(())
}
