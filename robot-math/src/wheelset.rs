//! Body twist from N measuring wheels (SPEC §2).
//!
//! Each wheel measures s_i' = row_i · (v_x, v_y, ω) (see [`Wheel::row`]). With
//! * **three** independent wheels the twist is exactly `J⁻¹ s'` (seed 000's closed form);
//! * **more** than three it is the least-squares fit `(JᵀJ)⁻¹ Jᵀ s'`, and the residual
//!   `s' − J·twist` measures slip (or a miscalibrated wheel);
//! * **two** wheels on one axle determine (v_x, ω) under the no-lateral-slip assumption: the
//!   axle's midpoint cannot move sideways, which is a third, virtual wheel that always reads 0.
//!
//! The same linear map applies to displacements over an update as to speeds, so estimators
//! pass count differences times travel per count.

use crate::wheel::{invert3, mul3, Mat3, Wheel};
use crate::Twist;

/// Most wheels a solver takes (room for redundant layouts without allocation).
pub const MAX_WHEELS: usize = 8;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SolveMode {
    /// Two wheels on one axle, no lateral slip.
    Axle,
    /// Three independent wheels, exact.
    Exact,
    /// Four or more wheels, least squares.
    LeastSquares,
}

/// Why a set of wheels cannot determine the twist.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GeometryError {
    /// Fewer than two, or more than [`MAX_WHEELS`].
    WheelCount(usize),
    /// Two wheels that do not share an axle (not parallel, or no lateral offset).
    NotOnOneAxle,
    /// The wheels do not see all three components of the twist (e.g. all parallel).
    Degenerate,
}

#[derive(Clone, Copy, Debug)]
pub struct WheelSolver {
    mode: SolveMode,
    n: usize,
    rows: [[f64; 3]; MAX_WHEELS],
    /// Maps measurements to the twist: 3 × n (for the axle mode, the two real wheels' columns).
    pinv: [[f64; MAX_WHEELS]; 3],
}

impl WheelSolver {
    /// A solver of no wheels: what [`init`](Self::init) fills where the solver lives.
    pub(crate) const EMPTY: WheelSolver = WheelSolver {
        mode: SolveMode::Exact,
        n: 0,
        rows: [[0.0; 3]; MAX_WHEELS],
        pinv: [[0.0; MAX_WHEELS]; 3],
    };

    pub fn new(wheels: &[Wheel]) -> Result<Self, GeometryError> {
        let mut solver = Self::EMPTY;
        solver.init(wheels)?;
        Ok(solver)
    }

    /// [`new`](Self::new) written where the solver lives: a board's float baselines build
    /// theirs inside their static state, and a 392 B value returned through the builders is
    /// a copy on the stack at each step. On `Err` the solver has no wheels.
    pub(crate) fn init(&mut self, wheels: &[Wheel]) -> Result<(), GeometryError> {
        let n = wheels.len();
        self.n = 0;
        if !(2..=MAX_WHEELS).contains(&n) {
            return Err(GeometryError::WheelCount(n));
        }
        self.rows = [[0.0; 3]; MAX_WHEELS];
        for (r, w) in self.rows.iter_mut().zip(wheels) {
            *r = w.row();
        }
        self.pinv = [[0.0; MAX_WHEELS]; 3];
        let (rows, pinv) = (&self.rows, &mut self.pinv);
        self.mode = match n {
            2 => {
                let (a, b) = (wheels[0], wheels[1]);
                // Parallel rolling directions, offset across them.
                let cross = a.ux * b.uy - a.uy * b.ux;
                let dot = a.ux * b.ux + a.uy * b.uy;
                let lateral = (b.x - a.x) * -a.uy + (b.y - a.y) * a.ux;
                let along = (b.x - a.x) * a.ux + (b.y - a.y) * a.uy;
                if cross.abs() > 1e-9 || dot <= 0.0 || lateral.abs() < 1e-9 || along.abs() > 1e-9 {
                    return Err(GeometryError::NotOnOneAxle);
                }
                // Virtual wheel at the axle midpoint, rolling sideways, always reading 0.
                let mid = Wheel {
                    x: (a.x + b.x) / 2.0,
                    y: (a.y + b.y) / 2.0,
                    ux: -a.uy,
                    uy: a.ux,
                };
                let inv = invert3(&[rows[0], rows[1], mid.row()], 1e-12)
                    .ok_or(GeometryError::Degenerate)?;
                for (r, row) in pinv.iter_mut().enumerate() {
                    row[0] = inv[r][0];
                    row[1] = inv[r][1];
                }
                SolveMode::Axle
            }
            _ => {
                // JᵀJ, scaled so the degeneracy test does not depend on units.
                let mut jtj: Mat3 = [[0.0; 3]; 3];
                for r in &rows[..n] {
                    for i in 0..3 {
                        for j in 0..3 {
                            jtj[i][j] += r[i] * r[j];
                        }
                    }
                }
                let scale = (jtj[0][0] + jtj[1][1] + jtj[2][2]) / 3.0;
                // NaN geometry gives a NaN scale: refuse it with the zero case.
                if scale.is_nan() || scale <= 0.0 {
                    return Err(GeometryError::Degenerate);
                }
                let inv =
                    invert3(&jtj, 1e-9 * scale * scale * scale).ok_or(GeometryError::Degenerate)?;
                for (k, r) in rows[..n].iter().enumerate() {
                    let col = mul3(&inv, *r);
                    for i in 0..3 {
                        pinv[i][k] = col[i];
                    }
                }
                if n == 3 {
                    SolveMode::Exact
                } else {
                    SolveMode::LeastSquares
                }
            }
        };
        self.n = n;
        Ok(())
    }

    pub fn mode(&self) -> SolveMode {
        self.mode
    }

    pub fn wheels(&self) -> usize {
        self.n
    }

    /// The twist (or body displacement) that explains the wheel speeds (or travels) best.
    pub fn solve(&self, s: &[f64]) -> Twist {
        let mut v = [0.0; 3];
        for (i, vi) in v.iter_mut().enumerate() {
            *vi = self.pinv[i][..self.n]
                .iter()
                .zip(s)
                .map(|(p, s)| p * s)
                .sum();
        }
        Twist::new(v[0], v[1], v[2])
    }

    /// Root-mean-square of what the fitted twist leaves unexplained: zero for exact and axle
    /// layouts (nothing is redundant), a slip measure for least squares.
    pub fn residual(&self, s: &[f64], t: Twist) -> f64 {
        let sum: f64 = self.rows[..self.n]
            .iter()
            .zip(s)
            .map(|(r, s)| {
                let e = s - (r[0] * t.vx + r[1] * t.vy + r[2] * t.omega);
                e * e
            })
            .sum();
        libm::sqrt(sum / self.n as f64)
    }

    /// The matrix that maps the wheels' measurements to the twist, row by row (3 × wheels).
    pub fn pseudo_inverse(&self) -> [[f64; MAX_WHEELS]; 3] {
        self.pinv
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::omni3::Omni3;
    use core::f64::consts::PI;
    use proptest::prelude::*;

    fn triangle(mount: f64) -> [Wheel; 3] {
        core::array::from_fn(|i| {
            let a = i as f64 * 2.0 * PI / 3.0;
            Wheel::at(0.115 * a.cos(), 0.115 * a.sin(), a + PI / 2.0 + mount)
        })
    }

    proptest! {
        #[test]
        fn three_wheels_recover_any_twist(vx in -2.0..2.0f64, vy in -2.0..2.0f64, w in -5.0..5.0f64, mount in -1.0..1.0f64) {
            let wheels = triangle(mount);
            let t = Twist::new(vx, vy, w);
            let s: Vec<f64> = wheels.iter().map(|wh| wh.rolling_speed(t)).collect();
            let solver = WheelSolver::new(&wheels).unwrap();
            prop_assert_eq!(solver.mode(), SolveMode::Exact);
            let back = solver.solve(&s);
            prop_assert!((back.vx - vx).abs() < 1e-9 && (back.vy - vy).abs() < 1e-9 && (back.omega - w).abs() < 1e-9);
        }

        #[test]
        fn redundant_wheels_fit_and_expose_slip(vx in -2.0..2.0f64, vy in -2.0..2.0f64, w in -5.0..5.0f64, slip in 0.001..0.1f64) {
            let mut wheels = triangle(0.3).to_vec();
            wheels.push(Wheel::at(-0.05, 0.02, 0.4));
            let t = Twist::new(vx, vy, w);
            let mut s: Vec<f64> = wheels.iter().map(|wh| wh.rolling_speed(t)).collect();
            let solver = WheelSolver::new(&wheels).unwrap();
            prop_assert_eq!(solver.mode(), SolveMode::LeastSquares);
            let back = solver.solve(&s);
            prop_assert!(solver.residual(&s, back) < 1e-9);
            prop_assert!((back.vx - vx).abs() < 1e-9 && (back.omega - w).abs() < 1e-9);
            // One wheel slips: the residual shows it.
            s[3] += slip;
            let fit = solver.solve(&s);
            prop_assert!(solver.residual(&s, fit) > slip / 10.0);
        }

        #[test]
        fn axle_recovers_forward_speed_and_turn_rate(v in -2.0..2.0f64, w in -5.0..5.0f64) {
            let wheels = [Wheel::at(0.0, 0.15, 0.0), Wheel::at(0.0, -0.15, 0.0)];
            let t = Twist::new(v, 0.0, w);
            let s = [wheels[0].rolling_speed(t), wheels[1].rolling_speed(t)];
            let solver = WheelSolver::new(&wheels).unwrap();
            prop_assert_eq!(solver.mode(), SolveMode::Axle);
            let back = solver.solve(&s);
            prop_assert!((back.vx - v).abs() < 1e-9 && back.vy.abs() < 1e-9 && (back.omega - w).abs() < 1e-9);
        }
    }

    #[test]
    fn seed_003_drive_wheels_solve_like_omni3() {
        let o = Omni3::new(0.22, 1.0).unwrap();
        let solver = WheelSolver::new(&Omni3::wheels(0.22)).unwrap();
        let w = [0.3, -0.2, 0.5];
        let (a, b) = (o.twist(w), solver.solve(&w));
        assert!(
            (a.vx - b.vx).abs() < 1e-12
                && (a.vy - b.vy).abs() < 1e-12
                && (a.omega - b.omega).abs() < 1e-12
        );
    }

    #[test]
    fn degenerate_layouts_are_refused() {
        // Three wheels all rolling along x: blind to v_y.
        let parallel = [
            Wheel::at(0.1, 0.0, 0.0),
            Wheel::at(0.0, 0.1, 0.0),
            Wheel::at(-0.1, -0.1, 0.0),
        ];
        assert_eq!(
            WheelSolver::new(&parallel).unwrap_err(),
            GeometryError::Degenerate
        );
        // Three wheels whose rolling lines meet in one point: blind to a spin about it.
        let concurrent: [Wheel; 3] = core::array::from_fn(|i| {
            let a = i as f64 * 2.0 * PI / 3.0;
            Wheel::at(0.1 * a.cos(), 0.1 * a.sin(), a)
        });
        assert_eq!(
            WheelSolver::new(&concurrent).unwrap_err(),
            GeometryError::Degenerate
        );
        // Two wheels one behind the other.
        let tandem = [Wheel::at(0.1, 0.0, 0.0), Wheel::at(-0.1, 0.0, 0.0)];
        assert_eq!(
            WheelSolver::new(&tandem).unwrap_err(),
            GeometryError::NotOnOneAxle
        );
        assert_eq!(
            WheelSolver::new(&tandem[..1]).unwrap_err(),
            GeometryError::WheelCount(1)
        );
    }
}
