//! A robot file with new numbers for its encoders, every other byte as it was: what
//! `calibrate --out` writes, so the user's comments, order and other tables survive.

use std::ops::Range;
use std::path::Path;

use super::raw::RawRobot;
use super::{robot_shape, Robot, RobotError, FORMAT};
use crate::formats::toml_file::TomlFile;

/// One encoder's geometry as a robot file gives it.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct EncoderGeometry {
    pub x_m: f64,
    pub y_m: f64,
    pub direction_deg: f64,
    pub metres_per_count: f64,
}

impl Robot {
    /// `text` (this robot's file) with its encoders' geometry replaced by `new` (in file
    /// order) and `note` as comment lines at its top. An encoder given by `counts_per_rev`
    /// and `wheel_diameter_m` keeps its counts and gets the diameter that makes the new
    /// metres per count. The result is read back: it must be a robot file with exactly
    /// these encoders.
    pub fn with_encoders(
        text: &str,
        path: &Path,
        new: &[EncoderGeometry],
        note: &[String],
    ) -> Result<String, RobotError> {
        let file = TomlFile {
            path,
            text,
            format: FORMAT,
            kind: "robot file",
        };
        let raw: RawRobot = file.read(robot_shape)?;
        if raw.encoders.len() != new.len() {
            return Err(file.at(
                0..1,
                "encoders",
                format!(
                    "has {} encoders, the new geometry {}",
                    raw.encoders.len(),
                    new.len()
                ),
            ));
        }
        let mut edits: Vec<(Range<usize>, String)> = Vec::new();
        for (e, g) in raw.encoders.iter().zip(new) {
            let e = e.get_ref();
            edits.push((e.x_m.span(), number(g.x_m)));
            edits.push((e.y_m.span(), number(g.y_m)));
            edits.push((e.direction_deg.span(), number(g.direction_deg)));
            match (&e.metres_per_count, &e.counts_per_rev, &e.wheel_diameter_m) {
                (Some(m), _, _) => edits.push((m.span(), number(g.metres_per_count))),
                (None, Some(counts), Some(d)) => {
                    let diameter =
                        g.metres_per_count * *counts.get_ref() as f64 / std::f64::consts::PI;
                    edits.push((d.span(), number(diameter)));
                }
                // The checks refuse such a file before this is reached.
                _ => return Err(file.at(0..1, "encoders", "an encoder without its scale")),
            }
        }
        edits.sort_by_key(|(span, _)| std::cmp::Reverse(span.start));
        let mut out = text.to_string();
        for (span, value) in edits {
            out.replace_range(span, &value);
        }
        let header: String = note.iter().map(|l| format!("# {l}\n")).collect();
        let out = header + &out;
        // Read back as any robot file is, and checked to hold what was asked.
        let robot = Robot::parse(&out, path)?;
        for (i, (got, want)) in robot.encoders.iter().zip(new).enumerate() {
            let close = |a: f64, b: f64| (a - b).abs() <= 1e-12 * a.abs().max(b.abs()).max(1.0);
            let dir = got.wheel.uy.atan2(got.wheel.ux).to_degrees();
            let turn = (dir - want.direction_deg).rem_euclid(360.0);
            if !(close(got.wheel.x, want.x_m)
                && close(got.wheel.y, want.y_m)
                && (turn < 1e-9 || 360.0 - turn < 1e-9)
                && close(got.metres_per_count, want.metres_per_count))
            {
                return Err(file.at(
                    0..1,
                    "encoders",
                    format!("encoder {i} did not read back as written: {got:?} for {want:?}"),
                ));
            }
        }
        Ok(out)
    }
}

/// A TOML float that reads back as exactly `v` (Rust's shortest round-trip form, which
/// always has a `.` or an exponent).
fn number(v: f64) -> String {
    let s = format!("{v:?}");
    if s.contains(['.', 'e', 'E']) || !v.is_finite() {
        s
    } else {
        format!("{s}.0")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn new_encoder_numbers_replace_the_old_and_nothing_else_changes() {
        let path = Path::new("robots/seed002.toml");
        let text = std::fs::read_to_string(
            Path::new(env!("CARGO_MANIFEST_DIR")).join("../robots/seed002.toml"),
        )
        .unwrap();
        let robot = Robot::parse(&text, path).unwrap();
        let new = [
            EncoderGeometry {
                x_m: 0.001,
                y_m: 0.1545,
                direction_deg: 0.0,
                metres_per_count: robot.encoders[0].metres_per_count * 1.01,
            },
            EncoderGeometry {
                x_m: 0.001,
                y_m: -0.1545,
                direction_deg: 0.0,
                metres_per_count: robot.encoders[1].metres_per_count,
            },
        ];
        let out = Robot::with_encoders(&text, path, &new, &["calibrated".into()]).unwrap();
        assert!(out.starts_with("# calibrated\n"));
        let back = Robot::parse(&out, path).unwrap();
        assert_eq!(back.drive_wheels, robot.drive_wheels);
        assert_eq!(back.motor, robot.motor);
        assert_eq!(back.encoders[0].wheel.y, 0.1545);
        // Only the numbers changed: every comment line is still there.
        let comments = |t: &str| t.lines().filter(|l| l.contains('#')).count();
        assert_eq!(comments(&out), comments(&text) + 1);
        // The wrong number of encoders is refused, not half-written.
        assert!(Robot::with_encoders(&text, path, &new[..1], &[]).is_err());
    }
}
