//! Trajectories of the body reference point (SPEC §5): the paths of the seed papers and
//! Borenstein's UMBmark, as exact functions of time.
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
//!   zero at both ends of the ramp), cruises, and comes down the same way. Every trajectory
//!   starts and ends at rest; speeds are continuous everywhere.
//! * **Heading** is either the path tangent (feasible for a differential-drive robot: no
//!   sideways velocity; see [`Drive`]) or, for omni robots, a start heading plus a change that
//!   is proportional to the distance travelled (linear in time while cruising — seed 000's
//!   "heading linear in time" — but starting and ending at rest with the speed, so the twist
//!   stays continuous).
//! * Polygons (squares) stop at every corner; a differential robot turns in place there with
//!   the same smooth profile on the heading. So twists are continuous at every hand-over.
//!
//! All trajectories start at the pose (0, 0, 0). Cruise 0.4 m/s, ramps of 0.8 s; turns in
//! place at π/2 rad/s with 0.5 s ramps.
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
//!
//! The papers give no control points, square sizes or circle radius; those are ours (the
//! lengths are the papers').

use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, PI, TAU};

use robot_math::se2::{wrap_angle, Pose2, Twist};

/// A smooth motion of the body reference point, for `t` in `[0, duration()]` seconds.
pub trait Trajectory {
    /// Seconds.
    fn duration(&self) -> f64;
    /// Pose of the body reference point in the field frame at time `t` (heading unwrapped).
    fn pose(&self, t: f64) -> Pose2;
    /// Body-frame twist (v_x forward, v_y left, ω counter-clockwise) at time `t`: the exact
    /// derivative of [`pose`](Self::pose).
    fn twist(&self, t: f64) -> Twist;
    /// Instants in `(0, duration)` where the motion is only finitely smooth (a speed ramp
    /// starts or ends, one part hands over to the next). The twist is analytic between them;
    /// the tick generator starts a new integration interval at each. Default: none.
    fn breakpoints(&self) -> Vec<f64> {
        Vec::new()
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
    /// Where it comes from, e.g. "seed 000".
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

const CATALOGUE: &[Named] = &[
    Named {
        name: "seed000-line",
        description: "straight line 80 cm along +x, heading 0",
        paper: "seed 000",
        drive: Drive::Differential,
    },
    Named {
        name: "seed000-bezier-0deg",
        description: "one cubic Bezier curve, 80 cm, heading constant 0",
        paper: "seed 000",
        drive: Drive::Holonomic,
    },
    Named {
        name: "seed000-bezier-90deg",
        description: "one cubic Bezier curve, 80 cm, heading turning 90 deg linearly with distance",
        paper: "seed 000",
        drive: Drive::Holonomic,
    },
    Named {
        name: "seed000-bezier-180deg",
        description:
            "one cubic Bezier curve, 80 cm, heading turning 180 deg linearly with distance",
        paper: "seed 000",
        drive: Drive::Holonomic,
    },
    Named {
        name: "seed000-two-beziers",
        description:
            "two cubic Bezier curves joined with a common tangent (an S), 80 cm, heading 0",
        paper: "seed 000",
        drive: Drive::Holonomic,
    },
    Named {
        name: "seed001-figure-eight",
        description: "figure-eight (lemniscate of Gerono), 284 cm, heading along the path",
        paper: "seed 001",
        drive: Drive::Differential,
    },
    Named {
        name: "seed001-straight-40m",
        description: "straight line 40 m along +x",
        paper: "seed 001",
        drive: Drive::Differential,
    },
    Named {
        name: "seed001-curve",
        description:
            "a left-hand curve (cubic Bezier turning 90 deg), 280 cm, heading along the path",
        paper: "seed 001",
        drive: Drive::Differential,
    },
    Named {
        name: "seed002-square",
        description:
            "1 m square counter-clockwise, heading kept at 0 (sideways sides), stop at each corner",
        paper: "seed 002",
        drive: Drive::Holonomic,
    },
    Named {
        name: "seed002-diagonal",
        description: "diagonal of a 1 m square, to (1, 1) m, heading kept at 0",
        paper: "seed 002",
        drive: Drive::Holonomic,
    },
    Named {
        name: "seed002-circle",
        description:
            "one counter-clockwise lap of a circle of radius 0.5 m, heading along the path",
        paper: "seed 002",
        drive: Drive::Differential,
    },
    Named {
        name: "umbmark-cw",
        description: "UMBmark: 4 m x 4 m square clockwise, stop and turn in place at each corner",
        paper: "Borenstein UMBmark",
        drive: Drive::Differential,
    },
    Named {
        name: "umbmark-ccw",
        description:
            "UMBmark: 4 m x 4 m square counter-clockwise, stop and turn in place at each corner",
        paper: "Borenstein UMBmark",
        drive: Drive::Differential,
    },
];

/// Every trajectory [`build`] knows, in a stable order.
pub fn catalogue() -> Vec<Named> {
    CATALOGUE.to_vec()
}

/// The catalogue entry of `name`.
pub fn named(name: &str) -> Option<Named> {
    CATALOGUE.iter().find(|n| n.name == name).copied()
}

/// Builds the trajectory called `name` (see [`catalogue`]).
pub fn build(name: &str) -> Option<Box<dyn Trajectory>> {
    let holonomic_fixed = Heading::Progress {
        start: 0.0,
        delta: 0.0,
    };
    Some(match name {
        "seed000-line" => Box::new(PathMotion::cruise(
            Line::new(0.0, 0.0, 0.0, SEED000_LENGTH_M),
            Heading::Tangent,
        )),
        "seed000-bezier-0deg" => seed000_bezier(0.0),
        "seed000-bezier-90deg" => seed000_bezier(FRAC_PI_2),
        "seed000-bezier-180deg" => seed000_bezier(PI),
        "seed000-two-beziers" => {
            let first = [[0.0, 0.0], [0.2, 0.0], [0.25, 0.2], [0.4, 0.2]];
            // G1 joint: the second curve's first control leg continues the first's last.
            let second = [[0.4, 0.2], [0.55, 0.2], [0.6, 0.0], [0.8, 0.0]];
            Box::new(PathMotion::cruise(
                ArcLength::new(Bezier::new(vec![first, second]), SEED000_LENGTH_M),
                holonomic_fixed,
            ))
        }
        "seed001-figure-eight" => Box::new(PathMotion::cruise(
            ArcLength::new(Gerono, SEED001_FIGURE_EIGHT_M),
            Heading::Tangent,
        )),
        "seed001-straight-40m" => Box::new(PathMotion::cruise(
            Line::new(0.0, 0.0, 0.0, SEED001_STRAIGHT_M),
            Heading::Tangent,
        )),
        "seed001-curve" => Box::new(PathMotion::cruise(
            ArcLength::new(
                Bezier::new(vec![[[0.0, 0.0], [1.0, 0.0], [2.0, 1.0], [2.0, 2.0]]]),
                SEED001_CURVE_M,
            ),
            Heading::Tangent,
        )),
        "seed002-square" => {
            let s = SEED002_SIDE_M;
            let corners = [(0.0, 0.0), (s, 0.0), (s, s), (0.0, s), (0.0, 0.0)];
            let parts = corners
                .windows(2)
                .map(|w| {
                    let ((x0, y0), (x1, y1)) = (w[0], w[1]);
                    let (dx, dy): (f64, f64) = (x1 - x0, y1 - y0);
                    Box::new(PathMotion::cruise(
                        Line::new(x0, y0, dy.atan2(dx), dx.hypot(dy)),
                        holonomic_fixed,
                    )) as Box<dyn Trajectory>
                })
                .collect();
            Box::new(Sequence::new(parts))
        }
        "seed002-diagonal" => Box::new(PathMotion::cruise(
            Line::new(
                0.0,
                0.0,
                FRAC_PI_4,
                SEED002_SIDE_M * std::f64::consts::SQRT_2,
            ),
            holonomic_fixed,
        )),
        "seed002-circle" => Box::new(PathMotion::cruise(
            Arc::circle_ccw_from_origin(SEED002_CIRCLE_RADIUS_M),
            Heading::Tangent,
        )),
        "umbmark-cw" => umbmark(false),
        "umbmark-ccw" => umbmark(true),
        _ => return None,
    })
}

fn seed000_bezier(heading_change: f64) -> Box<dyn Trajectory> {
    Box::new(PathMotion::cruise(
        ArcLength::new(
            Bezier::new(vec![[[0.0, 0.0], [0.3, 0.0], [0.45, 0.3], [0.7, 0.35]]]),
            SEED000_LENGTH_M,
        ),
        Heading::Progress {
            start: 0.0,
            delta: heading_change,
        },
    ))
}

/// Four sides of [`UMBMARK_SIDE_M`], each followed by a 90° turn in place (left for
/// counter-clockwise), ending where it started with the heading one turn further.
fn umbmark(ccw: bool) -> Box<dyn Trajectory> {
    let turn = if ccw { FRAC_PI_2 } else { -FRAC_PI_2 };
    let mut parts: Vec<Box<dyn Trajectory>> = Vec::new();
    let mut at = Pose2::new(0.0, 0.0, 0.0);
    for _ in 0..4 {
        let side = PathMotion::cruise(
            Line::new(at.x, at.y, at.theta, UMBMARK_SIDE_M),
            Heading::Tangent,
        );
        at = side.pose(side.duration());
        parts.push(Box::new(side));
        let spin = Turn::new(at, turn);
        at = spin.pose(spin.duration());
        parts.push(Box::new(spin));
    }
    Box::new(Sequence::new(parts))
}

// ---------------------------------------------------------------------------------------------
// Quadrature.

const GL5_X: [f64; 5] = [
    -0.906_179_845_938_664,
    -0.538_469_310_105_683_1,
    0.0,
    0.538_469_310_105_683_1,
    0.906_179_845_938_664,
];
const GL5_W: [f64; 5] = [
    0.236_926_885_056_189_1,
    0.478_628_670_499_366_5,
    0.568_888_888_888_888_9,
    0.478_628_670_499_366_5,
    0.236_926_885_056_189_1,
];

/// The 5-point Gauss–Legendre nodes on `[a, b]`.
pub(crate) fn gl5_nodes(a: f64, b: f64) -> [f64; 5] {
    let (m, h) = (0.5 * (a + b), 0.5 * (b - a));
    GL5_X.map(|x| m + h * x)
}

/// `∫_a^b f` from the values of `f` at [`gl5_nodes`]`(a, b)` (exact for polynomials of degree 9).
pub(crate) fn gl5_sum(a: f64, b: f64, values: &[f64; 5]) -> f64 {
    let mut sum = 0.0;
    for (w, v) in GL5_W.iter().zip(values) {
        sum += w * v;
    }
    0.5 * (b - a) * sum
}

/// `∫_a^b f`, 5-point Gauss–Legendre.
pub(crate) fn gl5(a: f64, b: f64, mut f: impl FnMut(f64) -> f64) -> f64 {
    let values = gl5_nodes(a, b).map(&mut f);
    gl5_sum(a, b, &values)
}

// ---------------------------------------------------------------------------------------------
// Time scaling.

/// Distance along a path as a function of time: smoothstep speed ramp up, cruise, ramp down.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Profile {
    length: f64,
    speed: f64,
    ramp: f64,
    cruise: f64,
}

impl Profile {
    fn new(length: f64, max_speed: f64, ramp: f64) -> Profile {
        assert!(length > 0.0 && max_speed > 0.0 && ramp > 0.0);
        // Each ramp covers speed·ramp/2.
        if length >= max_speed * ramp {
            Profile {
                length,
                speed: max_speed,
                ramp,
                cruise: (length - max_speed * ramp) / max_speed,
            }
        } else {
            Profile {
                length,
                speed: length / ramp,
                ramp,
                cruise: 0.0,
            }
        }
    }

    fn duration(&self) -> f64 {
        2.0 * self.ramp + self.cruise
    }

    fn breakpoints(&self) -> Vec<f64> {
        if self.cruise > 0.0 {
            vec![self.ramp, self.ramp + self.cruise]
        } else {
            vec![self.ramp]
        }
    }

    /// The first time at which the distance reaches `s` (bisection to the last bit).
    fn time_at(&self, s: f64) -> f64 {
        let (mut lo, mut hi) = (0.0, self.duration());
        loop {
            let mid = 0.5 * (lo + hi);
            if mid <= lo || mid >= hi {
                return hi;
            }
            if self.at(mid).0 >= s {
                hi = mid;
            } else {
                lo = mid;
            }
        }
    }

    /// `(s, ds/dt)` at time `t` (clamped to the motion).
    fn at(&self, t: f64) -> (f64, f64) {
        let t = t.clamp(0.0, self.duration());
        // Ramp from rest over x in [0, 1]: speed v·(3x² − 2x³), distance v·T·(x³ − x⁴/2).
        let ramp = |x: f64| {
            let x2 = x * x;
            (
                self.speed * self.ramp * x2 * x * (1.0 - 0.5 * x),
                self.speed * x2 * (3.0 - 2.0 * x),
            )
        };
        if t < self.ramp {
            ramp(t / self.ramp)
        } else if t <= self.ramp + self.cruise {
            (
                0.5 * self.speed * self.ramp + self.speed * (t - self.ramp),
                self.speed,
            )
        } else {
            let (d, v) = ramp((self.duration() - t) / self.ramp);
            (self.length - d, v)
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Paths parametrised by arc length.

/// A point of a path: position, unwrapped tangent angle, signed curvature (left turns > 0).
#[derive(Clone, Copy, Debug, PartialEq)]
struct PathPoint {
    x: f64,
    y: f64,
    phi: f64,
    kappa: f64,
}

trait Path {
    fn length(&self) -> f64;
    /// The point at arc length `s` (clamped to `[0, length]`).
    fn at(&self, s: f64) -> PathPoint;
    /// Arc lengths inside the path where it is only finitely smooth (e.g. the curvature jumps
    /// where two Bézier curves meet).
    fn kinks(&self) -> Vec<f64> {
        Vec::new()
    }
}

struct Line {
    x0: f64,
    y0: f64,
    phi: f64,
    length: f64,
}

impl Line {
    fn new(x0: f64, y0: f64, phi: f64, length: f64) -> Line {
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
struct Arc {
    x0: f64,
    y0: f64,
    phi0: f64,
    radius: f64,
    dir: f64,
    sweep: f64,
}

impl Arc {
    /// A full counter-clockwise lap starting at the origin heading +x (centre (0, r)).
    fn circle_ccw_from_origin(radius: f64) -> Arc {
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
trait ParamCurve {
    fn pieces(&self) -> usize;
    fn eval(&self, u: f64) -> [[f64; 2]; 3];
}

/// Cubic Bézier curves joined end to end; piece k is u in [k, k+1].
struct Bezier {
    control: Vec<[[f64; 2]; 4]>,
}

impl Bezier {
    fn new(control: Vec<[[f64; 2]; 4]>) -> Bezier {
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
struct Gerono;

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
struct ArcLength<C> {
    curve: C,
    /// Parameter nodes, the raw arc length at each, the unwrapped tangent angle at each.
    u: Vec<f64>,
    s: Vec<f64>,
    phi: Vec<f64>,
    /// Scale from the raw curve to the path.
    scale: f64,
}

const NODES_PER_PIECE: usize = 256;

impl<C: ParamCurve> ArcLength<C> {
    fn new(curve: C, length: f64) -> ArcLength<C> {
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
    fn param(&self, s: f64) -> (f64, usize) {
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

fn speed<C: ParamCurve>(curve: &C, u: f64) -> f64 {
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

// ---------------------------------------------------------------------------------------------
// Motions.

/// How the heading moves along a path.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Heading {
    /// Along the path tangent (no sideways velocity).
    Tangent,
    /// `start + delta · s / length`: independent of the path (omni robots).
    Progress { start: f64, delta: f64 },
}

/// A path driven from rest to rest with a [`Profile`].
struct PathMotion<P> {
    path: P,
    profile: Profile,
    heading: Heading,
}

impl<P: Path> PathMotion<P> {
    fn cruise(path: P, heading: Heading) -> PathMotion<P> {
        let profile = Profile::new(path.length(), CRUISE_SPEED_M_S, RAMP_S);
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
struct Turn {
    start: Pose2,
    sign: f64,
    profile: Profile,
}

impl Turn {
    fn new(start: Pose2, delta: f64) -> Turn {
        Turn {
            start,
            sign: delta.signum(),
            profile: Profile::new(delta.abs(), TURN_RATE_RAD_S, TURN_RAMP_S),
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

/// Motions one after the other; each must start where and how (at rest) the previous ended.
struct Sequence {
    parts: Vec<Box<dyn Trajectory>>,
    starts: Vec<f64>,
    duration: f64,
}

impl Sequence {
    fn new(parts: Vec<Box<dyn Trajectory>>) -> Sequence {
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

    fn part(&self, t: f64) -> (&dyn Trajectory, f64) {
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
    use super::*;

    #[test]
    fn profile_is_continuous_and_reaches_the_length() {
        for (len, v, ramp) in [(0.8, 0.4, 0.8), (0.1, 0.4, 0.8), (40.0, 0.4, 0.8)] {
            let p = Profile::new(len, v, ramp);
            let t_end = p.duration();
            assert_eq!(p.at(0.0), (0.0, 0.0));
            let (s, sd) = p.at(t_end);
            assert!((s - len).abs() < 1e-12 && sd.abs() < 1e-12, "{s} {sd}");
            for &b in &p.breakpoints() {
                let (a, va) = p.at(b - 1e-9);
                let (c, vc) = p.at(b + 1e-9);
                assert!((a - c).abs() < 1e-8 && (va - vc).abs() < 1e-7);
            }
            // ds/dt is the derivative of s.
            for k in 1..20 {
                let t = t_end * k as f64 / 20.0;
                let h = 1e-6;
                let num = (p.at(t + h).0 - p.at(t - h).0) / (2.0 * h);
                assert!(
                    (num - p.at(t).1).abs() < 1e-7,
                    "t {t}: {num} vs {}",
                    p.at(t).1
                );
            }
        }
    }

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
