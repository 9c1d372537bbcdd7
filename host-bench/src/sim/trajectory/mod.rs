//! Trajectories of the body reference point (SPEC §5): the paths of the seed papers and
//! Borenstein's UMBmark, and our own constant-twist segments, as exact functions of time.
//!
//! A [`Trajectory`] gives the pose and the body twist at every instant of `[0, duration]`,
//! consistently (the twist is the exact derivative of the pose, heading included), so that the
//! tick generator ([`crate::sim::generate`]) can integrate each wheel's rolling speed and find its
//! ticks by root finding.
//!
//! How the motions are built:
//! * **Paths** are parametrised by arc length `s`. Lines and circles are so in closed form;
//!   Bézier curves and the figure-eight are re-parametrised numerically (as seed 000 does): a
//!   table of arc lengths at 256 parameter nodes per curve piece, each from 5-point
//!   Gauss–Legendre quadrature of the speed `|p'(u)|`, and `u(s)` by Newton's method on
//!   `table + ∫ |p'|` between the node and `u` (to about 1e-15 of the parameter range). Curves
//!   are scaled so that their length is exactly the paper's number.
//! * **Speed along the path** is a smooth time-scaling `s(t)`: the speed rises from rest to the
//!   cruise speed with a smoothstep (`v·(3x² − 2x³)`, so the acceleration is continuous and
//!   zero at both ends of the ramp), cruises, and comes down the same way. Every seed
//!   trajectory starts and ends at rest; speeds are continuous everywhere.
//! * **Heading** is either the path tangent (feasible for a differential-drive robot: no
//!   sideways velocity; see [`Drive`]) or, for omni robots, a start heading plus a change that
//!   is proportional to the distance travelled (linear in time while cruising — seed 000's
//!   "heading linear in time" — but starting and ending at rest with the speed, so the twist
//!   stays continuous).
//! * Polygons (squares) stop at every corner; a differential robot turns in place there with
//!   the same smooth profile on the heading. So twists are continuous at every hand-over.
//! * **Ours** (`segments`, paper "ours"): a smooth rest-to-rest curve is one special case, so
//!   these move at a constant body twist per segment and change it abruptly at the joints
//!   (the twist jumps; [`Trajectory::twist_before`] gives its value just before a joint). The
//!   `twist-*` ones move from t = 0 to the end; the `rest-then-*` ones stand still first, then
//!   start abruptly or with the smoothstep ramp. Each segment's pose is the exact SE(2)
//!   exponential of its twist, chained.
//!
//! All trajectories start at the pose (0, 0, 0). Cruise 0.4 m/s, ramps of 0.8 s; turns in
//! place at π/2 rad/s with 0.5 s ramps. Ours: 0.3–0.5 m/s, turns up to 2 rad/s.
//!
//! | name | drive | length | duration |
//! |---|---|---|---|
//! | `seed000-line` | differential | 0.80 m | 2.80 s |
//! | `seed000-bezier-0deg`, `-90deg`, `-180deg` | holonomic | 0.80 m | 2.80 s |
//! | `seed000-two-beziers` | holonomic | 0.80 m | 2.80 s |
//! | `seed001-figure-eight` | differential | 2.84 m | 7.90 s |
//! | `seed001-straight-40m` | differential | 40 m | 100.80 s |
//! | `seed001-curve` | differential | 2.80 m | 7.80 s |
//! | `seed002-square` (1 m side, heading fixed) | holonomic | 4 m | 13.20 s |
//! | `seed002-diagonal` (to (1, 1) m, heading fixed) | holonomic | 1.414 m | 4.34 s |
//! | `seed002-circle` (radius 0.5 m) | differential | 3.14 m | 8.65 s |
//! | `umbmark-cw`, `umbmark-ccw` (4 m square, turns in place) | differential | 16 m | 49.20 s |
//! | `twist-arcs` (arcs of radius 0.5 m left, 0.3 m right, 1 m left) | differential | 2 m | 5.10 s |
//! | `twist-sideways-spin` (sideways, spin, diagonal turning, reversed) | holonomic | 1.993 m | 6.00 s |
//! | `twist-s-spin-reverse` (arc left, arc right, spin, straight back) | differential | 1.80 m | 6.00 s |
//! | `rest-then-arcs` (0.5 s at rest, then `twist-arcs`) | differential | 2 m | 5.60 s |
//! | `rest-then-smooth-line` (0.4 s at rest, 0.8 s ramp, cruise) | differential | 1.36 m | 4.20 s |
//!
//! The papers give no control points, square sizes or circle radius; those are ours (the
//! lengths are the papers').
//!
//! The parts: `catalogue` names and builds every trajectory; `motion` drives a path (or turns
//! in place) over time; `path` holds the paths by arc length (lines, arcs, Bézier curves, the
//! figure-eight); `profile` is the speed ramp; `segments` the constant-twist motions;
//! `quadrature` the Gauss–Legendre rule.

use std::f64::consts::FRAC_PI_2;

use robot_math::se2::{Pose2, Twist};

pub use catalogue::{build, catalogue, is_body_path, named, umbmark_square};

mod catalogue;
mod motion;
mod path;
mod profile;
mod quadrature;
mod segments;

/// A smooth motion of the body reference point, for `t` in `[0, duration()]` seconds.
pub trait Trajectory {
    /// Seconds.
    fn duration(&self) -> f64;
    /// Pose of the body reference point in the field frame at time `t` (heading unwrapped).
    fn pose(&self, t: f64) -> Pose2;
    /// Body-frame twist (v_x forward, v_y left, ω counter-clockwise) at time `t`: the exact
    /// derivative of [`pose`](Self::pose).
    fn twist(&self, t: f64) -> Twist;
    /// The twist just before `t`: its limit from the left. It differs from
    /// [`twist`](Self::twist) (which is the value from the right, that of the part starting at
    /// `t`) only at a breakpoint where the twist jumps (between constant-twist segments).
    /// Default: `twist(t)`, for motions whose twist is continuous.
    fn twist_before(&self, t: f64) -> Twist {
        self.twist(t)
    }
    /// Instants in `(0, duration)` where the motion is only finitely smooth (a speed ramp
    /// starts or ends, one part hands over to the next, the twist jumps). The twist is
    /// analytic between them; the tick generator starts a new integration interval at each.
    /// Default: none.
    fn breakpoints(&self) -> Vec<f64> {
        Vec::new()
    }
}

/// The point `ahead` along the body's +x from a body trajectory's reference point (seed 002's
/// A, which the master tracks): the body's heading, that point's position and velocity.
pub struct AheadOf {
    body: Box<dyn Trajectory>,
    ahead: f64,
}

impl AheadOf {
    pub fn new(body: Box<dyn Trajectory>, ahead: f64) -> Self {
        AheadOf { body, ahead }
    }

    fn moved(&self, t: Twist) -> Twist {
        // v_A = v_O + ω × (l, 0) in the body frame.
        Twist::new(t.vx, t.vy + t.omega * self.ahead, t.omega)
    }
}

impl Trajectory for AheadOf {
    fn duration(&self) -> f64 {
        self.body.duration()
    }
    fn pose(&self, t: f64) -> Pose2 {
        let p = self.body.pose(t);
        let (s, c) = p.theta.sin_cos();
        Pose2::new(p.x + self.ahead * c, p.y + self.ahead * s, p.theta)
    }
    fn twist(&self, t: f64) -> Twist {
        self.moved(self.body.twist(t))
    }
    fn twist_before(&self, t: f64) -> Twist {
        self.moved(self.body.twist_before(t))
    }
    fn breakpoints(&self) -> Vec<f64> {
        self.body.breakpoints()
    }
}

/// Which robots can follow a trajectory.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Drive {
    /// No sideways velocity anywhere (the heading follows the path, corners are turns in
    /// place): any robot, differential-drive included.
    Differential,
    /// Moves sideways or turns independently of the path: omni (holonomic) robots only.
    Holonomic,
}

/// A catalogue entry.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Named {
    pub name: &'static str,
    pub description: &'static str,
    /// Where it comes from, e.g. "tick-timing paper"; "ours" for the trajectories no paper has.
    pub paper: &'static str,
    pub drive: Drive,
}

/// Cruise speed along paths, m/s.
pub const CRUISE_SPEED_M_S: f64 = 0.4;
/// Time to reach the cruise speed from rest (and to stop), s.
pub const RAMP_S: f64 = 0.8;
/// Cruise turn rate of turns in place, rad/s.
pub const TURN_RATE_RAD_S: f64 = FRAC_PI_2;
/// Time to reach the cruise turn rate (and to stop turning), s.
pub const TURN_RAMP_S: f64 = 0.5;

/// Seed 000's path length (each Bézier case and the line), m.
pub const SEED000_LENGTH_M: f64 = 0.80;
/// Seed 001's figure-eight, m (7100 pulses of 0.04 cm).
pub const SEED001_FIGURE_EIGHT_M: f64 = 2.84;
/// Seed 001's straight line, m (100000 pulses).
pub const SEED001_STRAIGHT_M: f64 = 40.0;
/// Seed 001's curve, m (7000 pulses).
pub const SEED001_CURVE_M: f64 = 2.80;
/// Side of seed 002's square and of the square whose diagonal is seed 002's diagonal, m
/// (the paper prints no size: assumed).
pub const SEED002_SIDE_M: f64 = 1.0;
/// Radius of seed 002's circle, m (assumed).
pub const SEED002_CIRCLE_RADIUS_M: f64 = 0.5;
/// UMBmark's square side, m.
pub const UMBMARK_SIDE_M: f64 = 4.0;
