//! Seed 003's arc-versus-line comparison, driven on the simulated robot: from A (at rest) to a
//! goal B at the wheel limit, either straight along the best direction (two wheels at v_max,
//! 2·v_max/√3) or round the arc every wheel at v_max draws (radius 4d, spinning v_max/(3d)),
//! for goals at a range of central angles θ along that arc.
//!
//! Each run starts from rest and goes through the master's speed loops on seed 004's DC
//! motors ([`WheelDriver`]); it is timed from the ground truth to where the reference point
//! crosses B's line (perpendicular to its direction of travel at B, interpolated inside the
//! 10 ms step), and how far from B it crossed is reported. The model's times assume the
//! speeds from the first instant; measured ones include the motors' spin-up, about the same
//! for both paths, so the crossover stays put.

use anyhow::Result;
use robot_math::omni3::Omni3;
use robot_math::{Pose2, Twist};
use serde::Serialize;

use super::envelope::{WheelDriver, CONTROL_S};
use super::FieldPath;

/// The central angles compared, rad: either side of seed 003's crossover (1.831 rad).
pub const ANGLES_RAD: [f64; 7] = [0.5, 1.0, 1.5, 1.831, 2.2, 2.6, 3.0];

/// Seed 003's table 1, first row: wheels (−1, 1, 1)·v_max (the body spins the positive way).
const ARC_WHEELS: [f64; 3] = [-1.0, 1.0, 1.0];

#[derive(Clone, Debug, Serialize)]
pub struct Goal {
    pub angle_rad: f64,
    /// Straight distance from A to B, metres.
    pub chord_m: f64,
    pub line_model_s: f64,
    pub line_measured_s: f64,
    /// Distance from B where the straight run crossed B's line, metres.
    pub line_miss_m: f64,
    pub arc_model_s: f64,
    pub arc_measured_s: f64,
    pub arc_miss_m: f64,
    /// Seconds the arc saves over the line (negative: the line is quicker), measured.
    pub arc_gain_measured_s: f64,
}

/// One goal's runs, with the paths for a plot (field, metres; not in the JSON).
#[derive(Clone, Debug, Serialize)]
pub struct GoalRuns {
    #[serde(flatten)]
    pub goal: Goal,
    #[serde(skip)]
    pub b: (f64, f64),
    #[serde(skip)]
    pub line_path: FieldPath,
    #[serde(skip)]
    pub arc_path: FieldPath,
}

/// The goals of [`ANGLES_RAD`] on seed 003's drive.
pub fn run(omni: &Omni3, angles_rad: &[f64]) -> Result<Vec<GoalRuns>> {
    let v_max = omni.v_max;
    let arc_wheels = ARC_WHEELS.map(|w| w * v_max);
    let arc_twist = omni.twist(arc_wheels);
    let spin = arc_twist.omega.abs();
    angles_rad
        .iter()
        .map(|&angle| {
            // B: where the model's arc has turned `angle`, and its direction of travel there.
            let at_b = Pose2::default().integrate(arc_twist, angle / spin);
            let b = (at_b.x, at_b.y);
            let arc_dir = at_b.theta + arc_twist.vy.atan2(arc_twist.vx);
            let arc_model_s = angle / spin;
            let (arc_measured_s, arc_miss_m, arc_path) =
                drive_to(omni, Pose2::default(), arc_wheels, b, arc_dir, arc_model_s)?;
            // The line: turned at the start so that A→B is the body's fastest direction (0°,
            // along wheel 1's axle), two wheels at ∓v_max and the third idle.
            let chord_m = b.0.hypot(b.1);
            let line_dir = b.1.atan2(b.0);
            let (line_wheels, _) = omni.wheel_speeds_saturated(Twist::new(100.0, 0.0, 0.0));
            let line_speed = omni.twist(line_wheels).vx;
            let line_model_s = chord_m / line_speed;
            let start = Pose2::new(0.0, 0.0, line_dir);
            let (line_measured_s, line_miss_m, line_path) =
                drive_to(omni, start, line_wheels, b, line_dir, line_model_s)?;
            Ok(GoalRuns {
                goal: Goal {
                    angle_rad: angle,
                    chord_m,
                    line_model_s,
                    line_measured_s,
                    line_miss_m,
                    arc_model_s,
                    arc_measured_s,
                    arc_miss_m,
                    arc_gain_measured_s: line_measured_s - arc_measured_s,
                },
                b,
                line_path,
                arc_path,
            })
        })
        .collect()
}

/// Where the measured arc-minus-line time changes sign between two goals (linear between
/// them), rad; `None` if it never does over the goals.
pub fn measured_crossover(goals: &[Goal]) -> Option<f64> {
    goals.windows(2).find_map(|w| {
        let (a, b) = (&w[0], &w[1]);
        let (ga, gb) = (a.arc_gain_measured_s, b.arc_gain_measured_s);
        (ga > 0.0 && gb <= 0.0).then(|| a.angle_rad + (b.angle_rad - a.angle_rad) * ga / (ga - gb))
    })
}

/// From rest at `start`, wheels held at `wheels`, until the reference point crosses the line
/// through `b` across `direction`: (time, distance from `b` there, the path). Gives up at
/// three times the model's time and a second (an error: the drive never got there).
fn drive_to(
    omni: &Omni3,
    start: Pose2,
    wheels: [f64; 3],
    b: (f64, f64),
    direction: f64,
    model_s: f64,
) -> Result<(f64, f64, FieldPath)> {
    anyhow::ensure!(
        model_s.is_finite() && model_s > 0.0,
        "no time to reach B in the model ({model_s} s): zero speed"
    );
    let mut robot = WheelDriver::new(omni, start, wheels)?;
    let (ux, uy) = (direction.cos(), direction.sin());
    // Signed distance past B's line, and the point.
    let past = |p: Pose2| ((p.x - b.0) * ux + (p.y - b.1) * uy, (p.x, p.y));
    let (mut before, mut at) = past(robot.plant.body());
    let mut path = vec![at];
    let mut t = 0.0;
    while t < 3.0 * model_s + 1.0 {
        robot.step();
        let (now, p) = past(robot.plant.body());
        path.push(p);
        if before < 0.0 && now >= 0.0 {
            // Crossed inside this step: interpolate the time and the crossing point.
            let f = -before / (now - before);
            let x = (at.0 + f * (p.0 - at.0), at.1 + f * (p.1 - at.1));
            return Ok((t + f * CONTROL_S, (x.0 - b.0).hypot(x.1 - b.1), path));
        }
        (before, at) = (now, p);
        t += CONTROL_S;
    }
    anyhow::bail!(
        "the simulated robot did not reach ({:.3}, {:.3}) m within {:.1} s",
        b.0,
        b.1,
        t
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn driven_the_arc_wins_below_the_crossover_and_the_line_above() {
        let omni = Omni3::new(0.22, 1.0).unwrap();
        let runs = run(&omni, &ANGLES_RAD).unwrap();
        let goals: Vec<Goal> = runs.iter().map(|r| r.goal.clone()).collect();
        for g in &goals {
            // Both runs pass through B (the wheels spin up together, so the arc keeps its
            // radius and the line its direction) ...
            assert!(g.line_miss_m < 1e-4 && g.arc_miss_m < 1e-4, "{g:?}");
            // ... and take the model's time plus the motors' spin-up (58 ms time constant).
            for (model, measured) in [
                (g.line_model_s, g.line_measured_s),
                (g.arc_model_s, g.arc_measured_s),
            ] {
                let lag = measured - model;
                assert!(lag > 0.0 && lag < 0.15, "{g:?}");
            }
            // The model's chord: 8d·sin(θ/2).
            assert!((g.chord_m - 8.0 * 0.22 * (g.angle_rad / 2.0).sin()).abs() < 1e-9);
        }
        // The spin-up is the same on both paths (every wheel driven in proportion), so the
        // measured crossover is the model's by construction: this checks the driving, not the
        // crossover's value.
        assert!(goals[0].arc_gain_measured_s > 0.0, "{:?}", goals[0]);
        assert!(goals[6].arc_gain_measured_s < 0.0, "{:?}", goals[6]);
        let x = measured_crossover(&goals).expect("the sign changes once");
        assert!((x - 1.831).abs() < 0.1, "measured crossover {x} rad");
    }
}
