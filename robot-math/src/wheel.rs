//! The general wheel model (SPEC §2).

use crate::Twist;

/// A wheel (driven, or a free-rolling measuring wheel) in the body frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Wheel {
    /// Contact point, body frame, metres.
    pub x: f64,
    pub y: f64,
    /// Unit rolling direction, body frame.
    pub ux: f64,
    pub uy: f64,
}

impl Wheel {
    /// A wheel at `(x, y)` rolling along the direction `angle` (radians from body +x).
    pub fn at(x: f64, y: f64, angle: f64) -> Self {
        Wheel {
            x,
            y,
            ux: crate::trig::cos(angle),
            uy: crate::trig::sin(angle),
        }
    }

    /// The row of this wheel in the kinematic matrix: s' = row · (v_x, v_y, ω).
    pub fn row(&self) -> [f64; 3] {
        [self.ux, self.uy, self.x * self.uy - self.y * self.ux]
    }

    /// Rolling speed of this wheel for a body twist.
    pub fn rolling_speed(&self, t: Twist) -> f64 {
        let r = self.row();
        r[0] * t.vx + r[1] * t.vy + r[2] * t.omega
    }
}

/// A 3×3 matrix, row-major.
pub type Mat3 = [[f64; 3]; 3];

/// Inverse of a 3×3 matrix, or `None` when it is singular (|det| below `eps`).
pub fn invert3(m: &Mat3, eps: f64) -> Option<Mat3> {
    let c =
        |r0: usize, c0: usize, r1: usize, c1: usize| m[r0][c0] * m[r1][c1] - m[r0][c1] * m[r1][c0];
    let cof = [
        [c(1, 1, 2, 2), -c(1, 0, 2, 2), c(1, 0, 2, 1)],
        [-c(0, 1, 2, 2), c(0, 0, 2, 2), -c(0, 0, 2, 1)],
        [c(0, 1, 1, 2), -c(0, 0, 1, 2), c(0, 0, 1, 1)],
    ];
    let det = m[0][0] * cof[0][0] + m[0][1] * cof[0][1] + m[0][2] * cof[0][2];
    // NaN entries make a NaN determinant: refuse those too.
    if det.is_nan() || det.abs() <= eps {
        return None;
    }
    let mut inv = [[0.0; 3]; 3];
    for (r, row) in inv.iter_mut().enumerate() {
        for (c_, v) in row.iter_mut().enumerate() {
            // inverse = adjugate / det, adjugate = transpose of the cofactors
            *v = cof[c_][r] / det;
        }
    }
    Some(inv)
}

pub fn mul3(m: &Mat3, v: [f64; 3]) -> [f64; 3] {
    [
        m[0][0] * v[0] + m[0][1] * v[1] + m[0][2] * v[2],
        m[1][0] * v[0] + m[1][1] * v[1] + m[1][2] * v[2],
        m[2][0] * v[0] + m[2][1] * v[1] + m[2][2] * v[2],
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inverse_times_matrix_is_identity() {
        let m = [[2.0, 1.0, 0.5], [-1.0, 3.0, 0.2], [0.3, 0.1, 1.5]];
        let inv = invert3(&m, 1e-12).unwrap();
        for (i, col) in [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
            .iter()
            .enumerate()
        {
            let x = mul3(&m, mul3(&inv, *col));
            for j in 0..3 {
                assert!((x[j] - col[j]).abs() < 1e-12, "{i} {j}");
            }
        }
    }

    #[test]
    fn singular_is_refused() {
        let m = [[1.0, 2.0, 3.0], [2.0, 4.0, 6.0], [0.0, 1.0, 1.0]];
        assert!(invert3(&m, 1e-12).is_none());
    }

    #[test]
    fn wheel_rolling_speed_matches_rigid_body_velocity() {
        // The contact point's velocity is v + ω × r; the wheel measures its component along u.
        let w = Wheel::at(0.1, -0.2, 0.7);
        let t = Twist::new(0.3, -0.4, 1.1);
        let (vx, vy) = (t.vx - t.omega * w.y, t.vy + t.omega * w.x);
        assert!((w.rolling_speed(t) - (vx * w.ux + vy * w.uy)).abs() < 1e-15);
    }
}
