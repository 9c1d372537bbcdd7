//! Paths parametrised by arc length: lines, circular arcs, and curves (Bézier, the
//! figure-eight) re-parametrised numerically.

use std::f64::consts::{FRAC_PI_4, TAU};

use robot_math::se2::wrap_angle;

use super::quadrature::gl5;

/// A point of a path: position, unwrapped tangent angle, signed curvature (left turns > 0).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct PathPoint {
    pub(super) x: f64,
    pub(super) y: f64,
    pub(super) phi: f64,
    pub(super) kappa: f64,
}

pub(super) trait Path {
    fn length(&self) -> f64;
    /// The point at arc length `s` (clamped to `[0, length]`).
    fn at(&self, s: f64) -> PathPoint;
    /// Arc lengths inside the path where it is only finitely smooth (e.g. the curvature jumps
    /// where two Bézier curves meet).
    fn kinks(&self) -> Vec<f64> {
        Vec::new()
    }
}

pub(super) struct Line {
    x0: f64,
    y0: f64,
    phi: f64,
    length: f64,
}

impl Line {
    pub(super) fn new(x0: f64, y0: f64, phi: f64, length: f64) -> Line {
        Line {
            x0,
            y0,
            phi,
            length,
        }
    }
}

impl Path for Line {
    fn length(&self) -> f64 {
        self.length
    }
    fn at(&self, s: f64) -> PathPoint {
        let s = s.clamp(0.0, self.length);
        PathPoint {
            x: self.x0 + s * self.phi.cos(),
            y: self.y0 + s * self.phi.sin(),
            phi: self.phi,
            kappa: 0.0,
        }
    }
}

/// A circular arc from a start pose: radius, direction (+1 counter-clockwise) and swept
/// angle. Positions are written relative to the start so that it is exact.
pub(super) struct Arc {
    x0: f64,
    y0: f64,
    phi0: f64,
    radius: f64,
    dir: f64,
    sweep: f64,
}

impl Arc {
    /// A full counter-clockwise lap starting at the origin heading +x (centre (0, r)).
    pub(super) fn circle_ccw_from_origin(radius: f64) -> Arc {
        Arc {
            x0: 0.0,
            y0: 0.0,
            phi0: 0.0,
            radius,
            dir: 1.0,
            sweep: TAU,
        }
    }
}

impl Path for Arc {
    fn length(&self) -> f64 {
        self.radius * self.sweep
    }
    fn at(&self, s: f64) -> PathPoint {
        let s = s.clamp(0.0, self.length());
        let phi = self.phi0 + self.dir * s / self.radius;
        let r = self.dir * self.radius;
        PathPoint {
            x: self.x0 + r * (phi.sin() - self.phi0.sin()),
            y: self.y0 - r * (phi.cos() - self.phi0.cos()),
            phi,
            kappa: self.dir / self.radius,
        }
    }
}

/// A smooth plane curve p(u), u in `[0, pieces]`: value, first and second derivative.
pub(super) trait ParamCurve {
    fn pieces(&self) -> usize;
    fn eval(&self, u: f64) -> [[f64; 2]; 3];
}

/// Cubic Bézier curves joined end to end; piece k is u in [k, k+1].
pub(super) struct Bezier {
    control: Vec<[[f64; 2]; 4]>,
}

impl Bezier {
    pub(super) fn new(control: Vec<[[f64; 2]; 4]>) -> Bezier {
        assert!(!control.is_empty());
        Bezier { control }
    }
}

impl ParamCurve for Bezier {
    fn pieces(&self) -> usize {
        self.control.len()
    }
    fn eval(&self, u: f64) -> [[f64; 2]; 3] {
        let n = self.control.len();
        let k = (u.floor().max(0.0) as usize).min(n - 1);
        let p = &self.control[k];
        let t = (u - k as f64).clamp(0.0, 1.0);
        let m = 1.0 - t;
        let mut out = [[0.0; 2]; 3];
        for c in 0..2 {
            let (p0, p1, p2, p3) = (p[0][c], p[1][c], p[2][c], p[3][c]);
            out[0][c] =
                m * m * m * p0 + 3.0 * m * m * t * p1 + 3.0 * m * t * t * p2 + t * t * t * p3;
            out[1][c] = 3.0 * m * m * (p1 - p0) + 6.0 * m * t * (p2 - p1) + 3.0 * t * t * (p3 - p2);
            out[2][c] = 6.0 * m * (p2 - 2.0 * p1 + p0) + 6.0 * t * (p3 - 2.0 * p2 + p1);
        }
        out
    }
}

/// The lemniscate of Gerono (sin w, sin w cos w), w = 2πu, one lap from the crossing point,
/// turned by −45° so that it starts heading along +x.
pub(super) struct Gerono;

impl ParamCurve for Gerono {
    fn pieces(&self) -> usize {
        1
    }
    fn eval(&self, u: f64) -> [[f64; 2]; 3] {
        let w = TAU * u;
        let (s1, c1) = w.sin_cos();
        let (s2, c2) = (2.0 * w).sin_cos();
        let raw = [
            [s1, 0.5 * s2],
            [TAU * c1, TAU * c2],
            [-TAU * TAU * s1, -2.0 * TAU * TAU * s2],
        ];
        let (s, c) = (-FRAC_PI_4).sin_cos();
        raw.map(|[x, y]| [c * x - s * y, s * x + c * y])
    }
}

/// A [`ParamCurve`] re-parametrised by arc length and scaled to a given length.
pub(super) struct ArcLength<C> {
    curve: C,
    /// Parameter nodes, the raw arc length at each, the unwrapped tangent angle at each.
    u: Vec<f64>,
    s: Vec<f64>,
    phi: Vec<f64>,
    /// Scale from the raw curve to the path.
    pub(super) scale: f64,
}

const NODES_PER_PIECE: usize = 256;

impl<C: ParamCurve> ArcLength<C> {
    pub(super) fn new(curve: C, length: f64) -> ArcLength<C> {
        let n = curve.pieces() * NODES_PER_PIECE;
        let u: Vec<f64> = (0..=n).map(|k| k as f64 / NODES_PER_PIECE as f64).collect();
        let mut s = vec![0.0; n + 1];
        let mut phi = vec![0.0; n + 1];
        let angle = |u: f64| {
            let d = curve.eval(u)[1];
            d[1].atan2(d[0])
        };
        phi[0] = angle(0.0);
        for k in 1..=n {
            s[k] = s[k - 1] + gl5(u[k - 1], u[k], |v| speed(&curve, v));
            phi[k] = phi[k - 1] + wrap_angle(angle(u[k]) - phi[k - 1]);
        }
        let scale = length / s[n];
        ArcLength {
            curve,
            u,
            s,
            phi,
            scale,
        }
    }

    /// The parameter u at raw arc length `s`, and the node interval it is in.
    pub(super) fn param(&self, s: f64) -> (f64, usize) {
        let n = self.u.len() - 1;
        let s = s.clamp(0.0, self.s[n]);
        let k = (self.s.partition_point(|&v| v <= s).max(1) - 1).min(n - 1);
        let (u0, u1, s0, s1) = (self.u[k], self.u[k + 1], self.s[k], self.s[k + 1]);
        let mut u = u0 + (u1 - u0) * ((s - s0) / (s1 - s0));
        for _ in 0..30 {
            let f = s0 + gl5(u0, u, |v| speed(&self.curve, v)) - s;
            let step = f / speed(&self.curve, u);
            let next = (u - step).clamp(u0, u1);
            let done = (next - u).abs() <= 1e-16 * (1.0 + u.abs());
            u = next;
            if done {
                break;
            }
        }
        (u, k)
    }
}

pub(super) fn speed<C: ParamCurve>(curve: &C, u: f64) -> f64 {
    let d = curve.eval(u)[1];
    d[0].hypot(d[1])
}

impl<C: ParamCurve> Path for ArcLength<C> {
    fn length(&self) -> f64 {
        self.s[self.s.len() - 1] * self.scale
    }
    fn kinks(&self) -> Vec<f64> {
        (1..self.curve.pieces())
            .map(|k| self.s[k * NODES_PER_PIECE] * self.scale)
            .collect()
    }
    fn at(&self, s: f64) -> PathPoint {
        let (u, k) = self.param(s / self.scale);
        let [p, d1, d2] = self.curve.eval(u);
        let v = d1[0].hypot(d1[1]);
        PathPoint {
            x: p[0] * self.scale,
            y: p[1] * self.scale,
            phi: self.phi[k] + wrap_angle(d1[1].atan2(d1[0]) - self.phi[k]),
            kappa: (d1[0] * d2[1] - d1[1] * d2[0]) / (v * v * v) / self.scale,
        }
    }
}

#[cfg(test)]
mod tests {
    use std::f64::consts::FRAC_PI_2;

    use super::*;

    #[test]
    fn arc_length_table_matches_a_circle_quadrant() {
        // A Bézier that approximates a quarter circle: its length is close to π/2 (within
        // the approximation's 0.03 %), and the re-parametrisation has unit speed.
        let k = 0.552_284_749_830_793_4;
        let c = Bezier::new(vec![[[1.0, 0.0], [1.0, k], [k, 1.0], [0.0, 1.0]]]);
        let a = ArcLength::new(c, 1.0);
        let raw = a.s[a.s.len() - 1];
        assert!((raw - FRAC_PI_2).abs() < 1e-3, "{raw}");
        for i in 1..50 {
            let s = i as f64 / 50.0;
            let h = 1e-6;
            let p0 = a.at(s - h);
            let p1 = a.at(s + h);
            let speed = (p1.x - p0.x).hypot(p1.y - p0.y) / (2.0 * h);
            assert!((speed - 1.0).abs() < 1e-6, "s {s}: speed {speed}");
        }
    }
}
