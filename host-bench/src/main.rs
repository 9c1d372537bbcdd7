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
        /// Print the summary as one JSON object instead of text.
        #[arg(long)]
        json: bool,
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
            json,
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
            opts.faults.slave_off_at = fault_slave_off_at;
            opts.faults.host_silent_after = fault_host_silent_after;
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
    }
}
