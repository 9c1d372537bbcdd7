//! UMBmark's squares on the bench (`calibrate --port`): driven through the master, each one
//! recorded off the slave into a tick stream, and its end pose measured (typed in by the
//! person with the tape measure, or the virtual board's truth), ready for [`super::runs`].
//!
//! ```text
//!  set the drive ─► per square: [place the robot] ─► record ◄─ Track samples (serial::drive)
//!                                                      │
//!                        DIR/umbmark-cw-1.csv ◄────────┘ ─► [measured end pose] ─► DIR/measured.csv
//! ```

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use protocol::serial::{DriveGeometry, DriveKind, HostToMaster};
use robot_math::Pose2;
use serde::Serialize;

use crate::formats::robot::Robot;
use crate::serial::drive::PathDriver;
use crate::serial::link::Link;
use crate::serial::record::{record_moving, RecordOutcome, RecordRequest};
use crate::serial::session;
use crate::sim::trajectory::{umbmark_square, TURN_RATE_RAD_S};

/// What to drive.
pub struct Squares<'a> {
    /// The robot file the boards are given (its nominal geometry).
    pub robot_file: &'a Path,
    pub robot: &'a Robot,
    pub side_m: f64,
    /// Cruise speed; `None`: [`every_edge_speed`].
    pub speed_m_s: Option<f64>,
    /// Squares each way (UMBmark: 5).
    pub each_way: usize,
    /// Where the runs and their measured end poses go.
    pub dir: &'a Path,
    pub progress: Option<&'a indicatif::ProgressBar>,
}

/// One square driven.
#[derive(Clone, Debug, Serialize)]
pub struct DrivenSquare {
    pub file: String,
    pub counter_clockwise: bool,
    /// The end pose typed in (a real board); none when the board sent its truth.
    pub measured: Option<(f64, f64, f64)>,
    pub recording: RecordOutcome,
}

/// What was driven, and where it went.
#[derive(Clone, Debug, Serialize)]
pub struct DrivenSquares {
    pub side_m: f64,
    pub speed_m_s: f64,
    pub turn_rate_rad_s: f64,
    pub squares: Vec<DrivenSquare>,
    /// `DIR/measured.csv`, when end poses were typed in.
    pub measured_file: Option<String>,
}

impl DrivenSquares {
    pub fn run_files(&self, dir: &Path) -> Vec<PathBuf> {
        self.squares.iter().map(|s| dir.join(&s.file)).collect()
    }
}

/// The fastest cruise at which a recording keeps every edge of the robot's finest encoder at
/// `baud`: the virtual board's course speed for it ([`crate::sim::virtual_board::course_speed_for`],
/// 0.05 m/s for seed 004's 32.7 µm counts at 115 200 baud, where 0.08 m/s already loses
/// events), in proportion to the baud rate, and at most 80 % of the drive's top speed.
pub fn every_edge_speed(robot: &Robot, drive: &DriveGeometry, baud: u32) -> Result<f64> {
    let layout = robot.odometry_layout()?;
    let link = crate::sim::virtual_board::course_speed_for(&layout) * baud as f64 / 115_200.0;
    Ok(link.min(0.8 * drive.v_max_um_s as f64 * 1e-6))
}

/// The squares' file names, clockwise first as UMBmark drives them.
fn plan(each_way: usize) -> Vec<(String, bool)> {
    let mut out = Vec::new();
    for ccw in [false, true] {
        for k in 1..=each_way {
            let way = if ccw { "ccw" } else { "cw" };
            out.push((format!("umbmark-{way}-{k}.csv"), ccw));
        }
    }
    out
}

/// Drive the squares: `ask` puts a question to the person at the bench and returns the line
/// they answer (only asked of a board that does not send its truth).
pub fn drive_squares(
    link: &mut Link,
    sq: &Squares,
    ask: &mut dyn FnMut(&str) -> Result<String>,
) -> Result<DrivenSquares> {
    if !(sq.side_m > 0.0 && sq.side_m <= 20.0) {
        bail!(
            "--side is the square's side, over 0 and at most 20 m: got {}",
            sq.side_m
        );
    }
    if !(1..=20).contains(&sq.each_way) {
        bail!(
            "--each is how many squares each way, 1 to 20: got {}",
            sq.each_way
        );
    }
    let drive = sq
        .robot
        .drive_geometry()
        .with_context(|| format!("--robot {}: the master drives it", sq.robot_file.display()))?;
    let files = plan(sq.each_way);
    std::fs::create_dir_all(sq.dir).with_context(|| {
        format!(
            "--drive-squares {}: cannot make the folder",
            sq.dir.display()
        )
    })?;
    for (name, _) in &files {
        let path = sq.dir.join(name);
        if path.exists() {
            bail!(
                "--drive-squares {} already holds {name}: name a new folder (runs are never written \
                 over)",
                sq.dir.display()
            );
        }
    }
    let measured_path = sq.dir.join("measured.csv");
    if measured_path.exists() {
        bail!(
            "--drive-squares {} already holds measured.csv: name a new folder",
            sq.dir.display()
        );
    }
    let info = session::hello(link)?;
    // A virtual board sends its truth: the squares' end poses need no tape measure, and the
    // robot drives each from wherever the last one left it.
    let simulated = crate::serial::record::latest_truth(link)?.is_some();
    let v_max = drive.v_max_um_s as f64 * 1e-6;
    let speed = match sq.speed_m_s {
        Some(v) if v > 0.0 && v <= v_max => v,
        Some(v) => bail!(
            "--speed is the cruise speed, over 0 and at most the robot's {v_max} m/s: got {v}"
        ),
        None => every_edge_speed(sq.robot, &drive, info.baud)?,
    };
    // Turn in place no faster than the wheels roll on the straight.
    let lever = sq
        .robot
        .encoders
        .iter()
        .map(|e| e.wheel.x.hypot(e.wheel.y))
        .fold(0.0f64, f64::max);
    let turn_rate = if lever > 0.0 {
        (speed / lever).min(TURN_RATE_RAD_S)
    } else {
        TURN_RATE_RAD_S
    };
    let ahead_m = match drive.kind {
        DriveKind::OffsetDiff { offset_um, .. } => offset_um as f64 * 1e-6,
        DriveKind::Omni3 { .. } => 0.0,
    };
    session::set_drive(link, &drive)?;

    let mut squares = Vec::new();
    let mut measured: Vec<(String, Pose2)> = Vec::new();
    for (k, (name, ccw)) in files.iter().enumerate() {
        let out = sq.dir.join(name);
        let way = if *ccw {
            "counter-clockwise"
        } else {
            "clockwise"
        };
        let what = format!("square {} of {} ({way}, {name})", k + 1, files.len());
        if let Some(bar) = sq.progress {
            bar.set_message(what.clone());
        }
        if !simulated {
            ask(&format!(
                "{what}: put the robot on the start mark facing +x, {} m clear ahead and to the \
                 {}, and press Enter to drive",
                sq.side_m,
                if *ccw { "left" } else { "right" }
            ))?;
        }
        let mut driver = PathDriver::new(
            umbmark_square(sq.side_m, speed, turn_rate, *ccw),
            ahead_m,
            info.baud,
        );
        let req = RecordRequest {
            out: &out,
            duration_s: None,
            counts: false,
            robot: Some(sq.robot_file),
            progress: sq.progress,
            view: None,
        };
        let rec = record_moving(link, &req, Some(&mut driver));
        // Whatever happened, the motors stop.
        let _ = link.send(&HostToMaster::Stop);
        let rec = rec.with_context(|| format!("{what}: recording it"))?;
        if rec.stopped_by != "motion over" {
            bail!(
                "{what}: the recording ended before the square did ({}); {} kept as it is",
                rec.partial.as_deref().unwrap_or(&rec.stopped_by),
                out.display()
            );
        }
        if rec.lost_events > 0 || rec.lost_updates > 0 || rec.records_undecodable > 0 {
            bail!(
                "{what}: the link lost {} events and {} updates, and {} records did not decode: \
                 a square with gaps cannot be calibrated on. Drive slower (--speed, now {speed:.3} \
                 m/s) or at a higher baud rate",
                rec.lost_events,
                rec.lost_updates,
                rec.records_undecodable
            );
        }
        let mut typed = None;
        if !simulated {
            let pose = ask_pose(ask, &what)?;
            measured.push((name.clone(), pose));
            write_measured(&measured_path, &measured)?;
            typed = Some((pose.x, pose.y, pose.theta.to_degrees()));
        }
        squares.push(DrivenSquare {
            file: name.clone(),
            counter_clockwise: *ccw,
            measured: typed,
            recording: rec,
        });
    }
    Ok(DrivenSquares {
        side_m: sq.side_m,
        speed_m_s: speed,
        turn_rate_rad_s: turn_rate,
        squares,
        measured_file: (!measured.is_empty()).then(|| measured_path.display().to_string()),
    })
}

/// Ask for a measured end pose until one reads.
fn ask_pose(ask: &mut dyn FnMut(&str) -> Result<String>, what: &str) -> Result<Pose2> {
    let mut question = format!(
        "{what}: where did the robot stop? x_m y_m heading_deg, from the start mark (+x the first \
         side's way, +y to its left, heading counter-clockwise)"
    );
    loop {
        let line = ask(&question)?;
        match parse_pose(&line) {
            Ok(p) => return Ok(p),
            Err(e) => question = format!("{e}; again: x_m y_m heading_deg"),
        }
    }
}

/// `x_m y_m heading_deg`, separated by spaces or commas.
pub fn parse_pose(line: &str) -> Result<Pose2> {
    let parts: Vec<&str> = line
        .split(|c: char| c == ',' || c.is_whitespace())
        .filter(|s| !s.is_empty())
        .collect();
    let [x, y, h] = parts.as_slice() else {
        bail!("\"{}\" is not three numbers", line.trim());
    };
    let num = |s: &str, what: &str| -> Result<f64> {
        let v: f64 = s
            .parse()
            .map_err(|_| anyhow::anyhow!("{what} \"{s}\" is not a number"))?;
        if !v.is_finite() || v.abs() > 1e4 {
            bail!("{what} = {v} is no measured value");
        }
        Ok(v)
    };
    Ok(Pose2::new(
        num(x, "x_m")?,
        num(y, "y_m")?,
        num(h, "heading_deg")?.to_radians(),
    ))
}

/// `run,x_m,y_m,heading_deg`, as `calibrate --measured` reads it, written whole after every
/// answer (an interrupted session keeps what was typed).
fn write_measured(path: &Path, rows: &[(String, Pose2)]) -> Result<()> {
    crate::formats::atomic::write_atomically(path, |f| {
        use std::io::Write as _;
        writeln!(f, "run,x_m,y_m,heading_deg")?;
        for (run, p) in rows {
            writeln!(f, "{run},{:.4},{:.4},{:.3}", p.x, p.y, p.theta.to_degrees())?;
        }
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_typed_pose_reads_with_spaces_or_commas_and_a_bad_one_says_which_number() {
        let p = parse_pose(" 0.012, -0.034  2.5 ").unwrap();
        assert_eq!((p.x, p.y), (0.012, -0.034));
        assert!((p.theta.to_degrees() - 2.5).abs() < 1e-12);
        let e = parse_pose("0.1 0.2").unwrap_err().to_string();
        assert!(e.contains("three numbers"), "{e}");
        let e = parse_pose("0.1 y 3").unwrap_err().to_string();
        assert!(e.contains("y_m") && e.contains("\"y\""), "{e}");
        let e = parse_pose("0.1 0.2 inf").unwrap_err().to_string();
        assert!(e.contains("heading_deg"), "{e}");
    }

    #[test]
    fn squares_go_clockwise_first_each_named_for_its_way() {
        let p = plan(2);
        let names: Vec<_> = p.iter().map(|(n, _)| n.as_str()).collect();
        assert_eq!(
            names,
            [
                "umbmark-cw-1.csv",
                "umbmark-cw-2.csv",
                "umbmark-ccw-1.csv",
                "umbmark-ccw-2.csv"
            ]
        );
        assert_eq!(p.iter().filter(|(_, ccw)| *ccw).count(), 2);
    }
}
