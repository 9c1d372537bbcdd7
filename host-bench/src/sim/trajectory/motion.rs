//! Motions: a path driven from rest to rest, a turn in place, and motions one after another.

use robot_math::se2::{Pose2, Twist};

use super::path::Path;
use super::profile::Profile;
use super::{Trajectory, CRUISE_SPEED_M_S, RAMP_S, TURN_RAMP_S};

/// How the heading moves along a path.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Heading {
    /// Along the path tangent (no sideways velocity).
    Tangent,
    /// `start + delta · s / length`: independent of the path (omni robots).
    Progress { start: f64, delta: f64 },
}

/// A path driven from rest to rest with a [`Profile`].
pub(super) struct PathMotion<P> {
    path: P,
    profile: Profile,
    heading: Heading,
}

impl<P: Path> PathMotion<P> {
    pub(super) fn cruise(path: P, heading: Heading) -> PathMotion<P> {
        Self::at_speed(path, heading, CRUISE_SPEED_M_S)
    }

    /// From rest to `speed` in [`RAMP_S`], along the path, and to rest again.
    pub(super) fn at_speed(path: P, heading: Heading, speed: f64) -> PathMotion<P> {
        let profile = Profile::new(path.length(), speed, RAMP_S);
        PathMotion {
            path,
            profile,
            heading,
        }
    }
}

impl<P: Path> Trajectory for PathMotion<P> {
    fn duration(&self) -> f64 {
        self.profile.duration()
    }
    fn pose(&self, t: f64) -> Pose2 {
        let (s, _) = self.profile.at(t);
        let p = self.path.at(s);
        let theta = match self.heading {
            Heading::Tangent => p.phi,
            Heading::Progress { start, delta } => start + delta * s / self.profile.length,
        };
        Pose2::new(p.x, p.y, theta)
    }
    fn twist(&self, t: f64) -> Twist {
        let (s, v) = self.profile.at(t);
        let p = self.path.at(s);
        match self.heading {
            Heading::Tangent => Twist::new(v, 0.0, p.kappa * v),
            Heading::Progress { start, delta } => {
                let theta = start + delta * s / self.profile.length;
                // World velocity v·(cos φ, sin φ) in the body frame: the angle φ − θ.
                let (sn, cs) = (p.phi - theta).sin_cos();
                Twist::new(v * cs, v * sn, delta * v / self.profile.length)
            }
        }
    }
    fn breakpoints(&self) -> Vec<f64> {
        let mut b = self.profile.breakpoints();
        b.extend(
            self.path
                .kinks()
                .into_iter()
                .map(|s| self.profile.time_at(s)),
        );
        b
    }
}

/// A turn in place by `delta` radians from rest to rest.
pub(super) struct Turn {
    start: Pose2,
    sign: f64,
    profile: Profile,
}

impl Turn {
    /// Turning by `delta` at up to `rate` rad/s.
    pub(super) fn at_rate(start: Pose2, delta: f64, rate: f64) -> Turn {
        Turn {
            start,
            sign: delta.signum(),
            profile: Profile::new(delta.abs(), rate, TURN_RAMP_S),
        }
    }
}

impl Trajectory for Turn {
    fn duration(&self) -> f64 {
        self.profile.duration()
    }
    fn pose(&self, t: f64) -> Pose2 {
        let (a, _) = self.profile.at(t);
        Pose2::new(self.start.x, self.start.y, self.start.theta + self.sign * a)
    }
    fn twist(&self, t: f64) -> Twist {
        let (_, w) = self.profile.at(t);
        Twist::new(0.0, 0.0, self.sign * w)
    }
    fn breakpoints(&self) -> Vec<f64> {
        self.profile.breakpoints()
    }
}

/// Motions one after the other; each must start where the previous ended (the seed polygons
/// hand over at rest, so their twist is continuous too).
pub(super) struct Sequence {
    parts: Vec<Box<dyn Trajectory>>,
    starts: Vec<f64>,
    duration: f64,
}

impl Sequence {
    pub(super) fn new(parts: Vec<Box<dyn Trajectory>>) -> Sequence {
        let mut starts = Vec::with_capacity(parts.len());
        let mut t = 0.0;
        for p in &parts {
            starts.push(t);
            t += p.duration();
        }
        Sequence {
            parts,
            starts,
            duration: t,
        }
    }

    pub(super) fn part(&self, t: f64) -> (&dyn Trajectory, f64) {
        let k = self.starts.partition_point(|&s| s <= t).max(1) - 1;
        (self.parts[k].as_ref(), t - self.starts[k])
    }
}

impl Trajectory for Sequence {
    fn duration(&self) -> f64 {
        self.duration
    }
    fn pose(&self, t: f64) -> Pose2 {
        let (p, t) = self.part(t);
        p.pose(t)
    }
    fn twist(&self, t: f64) -> Twist {
        let (p, t) = self.part(t);
        p.twist(t)
    }
    fn twist_before(&self, t: f64) -> Twist {
        // The part that ends at `t` when `t` is a hand-over.
        let k = self.starts.partition_point(|&s| s < t).max(1) - 1;
        self.parts[k].twist_before(t - self.starts[k])
    }
    fn breakpoints(&self) -> Vec<f64> {
        let mut b = Vec::new();
        for (p, &start) in self.parts.iter().zip(&self.starts) {
            if start > 0.0 {
                b.push(start);
            }
            b.extend(p.breakpoints().into_iter().map(|t| start + t));
        }
        b
    }
}

#[cfg(test)]
mod tests {
    use super::super::path::{ArcLength, Bezier};
    use super::*;

    #[test]
    fn joined_curves_report_their_joint_as_a_breakpoint() {
        let first = [[0.0, 0.0], [0.2, 0.0], [0.25, 0.2], [0.4, 0.2]];
        let second = [[0.4, 0.2], [0.55, 0.2], [0.6, 0.0], [0.8, 0.0]];
        let path = ArcLength::new(Bezier::new(vec![first, second]), 0.8);
        let kinks = path.kinks();
        assert_eq!(kinks.len(), 1);
        let joint = path.at(kinks[0]);
        assert!((joint.x - 0.4 * path.scale).abs() < 1e-12, "{joint:?}");
        assert!((joint.y - 0.2 * path.scale).abs() < 1e-12, "{joint:?}");
        let motion = PathMotion::cruise(path, Heading::Tangent);
        let b = motion.breakpoints();
        assert_eq!(b.len(), 3);
        assert!((motion.profile.at(b[2]).0 - kinks[0]).abs() < 1e-12);
    }
}
