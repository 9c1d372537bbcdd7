//! Seed 004's pursuit: head straight at the target's current position at a set speed.
//!
//! The paper's Euler pursuit takes a step of V_t·τ towards the target every period τ. The
//! master runs the same law every control period, with one addition a real robot needs: the
//! speed falls off linearly within `slow_radius` of the target, so the robot settles on a
//! stopped target instead of overshooting it by up to V_t·τ forever.

use crate::se2::wrap_angle;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PursuitParams {
    /// Heading-hold gain, 1/s: ω = gain · (θ_ref − θ).
    pub heading_gain: f64,
    /// Within this distance of the target the speed falls linearly to zero, metres.
    pub slow_radius: f64,
    /// Highest body spin rate the heading hold may ask for, rad/s.
    pub max_spin: f64,
    /// Seed 004's Euler pursuit period τ, seconds: the direction to the target is taken once
    /// per period and held, at full speed ([`euler_step`]). Zero: the law above at every
    /// control step, slowing near the target.
    pub period_s: f64,
}

impl Default for PursuitParams {
    fn default() -> Self {
        PursuitParams {
            heading_gain: 4.0,
            slow_radius: 0.15,
            max_spin: 2.0,
            period_s: 0.0,
        }
    }
}

/// A target moving from `from` to `to` at `speed` m/s, starting at time `t0` (seconds).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SegmentTarget {
    pub from: (f64, f64),
    pub to: (f64, f64),
    pub speed: f64,
    pub t0: f64,
}

impl SegmentTarget {
    /// Where the target is at time `t`, and whether it has stopped at `to`.
    pub fn position(&self, t: f64) -> ((f64, f64), bool) {
        let (dx, dy) = (self.to.0 - self.from.0, self.to.1 - self.from.1);
        let len = crate::se2::norm(dx, dy);
        let travelled = (t - self.t0).max(0.0) * self.speed;
        if len == 0.0 || travelled >= len {
            return (self.to, true);
        }
        let f = travelled / len;
        ((self.from.0 + f * dx, self.from.1 + f * dy), false)
    }
}

/// Field-frame velocity (v_x, v_y) and spin ω that head at `target` at up to `speed` m/s
/// while holding `heading_ref`.
pub fn pursue(
    pos: (f64, f64),
    heading: f64,
    target: (f64, f64),
    heading_ref: f64,
    speed: f64,
    p: &PursuitParams,
) -> (f64, f64, f64) {
    // max/min rather than clamp: clamp's check of its run-time bounds would pull float
    // formatting (over 12 KiB) into the master's 64 KiB image.
    let omega = (p.heading_gain * wrap_angle(heading_ref - heading))
        .max(-p.max_spin)
        .min(p.max_spin);
    let (vx, vy) = towards(pos, target, |dist| speed * (dist / p.slow_radius).min(1.0));
    (vx, vy, omega)
}

/// Seed 004's Euler pursuit step: the field velocity that heads straight at `target` at
/// `speed`, whatever the distance (the paper steps V_t·τ each period, so near the target it
/// overshoots by up to that step). Zero on the target itself.
pub fn euler_step(pos: (f64, f64), target: (f64, f64), speed: f64) -> (f64, f64) {
    towards(pos, target, |_| speed)
}

/// The field velocity straight at `target` at the speed `speed_at(distance)`; zero on it.
fn towards(pos: (f64, f64), target: (f64, f64), speed_at: impl Fn(f64) -> f64) -> (f64, f64) {
    let (ex, ey) = (target.0 - pos.0, target.1 - pos.1);
    let dist = crate::se2::norm(ex, ey);
    if dist < 1e-9 {
        return (0.0, 0.0);
    }
    let v = speed_at(dist);
    (v * ex / dist, v * ey / dist)
}

/// Rotate a field-frame velocity into the body frame of a robot at `heading`.
pub fn field_to_body(vx: f64, vy: f64, heading: f64) -> (f64, f64) {
    let (s, c) = (crate::trig::sin(heading), crate::trig::cos(heading));
    (c * vx + s * vy, -s * vx + c * vy)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn heads_straight_at_the_target_at_full_speed() {
        let (vx, vy, w) = pursue(
            (0.0, 0.0),
            0.0,
            (3.0, 4.0),
            0.0,
            0.6,
            &PursuitParams::default(),
        );
        assert!((vx - 0.36).abs() < 1e-12 && (vy - 0.48).abs() < 1e-12 && w == 0.0);
    }

    #[test]
    fn slows_down_near_the_target() {
        let p = PursuitParams::default();
        let (vx, vy, _) = pursue((0.0, 0.0), 0.0, (p.slow_radius / 2.0, 0.0), 0.0, 0.6, &p);
        assert!((vx - 0.3).abs() < 1e-12 && vy == 0.0);
    }

    #[test]
    fn target_moves_then_stops() {
        let t = SegmentTarget {
            from: (0.0, 3.0),
            to: (2.5, 3.0),
            speed: 0.35,
            t0: 1.0,
        };
        assert_eq!(t.position(0.5), ((0.0, 3.0), false));
        let ((x, y), done) = t.position(3.0);
        assert!((x - 0.7).abs() < 1e-12 && y == 3.0 && !done);
        assert_eq!(t.position(100.0), ((2.5, 3.0), true));
    }

    #[test]
    fn body_frame_rotation() {
        let (bx, by) = field_to_body(0.0, 1.0, core::f64::consts::FRAC_PI_2);
        assert!((bx - 1.0).abs() < 1e-12 && by.abs() < 1e-12);
    }
}
