//! What the robot is asked to do (seed 004's moving target or a seed 002 path sample) and the
//! reference it gives the control step at each instant.

use embassy_time::Instant;

use super::secs;
use protocol::serial::TrackPoint;
use robot_math::pursuit::SegmentTarget;
use robot_math::tracking::PointReference;

/// What the robot is asked to do.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Goal {
    /// Seed 004: head at a target moving along a segment.
    Pursue {
        target: SegmentTarget,
        robot_speed: f64,
        heading: f64,
    },
    /// Seed 002: track a time-parametrised path, one sample at a time.
    Track {
        sample: TrackPoint,
        /// When the sample arrived (it is extrapolated from there).
        at: Instant,
    },
}

/// Where the tracked point should be now, and how it moves.
pub(super) struct Reference {
    pub(super) point: PointReference,
    /// The heading to hold, for a platform that chooses its heading.
    pub(super) heading: Option<f64>,
    pub(super) omega: f64,
    /// Not moving: the robot may arrive and hold.
    pub(super) standing: bool,
}

/// Whether a path sample stands still. A chassis whose heading follows its tracked point
/// (seed 002: A would move sideways were it to turn) stands whenever the point does.
fn sample_stands(sample: &TrackPoint, holds_heading: bool) -> bool {
    sample.velocity_um_s == [0; 2] && (sample.omega_urad_s == 0 || !holds_heading)
}

impl Goal {
    /// The reference now; `holds_heading`: whether the platform chooses its heading (omni)
    /// or its heading follows the tracked point's motion (seed 002's chassis), which then
    /// arrives by position alone.
    pub(super) fn reference(&self, now: Instant, holds_heading: bool) -> Reference {
        match *self {
            Goal::Pursue {
                target, heading, ..
            } => {
                let (position, standing) = target.position(secs(now));
                Reference {
                    point: PointReference {
                        position,
                        velocity: (0.0, 0.0),
                    },
                    heading: holds_heading.then_some(heading),
                    omega: 0.0,
                    standing,
                }
            }
            Goal::Track { sample, at } => {
                let dt = now.saturating_duration_since(at).as_micros() as f64 * 1e-6;
                let (x, y) = sample.position.to_metres();
                let v = sample.velocity_um_s.map(|v| v as f64 * 1e-6);
                let omega = sample.omega_urad_s as f64 * 1e-6;
                Reference {
                    point: PointReference {
                        position: (x + v[0] * dt, y + v[1] * dt),
                        velocity: (v[0], v[1]),
                    },
                    heading: holds_heading.then(|| sample.heading.to_radians() + omega * dt),
                    omega,
                    standing: sample_stands(&sample, holds_heading),
                }
            }
        }
    }

    /// A goal that stands still at one place (and heading, where the platform holds one).
    pub(super) fn standing_at(&self, holds_heading: bool) -> Option<(f64, f64, Option<f64>)> {
        let heading = |h: f64| holds_heading.then_some(h);
        match *self {
            Goal::Pursue {
                target, heading: h, ..
            } => (target.from == target.to).then_some((target.to.0, target.to.1, heading(h))),
            Goal::Track { sample, .. } => {
                let (x, y) = sample.position.to_metres();
                sample_stands(&sample, holds_heading)
                    .then(|| (x, y, heading(sample.heading.to_radians())))
            }
        }
    }
}
