//! [`LutN`]: seed 001's table method generalised to N wheels (the `lut` method on robots
//! other than a differential drive).

use super::RESOLUTION_M;
use crate::se2::Pose2;
use core::f64::consts::PI;

/// Seed 001's table method generalised to any wheel layout whose every wheel turns the body by
/// the same angle per tick (seed 000's symmetric triangle does), keeping its three ideas:
/// heading as a count of whole steps, per-tick position increments looked up by the heading
/// rounded to whole degrees (one 360-entry table per wheel, built once), and unsigned 32-bit
/// coordinates at 10⁻⁸ m. Tracks the body origin; no multiply, divide or trig per tick.
/// (The paper's own method is [`LutOdometry`], for its differential drive.)
#[derive(Clone, Debug)]
pub struct LutN {
    n: usize,
    /// Heading steps per forward tick of each wheel: +1, −1 or 0.
    turn: [i8; crate::wheelset::MAX_WHEELS],
    /// One heading step in 2^-32 degree units, and a turn in the same units.
    step_q: i64,
    /// Heading in 2^-32 degree units, kept in [0, 360°).
    heading_q: i64,
    steps: i64,
    /// Body displacement of a forward tick of wheel j at heading d°, in LSB.
    table: alloc_free::Tables,
    x: u32,
    y: u32,
    origin: (u32, u32),
    beta: f64,
}

mod alloc_free {
    /// 360 (dx, dy) increments per wheel, for up to 4 wheels (no allocation: `no_std`).
    pub type Tables = [[(i32, i32); 360]; 4];
}

/// Why a layout cannot use the generalised table method.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LutNError {
    /// More than 4 wheels.
    TooManyWheels,
    /// The wheels turn the body by different angles per tick: the heading is then no count
    /// of one step.
    UnequalTurnSteps,
    /// No wheel turns the body: heading cannot change, use a simpler method.
    NoTurn,
}

const DEG_Q: i64 = 1 << 32;
const TURN_Q: i64 = 360 * DEG_Q;

impl LutN {
    pub fn new(
        solver: &crate::wheelset::WheelSolver,
        metres_per_count: &[f64],
        start: Pose2,
        origin_lsb: (u32, u32),
    ) -> Result<Self, LutNError> {
        let n = solver.wheels();
        if n > 4 {
            return Err(LutNError::TooManyWheels);
        }
        let p = solver.pseudo_inverse();
        let kth: [f64; 4] = core::array::from_fn(|j| {
            if j < n {
                p[2][j] * metres_per_count[j]
            } else {
                0.0
            }
        });
        let beta = kth
            .iter()
            .map(|k| libm::fabs(*k))
            .filter(|k| *k > 1e-15)
            .fold(f64::MAX, f64::min);
        if beta == f64::MAX {
            return Err(LutNError::NoTurn);
        }
        let mut turn = [0i8; crate::wheelset::MAX_WHEELS];
        for j in 0..n {
            let r = kth[j] / beta;
            if libm::fabs(r) < 1e-9 {
                continue;
            }
            if libm::fabs(libm::fabs(r) - 1.0) > 1e-9 {
                return Err(LutNError::UnequalTurnSteps);
            }
            turn[j] = if r > 0.0 { 1 } else { -1 };
        }
        let mut table = [[(0i32, 0i32); 360]; 4];
        for (j, t) in table.iter_mut().enumerate().take(n) {
            let (dx, dy) = (p[0][j] * metres_per_count[j], p[1][j] * metres_per_count[j]);
            for (d, e) in t.iter_mut().enumerate() {
                let a = d as f64 * PI / 180.0;
                let (s, c) = (crate::trig::sin(a), crate::trig::cos(a));
                *e = (
                    libm::round((c * dx - s * dy) / RESOLUTION_M) as i32,
                    libm::round((s * dx + c * dy) / RESOLUTION_M) as i32,
                );
            }
        }
        let to_lsb =
            |v: f64, o: u32| (libm::round(v / RESOLUTION_M) as i64).wrapping_add(o as i64) as u32;
        let heading_q = libm::round(start.theta.to_degrees() * DEG_Q as f64) as i64;
        Ok(LutN {
            n,
            turn,
            step_q: libm::round(beta.to_degrees() * DEG_Q as f64) as i64,
            heading_q: heading_q.rem_euclid(TURN_Q),
            steps: 0,
            table,
            x: to_lsb(start.x, origin_lsb.0),
            y: to_lsb(start.y, origin_lsb.1),
            origin: origin_lsb,
            beta,
        })
    }

    /// One tick of wheel `j` (step = ±1): turn by whole steps, then add the table entry at the
    /// new heading's whole degree. Adds, compares and a table read only.
    pub fn tick(&mut self, j: usize, step: i8) {
        if j >= self.n || (step != 1 && step != -1) {
            return;
        }
        let turns = self.turn[j] * step;
        if turns > 0 {
            self.heading_q += self.step_q;
            if self.heading_q >= TURN_Q {
                self.heading_q -= TURN_Q;
            }
        } else if turns < 0 {
            self.heading_q -= self.step_q;
            if self.heading_q < 0 {
                self.heading_q += TURN_Q;
            }
        }
        self.steps += turns as i64;
        // Whole degree, rounded: add half a degree, keep the integer part (a shift).
        let mut d = ((self.heading_q + DEG_Q / 2) >> 32) as usize;
        if d == 360 {
            d = 0;
        }
        let (dx, dy) = self.table[j][d];
        if step > 0 {
            self.x = self.x.wrapping_add(dx as u32);
            self.y = self.y.wrapping_add(dy as u32);
        } else {
            self.x = self.x.wrapping_sub(dx as u32);
            self.y = self.y.wrapping_sub(dy as u32);
        }
    }

    /// The body origin's pose, converted for scoring.
    pub fn pose(&self) -> Pose2 {
        Pose2::new(
            (self.x as f64 - self.origin.0 as f64) * RESOLUTION_M,
            (self.y as f64 - self.origin.1 as f64) * RESOLUTION_M,
            self.heading_q as f64 / DEG_Q as f64 * PI / 180.0,
        )
    }

    /// Heading steps counted so far, and the step in radians.
    pub fn heading_steps(&self) -> (i64, f64) {
        (self.steps, self.beta)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wheel::Wheel;
    use crate::wheelset::WheelSolver;

    fn triangle() -> WheelSolver {
        let w: [Wheel; 3] = core::array::from_fn(|i| {
            let a = i as f64 * 2.0 * PI / 3.0;
            let r = 0.2 / libm::sqrt(3.0);
            Wheel::at(
                r * crate::trig::cos(a),
                r * crate::trig::sin(a),
                a + PI / 2.0 + PI / 4.0,
            )
        });
        WheelSolver::new(&w).unwrap()
    }

    #[test]
    fn a_symmetric_triangle_qualifies_and_a_pure_spin_stays_put() {
        let s = triangle();
        let mut l = LutN::new(&s, &[1e-4; 3], Pose2::default(), (1 << 31, 1 << 31)).unwrap();
        // Every wheel forward once per round: the body spins in place (by symmetry).
        for _ in 0..5000 {
            for j in 0..3 {
                l.tick(j, 1);
            }
        }
        let p = l.pose();
        assert!(p.x.hypot(p.y) < 1e-4, "{p:?}");
        assert_eq!(l.heading_steps().0.unsigned_abs(), 15_000);
    }

    #[test]
    fn forward_then_backward_returns_exactly() {
        let s = triangle();
        let mut l = LutN::new(
            &s,
            &[1e-4; 3],
            Pose2::new(1.0, 2.0, 0.3),
            (1 << 31, 1 << 31),
        )
        .unwrap();
        let start = (l.x, l.y, l.heading_q);
        let seq = [0usize, 1, 1, 2, 0, 2, 2, 1];
        for &j in &seq {
            l.tick(j, 1);
        }
        for &j in seq.iter().rev() {
            l.tick(j, -1);
        }
        assert_eq!((l.x, l.y, l.heading_q), start);
    }

    #[test]
    fn unequal_turn_steps_are_refused() {
        let w = [
            Wheel::at(0.1, 0.0, 1.2),
            Wheel::at(-0.05, 0.1, 2.9),
            Wheel::at(0.0, -0.1, 0.1),
        ];
        let s = WheelSolver::new(&w).unwrap();
        assert_eq!(
            LutN::new(&s, &[1e-4; 3], Pose2::default(), (0, 0)).unwrap_err(),
            LutNError::UnequalTurnSteps
        );
    }
}
