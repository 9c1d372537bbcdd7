//! The trajectories by name: the catalogue [`build`] reads from, and how each is made.

use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, PI};

use super::motion::{Heading, PathMotion, Sequence, Turn};
use super::path::{Arc, ArcLength, Bezier, Gerono, Line};
use super::*;

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
