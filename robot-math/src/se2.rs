//! Poses and twists on SE(2), and exact integration of a constant twist.

use crate::trig::{cos, sin};
use core::f64::consts::PI;

/// A pose in the field frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Pose2 {
    pub x: f64,
    pub y: f64,
    pub theta: f64,
}

/// A body-frame velocity (v_x forward, v_y left, ω counter-clockwise).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Twist {
    pub vx: f64,
    pub vy: f64,
    pub omega: f64,
}

impl Twist {
    pub const fn new(vx: f64, vy: f64, omega: f64) -> Self {
        Twist { vx, vy, omega }
    }
    pub fn scaled(self, k: f64) -> Self {
        Twist::new(self.vx * k, self.vy * k, self.omega * k)
    }
}

impl Pose2 {
    pub const fn new(x: f64, y: f64, theta: f64) -> Self {
        Pose2 { x, y, theta }
    }

    /// The pose reached by holding the body twist `t` for `dt` seconds: the SE(2)
    /// exponential, i.e. the exact arc rather than the chord or a straight Euler step.
    pub fn integrate(self, t: Twist, dt: f64) -> Pose2 {
        let d = t.scaled(dt);
        self.compose_increment(d.vx, d.vy, d.omega)
    }

    /// Apply a body-frame displacement `(dx, dy)` travelled along a constant-curvature arc
    /// while turning by `dtheta`: the increment `exp(dx, dy, dtheta)` composed on the right.
    pub fn compose_increment(self, dx: f64, dy: f64, dtheta: f64) -> Pose2 {
        // exp on se(2): V(dθ)·(dx, dy) with V = [[a, -b], [b, a]],
        // a = sin(dθ)/dθ, b = (1 - cos(dθ))/dθ; series near zero keep full precision.
        let (a, b) = arc_factors(dtheta);
        let lx = a * dx - b * dy;
        let ly = b * dx + a * dy;
        let (s, c) = (sin(self.theta), cos(self.theta));
        Pose2 {
            x: self.x + c * lx - s * ly,
            y: self.y + s * lx + c * ly,
            theta: self.theta + dtheta,
        }
    }

    /// Heading wrapped into (-π, π].
    pub fn wrapped(self) -> Pose2 {
        Pose2 {
            theta: wrap_angle(self.theta),
            ..self
        }
    }

    /// Where a point at `(x, y)` in this pose's body frame is in the field.
    pub fn transform_point(self, (x, y): (f64, f64)) -> (f64, f64) {
        let (s, c) = (sin(self.theta), cos(self.theta));
        (self.x + c * x - s * y, self.y + s * x + c * y)
    }

    pub fn distance_to(self, other: Pose2) -> f64 {
        norm(self.x - other.x, self.y - other.y)
    }
}

/// The length of `(x, y)`. Not `libm::hypot`: its guard against overflow is for lengths near
/// 1e308, never a robot's, and on the master (soft-float f64) it cost ~450 B of flash.
pub fn norm(x: f64, y: f64) -> f64 {
    libm::sqrt(x * x + y * y)
}

/// `(sin x / x, (1 - cos x) / x)`, accurate for every x including 0.
pub fn arc_factors(x: f64) -> (f64, f64) {
    if x.abs() < 1e-4 {
        let x2 = x * x;
        (1.0 - x2 / 6.0 + x2 * x2 / 120.0, x / 2.0 - x * x2 / 24.0)
    } else {
        (sin(x) / x, (1.0 - cos(x)) / x)
    }
}

/// An angle wrapped into (-π, π].
pub fn wrap_angle(a: f64) -> f64 {
    // `a - 2π·round(a / 2π)`, not `libm::remainder` (exact, but ~300 B more flash on the
    // master): the angles wrapped here are within a few turns, where the two agree to ~1e-15.
    let mut r = a - 2.0 * PI * libm::round(a / (2.0 * PI));
    if r <= -PI {
        r += 2.0 * PI;
    }
    r
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: Pose2, b: Pose2, tol: f64) -> bool {
        (a.x - b.x).abs() < tol
            && (a.y - b.y).abs() < tol
            && wrap_angle(a.theta - b.theta).abs() < tol
    }

    #[test]
    fn straight_line() {
        let p = Pose2::new(1.0, 2.0, PI / 2.0).integrate(Twist::new(0.5, 0.0, 0.0), 4.0);
        assert!(close(p, Pose2::new(1.0, 4.0, PI / 2.0), 1e-12), "{p:?}");
    }

    #[test]
    fn pure_spin_stays_put() {
        let p = Pose2::default().integrate(Twist::new(0.0, 0.0, 3.0), 2.0);
        assert!(close(p, Pose2::new(0.0, 0.0, 6.0), 1e-12), "{p:?}");
    }

    #[test]
    fn quarter_circle_is_exact_in_one_step() {
        // Radius 2 m, a quarter turn: from (0,0,0) to (2,2,π/2), in a single step.
        let r = 2.0;
        let p = Pose2::default().integrate(Twist::new(r * PI / 2.0, 0.0, PI / 2.0), 1.0);
        assert!(close(p, Pose2::new(r, r, PI / 2.0), 1e-12), "{p:?}");
    }

    #[test]
    fn many_small_steps_equal_one_big_step() {
        let t = Twist::new(0.3, -0.1, 0.7);
        let mut p = Pose2::new(0.1, 0.2, 0.3);
        for _ in 0..1000 {
            p = p.integrate(t, 0.01);
        }
        let q = Pose2::new(0.1, 0.2, 0.3).integrate(t, 10.0);
        assert!(close(p, q, 1e-9), "{p:?} vs {q:?}");
    }

    #[test]
    fn wrap_is_half_open() {
        assert!((wrap_angle(PI) - PI).abs() < 1e-15);
        assert!((wrap_angle(-PI) - PI).abs() < 1e-15);
        assert!((wrap_angle(3.0 * PI + 0.1) - (-PI + 0.1)).abs() < 1e-12);
    }
}
