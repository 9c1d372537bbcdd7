//! Where the tracked point should be: the moving target of seed 004's pursuit, or a catalogue
//! trajectory for seed 002's tracking, as a function of the time since the host started the
//! motion. The host session sends it; the run scores against it.

use anyhow::{anyhow, Result};
use robot_math::pursuit::SegmentTarget;

use super::Motion;
use crate::sim::trajectory::{self, Trajectory};

/// One instant of the reference, in the field frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    pub position: (f64, f64),
    pub velocity: (f64, f64),
    pub heading: f64,
    pub omega: f64,
}

pub enum ReferencePath {
    Target(SegmentTarget),
    Path(Box<dyn Trajectory>),
}

impl ReferencePath {
    pub fn new(motion: &Motion) -> Result<Self> {
        Ok(match motion {
            Motion::Pursue {
                target_from,
                target_to,
                target_speed,
                ..
            } => ReferencePath::Target(SegmentTarget {
                from: *target_from,
                to: *target_to,
                speed: *target_speed,
                t0: 0.0,
            }),
            Motion::Track {
                trajectory: name,
                ahead_m,
                ..
            } => {
                let path =
                    trajectory::build(name).ok_or_else(|| anyhow!("no trajectory \"{name}\""))?;
                ReferencePath::Path(if *ahead_m != 0.0 {
                    Box::new(trajectory::AheadOf::new(path, *ahead_m))
                } else {
                    path
                })
            }
        })
    }

    /// The reference `t` seconds after the motion started (held at its end once over).
    pub fn at(&self, t: f64) -> Sample {
        match self {
            ReferencePath::Target(target) => Sample {
                position: target.position(t).0,
                velocity: (0.0, 0.0),
                heading: 0.0,
                omega: 0.0,
            },
            ReferencePath::Path(path) => {
                let end = path.duration();
                let t = t.clamp(0.0, end);
                let pose = path.pose(t);
                let twist = if t >= end {
                    Default::default()
                } else {
                    path.twist(t)
                };
                let (s, c) = pose.theta.sin_cos();
                Sample {
                    position: (pose.x, pose.y),
                    velocity: (c * twist.vx - s * twist.vy, s * twist.vx + c * twist.vy),
                    heading: pose.theta,
                    omega: twist.omega,
                }
            }
        }
    }

    /// How long the motion lasts, seconds (a pursuit: until the target stops).
    pub fn duration(&self) -> f64 {
        match self {
            ReferencePath::Target(t) => {
                let (dx, dy) = (t.to.0 - t.from.0, t.to.1 - t.from.1);
                if t.speed > 0.0 {
                    dx.hypot(dy) / t.speed
                } else {
                    0.0
                }
            }
            ReferencePath::Path(p) => p.duration(),
        }
    }
}
