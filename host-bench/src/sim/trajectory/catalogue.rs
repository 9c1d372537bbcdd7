//! The trajectories by name: the catalogue [`build`] reads from, and how each is made.

use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, PI};

use super::motion::{Heading, PathMotion, Sequence, Turn};
use super::path::{Arc, ArcLength, Bezier, Gerono, Line};
use super::segments::{Segment, Segments};
use super::*;

const CATALOGUE: &[Named] = &[
    Named {
        name: "seed000-line",
        description: "straight line 80 cm along +x, heading 0",
        paper: "tick-timing paper",
        drive: Drive::Differential,
    },
    Named {
        name: "seed000-bezier-0deg",
        description: "one cubic Bezier curve, 80 cm, heading constant 0",
        paper: "tick-timing paper",
        drive: Drive::Holonomic,
    },
    Named {
        name: "seed000-bezier-90deg",
        description: "one cubic Bezier curve, 80 cm, heading turning 90 deg linearly with distance",
        paper: "tick-timing paper",
        drive: Drive::Holonomic,
    },
    Named {
        name: "seed000-bezier-180deg",
        description:
            "one cubic Bezier curve, 80 cm, heading turning 180 deg linearly with distance",
        paper: "tick-timing paper",
        drive: Drive::Holonomic,
    },
    Named {
        name: "seed000-two-beziers",
        description:
            "two cubic Bezier curves joined with a common tangent (an S), 80 cm, heading 0",
        paper: "tick-timing paper",
        drive: Drive::Holonomic,
    },
    Named {
        name: "seed001-figure-eight",
        description: "figure-eight (lemniscate of Gerono), 284 cm, heading along the path",
        paper: "Batbayar and Zoljargal 2013",
        drive: Drive::Differential,
    },
    Named {
        name: "seed001-straight-40m",
        description: "straight line 40 m along +x",
        paper: "Batbayar and Zoljargal 2013",
        drive: Drive::Differential,
    },
    Named {
        name: "seed001-curve",
        description:
            "a left-hand curve (cubic Bezier turning 90 deg), 280 cm, heading along the path",
        paper: "Batbayar and Zoljargal 2013",
        drive: Drive::Differential,
    },
    Named {
        name: "seed002-square",
        description:
            "1 m square counter-clockwise, heading kept at 0 (sideways sides), stop at each corner",
        paper: "Dehghan Banadaki et al. 2005",
        drive: Drive::Holonomic,
    },
    Named {
        name: "seed002-square-steps",
        description: "1 m square counter-clockwise at a constant 0.4 m/s, heading kept at 0: \
                      the velocity steps at the start, at each corner and at the end (0.5 s at rest \
                      either side)",
        paper: "Dehghan Banadaki et al. 2005",
        drive: Drive::Holonomic,
    },
    Named {
        name: "seed002-diagonal",
        description: "diagonal of a 1 m square, to (1, 1) m, heading kept at 0",
        paper: "Dehghan Banadaki et al. 2005",
        drive: Drive::Holonomic,
    },
    Named {
        name: "seed002-circle",
        description:
            "one counter-clockwise lap of a circle of radius 0.5 m, heading along the path",
        paper: "Dehghan Banadaki et al. 2005",
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
    Named {
        name: "twist-arcs",
        description: "three arcs at constant twist, abrupt changes: left r 0.5 m, right r 0.3 m, \
                      left r 1 m; moving from t = 0 to the end, 2 m",
        paper: "ours",
        drive: Drive::Differential,
    },
    Named {
        name: "twist-sideways-spin",
        description: "constant twists, abrupt changes: sideways run, spin in place, diagonal \
                      run while turning, then that twist reversed; moving throughout, 2 m",
        paper: "ours",
        drive: Drive::Holonomic,
    },
    Named {
        name: "twist-s-spin-reverse",
        description: "constant twists, abrupt changes: arc left, arc right, spin in place, \
                      straight in reverse; moving throughout, 1.8 m",
        paper: "ours",
        drive: Drive::Differential,
    },
    Named {
        name: "rest-then-arcs",
        description: "0.5 s at rest, then twist-arcs starting abruptly at full speed, 2 m",
        paper: "ours",
        drive: Drive::Differential,
    },
    Named {
        name: "rest-then-smooth-line",
        description: "0.4 s at rest, then a smooth start (0.8 s ramp) to 0.4 m/s along +x, \
                      still moving at the end, 1.36 m",
        paper: "ours",
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
/// Whether the trajectory is the body's own path, not one for a tracked point ahead of it:
/// UMBmark's squares, whose corners are turns in place of the body (Borenstein's procedure
/// is defined by what the wheels do), so a robot that tracks a point ahead of its axle is
/// sent that point's path round them ([`super::AheadOf`]).
pub fn is_body_path(name: &str) -> bool {
    matches!(name, "umbmark-cw" | "umbmark-ccw")
}

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
        "seed002-square-steps" => {
            // Seed 002's square as its figures show it: no ramps, the velocity turns by 90°
            // at each corner in one step (and steps from and to rest, half a second each side).
            let (s, v) = (SEED002_SIDE_M, 0.4);
            let side = s / v;
            Box::new(Segments::new(
                Pose2::default(),
                vec![
                    Segment::rest(0.5),
                    Segment::constant(side, v, 0.0, 0.0),
                    Segment::constant(side, 0.0, v, 0.0),
                    Segment::constant(side, -v, 0.0, 0.0),
                    Segment::constant(side, 0.0, -v, 0.0),
                    Segment::rest(0.5),
                ],
            ))
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
        "twist-arcs" => Box::new(Segments::new(Pose2::default(), twist_arcs())),
        "twist-sideways-spin" => Box::new(Segments::new(
            Pose2::default(),
            vec![
                Segment::constant(1.8, 0.0, 0.4, 0.0),   // 0.72 m to the left
                Segment::constant(1.2, 0.0, 0.0, 1.5),   // 1.8 rad on the spot
                Segment::constant(1.5, 0.3, -0.3, 0.8),  // 0.64 m, turning 1.2 rad
                Segment::constant(1.5, -0.3, 0.3, -0.8), // back along it exactly
            ],
        )),
        "twist-s-spin-reverse" => Box::new(Segments::new(
            Pose2::default(),
            vec![
                Segment::constant(1.5, 0.4, 0.0, 1.0), // 0.6 m left, radius 0.4 m
                Segment::constant(1.5, 0.4, 0.0, -1.0), // 0.6 m right, radius 0.4 m
                Segment::constant(1.0, 0.0, 0.0, 2.0), // 2 rad on the spot
                Segment::constant(2.0, -0.3, 0.0, 0.0), // 0.6 m backwards
            ],
        )),
        "rest-then-arcs" => {
            let mut segments = vec![Segment::rest(0.5)];
            segments.extend(twist_arcs());
            Box::new(Segments::new(Pose2::default(), segments))
        }
        "rest-then-smooth-line" => Box::new(Segments::new(
            Pose2::default(),
            vec![
                Segment::rest(0.4),
                // The seed paths' ramp (0.16 m), but the motion does not start at t = 0.
                Segment::ramp_up(RAMP_S, CRUISE_SPEED_M_S, 0.0, 0.0),
                Segment::constant(3.0, CRUISE_SPEED_M_S, 0.0, 0.0), // 1.2 m
            ],
        )),
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
    umbmark_square(UMBMARK_SIDE_M, CRUISE_SPEED_M_S, TURN_RATE_RAD_S, ccw)
}

/// UMBmark's square of any size, for the bench (`calibrate --port`): four sides of `side_m`
/// at up to `speed` m/s, each followed by a 90° turn in place at up to `turn_rate` rad/s
/// (left for counter-clockwise), from the origin facing +x, back to it.
pub fn umbmark_square(side_m: f64, speed: f64, turn_rate: f64, ccw: bool) -> Box<dyn Trajectory> {
    let turn = if ccw { FRAC_PI_2 } else { -FRAC_PI_2 };
    let mut parts: Vec<Box<dyn Trajectory>> = Vec::new();
    let mut at = Pose2::new(0.0, 0.0, 0.0);
    for _ in 0..4 {
        let side = PathMotion::at_speed(
            Line::new(at.x, at.y, at.theta, side_m),
            Heading::Tangent,
            speed,
        );
        at = side.pose(side.duration());
        parts.push(Box::new(side));
        let spin = Turn::at_rate(at, turn, turn_rate);
        at = spin.pose(spin.duration());
        parts.push(Box::new(spin));
    }
    Box::new(Sequence::new(parts))
}

/// Three arcs of constant twist, 2 m: left with radius 0.5 m (0.6 m), right with radius 0.3 m
/// (0.6 m), left with radius 1 m (0.8 m), at 0.4, 0.3 and 0.5 m/s.
fn twist_arcs() -> Vec<Segment> {
    vec![
        Segment::constant(1.5, 0.4, 0.0, 0.8),
        Segment::constant(2.0, 0.3, 0.0, -1.0),
        Segment::constant(1.6, 0.5, 0.0, 0.5),
    ]
}
