//! Motions made of segments of constant body twist, changing abruptly from one segment to the
//! next: the papers' curves all start and stop smoothly at rest, at t = 0 and at the end, so
//! they never show what an abrupt start or change does to the odometry (to placing each wheel
//! inside its count at power-on, for one: docs/odometry.md, "Where a wheel starts inside its
//! count").
//!
//! Over a segment the twist is `ξ·σ(τ)` for a fixed twist ξ and a scalar shape σ of the time τ
//! into the segment: 1 (constant), or a smoothstep ramp from 0 to 1 (a smooth start). A twist of
//! fixed direction commutes with itself, so the pose is exact in closed form: the SE(2)
//! exponential of `S(τ)·ξ`, `S = ∫σ`, composed on the segment's start pose (`Pose2::integrate`,
//! which is that exponential), and the segments chain. Nothing is integrated numerically.

use robot_math::se2::{Pose2, Twist};

use super::Trajectory;

/// How a segment's twist varies over its duration T: `ξ·σ(τ/T)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Shape {
    /// σ = 1: the twist is ξ from the segment's first instant to its last.
    Constant,
    /// σ(x) = 3x² − 2x³: from rest up to ξ, smoothly (zero acceleration at both ends), as the
    /// speed ramps of the seed paths.
    RampUp,
}

/// One segment: `duration` seconds of the twist `twist` shaped by `shape`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Segment {
    pub(super) duration: f64,
    pub(super) twist: Twist,
    pub(super) shape: Shape,
}

impl Segment {
    /// `duration` seconds of the twist (v_x, v_y, ω).
    pub(super) fn constant(duration: f64, vx: f64, vy: f64, omega: f64) -> Segment {
        Segment {
            duration,
            twist: Twist::new(vx, vy, omega),
            shape: Shape::Constant,
        }
    }

    /// `duration` seconds standing still.
    pub(super) fn rest(duration: f64) -> Segment {
        Segment::constant(duration, 0.0, 0.0, 0.0)
    }

    /// `duration` seconds ramping from rest up to the twist (v_x, v_y, ω).
    pub(super) fn ramp_up(duration: f64, vx: f64, vy: f64, omega: f64) -> Segment {
        Segment {
            shape: Shape::RampUp,
            ..Segment::constant(duration, vx, vy, omega)
        }
    }

    /// `(S(τ), σ(τ))`: how much of the twist has been applied by τ seconds into the segment
    /// (seconds' worth), and the factor on the twist at τ.
    fn scale(&self, tau: f64) -> (f64, f64) {
        let big_t = self.duration;
        let tau = tau.clamp(0.0, big_t);
        let x = tau / big_t;
        match self.shape {
            Shape::Constant => (tau, 1.0),
            // ∫_0^x (3u² − 2u³) du = x³ − x⁴/2.
            Shape::RampUp => (big_t * x * x * x * (1.0 - 0.5 * x), x * x * (3.0 - 2.0 * x)),
        }
    }
}

/// Segments one after the other from a start pose; the twist may jump at every joint.
pub(super) struct Segments {
    segments: Vec<Segment>,
    /// When each segment starts, and the pose there.
    starts: Vec<f64>,
    poses: Vec<Pose2>,
    duration: f64,
}

impl Segments {
    pub(super) fn new(start: Pose2, segments: Vec<Segment>) -> Segments {
        assert!(!segments.is_empty());
        let mut starts = Vec::with_capacity(segments.len());
        let mut poses = Vec::with_capacity(segments.len());
        let (mut t, mut pose) = (0.0, start);
        for s in &segments {
            assert!(s.duration > 0.0 && s.duration.is_finite(), "{s:?}");
            starts.push(t);
            poses.push(pose);
            t += s.duration;
            pose = pose.integrate(s.twist, s.scale(s.duration).0);
        }
        Segments {
            segments,
            starts,
            poses,
            duration: t,
        }
    }

    /// The segment that holds `t` (the later one at a joint, the earlier one with
    /// `before`), and the time into it.
    fn locate(&self, t: f64, before: bool) -> (usize, f64) {
        let k = if before {
            self.starts.partition_point(|&s| s < t)
        } else {
            self.starts.partition_point(|&s| s <= t)
        };
        let k = k.max(1) - 1;
        (k, t - self.starts[k])
    }

    fn twist_in(&self, k: usize, tau: f64) -> Twist {
        let s = &self.segments[k];
        s.twist.scaled(s.scale(tau).1)
    }
}

impl Trajectory for Segments {
    fn duration(&self) -> f64 {
        self.duration
    }
    fn pose(&self, t: f64) -> Pose2 {
        let (k, tau) = self.locate(t, false);
        let s = &self.segments[k];
        self.poses[k].integrate(s.twist, s.scale(tau).0)
    }
    fn twist(&self, t: f64) -> Twist {
        let (k, tau) = self.locate(t, false);
        self.twist_in(k, tau)
    }
    fn twist_before(&self, t: f64) -> Twist {
        let (k, tau) = self.locate(t, true);
        self.twist_in(k, tau)
    }
    fn breakpoints(&self) -> Vec<f64> {
        self.starts[1..].to_vec()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_constant_segment_is_the_se2_exponential() {
        // A circle of radius 0.5 at 0.4 m/s: after a quarter turn the pose is (r, r, π/2).
        let r = 0.5;
        let quarter = std::f64::consts::FRAC_PI_2 * r / 0.4;
        let m = Segments::new(
            Pose2::default(),
            vec![Segment::constant(quarter, 0.4, 0.0, 0.4 / r)],
        );
        let p = m.pose(quarter);
        assert!((p.x - r).abs() < 1e-15 && (p.y - r).abs() < 1e-15, "{p:?}");
        assert!((p.theta - std::f64::consts::FRAC_PI_2).abs() < 1e-15);
    }

    #[test]
    fn the_twist_jumps_at_a_joint_and_twist_before_sees_the_left_side() {
        let m = Segments::new(
            Pose2::default(),
            vec![
                Segment::constant(1.0, 0.3, 0.0, 0.0),
                Segment::constant(0.5, 0.0, 0.0, 1.5),
            ],
        );
        assert_eq!(m.breakpoints(), vec![1.0]);
        assert_eq!(m.twist(1.0), Twist::new(0.0, 0.0, 1.5));
        assert_eq!(m.twist_before(1.0), Twist::new(0.3, 0.0, 0.0));
        // At t = 0 and at the end there is only one side.
        assert_eq!(m.twist_before(0.0), m.twist(0.0));
        assert_eq!(m.twist_before(1.5), m.twist(1.5));
        // The pose is continuous through the joint.
        let (a, b) = (m.pose(1.0 - 1e-12), m.pose(1.0));
        assert!(a.distance_to(b) < 1e-12 && (a.theta - b.theta).abs() < 1e-12);
    }

    #[test]
    fn a_ramp_reaches_its_twist_and_covers_half_of_it() {
        let up = Segment::ramp_up(0.8, 0.4, 0.0, 0.0);
        assert_eq!(up.scale(0.0), (0.0, 0.0));
        let (s, sigma) = up.scale(0.8);
        assert!((s - 0.4).abs() < 1e-15 && sigma == 1.0, "{s} {sigma}");
        // σ is the derivative of S.
        for k in 1..20 {
            let tau = 0.8 * k as f64 / 20.0;
            let h = 1e-6;
            let num = (up.scale(tau + h).0 - up.scale(tau - h).0) / (2.0 * h);
            assert!((num - up.scale(tau).1).abs() < 1e-9, "{tau}");
        }
    }
}
