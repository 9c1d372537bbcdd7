//! Polynomial interpolation of the twist over one integration interval, and the frame the
//! encoders' wheels are in (the body, or seed 004's trailing swivel carriage).

use super::Trajectory;

/// Sample points per interval: Chebyshev–Lobatto, degree 10.
pub(super) const SAMPLES: usize = 11;

/// A polynomial interpolant on one interval of four quantities: the wheels' frame twist
/// (v_x, v_y, ω) and, with a carriage, its heading φ.
pub(super) struct Interp {
    /// Sample points, increasing, from the interval's start to its end.
    pub(super) t: [f64; SAMPLES],
    pub(super) v: [[f64; 4]; SAMPLES],
}

impl Interp {
    fn points(t0: f64, t1: f64) -> [f64; SAMPLES] {
        let (m, r) = (0.5 * (t0 + t1), 0.5 * (t1 - t0));
        let n = (SAMPLES - 1) as f64;
        let mut t: [f64; SAMPLES] =
            std::array::from_fn(|j| m - r * (std::f64::consts::PI * j as f64 / n).cos());
        t[0] = t0;
        t[SAMPLES - 1] = t1;
        t
    }

    /// Samples `f(t, at_end)` at the interval's points; `at_end` is true at its last point,
    /// `t1`, where a twist that jumps at `t1` must be taken from the left.
    pub(super) fn sample(t0: f64, t1: f64, mut f: impl FnMut(f64, bool) -> [f64; 4]) -> Interp {
        let t = Interp::points(t0, t1);
        Interp {
            t,
            v: std::array::from_fn(|j| f(t[j], j == SAMPLES - 1)),
        }
    }

    /// The interpolant at `t` (barycentric formula; Chebyshev–Lobatto weights (−1)^j, halved
    /// at both ends).
    pub(super) fn eval(&self, t: f64) -> [f64; 4] {
        let mut num = [0.0; 4];
        let mut den = 0.0;
        for j in 0..SAMPLES {
            let d = t - self.t[j];
            if d == 0.0 {
                return self.v[j];
            }
            let mut w = if j % 2 == 0 { 1.0 } else { -1.0 };
            if j == 0 || j == SAMPLES - 1 {
                w *= 0.5;
            }
            let q = w / d;
            den += q;
            for (n, v) in num.iter_mut().zip(&self.v[j]) {
                *n += q * v;
            }
        }
        num.map(|n| n / den)
    }
}

/// The frame the encoders' wheels are in: the body, or a trailing swivel carriage whose
/// heading φ follows the caster equation. The pivot is the body reference point P; the axle
/// midpoint trails it by `trail` and cannot slide sideways, so with P's field velocity w,
/// φ' = (−sin φ·w_x + cos φ·w_y) / trail and the carriage moves forward at
/// cos φ·w_x + sin φ·w_y (the same model as the emulator's plant). φ(0) = θ(0) plus the
/// swivel at the start (`GenerateOptions::start_swivel_rad`).
pub(super) struct Frames<'a> {
    pub(super) traj: &'a dyn Trajectory,
    pub(super) trail: Option<f64>,
    /// Carriage heading at the end of the last interval.
    pub(super) phi: f64,
}

impl Frames<'_> {
    /// The wheels' frame over the interval that `body` (the body twist) samples; intervals
    /// come in order, each starting where the last ended.
    pub(super) fn interval(&mut self, body: Interp) -> Interp {
        let Some(trail) = self.trail else {
            return body;
        };
        // The pivot's field velocity at the sample points, and its interpolant.
        let world = Interp {
            t: body.t,
            v: std::array::from_fn(|j| {
                let theta = self.traj.pose(body.t[j]).theta;
                let (s, c) = theta.sin_cos();
                let [vx, vy, _, _] = body.v[j];
                [c * vx - s * vy, s * vx + c * vy, 0.0, 0.0]
            }),
        };
        let rate = |w: [f64; 4], phi: f64| {
            let (sp, cp) = phi.sin_cos();
            ((-sp * w[0] + cp * w[1]) / trail, cp * w[0] + sp * w[1])
        };
        // RK4 from one sample point to the next.
        let mut phi = [0.0; SAMPLES];
        phi[0] = self.phi;
        for j in 0..SAMPLES - 1 {
            let (ta, tb) = (world.t[j], world.t[j + 1]);
            let h = tb - ta;
            let mid = world.eval(0.5 * (ta + tb));
            let k1 = rate(world.v[j], phi[j]).0;
            let k2 = rate(mid, phi[j] + 0.5 * h * k1).0;
            let k3 = rate(mid, phi[j] + 0.5 * h * k2).0;
            let k4 = rate(world.v[j + 1], phi[j] + h * k3).0;
            phi[j + 1] = phi[j] + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
        }
        self.phi = phi[SAMPLES - 1];
        Interp {
            t: body.t,
            v: std::array::from_fn(|j| {
                let (phi_dot, forward) = rate(world.v[j], phi[j]);
                [forward, 0.0, phi_dot, phi[j]]
            }),
        }
    }
}
