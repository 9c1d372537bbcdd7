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
        Command::Replay {
            robot,
            ticks,
            algorithm,
            counts_rate,
            json,
        } => run_replay(robot, ticks, algorithm, counts_rate, json),
    }
}

fn run_replay(
    robot: Option<PathBuf>,
    ticks: PathBuf,
    algorithm: String,
    counts_rate: Option<f64>,
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
