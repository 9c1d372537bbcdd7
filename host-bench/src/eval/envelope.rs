//! Seed 003's speed envelope of the three-omni drive, from the model and measured on the
//! simulated robot, and its arc-versus-line comparison (SPEC §4, §6).
//!
//! Pure translation tops out at 2·v_max/√3 in six directions (and 1·v_max between them):
//! with no spin the three wheel speeds sum to zero, so at most two reach v_max. Spinning lets
//! all three reach v_max (seed 003's table 1: each wheel ±v_max, not all alike): the body then
//! translates at 4·v_max/3 while spinning at v_max/(3d), so in the field its reference point runs
//! round a circle of radius 4d. Measured here means driven flat out on the plant of `emulate`
//! (seed 004's DC gear motors with friction and dead band), each wheel held at its limit by the
//! master's speed loop (`robot_math::pid::SpeedPid`, its gains and 100 Hz, fed by the motor
//! encoders' counts as on the board), and timed from the ground truth once settled.

use anyhow::{Context, Result};
use robot_math::omni3::Omni3;
use robot_math::se2::wrap_angle;
use robot_math::wheel::Wheel;
use robot_math::{Pose2, Twist};
use serde::Serialize;

use super::arc_vs_line::{self, GoalRuns};
use crate::sim::plant::{MeasuringSensors, Plant, PlantConfig};
use firmware_master::drive_setup::{DriveSetup, SEED_004_DRIVE};
use robot_math::motor::DcMotor;
use robot_math::pid::SpeedPid;
use robot_math::sensors::speeds_from_counts;

/// Settling before a measurement (the speed loops' integrators included), and the measuring
/// window, seconds.
const SETTLE_S: f64 = 2.0;
const WINDOW_S: f64 = 1.0;
/// The plant's longest integration step, seconds: the motors' response is integrated exactly
/// and the pose by RK4, so a millisecond is far inside what a speed needs.
const STEP_S: f64 = 1e-3;
/// The master's control period, seconds (its speed loops run at it).
pub(crate) const CONTROL_S: f64 = 0.01;

#[derive(Clone, Debug, Serialize)]
pub struct Envelope {
    pub wheel_distance_m: f64,
    pub v_max_m_s: f64,
    /// Pure translation, one row per direction of the body frame (every degree).
    pub directions: Vec<Direction>,
    /// Measured top translation speed over the directions / v_max, and the model's 2/√3.
    pub translate_max_ratio: f64,
    pub translate_max_ratio_model: f64,
    /// Measured slowest direction's top speed / v_max (the model's 1).
    pub translate_min_ratio: f64,
    /// Seed 003's six cases of every wheel at ±v_max.
    pub spin_cases: Vec<SpinCase>,
    /// Measured top translation speed while spinning / v_max, and the model's 4/3.
    pub spin_translate_max_ratio: f64,
    pub spin_translate_max_ratio_model: f64,
    pub arc_vs_line: ArcVsLine,
}

#[derive(Clone, Debug, Serialize)]
pub struct Direction {
    pub direction_deg: f64,
    pub model_m_s: f64,
    pub measured_m_s: f64,
}

#[derive(Clone, Debug, Serialize)]
pub struct SpinCase {
    /// Wheel speeds as fractions of v_max.
    pub wheels: [f64; 3],
    pub model_speed_m_s: f64,
    pub model_spin_rad_s: f64,
    pub measured_speed_m_s: f64,
    pub measured_spin_rad_s: f64,
}

/// From A to B at the wheel limit: straight at the best direction's 2·v_max/√3, or along the
/// arc of radius 4d (translating at 4·v_max/3 while spinning) with central angle θ. Times:
/// line √3·R·sin(θ/2)/v_max, arc 3·R·θ/(4·v_max), R = 4d; the arc is quicker below θ*.
#[derive(Clone, Debug, Serialize)]
pub struct ArcVsLine {
    pub arc_radius_m: f64,
    /// Where the two times are equal, rad, and the chord there, in units of d.
    pub crossover_angle_rad: f64,
    pub crossover_chord_over_d: f64,
    /// What seed 003 prints for the same crossover (θ = 1.831 rad, "D ≈ 6.695 d"). Its own
    /// equations give 8·sin(θ*/2)·d = 6.34 d.
    pub paper_crossover_angle_rad: f64,
    pub paper_crossover_chord_over_d: f64,
    /// Driven on the simulated robot from rest, goals either side of the crossover
    /// (`eval::arc_vs_line`), and where the measured times cross.
    pub driven: Vec<GoalRuns>,
    pub measured_crossover_angle_rad: Option<f64>,
}

/// The envelope of seed 003's drive (d, v_max as the master's default configuration).
pub fn run(wheel_distance_m: f64, v_max_m_s: f64) -> Result<Envelope> {
    let omni = Omni3::new(wheel_distance_m, v_max_m_s)
        .context("wheel distance and v_max must be positive")?;
    let mut directions = Vec::new();
    for deg in 0..360 {
        let a = (deg as f64).to_radians();
        // Far beyond the limit, so the saturation sets the speed.
        let ask = Twist::new(100.0 * a.cos(), 100.0 * a.sin(), 0.0);
        let (wheels, _) = omni.wheel_speeds_saturated(ask);
        let t = omni.twist(wheels);
        let measured = drive_flat_out(&omni, wheels)?;
        directions.push(Direction {
            direction_deg: deg as f64,
            model_m_s: t.vx.hypot(t.vy),
            measured_m_s: measured.0,
        });
    }
    let (lo, hi) = directions
        .iter()
        .map(|d| d.measured_m_s)
        .fold((f64::MAX, 0.0f64), |(lo, hi), v| (lo.min(v), hi.max(v)));
    // Seed 003's table 1: (v1, v2, v3) in units of v_max.
    let table1 = [
        [-1.0, 1.0, 1.0],
        [1.0, -1.0, -1.0],
        [1.0, -1.0, 1.0],
        [-1.0, 1.0, -1.0],
        [1.0, 1.0, -1.0],
        [-1.0, -1.0, 1.0],
    ];
    let mut spin_cases = Vec::new();
    for w in table1 {
        let wheels = w.map(|f| f * v_max_m_s);
        let t = omni.twist(wheels);
        let (speed, spin) = drive_flat_out(&omni, wheels)?;
        spin_cases.push(SpinCase {
            wheels: w,
            model_speed_m_s: t.vx.hypot(t.vy),
            model_spin_rad_s: t.omega,
            measured_speed_m_s: speed,
            measured_spin_rad_s: spin,
        });
    }
    let spin_max = spin_cases
        .iter()
        .map(|c| c.measured_speed_m_s)
        .fold(0.0, f64::max);
    Ok(Envelope {
        wheel_distance_m,
        v_max_m_s,
        directions,
        translate_max_ratio: hi / v_max_m_s,
        translate_max_ratio_model: 2.0 / 3f64.sqrt(),
        translate_min_ratio: lo / v_max_m_s,
        spin_cases,
        spin_translate_max_ratio: spin_max / v_max_m_s,
        spin_translate_max_ratio_model: 4.0 / 3.0,
        arc_vs_line: arc_vs_line(&omni)?,
    })
}

/// The simulated robot with its wheels commanded to `wheels` (m/s) from rest: once settled,
/// the speed of its reference point along its path (m/s) and its spin (rad/s).
fn drive_flat_out(omni: &Omni3, wheels: [f64; 3]) -> Result<(f64, f64)> {
    let mut robot = WheelDriver::new(omni, Pose2::default(), wheels)?;
    for _ in 0..(SETTLE_S / CONTROL_S).round() as usize {
        robot.step();
    }
    let (s0, th0) = (robot.plant.path_length(), robot.plant.body().theta);
    // In short steps, so the heading's change is unwrapped however fast it spins.
    let mut turned = 0.0;
    let mut th = th0;
    for _ in 0..(WINDOW_S / CONTROL_S).round() as usize {
        robot.step();
        let now = robot.plant.body().theta;
        turned += wrap_angle(now - th);
        th = now;
    }
    Ok((
        (robot.plant.path_length() - s0) / WINDOW_S,
        turned / WINDOW_S,
    ))
}

/// Seed 003's robot on the plant of `emulate` (seed 004's DC motors), its wheels held at
/// given speeds by the master's speed loops fed by the motor encoders, one control period
/// (10 ms) at a time.
pub(crate) struct WheelDriver {
    pub plant: Plant,
    wheels: [f64; 3],
    pids: [SpeedPid; 3],
    counts: [u16; 3],
    per_count: f64,
    first: bool,
}

impl WheelDriver {
    pub fn new(omni: &Omni3, start: Pose2, wheels: [f64; 3]) -> Result<Self> {
        let drive = DriveSetup::from_geometry(&SEED_004_DRIVE)
            .context("the drive of the carriage robot (Xu, Zhu and Hu 2015)")?;
        let cfg = PlantConfig {
            drive: robot_math::drive::DriveKinematics::Omni3(*omni),
            motor: DcMotor::SEED_004,
            motor_metres_per_count: drive.metres_per_motor_count,
            // Not read here: two body-fixed wheels with metre-long counts, so the plant keeps
            // next to no encoder edges.
            sensors: MeasuringSensors::Wheels {
                wheels: [Wheel::at(0.0, 0.1, 0.0), Wheel::at(0.0, -0.1, 0.0)],
                metres_per_count: [1.0; 2],
            },
        };
        let per_count = drive
            .metres_per_motor_count
            .context("the carriage robot's motors (Xu, Zhu and Hu 2015) have encoders")?;
        let plant = Plant::new(cfg, start, 0.0, [0.0; 2]);
        let counts = plant.motor_counts();
        Ok(WheelDriver {
            plant,
            wheels,
            pids: [SpeedPid::new(drive.speed_pid); 3],
            counts,
            per_count,
            first: true,
        })
    }

    /// One control period: the speed each encoder showed over the last, the loops' duty, and
    /// the plant run on for the period.
    pub fn step(&mut self) {
        let now = self.plant.motor_counts();
        let measured = speeds_from_counts(self.counts, now, self.per_count, CONTROL_S);
        self.counts = now;
        let dt = if self.first { 0.0 } else { CONTROL_S };
        self.first = false;
        let duty: [i16; 3] = core::array::from_fn(|i| {
            (self.pids[i].update(self.wheels[i], measured[i], dt) * 1000.0).round() as i16
        });
        self.plant.set_duty(duty);
        self.plant.advance(CONTROL_S, STEP_S);
        self.plant.take_edges();
    }
}

fn arc_vs_line(omni: &Omni3) -> Result<ArcVsLine> {
    let d = omni.d;
    // 3θ/4 = √3·sin(θ/2) (both times over R/v_max): bisect on (1, 3), where the sign changes.
    let f = |th: f64| 3f64.sqrt() * (th / 2.0).sin() - 0.75 * th;
    let (mut lo, mut hi) = (1.0, 3.0);
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if f(mid) > 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let theta = 0.5 * (lo + hi);
    let driven = arc_vs_line::run(omni, &arc_vs_line::ANGLES_RAD)?;
    let goals: Vec<_> = driven.iter().map(|r| r.goal.clone()).collect();
    Ok(ArcVsLine {
        arc_radius_m: 4.0 * d,
        crossover_angle_rad: theta,
        crossover_chord_over_d: 8.0 * (theta / 2.0).sin(),
        paper_crossover_angle_rad: 1.831,
        paper_crossover_chord_over_d: 6.695,
        measured_crossover_angle_rad: arc_vs_line::measured_crossover(&goals),
        driven,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_model_and_the_plant_give_seed_003s_limits() {
        let e = run(0.22, 1.0).unwrap();
        let two_over_root3 = 2.0 / 3f64.sqrt();
        // Six peaks of 2/√3 (along and against each wheel's axle: wheel 1 at 0° rolls along
        // y), six troughs of 1, 30° apart.
        for d in &e.directions {
            let deg = d.direction_deg as i64;
            if deg % 60 == 0 {
                assert!((d.model_m_s - two_over_root3).abs() < 1e-12, "{d:?}");
            }
            if deg % 60 == 30 {
                assert!((d.model_m_s - 1.0).abs() < 1e-12, "{d:?}");
            }
        }
        assert!(
            (e.translate_max_ratio / two_over_root3 - 1.0).abs() < 0.02,
            "{e:?}"
        );
        assert!((e.translate_min_ratio - 1.0).abs() < 0.02, "{e:?}");
        for c in &e.spin_cases {
            assert!((c.model_speed_m_s - 4.0 / 3.0).abs() < 1e-12, "{c:?}");
            assert!((c.model_spin_rad_s.abs() - 1.0 / (3.0 * 0.22)).abs() < 1e-12);
            assert!((c.measured_spin_rad_s / c.model_spin_rad_s - 1.0).abs() < 0.02);
        }
        assert!(
            (e.spin_translate_max_ratio / (4.0 / 3.0) - 1.0).abs() < 0.02,
            "{e:?}"
        );
        let a = &e.arc_vs_line;
        assert!((a.crossover_angle_rad - 1.831).abs() < 1e-3, "{a:?}");
        assert!((a.crossover_chord_over_d - 6.34).abs() < 0.01, "{a:?}");
    }
}
