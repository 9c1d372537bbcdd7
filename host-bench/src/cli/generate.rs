//! `generate`: the exact tick stream of a robot's ideal encoders along a catalogue trajectory.

use std::path::{Path, PathBuf};

use anyhow::{bail, ensure, Context, Result};
use clap::Args;
use host_bench::formats::{robot::Robot, tickstream};
use host_bench::sim::generate::{self, PowerOnPhase};
use host_bench::sim::trajectory as traj;

#[derive(Args, Debug)]
pub struct GenerateArgs {
    /// List the trajectories and exit.
    #[arg(long)]
    pub list: bool,
    /// Robot description (docs/robot-format.md).
    #[arg(long, value_name = "FILE", required_unless_present = "list")]
    pub robot: Option<PathBuf>,
    /// Trajectory name (see --list).
    #[arg(long, required_unless_present = "list")]
    pub trajectory: Option<String>,
    /// Output file (.csv, or .csv.gz to compress).
    #[arg(long, value_name = "FILE", required_unless_present = "list")]
    pub out: Option<PathBuf>,
    /// Ground-truth rows per second.
    #[arg(long, default_value_t = 100.0)]
    pub truth_rate: f64,
    /// Absolute-encoder readings per second (robots that have one).
    #[arg(long, default_value_t = 1000.0)]
    pub abs_rate: f64,
    /// Where each encoder stands inside its count at power-on: `random` (each encoder its own
    /// phase, from --seed), `zero` (every encoder exactly on an edge: the special case), or a
    /// fraction of a count in [0, 1) for every encoder.
    #[arg(long, value_name = "random|zero|FRACTION", default_value = "random")]
    pub phase: String,
    /// Seed of the random phases [default: 0]; only with --phase random. It draws each
    /// encoder's edges too (with --edges typical or max).
    #[arg(long, value_name = "N")]
    pub seed: Option<u64>,
    /// Where the encoders put their edges: `ideal` (one count apart), or Broadcom HEDS-9040's
    /// datasheet errors, `typical` or `max` (state widths, phase, cycle and position errors,
    /// capture latency: docs/odometry.md, "Encoders as they are"); `typical-cycle` and
    /// `max-cycle` without the errors over a revolution and the latency.
    #[arg(
        long,
        value_name = "ideal|typical|max|typical-cycle|max-cycle",
        default_value = "ideal"
    )]
    pub edges: String,
    /// A carriage's swivel at the start, degrees (its heading minus the body's; -180 to 180):
    /// where the last motion left it (0: aligned with the body).
    #[arg(
        long,
        value_name = "DEG",
        default_value_t = 0.0,
        allow_negative_numbers = true
    )]
    pub start_swivel_deg: f64,
}

/// `--phase` and `--seed` as a [`PowerOnPhase`].
fn power_on_phase(phase: &str, seed: Option<u64>) -> Result<PowerOnPhase> {
    let p = match phase {
        "random" => PowerOnPhase::Random {
            seed: seed.unwrap_or(0),
        },
        "zero" => PowerOnPhase::Zero,
        other => match other.parse::<f64>() {
            Ok(x) if (0.0..1.0).contains(&x) => PowerOnPhase::Fraction(x),
            _ => bail!(
                "--phase must be random, zero, or a fraction of a count in [0, 1), got {other:?}"
            ),
        },
    };
    if seed.is_some() && !matches!(p, PowerOnPhase::Random { .. }) {
        bail!("--seed only applies to --phase random (got --phase {phase})");
    }
    Ok(p)
}

pub fn run_generate(a: GenerateArgs) -> Result<()> {
    if a.list {
        for t in traj::catalogue() {
            let drive = match t.drive {
                traj::Drive::Differential => "any robot",
                traj::Drive::Holonomic => "omni robots",
            };
            println!(
                "{:<24} {:<28} {:<11} {}",
                t.name, t.paper, drive, t.description
            );
        }
        return Ok(());
    }
    // clap guarantees these without --list.
    let (Some(robot_path), Some(name), Some(out)) = (a.robot, a.trajectory, a.out) else {
        bail!("--robot, --trajectory and --out are required");
    };
    for (flag, v) in [("--truth-rate", a.truth_rate), ("--abs-rate", a.abs_rate)] {
        let max = host_bench::sim::generate::MAX_SAMPLE_RATE_HZ;
        ensure!(
            v > 0.0 && v <= max,
            "{flag} must be in (0, {max}] Hz, got {v}"
        );
    }
    // Writing the stream over its own robot file would lose the robot it names.
    if let (Ok(o), Ok(r)) = (out.canonicalize(), robot_path.canonicalize()) {
        ensure!(
            o != r,
            "--out {} is the robot file given with --robot: the stream would overwrite the robot \
             it is made for",
            out.display()
        );
    }
    // Before the work, as every command's outputs: a folder that is not there, or a device.
    host_bench::formats::atomic::check_output(&out)
        .with_context(|| format!("--out {}", out.display()))?;
    let phase = power_on_phase(&a.phase, a.seed)?;
    if !(-180.0..=180.0).contains(&a.start_swivel_deg) {
        bail!(
            "--start-swivel-deg is an angle from -180 to 180 degrees: got {}",
            a.start_swivel_deg
        );
    }
    let edges = generate::EdgeErrors::preset(&a.edges).context("--edges")?;
    let robot = Robot::load(&robot_path)?;
    if a.start_swivel_deg != 0.0 && robot.carriage.is_none() {
        bail!(
            "--start-swivel-deg: robot {} has no swivel carriage to start swung",
            robot.name
        );
    }
    let named = traj::named(&name).ok_or_else(|| {
        anyhow::anyhow!("unknown trajectory {name:?}; `host-bench generate --list` names them")
    })?;
    generate::check_drive(&robot, named.drive)?;
    let t = traj::build(&name)
        .ok_or_else(|| anyhow::anyhow!("trajectory {name:?} could not be built"))?;
    // The stream names its robot relative to where the stream is written.
    let header = relative_path(&robot_path, out.parent().unwrap_or(Path::new(".")));
    let stream = generate::generate(
        &robot,
        header.as_deref(),
        t.as_ref(),
        &generate::GenerateOptions {
            truth_rate_hz: a.truth_rate,
            abs_rate_hz: a.abs_rate,
            phase,
            edges,
            start_swivel_rad: a.start_swivel_deg.to_radians(),
        },
    )?;
    tickstream::write(&out, &stream)?;
    let ticks = stream
        .events
        .iter()
        .filter(|e| matches!(e, tickstream::Event::Tick { .. }))
        .count();
    eprintln!(
        "wrote {} ({} events, {} ticks, {:.3} s of {}, power-on phase {phase}, edges {edges})",
        out.display(),
        stream.events.len(),
        ticks,
        t.duration(),
        name
    );
    Ok(())
}

/// `target` relative to the directory `from`, when both resolve (for the `# robot:` line).
fn relative_path(target: &Path, from: &Path) -> Option<String> {
    let target = std::fs::canonicalize(target).ok()?;
    let from = std::fs::canonicalize(if from.as_os_str().is_empty() {
        Path::new(".")
    } else {
        from
    })
    .ok()?;
    let common = target
        .components()
        .zip(from.components())
        .take_while(|(a, b)| a == b)
        .count();
    let mut rel = PathBuf::new();
    for _ in from.components().skip(common) {
        rel.push("..");
    }
    for c in target.components().skip(common) {
        rel.push(c);
    }
    rel.to_str().map(str::to_owned)
}
