//! Seed 002's tracking law for a holonomic point: the velocity asked of the tracked point, in
//! the robot frame, is a gain times the position error rotated into that frame, plus the
//! reference's own velocity (feed-forward), plus a damping term on how far the last command
//! and the velocity measured since differ (seed 002, eq. 31–33 and the last, unnumbered one).
//!
//! The paper's frame has y forward and x to the right: its k1 acts sideways and k2 along the
//! heading. Ours has x forward and y to the left, so `forward` here is the paper's k2 and
//! `lateral` its k1. With V = ½|e|² the law gives V' = −k_fwd·e_fwd² − k_lat·e_lat² (eq. 23), so
//! any positive gains are stable while the motors keep up; the settling time along the
//! heading is about 4/k (eq. 27 for the coupled lateral part: 8/k1).

use crate::pursuit::field_to_body;

/// The gains: one pair per robot-frame axis (the paper's k2/k1, k2_ff/k1_ff, k2_diff/k1_diff).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrackingGains {
    /// Position error to velocity, 1/s, along the heading and sideways.
    pub k_forward: f64,
    pub k_lateral: f64,
    /// Share of the reference velocity fed forward (1: all of it).
    pub ff_forward: f64,
    pub ff_lateral: f64,
    /// Share of (last command − velocity measured since) added back: damps the oscillation
    /// motor lag leaves around the path.
    pub diff_forward: f64,
    pub diff_lateral: f64,
}

impl TrackingGains {
    /// Positive position gains, finite everything: what the Lyapunov argument needs.
    pub fn valid(&self) -> bool {
        let g = [
            self.k_forward,
            self.k_lateral,
            self.ff_forward,
            self.ff_lateral,
            self.diff_forward,
            self.diff_lateral,
        ];
        g.iter().all(|v| v.is_finite()) && self.k_forward > 0.0 && self.k_lateral > 0.0
    }
}

/// Where the tracked point should be now, and how fast it should move, in the field frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PointReference {
    pub position: (f64, f64),
    pub velocity: (f64, f64),
}

/// The law with its one sample of memory (the last command).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointTracker {
    pub gains: TrackingGains,
    last_command: Option<(f64, f64)>,
}

impl PointTracker {
    pub fn new(gains: TrackingGains) -> Self {
        PointTracker {
            gains,
            last_command: None,
        }
    }

    /// Forget the last command (a new run, or the motors were off).
    pub fn reset(&mut self) {
        self.last_command = None;
    }

    /// The robot-frame velocity (forward, left) to ask of the tracked point, at `point` with
    /// the robot at `heading`; `measured` is the point's robot-frame velocity over the last
    /// control period (used by the damping term only).
    pub fn command(
        &mut self,
        reference: &PointReference,
        point: (f64, f64),
        heading: f64,
        measured: (f64, f64),
    ) -> (f64, f64) {
        let g = &self.gains;
        let (ex, ey) = field_to_body(
            reference.position.0 - point.0,
            reference.position.1 - point.1,
            heading,
        );
        let (fx, fy) = field_to_body(reference.velocity.0, reference.velocity.1, heading);
        let (dx, dy) = self
            .last_command
            .map_or((0.0, 0.0), |(cx, cy)| (cx - measured.0, cy - measured.1));
        let cmd = (
            g.k_forward * ex + g.ff_forward * fx + g.diff_forward * dx,
            g.k_lateral * ey + g.ff_lateral * fy + g.diff_lateral * dy,
        );
        self.last_command = Some(cmd);
        cmd
    }

    /// The command actually sent after saturation, for the next damping term.
    pub fn sent(&mut self, command: (f64, f64)) {
        self.last_command = Some(command);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::offset_diff::OffsetDiff;
    use crate::Pose2;

    const GAINS: TrackingGains = TrackingGains {
        k_forward: 4.0,
        k_lateral: 4.0,
        ff_forward: 1.0,
        ff_lateral: 1.0,
        diff_forward: 0.0,
        diff_lateral: 0.0,
    };

    #[test]
    fn validity_needs_positive_position_gains() {
        assert!(GAINS.valid());
        assert!(!TrackingGains {
            k_lateral: 0.0,
            ..GAINS
        }
        .valid());
        assert!(!TrackingGains {
            diff_forward: f64::NAN,
            ..GAINS
        }
        .valid());
    }

    #[test]
    fn error_is_rotated_into_the_robot_frame() {
        let mut t = PointTracker::new(GAINS);
        let r = PointReference {
            position: (1.0, 0.0),
            velocity: (0.0, 0.0),
        };
        // Facing +y, a target at +x is on the robot's right.
        let (f, l) = t.command(&r, (0.0, 0.0), core::f64::consts::FRAC_PI_2, (0.0, 0.0));
        assert!(f.abs() < 1e-12 && (l + 4.0).abs() < 1e-12, "{f} {l}");
    }

    #[test]
    fn damping_adds_back_what_the_robot_did_not_do() {
        let g = TrackingGains {
            diff_forward: 0.5,
            diff_lateral: 0.25,
            ..GAINS
        };
        let mut t = PointTracker::new(g);
        let r = PointReference {
            position: (0.1, 0.0),
            velocity: (0.0, 0.0),
        };
        let first = t.command(&r, (0.0, 0.0), 0.0, (0.0, 0.0));
        assert!((first.0 - 0.4).abs() < 1e-12, "no memory yet: no damping");
        let second = t.command(&r, (0.0, 0.0), 0.0, (0.1, 0.0));
        assert!((second.0 - (0.4 + 0.5 * (0.4 - 0.1))).abs() < 1e-12);
    }

    /// The law closed around seed 002's kinematics (ideal motors) converges from an offset
    /// start and then follows a circle with the error gone: V decreases as eq. 23 says.
    #[test]
    fn closed_loop_on_the_offset_point_follows_a_circle() {
        let d = OffsetDiff::symmetric(0.15, 0.2, 1.0).unwrap();
        let mut t = PointTracker::new(GAINS);
        let mut body = Pose2::new(0.05, -0.04, 0.3);
        let (radius, rate, dt) = (0.5, 0.6, 1e-3);
        let reference = |s: f64| PointReference {
            position: (
                radius * crate::trig::sin(rate * s),
                radius - radius * crate::trig::cos(rate * s),
            ),
            velocity: (
                radius * rate * crate::trig::cos(rate * s),
                radius * rate * crate::trig::sin(rate * s),
            ),
        };
        let point = |b: &Pose2| b.transform_point((d.offset, 0.0));
        let mut worst_late = 0.0f64;
        let mut last_v = f64::INFINITY;
        for k in 0..10_000 {
            let s = k as f64 * dt;
            let r = reference(s);
            let p = point(&body);
            let e = crate::se2::norm(r.position.0 - p.0, r.position.1 - p.1);
            if s < 2.0 {
                // Off the circle's start: V only falls (the reference moves, hence the slack).
                assert!(e <= last_v + 1e-4, "error grew at {s}: {e} > {last_v}");
                last_v = e;
            } else {
                worst_late = worst_late.max(e);
            }
            let (f, l) = t.command(&r, p, body.theta, (0.0, 0.0));
            let (w, _) = d.wheel_speeds_saturated(f, l);
            body = body.integrate(d.twist(w), dt);
        }
        assert!(
            worst_late < 1e-3,
            "after two seconds (e^-8 of the start): {worst_late}"
        );
    }
}
