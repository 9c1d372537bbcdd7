//! Scenario files: one emulated run in a small TOML file, format `"omnibench scenario v1"`:
//! the robot (a robot file), where it starts, what the host asks of it (seed 004's moving
//! target or a time-parametrised trajectory for seed 002's tracking law), the controller's
//! gains, how long to run, the encoders' power-on phases and the faults to inject. Every key is
//! in `docs/scenario-format.md`; the scenarios are in `scenarios/`.
//!
//! Errors name the file, line, column and key, as the robot format's do.

use std::path::{Path, PathBuf};

use anyhow::{anyhow, Result};
use serde::Deserialize;
use toml::Spanned;

use super::robot::Robot;
use super::run_robot::{power_on_robot, robot_model, same_kind};
use super::toml_file::{read_text, FileError, Res, Shape, TomlFile};
use crate::sim::emulator::{Faults, Motion, RobotModel, Scenario, MAX_DURATION_S};

/// How far from the field origin a start or target may lie, metres: the slave reports its
/// pose in micrometres in an `i32` (±2147 m), and a run must stay inside that.
pub const MAX_FIELD_M: f64 = 1000.0;
use crate::sim::trajectory;

/// The value of the `format` key this module reads.
pub const FORMAT: &str = "omnibench scenario v1";

/// How often the host sends the tracked path's next sample by default, seconds.
pub const SAMPLE_PERIOD_S: f64 = 0.02;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawScenario {
    #[allow(dead_code)]
    format: Spanned<String>,
    name: Spanned<String>,
    #[serde(default)]
    description: String,
    /// Relative to the scenario file's folder.
    robot: Option<Spanned<String>>,
    /// The robot as it really is, when it is not as `robot` says (relative, as `robot`).
    true_robot: Option<Spanned<String>>,
    duration_s: Spanned<f64>,
    start: RawStart,
    target: Option<Spanned<RawTarget>>,
    trajectory: Option<Spanned<RawTrajectory>>,
    controller: Option<RawController>,
    noise: Option<RawNoise>,
    faults: Option<RawFaults>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawStart {
    x_m: Spanned<f64>,
    y_m: Spanned<f64>,
    heading_deg: Spanned<f64>,
    swivel_deg: Option<Spanned<f64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawTarget {
    from_m: Spanned<[f64; 2]>,
    to_m: Spanned<[f64; 2]>,
    speed_m_s: Spanned<f64>,
    robot_speed_m_s: Spanned<f64>,
    heading_deg: Option<Spanned<f64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawTrajectory {
    name: Spanned<String>,
    sample_period_s: Option<Spanned<f64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawController {
    k_forward: Option<Spanned<f64>>,
    k_lateral: Option<Spanned<f64>>,
    ff_forward: Option<Spanned<f64>>,
    ff_lateral: Option<Spanned<f64>>,
    diff_forward: Option<Spanned<f64>>,
    diff_lateral: Option<Spanned<f64>>,
    speed_kp: Option<Spanned<f64>>,
    speed_ki: Option<Spanned<f64>>,
    speed_kd: Option<Spanned<f64>>,
    pursuit_period_s: Option<Spanned<f64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawNoise {
    // A list, its length checked here: as `[f64; 2]` a third value was dropped unseen.
    encoder_phase: Option<Spanned<Vec<f64>>>,
    encoder_edges: Option<Spanned<String>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawFaults {
    slave_off_at_s: Option<Spanned<f64>>,
    slave_reset_at_s: Option<Spanned<f64>>,
    host_silent_after_s: Option<Spanned<f64>>,
    spi_corrupt: Option<Spanned<f64>>,
    spi_drop: Option<Spanned<f64>>,
    spi_torn: Option<Spanned<f64>>,
    spi_duplicate: Option<Spanned<f64>>,
    spi_late: Option<Spanned<f64>>,
    serial_corrupt: Option<Spanned<f64>>,
    serial_drop: Option<Spanned<f64>>,
    serial_duplicate: Option<Spanned<f64>>,
    serial_delay: Option<Spanned<f64>>,
    serial_torn: Option<Spanned<f64>>,
}

/// Every table is a single table.
fn scenario_shape(file: &TomlFile, s: Shape) -> Res<()> {
    let tables = [
        "start",
        "target",
        "trajectory",
        "controller",
        "noise",
        "faults",
    ];
    if tables.contains(&s.key) && s.array {
        return Err(file.at(
            s.span,
            s.key,
            format!("write [{}], not [[{}]]: a scenario has one", s.key, s.key),
        ));
    }
    Ok(())
}

/// Reads and checks a scenario file (and the robot file it names).
pub fn load(path: &Path) -> Result<Scenario> {
    let text = read_text(path, "scenario").map_err(|e| anyhow!(e))?;
    parse(&text, path)
}

/// Checks a scenario's text; `path` names it in errors and places the robot file it names.
pub fn parse(text: &str, path: &Path) -> Result<Scenario> {
    let file = TomlFile {
        path,
        text,
        format: FORMAT,
        kind: "scenario",
    };
    let raw: RawScenario = file.read(scenario_shape).map_err(|e| anyhow!(e))?;
    file.check_scenario(raw)
}

impl TomlFile<'_> {
    fn check_scenario(&self, raw: RawScenario) -> Result<Scenario> {
        let name = self.name(&raw.name, "name")?;
        let duration = self.within(&raw.duration_s, "duration_s", 0.1, MAX_DURATION_S, "s")?;
        // The robot's drive (for the master) and sensors (for the slave); without a robot
        // file, the boards' power-on robot.
        let told = match &raw.robot {
            Some(r) => {
                let here = |e: anyhow::Error| anyhow!(self.at(r.span(), "robot", e.to_string()));
                robot_model(self.robot(r)?).map_err(here)?
            }
            None => power_on_robot(),
        };
        let true_robot = match &raw.true_robot {
            Some(r) => {
                let here =
                    |e: anyhow::Error| anyhow!(self.at(r.span(), "true_robot", e.to_string()));
                let truly = robot_model(self.robot(r)?).map_err(here)?;
                same_kind(&told, &truly).map_err(here)?;
                Some(truly)
            }
            None => None,
        };
        let RobotModel {
            name: robot,
            mut drive,
            layout,
            motor,
        } = told;
        let has_carriage = layout.carriage_geometry().is_some();

        let s = &raw.start;
        let start = (
            self.within(&s.x_m, "start.x_m", -MAX_FIELD_M, MAX_FIELD_M, "m")?,
            self.within(&s.y_m, "start.y_m", -MAX_FIELD_M, MAX_FIELD_M, "m")?,
            self.within(&s.heading_deg, "start.heading_deg", -360.0, 360.0, "deg")?
                .to_radians(),
        );
        let start_swivel = match (&s.swivel_deg, has_carriage) {
            (Some(v), true) => self
                .within(v, "start.swivel_deg", -360.0, 360.0, "deg")?
                .to_radians(),
            (Some(v), false) => {
                return Err(anyhow!(self.at(
                    v.span(),
                    "start.swivel_deg",
                    "this robot has no swivel carriage",
                )))
            }
            // The carriage trails the body's +y (seed 004's pursuit heads that way first).
            (None, true) => std::f64::consts::FRAC_PI_2,
            (None, false) => 0.0,
        };

        let mut motion = match (&raw.target, &raw.trajectory) {
            (Some(t), None) => self.target(t.get_ref())?,
            (None, Some(t)) => self.trajectory(t.get_ref())?,
            (Some(_), Some(t)) => {
                return Err(anyhow!(self.at(
                    t.span(),
                    "trajectory",
                    "give either [target] (the pursuit of Xu, Zhu and Hu 2015) or [trajectory] \
                     (the tracking of Dehghan Banadaki, Nili Ahmadabadi and Moaveni Sabet 2005), \
                     not both",
                )))
            }
            (None, None) => {
                return Err(anyhow!(self.error(
                    Some(0),
                    Some("target".into()),
                    "missing: a scenario has a [target] (pursuit) or a [trajectory] (tracking)"
                        .into(),
                )))
            }
        };
        // A body's path (UMBmark's squares) is sent as the path of the point the master
        // tracks: seed 002's A, ahead of the axle, which its turns in place swing round.
        if let (
            Motion::Track {
                trajectory: name,
                ahead_m,
                ..
            },
            protocol::serial::DriveKind::OffsetDiff { offset_um, .. },
        ) = (&mut motion, drive.kind)
        {
            if trajectory::is_body_path(name) {
                *ahead_m = offset_um as f64 * 1e-6;
            }
        }

        let mut pursuit_period_s = None;
        if let Some(c) = &raw.controller {
            // Each gain in [0, 1000] (> 0 where `positive`), as the whole number of `unit`s it
            // travels in: thousandths for the law, millionths for the speed loops (a small kd
            // is a real setting). 1000 of them fits both wire types.
            let gain = |v: &Option<Spanned<f64>>,
                        key: &str,
                        positive: bool,
                        unit: f64|
             -> Res<Option<f64>> {
                let Some(v) = v else { return Ok(None) };
                let key = format!("controller.{key}");
                let x = if positive {
                    self.positive(v, &key)?
                } else {
                    self.non_negative(v, &key)?
                };
                if x > 1000.0 {
                    return Err(self.at(v.span(), &key, format!("must be at most 1000, got {x}")));
                }
                let on_wire = (x / unit).round();
                if positive && on_wire == 0.0 {
                    return Err(self.at(
                        v.span(),
                        &key,
                        format!(
                            "must be at least {unit} (the master takes it in steps of {unit}), \
                             got {x}"
                        ),
                    ));
                }
                Ok(Some(on_wire))
            };
            let milli = |v, key, positive| gain(v, key, positive, 1e-3);
            let micro = |v, key| gain(v, key, false, 1e-6);
            if let Some(k) = milli(&c.k_forward, "k_forward", true)? {
                drive.k_forward_milli = k as u32;
            }
            if let Some(k) = milli(&c.k_lateral, "k_lateral", true)? {
                drive.k_lateral_milli = k as u32;
            }
            if let Some(k) = milli(&c.ff_forward, "ff_forward", false)? {
                drive.ff_forward_milli = k as i32;
            }
            if let Some(k) = milli(&c.ff_lateral, "ff_lateral", false)? {
                drive.ff_lateral_milli = k as i32;
            }
            if let Some(k) = milli(&c.diff_forward, "diff_forward", false)? {
                drive.diff_forward_milli = k as i32;
            }
            if let Some(k) = milli(&c.diff_lateral, "diff_lateral", false)? {
                drive.diff_lateral_milli = k as i32;
            }
            if let Some(k) = micro(&c.speed_kp, "speed_kp")? {
                drive.speed_kp_micro = k as u32;
            }
            if let Some(k) = micro(&c.speed_ki, "speed_ki")? {
                drive.speed_ki_micro = k as u32;
            }
            if let Some(k) = micro(&c.speed_kd, "speed_kd")? {
                drive.speed_kd_micro = k as u32;
            }
            if let Some(p) = &c.pursuit_period_s {
                pursuit_period_s =
                    Some(self.within(p, "controller.pursuit_period_s", 0.0, 60.0, "s")?);
            }
        }

        let encoder_phase = match raw.noise.as_ref().and_then(|n| n.encoder_phase.as_ref()) {
            Some(p) => {
                let &[a, b] = p.get_ref().as_slice() else {
                    return Err(anyhow!(self.at(
                        p.span(),
                        "noise.encoder_phase",
                        format!(
                            "two fractions of a count, one per measuring wheel: got {} values",
                            p.get_ref().len()
                        ),
                    )));
                };
                let v = [a, b];
                if !v.iter().all(|x| (0.0..1.0).contains(x)) {
                    return Err(anyhow!(self.at(
                        p.span(),
                        "noise.encoder_phase",
                        format!("fractions of a count, each in [0, 1): got {v:?}"),
                    )));
                }
                Some(v)
            }
            None => None,
        };
        let encoder_edges = match raw.noise.as_ref().and_then(|n| n.encoder_edges.as_ref()) {
            Some(e) => crate::sim::generate::EdgeErrors::preset(e.get_ref()).map_err(|err| {
                anyhow!(self.at(e.span(), "noise.encoder_edges", format!("{err:#}")))
            })?,
            None => crate::sim::generate::EdgeErrors::IDEAL,
        };
        let mut faults = Faults::default();
        if let Some(f) = &raw.faults {
            if let Some(v) = &f.slave_off_at_s {
                faults.slave_off_at = Some(self.non_negative(v, "faults.slave_off_at_s")?);
            }
            if let Some(v) = &f.slave_reset_at_s {
                faults.slave_reset_at = Some(self.non_negative(v, "faults.slave_reset_at_s")?);
            }
            if let Some(v) = &f.host_silent_after_s {
                faults.host_silent_after =
                    Some(self.non_negative(v, "faults.host_silent_after_s")?);
            }
            let rate = |v: &Spanned<f64>, key: &str| -> Res<f64> {
                let x = self.non_negative(v, key)?;
                if x >= 1.0 {
                    return Err(self.at(
                        v.span(),
                        key,
                        format!("a probability per transaction or frame, below 1: got {x}"),
                    ));
                }
                Ok(x)
            };
            if let Some(v) = &f.spi_corrupt {
                faults.spi.corrupt = rate(v, "faults.spi_corrupt")?;
            }
            if let Some(v) = &f.spi_drop {
                faults.spi.drop = rate(v, "faults.spi_drop")?;
            }
            if let Some(v) = &f.spi_torn {
                faults.spi.torn = rate(v, "faults.spi_torn")?;
            }
            if let Some(v) = &f.spi_duplicate {
                faults.spi.duplicate = rate(v, "faults.spi_duplicate")?;
            }
            if let Some(v) = &f.spi_late {
                faults.spi.late = rate(v, "faults.spi_late")?;
            }
            let serial = [
                (
                    &f.serial_corrupt,
                    "faults.serial_corrupt",
                    &mut faults.serial.corrupt,
                ),
                (
                    &f.serial_drop,
                    "faults.serial_drop",
                    &mut faults.serial.drop,
                ),
                (
                    &f.serial_duplicate,
                    "faults.serial_duplicate",
                    &mut faults.serial.duplicate,
                ),
                (
                    &f.serial_delay,
                    "faults.serial_delay",
                    &mut faults.serial.delay,
                ),
                (
                    &f.serial_torn,
                    "faults.serial_torn",
                    &mut faults.serial.torn,
                ),
            ];
            let mut last_span = None;
            for (v, key, slot) in serial {
                if let Some(v) = v {
                    *slot = rate(v, key)?;
                    last_span = Some(v.span());
                }
            }
            if let Some(span) = last_span.filter(|_| faults.serial.total() >= 1.0) {
                return Err(anyhow!(self.at(
                    span,
                    "faults.serial_*",
                    format!(
                        "the serial fault rates share one draw per frame and must add up to \
                         under 1: they add up to {}",
                        faults.serial.total()
                    ),
                )));
            }
        }

        self.check_within_drive(&raw, &drive, &motion)?;
        Ok(Scenario {
            name,
            description: raw.description.trim().to_string(),
            robot,
            drive,
            motor,
            layout,
            start,
            start_swivel,
            motion,
            duration,
            pursuit_period_s,
            encoder_phase,
            encoder_edges,
            faults,
            source_files: std::iter::once(("the scenario file", self.path.to_path_buf()))
                .chain(
                    (raw.robot.as_ref()).map(|r| ("the scenario's robot file", self.robot_path(r))),
                )
                .chain(
                    (raw.true_robot.as_ref())
                        .map(|r| ("the scenario's true robot file", self.robot_path(r))),
                )
                .collect(),
            true_robot,
        })
    }

    /// The robot file a scenario names, relative to the scenario's folder.
    fn robot_path(&self, r: &Spanned<String>) -> PathBuf {
        let rel = PathBuf::from(r.get_ref());
        match self.path.parent() {
            Some(dir) if rel.is_relative() => dir.join(&rel),
            _ => rel,
        }
    }

    fn robot(&self, r: &Spanned<String>) -> Result<Robot> {
        let path = self.robot_path(r);
        Robot::load(&path).map_err(|e: FileError| {
            anyhow!(self.at(
                r.span(),
                "robot",
                format!("cannot use {}: {e}", path.display())
            ))
        })
    }

    /// What the master would refuse, refused here at its key with the same test (the master's
    /// own `DriveSetup` and top speed): a scenario inside every documented range can still ask
    /// more than its robot can do, and the run would only say "the master refused".
    fn check_within_drive(
        &self,
        raw: &RawScenario,
        drive: &protocol::serial::DriveGeometry,
        motion: &Motion,
    ) -> Result<()> {
        let Some(setup) = firmware_master::drive_setup::DriveSetup::from_geometry(drive) else {
            // The controller's gains have no span of their own here: the robot line, or the
            // file's first.
            let span = raw.robot.as_ref().map_or(0..1, |r| r.span());
            return Err(anyhow!(self.at(
                span,
                "controller",
                "the master cannot drive this robot with these settings (its drive geometry \
                 is impossible: check the robot's drive wheels and the controller's gains)",
            )));
        };
        let top = setup.kinematics.max_speed();
        let too_fast = |v: f64| v > top;
        match (motion, &raw.target, &raw.trajectory) {
            (
                Motion::Pursue {
                    robot_speed,
                    target_speed,
                    ..
                },
                Some(t),
                _,
            ) => {
                for (v, spanned, key) in [
                    (
                        *robot_speed,
                        &t.get_ref().robot_speed_m_s,
                        "target.robot_speed_m_s",
                    ),
                    (*target_speed, &t.get_ref().speed_m_s, "target.speed_m_s"),
                ] {
                    if too_fast(v) {
                        return Err(anyhow!(self.at(
                            spanned.span(),
                            key,
                            format!(
                                "{v} m/s is above the robot's top speed, {top:.3} m/s (the \
                                 master refuses it)"
                            ),
                        )));
                    }
                }
            }
            (Motion::Track { .. }, _, Some(t)) => {
                let path = crate::sim::emulator::reference::ReferencePath::new(motion)?;
                // Every millisecond of the path: the host samples it no finer.
                let steps = (path.duration() * 1e3).ceil().min(1e7) as u64;
                let peak = (0..=steps)
                    .map(|k| {
                        let (vx, vy) = path.at(k as f64 * 1e-3).velocity;
                        vx.hypot(vy)
                    })
                    .fold(0.0, f64::max);
                if too_fast(peak) {
                    return Err(anyhow!(self.at(
                        t.get_ref().name.span(),
                        "trajectory.name",
                        format!(
                            "the path's peak speed, {peak:.3} m/s, is above the robot's top \
                             speed, {top:.3} m/s (the master refuses its samples)"
                        ),
                    )));
                }
            }
            _ => {}
        }
        Ok(())
    }

    fn target(&self, t: &RawTarget) -> Result<Motion> {
        let point = |v: &Spanned<[f64; 2]>, key: &str| -> Res<(f64, f64)> {
            let [x, y] = *v.get_ref();
            if !(x.is_finite() && y.is_finite()) || x.abs().max(y.abs()) > MAX_FIELD_M {
                return Err(self.at(
                    v.span(),
                    key,
                    format!("must be two numbers within ±{MAX_FIELD_M} m, got [{x}, {y}]"),
                ));
            }
            Ok((x, y))
        };
        Ok(Motion::Pursue {
            target_from: point(&t.from_m, "target.from_m")?,
            target_to: point(&t.to_m, "target.to_m")?,
            target_speed: self.within(&t.speed_m_s, "target.speed_m_s", 0.0, 100.0, "m/s")?,
            robot_speed: self.within(
                &t.robot_speed_m_s,
                "target.robot_speed_m_s",
                1e-3,
                100.0,
                "m/s",
            )?,
            heading: match &t.heading_deg {
                Some(h) => self.within(h, "target.heading_deg", -360.0, 360.0, "deg")?,
                None => 0.0,
            }
            .to_radians(),
        })
    }

    fn trajectory(&self, t: &RawTrajectory) -> Result<Motion> {
        let name = self.name(&t.name, "trajectory.name")?;
        if trajectory::build(&name).is_none() {
            let known: Vec<_> = trajectory::catalogue().iter().map(|n| n.name).collect();
            return Err(anyhow!(self.at(
                t.name.span(),
                "trajectory.name",
                format!(
                    "no trajectory \"{name}\"; the catalogue has: {}",
                    known.join(", ")
                ),
            )));
        }
        let sample_period_s = match &t.sample_period_s {
            Some(p) => {
                let v = self.positive(p, "trajectory.sample_period_s")?;
                if !(0.001..=0.2).contains(&v) {
                    return Err(anyhow!(self.at(
                        p.span(),
                        "trajectory.sample_period_s",
                        format!(
                            "must be 0.001 to 0.2 s (the master's host timeout is 0.5 s), got {v}"
                        ),
                    )));
                }
                v
            }
            None => SAMPLE_PERIOD_S,
        };
        Ok(Motion::Track {
            trajectory: name,
            sample_period_s,
            ahead_m: 0.0,
        })
    }
}
