//! `arc`: seed 004's "arc algorithm" (圆弧算法), the robot-competition classic, as a baseline.
//!
//! Seed 004, eqs. (1)–(4): each sampling period the wheels travel L1, L2; the heading moves by
//! ∠a = (L1 − L2)/L, *accumulated* from these increments; the travel ∇s steps the position
//! along the heading after the step: x1 = x0 + ∇s·cos∠a, y1 = y0 + ∇s·sin∠a. (The printed
//! ∇s = L1 − L2 is a typo for the travel (L1 + L2)/2, which the paper states just before.)
//! The body heading is the carriage heading ± the absolute encoder's angle (∠3 = ∠1 ± ∠2).
//!
//! Generalised to any wheel layout the same way: the per-step body displacement and turn come
//! from the wheel solver, the turn is accumulated, and the displacement is rotated by the
//! heading after the step (an Euler step on the end heading: neither the arc nor the
//! mid-point chord). Eqs. (5)–(6) step the *body* along ∠3; on an omni body whose carriage
//! swivels that moves the body sideways to its real motion, so the axle (carriage) position is
//! stepped along the carriage heading as eqs. (3)–(4) do, and the body follows through the
//! swivel geometry ([`crate::carriage::CarriageGeometry::body_pose`]).
//!
//! Floats: a baseline for the host (and the slave can run it on request, slowly).

use crate::carriage::CarriageGeometry;
use crate::wheel::Wheel;
use crate::wheelset::{GeometryError, WheelSolver};
use crate::Pose2;

/// The arc algorithm over any solvable wheel layout.
#[derive(Clone, Copy, Debug)]
pub struct ArcOdometry {
    solver: WheelSolver,
    k: [f64; crate::wheelset::MAX_WHEELS],
    last: [f64; crate::wheelset::MAX_WHEELS],
    pose: Pose2,
}

impl ArcOdometry {
    pub fn new(
        solver: WheelSolver,
        metres_per_count: &[f64],
        start: Pose2,
        counts: &[f64],
    ) -> Self {
        let mut arc = ArcOdometry {
            solver,
            ..Self::EMPTY
        };
        arc.begin(metres_per_count, start, counts);
        arc
    }

    /// No wheels, at the origin: what [`init_from_wheels`](Self::init_from_wheels) fills
    /// where the state lives.
    pub(crate) const EMPTY: ArcOdometry = ArcOdometry {
        solver: WheelSolver::EMPTY,
        k: [0.0; crate::wheelset::MAX_WHEELS],
        last: [0.0; crate::wheelset::MAX_WHEELS],
        pose: Pose2 {
            x: 0.0,
            y: 0.0,
            theta: 0.0,
        },
    };

    /// [`new`](Self::new) with the solver of `wheels`, written where the state lives (a
    /// board's stack would hold each 0.5 KB pass through a builder). On `Err` the state is
    /// not usable.
    pub fn init_from_wheels(
        &mut self,
        wheels: &[Wheel],
        metres_per_count: &[f64],
        start: Pose2,
        counts: &[f64],
    ) -> Result<(), GeometryError> {
        self.solver.init(wheels)?;
        self.begin(metres_per_count, start, counts);
        Ok(())
    }

    fn begin(&mut self, metres_per_count: &[f64], start: Pose2, counts: &[f64]) {
        let n = self.solver.wheels();
        self.k = [0.0; crate::wheelset::MAX_WHEELS];
        self.last = [0.0; crate::wheelset::MAX_WHEELS];
        self.k[..n].copy_from_slice(&metres_per_count[..n]);
        self.last[..n].copy_from_slice(&counts[..n]);
        self.pose = start;
    }

    /// One sampling period ending with the encoders at `counts` (cumulative).
    pub fn update(&mut self, counts: &[f64]) -> Pose2 {
        let n = self.solver.wheels();
        let mut travel = [0.0; crate::wheelset::MAX_WHEELS];
        for j in 0..n {
            travel[j] = (counts[j] - self.last[j]) * self.k[j];
            self.last[j] = counts[j];
        }
        let d = self.solver.solve(&travel[..n]);
        // Eq. (1): the heading accumulates the per-step turn ...
        let theta = self.pose.theta + d.omega;
        // ... eqs. (3)-(4): and the step goes along the heading after the turn.
        let (s, c) = (crate::trig::sin(theta), crate::trig::cos(theta));
        self.pose = Pose2::new(
            self.pose.x + c * d.vx - s * d.vy,
            self.pose.y + s * d.vx + c * d.vy,
            theta,
        );
        self.pose
    }

    pub fn pose(&self) -> Pose2 {
        self.pose
    }
}

/// Seed 004's full layout: the arc algorithm on the carriage, the absolute encoder for the
/// body heading.
#[derive(Clone, Copy, Debug)]
pub struct CarriageArc {
    geom: CarriageGeometry,
    carriage: ArcOdometry,
    body: Pose2,
}

impl CarriageArc {
    pub fn new(
        geom: CarriageGeometry,
        body: Pose2,
        counts: [f64; 2],
        abs_code: u16,
    ) -> Option<Self> {
        let half = geom.wheel_base / 2.0;
        let solver =
            WheelSolver::new(&[Wheel::at(0.0, half, 0.0), Wheel::at(0.0, -half, 0.0)]).ok()?;
        let carriage_pose = geom.carriage_pose(body, geom.swivel_angle(abs_code));
        Some(CarriageArc {
            geom,
            carriage: ArcOdometry::new(solver, &geom.metres_per_count, carriage_pose, &counts),
            body,
        })
    }

    pub fn update(&mut self, counts: [f64; 2], abs_code: u16) -> Pose2 {
        let c = self.carriage.update(&counts);
        self.body = self.geom.body_pose(c, self.geom.swivel_angle(abs_code));
        self.body
    }

    pub fn body(&self) -> Pose2 {
        self.body
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::exact::ExactOracle;
    use crate::wheel::Wheel;
    use crate::Twist;
    use core::f64::consts::PI;

    fn diff_drive() -> WheelSolver {
        WheelSolver::new(&[Wheel::at(0.0, 0.15, 0.0), Wheel::at(0.0, -0.15, 0.0)]).unwrap()
    }

    #[test]
    fn straight_line_is_exact() {
        let mut a = ArcOdometry::new(
            diff_drive(),
            &[1e-4, 1e-4],
            Pose2::new(0.0, 0.0, 0.5),
            &[0.0, 0.0],
        );
        for i in 1..=1000 {
            a.update(&[i as f64 * 10.0, i as f64 * 10.0]);
        }
        let p = a.pose();
        assert!((p.x - 0.5f64.cos()).abs() < 1e-12 && (p.y - 0.5f64.sin()).abs() < 1e-12);
    }

    #[test]
    fn on_a_circle_the_end_heading_step_errs_where_the_exact_arc_does_not() {
        // Half a circle of radius 0.5 m in 50 steps (Δθ = 0.063 rad). The end-heading step
        // turns every chord early by Δθ/2, so after the half circle (a 1 m chord) the
        // position is off by about 1 m · Δθ/2 ≈ 31 mm; the exact arc lands on the spot.
        // (A *full* circle would hide it: uniformly rotated steps close on themselves.)
        let solver = diff_drive();
        let t = Twist::new(0.5, 0.0, 1.0);
        let wheels = [Wheel::at(0.0, 0.15, 0.0), Wheel::at(0.0, -0.15, 0.0)];
        let mut arc = ArcOdometry::new(solver, &[1e-4, 1e-4], Pose2::default(), &[0.0, 0.0]);
        let mut exact = ExactOracle::new(solver, &[1e-4, 1e-4], Pose2::default(), &[0.0, 0.0]);
        let steps = 50;
        for i in 1..=steps {
            let tt = PI * i as f64 / steps as f64;
            let c = wheels.map(|w| w.rolling_speed(t) * tt / 1e-4);
            arc.update(&c);
            exact.update(&c);
        }
        let target = Pose2::new(0.0, 1.0, PI);
        let arc_err = arc.pose().distance_to(target);
        let exact_err = exact.pose().distance_to(target);
        assert!(exact_err < 1e-9, "{exact_err}");
        let expected = 1.0 * (PI / steps as f64) / 2.0;
        assert!(
            (arc_err - expected).abs() < 0.1 * expected,
            "{arc_err} vs {expected}"
        );
    }
}
