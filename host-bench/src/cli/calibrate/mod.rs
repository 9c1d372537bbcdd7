//! `host-bench calibrate`: a robot's geometry errors from runs, and its robot file corrected.

mod fit;
mod umbmark;

use std::path::PathBuf;

use anyhow::{bail, Context, Result};
use clap::Args;
use host_bench::calibrate::runs::{self, RunEnd};
use host_bench::formats::robot::Robot;

#[derive(Args)]
pub struct CalibrateArgs {
    /// The robot file the runs were driven with (its nominal geometry).
    #[arg(long, value_name = "FILE")]
    pub robot: PathBuf,
    /// The runs: tick streams (their end pose the last truth row, or --measured), or what
    /// `emulate --json` printed (one run, or a --sweep's runs).
    #[arg(long, value_name = "FILE", num_args = 1.., required = true)]
    pub runs: Vec<PathBuf>,
    /// `umbmark`: Borenstein's UMBmark, for two parallel measuring wheels, from squares
    /// driven both ways. `fit`: every encoder's lever arm, direction and travel per count by
    /// least squares over the runs' end poses, any body-fixed layout (docs/calibration.md).
    #[arg(long, default_value = "umbmark", value_parser = ["umbmark", "fit"])]
    pub method: String,
    /// End poses measured by hand, `run,x_m,y_m,heading_deg` (run: the file as given to
    /// --runs, or its name), in the frame the run started in (origin, facing +x) for a stream
    /// with no truth rows, else in its truth's frame.
    #[arg(long, value_name = "FILE")]
    pub measured: Option<PathBuf>,
    /// Write the corrected robot file here: the nominal file with its encoders' numbers
    /// replaced, every comment kept, whole or not at all.
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
    /// Print the whole calibration as one JSON object.
    #[arg(long)]
    pub json: bool,
    /// `fit`: the end poses' measuring noise, one standard deviation, in mm and degrees: the
    /// residuals' units and the parameters' σ.
    #[arg(long, value_name = "MM", default_value_t = 1.0)]
    pub sigma_mm: f64,
    #[arg(long, value_name = "DEG", default_value_t = 0.2)]
    pub sigma_deg: f64,
    /// `fit`: runs not used in the fit (tick streams), replayed on the nominal and the
    /// corrected robot: each one's end error both ways.
    #[arg(long, value_name = "FILE", num_args = 1..)]
    pub check: Vec<PathBuf>,
}

pub fn run_calibrate(a: CalibrateArgs) -> Result<()> {
    // Every output checked before any work.
    if let Some(out) = &a.out {
        host_bench::formats::atomic::check_output(out).context("--out")?;
        let mut inputs = vec![("the robot file", a.robot.as_path())];
        inputs.extend(a.runs.iter().map(|r| ("a run", r.as_path())));
        inputs.extend(a.check.iter().map(|r| ("a run to check", r.as_path())));
        inputs.extend(a.measured.as_deref().map(|m| ("the measured poses", m)));
        host_bench::formats::atomic::refuse_inputs("--out", std::slice::from_ref(out), &inputs)?;
    }
    let text = std::fs::read_to_string(&a.robot)
        .with_context(|| format!("--robot {}", a.robot.display()))?;
    let robot = Robot::parse(&text, &a.robot)?;
    let measured = match &a.measured {
        Some(m) => runs::read_measured(m)?,
        None => Default::default(),
    };
    let mut all: Vec<RunEnd> = Vec::new();
    for path in &a.runs {
        all.extend(runs::read_runs(path, &robot, &measured)?);
    }
    match a.method.as_str() {
        "fit" => fit::run(&a, &text, &robot, &measured, &all),
        _ => umbmark::run(&a, &text, &robot, &all),
    }
}

/// The corrected robot file written whole, if `--out` asked for it.
fn write_out(a: &CalibrateArgs, text: &str) -> Result<()> {
    if let Some(out) = &a.out {
        host_bench::formats::atomic::write_atomically(out, |f| {
            use std::io::Write as _;
            f.write_all(text.as_bytes())?;
            Ok(())
        })?;
    }
    Ok(())
}

/// `--sigma-mm` and `--sigma-deg`, checked.
fn noise(a: &CalibrateArgs) -> Result<host_bench::calibrate::fit::Noise> {
    for (v, name) in [(a.sigma_mm, "--sigma-mm"), (a.sigma_deg, "--sigma-deg")] {
        if !(v > 0.0 && v < 1e4) {
            bail!("{name} is a measuring noise, over 0: got {v}");
        }
    }
    Ok(host_bench::calibrate::fit::Noise {
        sigma_m: a.sigma_mm * 1e-3,
        sigma_rad: a.sigma_deg.to_radians(),
    })
}
