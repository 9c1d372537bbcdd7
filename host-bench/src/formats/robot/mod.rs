//! Robot descriptions: a robot's sensors and geometry in a small TOML file, format
//! `"omnibench robot v1"`. Every key, unit and sign convention is in `docs/robot-format.md`;
//! the seed robots are in `robots/`.
//!
//! Loading is strict: an unknown key, a value of the wrong type or a geometry the odometry
//! cannot use is an error that names the file, the line and column, and the key (a dotted path
//! with array indices, e.g. `encoders[2].direction_deg`). Nothing here panics on bad input.
//!
//! The parts: `raw` is the file as written (serde types that keep every value's span),
//! `parse` reads it (TOML syntax, the format line, keys and types) and locates errors,
//! `check` turns it into a [`Robot`] (values and geometry).

use std::f64::consts::PI;
use std::path::Path;

use robot_math::carriage::CarriageGeometry;
use robot_math::sensors::{binary_to_gray, gray_to_binary};
use robot_math::wheel::Wheel;
use serde::Deserialize;

pub use super::toml_file::FileError;
use super::toml_file::{read_text, Res, Shape, TomlFile};
pub use edit::EncoderGeometry;
use raw::RawRobot;

mod check;
mod edit;
mod raw;
#[cfg(test)]
mod tests;

/// The value of the `format` key this module reads.
pub const FORMAT: &str = "omnibench robot v1";

/// A robot: its sensors and its geometry, in the body frame (x forward, y to the left, origin at
/// the body's reference point, the point whose pose odometry reports). Radians inside.
#[derive(Clone, Debug, PartialEq)]
pub struct Robot {
    pub name: String,
    pub description: String,
    /// Incremental encoders on measuring wheels; index = position in the file. With a
    /// carriage, their wheels are in the carriage frame (see [`Carriage`]).
    pub encoders: Vec<Encoder>,
    pub absolute_encoders: Vec<AbsoluteEncoder>,
    pub carriage: Option<Carriage>,
    pub drive_wheels: Vec<DriveWheel>,
    /// Seed 002's point A: the point a differential drive tracks, this far ahead of the
    /// reference point on body +x (never 0). `None`: the reference point itself.
    pub tracked_point_x_m: Option<f64>,
    /// The drive wheels' motors (one model for all), which the emulator's plant runs.
    pub motor: Option<Motor>,
}

/// `[motor]`: every drive wheel's DC gear motor and the encoder on its shaft.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Motor {
    pub model: robot_math::motor::DcMotor,
    /// Counts per motor turn after x4 decoding (0: no motor encoders).
    pub encoder_counts_per_motor_rev: u32,
}

impl Motor {
    /// Rim travel per motor-encoder count, m (None without encoders).
    pub fn metres_per_count(&self) -> Option<f64> {
        let m = &self.model;
        (self.encoder_counts_per_motor_rev > 0).then(|| {
            2.0 * std::f64::consts::PI * m.wheel_radius_m
                / (self.encoder_counts_per_motor_rev as f64 * m.gear_ratio)
        })
    }
}

/// An incremental (quadrature) encoder on a measuring wheel.
#[derive(Clone, Debug, PartialEq)]
pub struct Encoder {
    pub name: String,
    /// Contact point and unit rolling direction (a positive count = rolling along it).
    pub wheel: Wheel,
    /// Wheel travel per count, after quadrature decoding, metres.
    pub metres_per_count: f64,
}

/// An absolute encoder read in parallel (one pin per bit).
#[derive(Clone, Debug, PartialEq)]
pub struct AbsoluteEncoder {
    pub name: String,
    /// Resolution: 2^bits positions per turn (1..=16).
    pub bits: u8,
    /// Gray code on the outputs (else plain binary).
    pub gray: bool,
    /// Outputs active-low (an output reads 0 when its bit is 1), as open-collector encoders are.
    pub inverted: bool,
    pub measures: AbsMeasures,
}

/// What angle an absolute encoder measures. Position k of 2^bits stands for the angle
/// k · 360° / 2^bits, counter-clockwise positive.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AbsMeasures {
    /// The carriage's heading minus the body's heading (seed 004's swivel angle β).
    CarriageSwivel,
    /// The body's heading in the field.
    BodyHeading,
}

impl AbsMeasures {
    fn as_str(self) -> &'static str {
        match self {
            AbsMeasures::CarriageSwivel => "carriage_swivel",
            AbsMeasures::BodyHeading => "body_heading",
        }
    }
}

/// A trailing swivel carriage that carries the two measuring wheels (seed 004). The pivot is at
/// the body's reference point; the carriage frame has x along the carriage's heading and its
/// origin at the axle midpoint, which trails the pivot by `trail_m`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Carriage {
    pub trail_m: f64,
}

/// A driven wheel: where it is, which way it pushes (positive speed), and its speed limit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DriveWheel {
    pub wheel: Wheel,
    pub v_max_m_s: f64,
}

/// Why a robot file was refused (see [`FileError`]).
pub type RobotError = FileError;

impl AbsoluteEncoder {
    /// Positions per turn (2^bits).
    pub fn positions(&self) -> u32 {
        1u32 << self.bits
    }

    /// Angle step of one position, radians.
    pub fn step_rad(&self) -> f64 {
        2.0 * PI / self.positions() as f64
    }

    fn mask(&self) -> u16 {
        (self.positions() - 1) as u16
    }

    /// The position (0..2^bits) that the levels on the outputs stand for (bit i = output i,
    /// 1 = high): undo the inversion, then the Gray code.
    pub fn decode(&self, levels: u16) -> u16 {
        let mut v = levels & self.mask();
        if self.inverted {
            v = !v & self.mask();
        }
        if self.gray {
            v = gray_to_binary(v) & self.mask();
        }
        v
    }

    /// The levels the outputs show at a position (the inverse of [`decode`](Self::decode)).
    pub fn levels(&self, position: u16) -> u16 {
        let mut v = position & self.mask();
        if self.gray {
            v = binary_to_gray(v) & self.mask();
        }
        if self.inverted {
            v = !v & self.mask();
        }
        v
    }
}

impl Robot {
    /// Reads and checks a robot file.
    pub fn load(path: &Path) -> Result<Robot, RobotError> {
        let text = read_text(path, "robot file")?;
        Robot::parse(&text, path)
    }

    /// Parses and checks a robot description; `name_for_errors` is what errors call the file.
    pub fn parse(text: &str, name_for_errors: &Path) -> Result<Robot, RobotError> {
        let file = TomlFile {
            path: name_for_errors,
            text,
            format: FORMAT,
            kind: "robot file",
        };
        let raw: RawRobot = file.read(robot_shape)?;
        file.check_robot(raw)
    }

    /// The measuring wheels of the encoders, in encoder order.
    pub fn encoder_wheels(&self) -> Vec<Wheel> {
        self.encoders.iter().map(|e| e.wheel).collect()
    }

    /// The absolute encoder that measures `what`, if there is one (a file has at most one of
    /// each kind).
    pub fn absolute_encoder(&self, what: AbsMeasures) -> Option<&AbsoluteEncoder> {
        self.absolute_encoders.iter().find(|a| a.measures == what)
    }

    /// For seed 004-style robots: the carriage geometry robot-math's `CarriageOdometry` takes
    /// (wheel 0 left, wheel 1 right). `None` without a carriage (or for a hand-built `Robot`
    /// that breaks the rules `load` enforces).
    pub fn carriage_geometry(&self) -> Option<CarriageGeometry> {
        let carriage = self.carriage?;
        let swivel = self.absolute_encoder(AbsMeasures::CarriageSwivel)?;
        let [left, right] = self.encoders.as_slice() else {
            return None;
        };
        Some(CarriageGeometry {
            wheel_base: left.wheel.y - right.wheel.y,
            trail: carriage.trail_m,
            metres_per_count: [left.metres_per_count, right.metres_per_count],
            abs_bits: swivel.bits,
        })
    }
}

/// The robot file's tables' shapes, which serde would report in terms of its own internals.
fn robot_shape(file: &TomlFile, s: Shape) -> Res<()> {
    if s.key == "carriage" && s.array {
        return Err(file.at(
            s.span,
            s.key,
            "a robot has at most one carriage: write [carriage], not [[carriage]]",
        ));
    }
    if ["encoders", "absolute_encoders", "drive_wheels"].contains(&s.key) && !s.array {
        return Err(file.at(
            s.span,
            s.key,
            format!(
                "must be an array of tables: write [[{}]] before each one",
                s.key
            ),
        ));
    }
    Ok(())
}
