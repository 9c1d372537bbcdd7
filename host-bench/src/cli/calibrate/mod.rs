//! `host-bench calibrate`: a robot's geometry errors from runs, and its robot file corrected.

mod fit;
mod umbmark;

use std::path::PathBuf;

use anyhow::{bail, Context, Result};
use clap::Args;
use host_bench::calibrate::bench;
use host_bench::calibrate::runs::{self, RunEnd};
use host_bench::formats::robot::Robot;

#[derive(Args)]
pub struct CalibrateArgs {
    /// The robot file the runs were driven with (its nominal geometry).
    #[arg(long, value_name = "FILE")]
    pub robot: PathBuf,
    /// The runs: tick streams (their end pose the last truth row, or --measured), or what
    /// `emulate --json` printed (one run, or a --sweep's runs).
    #[arg(long, value_name = "FILE", num_args = 1.., required_unless_present = "drive_squares")]
    pub runs: Vec<PathBuf>,
    /// On the bench instead of --runs: drive UMBmark's squares through the master (--port),
    /// record each into DIR (a new folder), ask for each one's measured end pose (a virtual
    /// board's truth needs none: DIR/measured.csv keeps what was typed), then calibrate on them.
    #[arg(long, value_name = "DIR", conflicts_with_all = ["runs", "measured"])]
    pub drive_squares: Option<PathBuf>,
    #[command(flatten)]
    pub port: crate::cli::serial::PortArgs,
    /// --drive-squares: the squares' side, m (UMBmark's: 4).
    #[arg(long, value_name = "M", default_value_t = 4.0)]
    pub side: f64,
    /// --drive-squares: how many squares each way (UMBmark's: 5).
    #[arg(long, value_name = "N", default_value_t = 5)]
    pub each: usize,
    /// --drive-squares: cruise speed, m/s [default: the fastest at which the link carries
    /// every edge of the robot's finest encoder].
    #[arg(long, value_name = "M_S")]
    pub speed: Option<f64>,
    /// --drive-squares: load the corrected robot into the slave afterwards, confirmed by the
    /// fingerprint the slave then reports.
    #[arg(long, requires = "drive_squares")]
    pub upload: bool,
    /// `umbmark`: Borenstein's UMBmark, for two parallel measuring wheels (on the body or a
    /// swivel carriage), from squares driven both ways. `fit`: every encoder's lever arm,
    /// direction and travel per count by least squares over the runs' end poses, any
    /// body-fixed layout, or a carriage's wheel spacing and travels (docs/calibration.md).
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

/// A calibration made: its report both ways, and the corrected robot file's text.
pub(crate) struct Calibrated {
    json: serde_json::Value,
    text: String,
    fitted: String,
}

pub fn run_calibrate(mut a: CalibrateArgs) -> Result<()> {
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
    // On the bench: the squares first, then the calibration on them as on any runs.
    let mut bench = None;
    if let Some(dir) = a.drive_squares.clone() {
        let mut link = a.port.open()?;
        let driven = drive_squares(&a, &dir, &robot, &mut link)?;
        a.runs = driven.run_files(&dir);
        a.measured = driven.measured_file.as_ref().map(PathBuf::from);
        bench = Some((link, driven));
    }
    let measured = match &a.measured {
        Some(m) => runs::read_measured(m)?,
        None => Default::default(),
    };
    let mut all: Vec<RunEnd> = Vec::new();
    for path in &a.runs {
        all.extend(runs::read_runs(path, &robot, &measured)?);
    }
    let mut done = match a.method.as_str() {
        "fit" => fit::run(&a, &text, &robot, &measured, &all)?,
        _ => umbmark::run(&a, &text, &robot, &all)?,
    };
    write_out(&a, &done.fitted)?;
    if let Some((mut link, driven)) = bench {
        done.json["bench"] = serde_json::to_value(&driven)?;
        if a.upload {
            let fitted = Robot::parse(&done.fitted, &a.robot)?;
            let layout = fitted.odometry_layout()?;
            let fp = host_bench::serial::session::load_robot(&mut link, &layout)?;
            done.json["uploaded_fingerprint"] = format!("{fp:08x}").into();
            done.text += &format!(
                "uploaded    the slave runs the corrected robot now (fingerprint {fp:08x})\n"
            );
        }
    }
    if a.json {
        println!("{}", serde_json::to_string(&done.json)?);
    } else {
        print!("{}", done.text);
    }
    Ok(())
}

/// `--drive-squares`: UMBmark's squares on the bench, the person at it asked on the terminal.
fn drive_squares(
    a: &CalibrateArgs,
    dir: &std::path::Path,
    robot: &Robot,
    link: &mut host_bench::serial::link::Link,
) -> Result<bench::DrivenSquares> {
    let bar = crate::cli::serial::progress_bar("{spinner} {elapsed} {msg}");
    let mut ask = |question: &str| -> Result<String> {
        bar.suspend(|| {
            eprint!("{question}: ");
            let mut line = String::new();
            match std::io::stdin().read_line(&mut line) {
                Ok(0) => bail!("no answer (the input ended) to: {question}"),
                Ok(_) => Ok(line),
                Err(e) => Err(e).context("reading the answer"),
            }
        })
    };
    let driven = bench::drive_squares(
        link,
        &bench::Squares {
            robot_file: &a.robot,
            robot,
            side_m: a.side,
            speed_m_s: a.speed,
            each_way: a.each,
            dir,
            progress: Some(&bar),
        },
        &mut ask,
    )?;
    bar.finish_and_clear();
    eprintln!(
        "drove {} squares of {} m at {:.3} m/s (turns at {:.2} rad/s) into {}",
        driven.squares.len(),
        driven.side_m,
        driven.speed_m_s,
        driven.turn_rate_rad_s,
        dir.display()
    );
    Ok(driven)
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
