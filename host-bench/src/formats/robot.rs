//! Robot descriptions: a robot's sensors and geometry in a small TOML file, format
//! `"omnibench robot v1"`. Every key, unit and sign convention is in `docs/robot-format.md`;
//! the seed robots are in `robots/`.
//!
//! Loading is strict: an unknown key, a value of the wrong type or a geometry the odometry
//! cannot use is an error that names the file, the line and column, and the key (a dotted path
//! with array indices, e.g. `encoders[2].direction_deg`). Nothing here panics on bad input.

use std::collections::HashMap;
use std::f64::consts::PI;
use std::fmt;
use std::ops::Range;
use std::path::{Path, PathBuf};

use robot_math::carriage::CarriageGeometry;
use robot_math::sensors::{binary_to_gray, gray_to_binary};
use robot_math::wheel::{invert3, Mat3, Wheel};
use serde::Deserialize;
use toml::de::{DeTable, DeValue};
use toml::Spanned;

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

/// Why a robot file was refused. Displays as `path:LINE:COL: key `k`: message`, with the parts
/// that are unknown left out (an unreadable file has neither line nor key).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RobotError {
    pub path: PathBuf,
    /// 1-based line of the offending key or value.
    pub line: Option<usize>,
    /// 1-based column (in characters) on that line.
    pub column: Option<usize>,
    /// Dotted key path with array indices, e.g. `encoders[1].metres_per_count`.
    pub key: Option<String>,
    pub message: String,
}

impl fmt::Display for RobotError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.path.display())?;
        match (self.line, self.column) {
            (Some(l), Some(c)) => write!(f, ":{l}:{c}")?,
            (Some(l), None) => write!(f, ":{l}")?,
            _ => {}
        }
        write!(f, ": ")?;
        if let Some(k) = &self.key {
            write!(f, "key `{k}`: ")?;
        }
        write!(f, "{}", self.message)
    }
}

impl std::error::Error for RobotError {}

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
        let text = std::fs::read_to_string(path).map_err(|e| RobotError {
            path: path.to_path_buf(),
            line: None,
            column: None,
            key: None,
            message: format!("cannot read the robot file: {e}"),
        })?;
        Robot::parse(&text, path)
    }

    /// Parses and checks a robot description; `name_for_errors` is what errors call the file.
    pub fn parse(text: &str, name_for_errors: &Path) -> Result<Robot, RobotError> {
        Parser {
            path: name_for_errors,
            text,
        }
        .parse()
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

// ---------------------------------------------------------------------------------------------
// The file as written (before checking). Every value keeps its span for error messages.

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawRobot {
    // Checked before these structs are deserialized; kept so that it is a known key.
    #[allow(dead_code)]
    format: Spanned<String>,
    name: Spanned<String>,
    #[serde(default)]
    description: String,
    #[serde(default)]
    encoders: Vec<Spanned<RawEncoder>>,
    #[serde(default)]
    absolute_encoders: Vec<Spanned<RawAbsolute>>,
    carriage: Option<Spanned<RawCarriage>>,
    #[serde(default)]
    drive_wheels: Vec<Spanned<RawDriveWheel>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawEncoder {
    name: Spanned<String>,
    x_m: Spanned<f64>,
    y_m: Spanned<f64>,
    direction_deg: Spanned<f64>,
    metres_per_count: Option<Spanned<f64>>,
    counts_per_rev: Option<Spanned<i64>>,
    wheel_diameter_m: Option<Spanned<f64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawAbsolute {
    name: Spanned<String>,
    bits: Spanned<i64>,
    code: RawCode,
    #[serde(default)]
    inverted: bool,
    measures: Spanned<AbsMeasures>,
}

#[derive(Deserialize, Clone, Copy, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
enum RawCode {
    Gray,
    Binary,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawCarriage {
    trail_m: Spanned<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawDriveWheel {
    x_m: Spanned<f64>,
    y_m: Spanned<f64>,
    direction_deg: Spanned<f64>,
    v_max_m_s: Spanned<f64>,
}

// ---------------------------------------------------------------------------------------------

struct Parser<'a> {
    path: &'a Path,
    text: &'a str,
}

type Res<T> = Result<T, RobotError>;

impl Parser<'_> {
    fn error(&self, offset: Option<usize>, key: Option<String>, message: String) -> RobotError {
        let (line, column) = match offset {
            Some(o) => {
                let (l, c) = line_col(self.text, o);
                (Some(l), Some(c))
            }
            None => (None, None),
        };
        RobotError {
            path: self.path.to_path_buf(),
            line,
            column,
            key,
            message,
        }
    }

    fn at(&self, span: Range<usize>, key: &str, message: impl Into<String>) -> RobotError {
        self.error(Some(span.start), Some(key.to_string()), message.into())
    }

    fn finite(&self, v: &Spanned<f64>, key: &str) -> Res<f64> {
        let x = *v.get_ref();
        if x.is_finite() {
            Ok(x)
        } else {
            Err(self.at(v.span(), key, format!("must be a finite number, got {x}")))
        }
    }

    fn positive(&self, v: &Spanned<f64>, key: &str) -> Res<f64> {
        let x = self.finite(v, key)?;
        if x > 0.0 {
            Ok(x)
        } else {
            Err(self.at(v.span(), key, format!("must be > 0, got {x}")))
        }
    }

    fn name(&self, v: &Spanned<String>, key: &str) -> Res<String> {
        let s = v.get_ref().trim();
        if s.is_empty() {
            return Err(self.at(v.span(), key, "must not be empty"));
        }
        Ok(s.to_string())
    }

    fn parse(&self) -> Res<Robot> {
        // 1. TOML syntax.
        let (tree, errors) = DeTable::parse_recoverable(self.text);
        if let Some(e) = errors.first() {
            let offset = e.span().map_or(0, |s| s.start);
            return Err(self.error(
                Some(offset),
                key_on_line(self.text, offset),
                format!("TOML syntax: {}", e.message()),
            ));
        }
        let tree = Spanned::new(tree.span(), DeValue::Table(tree.into_inner()));

        // 2. The format line, before anything else: a file of another version must be told so,
        //    not have its new keys called unknown.
        self.check_format_and_shape(&tree)?;

        // 3. Keys and types.
        //    serde_path_to_error names the key (`encoders[2].direction_deg`); toml's error has
        //    the span, hence the line.
        let document = toml::Deserializer::parse(self.text).map_err(|e| {
            let offset = e.span().map_or(0, |s| s.start);
            self.error(Some(offset), None, format!("TOML syntax: {}", e.message()))
        })?;
        let raw: RawRobot =
            serde_path_to_error::deserialize(document).map_err(|e| self.type_error(&e))?;

        // 4. Values and geometry.
        self.check(raw)
    }

    fn check_format_and_shape(&self, tree: &Spanned<DeValue<'_>>) -> Res<()> {
        let found = match tree.get_ref() {
            DeValue::Table(t) => t.iter().find(|(k, _)| k.get_ref() == "format"),
            _ => None,
        };
        let Some((_, value)) = found else {
            return Err(self.error(
                Some(0),
                Some("format".into()),
                format!("missing: a robot file starts with format = \"{FORMAT}\""),
            ));
        };
        match value.get_ref().as_str() {
            Some(FORMAT) => {}
            Some(other) => {
                return Err(self.at(
                    value.span(),
                    "format",
                    format!("unsupported format \"{other}\": this program reads \"{FORMAT}\""),
                ))
            }
            None => {
                return Err(self.at(
                    value.span(),
                    "format",
                    format!("must be the string \"{FORMAT}\""),
                ))
            }
        }
        // The tables' shapes, which serde would report in terms of its own internals.
        let DeValue::Table(t) = tree.get_ref() else {
            return Ok(());
        };
        for (k, v) in t.iter() {
            let key = k.get_ref().as_ref();
            let array = matches!(v.get_ref(), DeValue::Array(_));
            if key == "carriage" && array {
                return Err(self.at(
                    v.span(),
                    key,
                    "a robot has at most one carriage: write [carriage], not [[carriage]]",
                ));
            }
            if ["encoders", "absolute_encoders", "drive_wheels"].contains(&key) && !array {
                return Err(self.at(
                    v.span(),
                    key,
                    format!("must be an array of tables: write [[{key}]] before each one"),
                ));
            }
        }
        Ok(())
    }

    /// A serde error (unknown key, wrong type, missing key), at the key path where it happened.
    fn type_error(&self, e: &serde_path_to_error::Error<toml::de::Error>) -> RobotError {
        let span = e.inner().span().unwrap_or(0..0);
        let mut path = key_path(e.path());
        let mut message = e
            .inner()
            .message()
            .replace("expected f64", "expected a number");
        message = message.replace("expected i64", "expected an integer");
        if let Some(missing) = message
            .strip_prefix("missing field `")
            .and_then(|m| m.strip_suffix('`'))
        {
            path = if path.is_empty() {
                missing.to_string()
            } else {
                format!("{path}.{missing}")
            };
            message = "missing (required)".into();
        }
        self.error(
            Some(span.start),
            Some(path).filter(|p| !p.is_empty()),
            message,
        )
    }

    fn check(&self, raw: RawRobot) -> Res<Robot> {
        let name = self.name(&raw.name, "name")?;

        let mut encoders = Vec::with_capacity(raw.encoders.len());
        let mut names: HashMap<String, usize> = HashMap::new();
        for (i, e) in raw.encoders.iter().enumerate() {
            let k = |f: &str| format!("encoders[{i}].{f}");
            let span = e.span();
            let e = e.get_ref();
            let ename = self.name(&e.name, &k("name"))?;
            if let Some(j) = names.insert(ename.clone(), i) {
                return Err(self.at(
                    e.name.span(),
                    &k("name"),
                    format!("\"{ename}\" is already the name of encoders[{j}]"),
                ));
            }
            let x = self.finite(&e.x_m, &k("x_m"))?;
            let y = self.finite(&e.y_m, &k("y_m"))?;
            let dir = self.finite(&e.direction_deg, &k("direction_deg"))?;
            let metres_per_count =
                match (&e.metres_per_count, &e.counts_per_rev, &e.wheel_diameter_m) {
                    (Some(m), None, None) => self.positive(m, &k("metres_per_count"))?,
                    (Some(m), _, _) => return Err(self.at(
                        m.span(),
                        &k("metres_per_count"),
                        "give either metres_per_count, or counts_per_rev with wheel_diameter_m, \
                         not both",
                    )),
                    (None, Some(c), Some(d)) => {
                        let counts = *c.get_ref();
                        if !(1..=i64::from(u32::MAX)).contains(&counts) {
                            return Err(self.at(
                                c.span(),
                                &k("counts_per_rev"),
                                format!("must be a whole number of counts > 0, got {counts}"),
                            ));
                        }
                        let d = self.positive(d, &k("wheel_diameter_m"))?;
                        PI * d / counts as f64
                    }
                    (None, Some(c), None) => {
                        return Err(self.at(
                            c.span(),
                            &k("wheel_diameter_m"),
                            "missing: counts_per_rev needs wheel_diameter_m",
                        ))
                    }
                    (None, None, Some(d)) => {
                        return Err(self.at(
                            d.span(),
                            &k("counts_per_rev"),
                            "missing: wheel_diameter_m needs counts_per_rev",
                        ))
                    }
                    (None, None, None) => return Err(self.at(
                        span,
                        &k("metres_per_count"),
                        "missing: give metres_per_count, or counts_per_rev and wheel_diameter_m",
                    )),
                };
            encoders.push(Encoder {
                name: ename,
                wheel: Wheel::at(x, y, dir.to_radians()),
                metres_per_count,
            });
        }

        let mut absolute_encoders = Vec::with_capacity(raw.absolute_encoders.len());
        let mut abs_names: HashMap<String, usize> = HashMap::new();
        let mut kinds: HashMap<AbsMeasures, usize> = HashMap::new();
        for (i, a) in raw.absolute_encoders.iter().enumerate() {
            let k = |f: &str| format!("absolute_encoders[{i}].{f}");
            let a = a.get_ref();
            let aname = self.name(&a.name, &k("name"))?;
            if let Some(j) = abs_names.insert(aname.clone(), i) {
                return Err(self.at(
                    a.name.span(),
                    &k("name"),
                    format!("\"{aname}\" is already the name of absolute_encoders[{j}]"),
                ));
            }
            let bits = *a.bits.get_ref();
            if !(1..=16).contains(&bits) {
                return Err(self.at(
                    a.bits.span(),
                    &k("bits"),
                    format!("must be 1 to 16, got {bits}"),
                ));
            }
            let measures = *a.measures.get_ref();
            if let Some(j) = kinds.insert(measures, i) {
                return Err(self.at(
                    a.measures.span(),
                    &k("measures"),
                    format!(
                        "absolute_encoders[{j}] already measures {}: at most one of each kind",
                        measures.as_str()
                    ),
                ));
            }
            absolute_encoders.push(AbsoluteEncoder {
                name: aname,
                bits: bits as u8,
                gray: a.code == RawCode::Gray,
                inverted: a.inverted,
                measures,
            });
        }

        let mut drive_wheels = Vec::with_capacity(raw.drive_wheels.len());
        for (i, w) in raw.drive_wheels.iter().enumerate() {
            let k = |f: &str| format!("drive_wheels[{i}].{f}");
            let w = w.get_ref();
            let x = self.finite(&w.x_m, &k("x_m"))?;
            let y = self.finite(&w.y_m, &k("y_m"))?;
            let dir = self.finite(&w.direction_deg, &k("direction_deg"))?;
            let v_max_m_s = self.positive(&w.v_max_m_s, &k("v_max_m_s"))?;
            drive_wheels.push(DriveWheel {
                wheel: Wheel::at(x, y, dir.to_radians()),
                v_max_m_s,
            });
        }

        let carriage =
            match &raw.carriage {
                Some(c) => Some(self.check_carriage(c, &raw, &encoders)?),
                None => {
                    if let Some(a) = raw.absolute_encoders.iter().position(|a| {
                        *a.get_ref().measures.get_ref() == AbsMeasures::CarriageSwivel
                    }) {
                        return Err(self.at(
                            raw.absolute_encoders[a].get_ref().measures.span(),
                            &format!("absolute_encoders[{a}].measures"),
                            "carriage_swivel needs a [carriage] table (there is no carriage)",
                        ));
                    }
                    self.check_encoder_geometry(&raw, &encoders)?;
                    None
                }
            };

        Ok(Robot {
            name,
            description: raw.description.trim().to_string(),
            encoders,
            absolute_encoders,
            carriage,
            drive_wheels,
        })
    }

    fn check_carriage(
        &self,
        c: &Spanned<RawCarriage>,
        raw: &RawRobot,
        encoders: &[Encoder],
    ) -> Res<Carriage> {
        let trail_m = self.positive(&c.get_ref().trail_m, "carriage.trail_m")?;
        if encoders.len() != 2 {
            return Err(self.at(
                c.span(),
                "carriage",
                format!(
                    "a carriage carries exactly two encoders (left, then right), this file has {}",
                    encoders.len()
                ),
            ));
        }
        if !raw
            .absolute_encoders
            .iter()
            .any(|a| *a.get_ref().measures.get_ref() == AbsMeasures::CarriageSwivel)
        {
            return Err(self.at(
                c.span(),
                "carriage",
                "a carriage needs an absolute encoder with measures = \"carriage_swivel\" \
                 (the body heading is the carriage heading minus the swivel angle)",
            ));
        }
        for (i, e) in raw.encoders.iter().enumerate() {
            let e = e.get_ref();
            let dir = e.direction_deg.get_ref().rem_euclid(360.0);
            if dir.min(360.0 - dir) > 1e-9 {
                return Err(self.at(
                    e.direction_deg.span(),
                    &format!("encoders[{i}].direction_deg"),
                    format!(
                        "must be 0 on a carriage (both measuring wheels roll along the carriage's \
                         +x), got {}",
                        e.direction_deg.get_ref()
                    ),
                ));
            }
            if e.x_m.get_ref().abs() > 1e-9 {
                return Err(self.at(
                    e.x_m.span(),
                    &format!("encoders[{i}].x_m"),
                    format!(
                        "must be 0 on a carriage (the carriage frame's origin is the axle \
                         midpoint), got {}",
                        e.x_m.get_ref()
                    ),
                ));
            }
        }
        let (left, right) = (
            &raw.encoders[0].get_ref().y_m,
            &raw.encoders[1].get_ref().y_m,
        );
        let (yl, yr) = (*left.get_ref(), *right.get_ref());
        if yl <= 0.0 {
            return Err(self.at(
                left.span(),
                "encoders[0].y_m",
                format!("must be > 0 on a carriage (encoder 0 is the left wheel), got {yl}"),
            ));
        }
        if (yl + yr).abs() > 1e-9 {
            return Err(self.at(
                right.span(),
                "encoders[1].y_m",
                format!(
                    "must be -{yl} on a carriage (the right wheel, opposite the left one about \
                     the axle midpoint), got {yr}"
                ),
            ));
        }
        Ok(Carriage { trail_m })
    }

    /// Can the encoders (body frame, no carriage) determine the body's motion?
    fn check_encoder_geometry(&self, raw: &RawRobot, encoders: &[Encoder]) -> Res<()> {
        let Some(first) = raw.encoders.first() else {
            return Ok(()); // no odometry sensors: a description of drive wheels only
        };
        let fail = |message: &str| Err(self.at(first.span(), "encoders", message));
        match encoders {
            [_] => fail(
                "one encoder cannot determine the body's motion: give two on one axle, or three \
                 or more",
            ),
            [a, b] => {
                let (a, b) = (a.wheel, b.wheel);
                let cross = a.ux * b.uy - a.uy * b.ux;
                let dot = a.ux * b.ux + a.uy * b.uy;
                let (dx, dy) = (b.x - a.x, b.y - a.y);
                let lateral = -dx * a.uy + dy * a.ux;
                let along = dx * a.ux + dy * a.uy;
                if cross.abs() > 1e-9 || dot <= 0.0 || lateral.abs() < 1e-9 || along.abs() > 1e-9 {
                    fail(
                        "two encoders must be on one axle: the same direction_deg, side by side \
                         (the line between them perpendicular to the rolling direction)",
                    )
                } else {
                    Ok(())
                }
            }
            _ => {
                let mut jtj: Mat3 = [[0.0; 3]; 3];
                for e in encoders {
                    let r = e.wheel.row();
                    for (i, row) in jtj.iter_mut().enumerate() {
                        for (j, v) in row.iter_mut().enumerate() {
                            *v += r[i] * r[j];
                        }
                    }
                }
                let scale = (jtj[0][0] + jtj[1][1] + jtj[2][2]) / 3.0;
                if scale > 0.0 && invert3(&jtj, 1e-9 * scale * scale * scale).is_some() {
                    Ok(())
                } else {
                    fail(
                        "these encoders cannot determine the body's motion (their kinematic \
                         matrix has rank < 3: e.g. all rolling the same way, or all rolling \
                         lines through one point)",
                    )
                }
            }
        }
    }
}

/// 1-based line and column (in characters) of a byte offset.
fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let mut off = offset.min(text.len());
    while !text.is_char_boundary(off) {
        off -= 1;
    }
    let before = &text[..off];
    let line = before.matches('\n').count() + 1;
    let line_start = before.rfind('\n').map_or(0, |i| i + 1);
    (line, before[line_start..].chars().count() + 1)
}

/// A serde path as the file's key path, `encoders[2].direction_deg` (empty for the document
/// itself), leaving out the fields `toml::Spanned` deserializes through.
fn key_path(path: &serde_path_to_error::Path) -> String {
    use serde_path_to_error::Segment;
    let mut out = String::new();
    for segment in path.iter() {
        match segment {
            Segment::Seq { index } => out.push_str(&format!("[{index}]")),
            // Spanned<T> is read as a map of private fields (serde_spanned's naming; a change
            // there fails `inline_tables_are_located_too` and `missing_keys_are_named`).
            Segment::Map { key } if key.starts_with("$__serde_spanned_private_") => {}
            Segment::Map { key } | Segment::Enum { variant: key } => {
                if !out.is_empty() {
                    out.push('.');
                }
                out.push_str(key);
            }
            Segment::Unknown => out.push_str(if out.is_empty() { "?" } else { ".?" }),
        }
    }
    out
}

/// For a syntax error (no parsed tree to consult): the key path of the line at `offset`, from
/// the table headers above it and the `key =` on that line. Covers one-key-per-line files.
fn key_on_line(text: &str, offset: usize) -> Option<String> {
    let (line, _) = line_col(text, offset);
    let mut prefix = String::new();
    let mut counts: HashMap<String, usize> = HashMap::new();
    for (n, l) in text.lines().enumerate() {
        let t = l.trim();
        let header = table_header(t);
        if let Some((name, array)) = &header {
            prefix = if *array {
                let c = counts.entry(name.clone()).or_insert(0);
                *c += 1;
                format!("{name}[{}]", *c - 1)
            } else {
                name.clone()
            };
        }
        if n + 1 == line {
            if header.is_some() {
                return Some(prefix);
            }
            let key = t.split_once('=').map(|(k, _)| k.trim()).filter(|k| {
                !k.is_empty()
                    && k.chars()
                        .all(|c| c.is_ascii_alphanumeric() || "_-.\"' ".contains(c))
            });
            return match key {
                Some(k) if prefix.is_empty() => Some(k.to_string()),
                Some(k) => Some(format!("{prefix}.{k}")),
                None if prefix.is_empty() => None,
                None => Some(prefix),
            };
        }
    }
    None
}

/// `[name]` → (name, false), `[[name]]` → (name, true), anything else → None.
fn table_header(line: &str) -> Option<(String, bool)> {
    let line = match line.find('#') {
        Some(i) => line[..i].trim(),
        None => line,
    };
    let (inner, array) = if let Some(r) = line.strip_prefix("[[") {
        (r.strip_suffix("]]")?, true)
    } else {
        (line.strip_prefix('[')?.strip_suffix(']')?, false)
    };
    let inner = inner.trim();
    let ok = !inner.is_empty()
        && inner
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || "_-.\"' ".contains(c));
    ok.then(|| (inner.to_string(), array))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Robot, RobotError> {
        Robot::parse(text, Path::new("t.toml"))
    }

    const HEAD: &str = "format = \"omnibench robot v1\"\nname = \"t\"\n";

    #[test]
    fn line_col_counts_characters_from_one() {
        let t = "ab\nγδ = 1\n";
        assert_eq!(line_col(t, 0), (1, 1));
        assert_eq!(line_col(t, 3), (2, 1));
        assert_eq!(line_col(t, 3 + "γδ ".len()), (2, 4));
        assert_eq!(line_col(t, 1000), (3, 1));
    }

    #[test]
    fn key_on_line_follows_headers() {
        let t = "a = 1\n[[e]]\nx = 1\n[[e]]\nx = \"\n[c]\ny = 2\n";
        let at = |line: usize| {
            let off: usize = t.lines().take(line - 1).map(|l| l.len() + 1).sum();
            key_on_line(t, off)
        };
        assert_eq!(at(1).as_deref(), Some("a"));
        assert_eq!(at(4).as_deref(), Some("e[1]"));
        assert_eq!(at(5).as_deref(), Some("e[1].x"));
        assert_eq!(at(7).as_deref(), Some("c.y"));
    }

    #[test]
    fn table_headers_are_told_from_arrays() {
        assert_eq!(
            table_header("[[encoders]]"),
            Some(("encoders".into(), true))
        );
        assert_eq!(
            table_header("[carriage] # x"),
            Some(("carriage".into(), false))
        );
        assert_eq!(table_header("[1, 2],"), None);
    }

    #[test]
    fn syntax_errors_name_key_and_line() {
        let e = parse(&format!("{HEAD}[[encoders]]\nname = \"a\nx_m = 1\n")).unwrap_err();
        assert_eq!(
            (e.line, e.key.as_deref()),
            (Some(4), Some("encoders[0].name")),
            "{e}"
        );
        let e = parse(&format!("{HEAD}[carriage]\ntrail_m = 0.1\ntrail_m = 0.2\n")).unwrap_err();
        assert_eq!(
            (e.line, e.key.as_deref()),
            (Some(5), Some("carriage.trail_m")),
            "{e}"
        );
    }

    #[test]
    fn inline_tables_are_located_too() {
        let e = parse(&format!(
            "{HEAD}drive_wheels = [\n  {{ x_m = 0, y_m = 0, direction_deg = 0, v_max_m_s = 1 }},\n  {{ x_m = 0, y_m = true, direction_deg = 0, v_max_m_s = 1 }},\n]\n"
        ))
        .unwrap_err();
        assert_eq!(
            (e.line, e.key.as_deref()),
            (Some(5), Some("drive_wheels[1].y_m")),
            "{e}"
        );
        assert!(e.message.contains("expected a number"), "{e}");
    }

    #[test]
    fn missing_keys_are_named() {
        let e = parse("format = \"omnibench robot v1\"\n").unwrap_err();
        assert_eq!((e.line, e.key.as_deref()), (Some(1), Some("name")), "{e}");
        let e = parse(&format!("{HEAD}[[encoders]]\nname = \"a\"\ny_m = 0\n")).unwrap_err();
        assert_eq!(
            (e.line, e.key.as_deref()),
            (Some(3), Some("encoders[0].x_m")),
            "{e}"
        );
    }

    #[test]
    fn other_format_versions_are_refused_first() {
        let e = parse("format = \"omnibench robot v2\"\nname = \"t\"\nnew_key = 1\n").unwrap_err();
        assert_eq!((e.line, e.key.as_deref()), (Some(1), Some("format")), "{e}");
        assert!(e.message.contains("unsupported"), "{e}");
    }

    #[test]
    fn table_shapes_are_checked() {
        let e = parse(&format!("{HEAD}[[carriage]]\ntrail_m = 0.06\n")).unwrap_err();
        assert_eq!(
            (e.line, e.key.as_deref()),
            (Some(3), Some("carriage")),
            "{e}"
        );
        assert!(e.message.contains("at most one carriage"), "{e}");
        let e = parse(&format!("{HEAD}[encoders]\nname = \"a\"\n")).unwrap_err();
        assert_eq!(
            (e.line, e.key.as_deref()),
            (Some(3), Some("encoders")),
            "{e}"
        );
    }

    #[test]
    fn non_finite_values_are_refused() {
        let e = parse(&format!(
            "{HEAD}[[drive_wheels]]\nx_m = nan\ny_m = 0\ndirection_deg = 0\nv_max_m_s = 1\n"
        ))
        .unwrap_err();
        assert_eq!(
            (e.line, e.key.as_deref()),
            (Some(4), Some("drive_wheels[0].x_m")),
            "{e}"
        );
    }

    #[test]
    fn absolute_encoder_levels_round_trip() {
        let a = AbsoluteEncoder {
            name: "s".into(),
            bits: 8,
            gray: true,
            inverted: true,
            measures: AbsMeasures::CarriageSwivel,
        };
        for p in 0..256u16 {
            assert_eq!(a.decode(a.levels(p)), p);
        }
        // Inverted Gray: position 1 is Gray 0b1, shown as all pins high but bit 0.
        assert_eq!(a.levels(1), 0xFE);
        assert_eq!(a.decode(0xFF), 0);
    }

    #[test]
    fn display_has_path_line_column_key() {
        let e = parse(&format!(
            "{HEAD}[[encoders]]\nname = \"a\"\nx_m = 0\ny_m = 0\ndirection_deg = 0\nmetres_per_count = -1\n"
        ))
        .unwrap_err();
        assert_eq!(
            e.to_string(),
            "t.toml:8:20: key `encoders[0].metres_per_count`: must be > 0, got -1"
        );
    }
}
