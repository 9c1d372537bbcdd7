//! `host-bench calibrate`: how far a robot's geometry is off its robot file, from runs whose
//! true end pose is known, and the robot file corrected.
//!
//! `umbmark` ([`umbmark`]) is Borenstein and Feng's procedure for two parallel measuring
//! wheels. The runs ([`runs`]) are tick streams replayed on the nominal robot, or emulated runs
//! whose slave ran it.

pub mod bench;
pub mod fit;
pub mod runs;
pub mod umbmark;
pub mod wiring;

use anyhow::{bail, Result};
use serde::Serialize;

use crate::formats::robot::{EncoderGeometry, Robot};
use runs::RunEnd;
use umbmark::{Direction, SquareRun, Umbmark};

/// The two parallel measuring wheels UMBmark is about: which encoder is on the left of their
/// rolling direction, which on the right, and how far apart they are across it.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct WheelPair {
    pub left: usize,
    pub right: usize,
    pub base_m: f64,
}

/// The robot's two measuring wheels, if they are a UMBmark pair.
pub fn wheel_pair(robot: &Robot) -> Result<WheelPair> {
    let [a, b] = robot.encoders.as_slice() else {
        bail!(
            "robot {}: UMBmark is for two measuring wheels; this robot has {} encoders",
            robot.name,
            robot.encoders.len()
        );
    };
    let (wa, wb) = (a.wheel, b.wheel);
    if (wa.ux * wb.uy - wa.uy * wb.ux).abs() > 1e-9 || wa.ux * wb.ux + wa.uy * wb.uy < 0.0 {
        bail!(
            "robot {}: UMBmark takes two wheels rolling the same way; {} and {} do not",
            robot.name,
            a.name,
            b.name
        );
    }
    // Across the rolling direction, to its left.
    let lateral = |w: robot_math::wheel::Wheel| -w.x * wa.uy + w.y * wa.ux;
    let (la, lb) = (lateral(wa), lateral(wb));
    let (left, right) = if la > lb { (0, 1) } else { (1, 0) };
    Ok(WheelPair {
        left,
        right,
        base_m: (la - lb).abs(),
    })
}

/// The encoders as a robot file gives them.
pub fn geometry(robot: &Robot) -> Vec<EncoderGeometry> {
    (robot.encoders.iter())
        .map(|e| EncoderGeometry {
            x_m: e.wheel.x,
            y_m: e.wheel.y,
            direction_deg: e.wheel.uy.atan2(e.wheel.ux).to_degrees(),
            metres_per_count: e.metres_per_count,
        })
        .collect()
}

/// One run as UMBmark reads it: which way round, its side, its return error, from the
/// counts on the nominal robot. A run that is not one square driven forward once round is
/// refused, and a wheel counting backwards is named.
pub fn square_run(robot: &Robot, pair: WheelPair, run: &RunEnd) -> Result<SquareRun> {
    let (k, n) = (
        |i: usize| robot.encoders[i].metres_per_count,
        |i: usize| run.counts[i],
    );
    let name = |i: usize| &robot.encoders[i].name;
    let (l, r) = (pair.left, pair.right);
    // A square's legs roll both wheels forward: the turns in place cancel out.
    for (i, other) in [(l, r), (r, l)] {
        if n(i) < 0 && n(other) > 0 {
            bail!(
                "{}: encoder {} counted backwards ({} counts while {} counted {}): a square \
                 run rolls both wheels forward, so it is wired or signed the wrong way \
                 (swap its A and B lines, or turn its direction_deg by 180 in the robot file); \
                 no fit is made with a wheel that counts backwards",
                run.name,
                name(i),
                n(i),
                name(other),
                n(other)
            );
        }
    }
    let travel = (k(l) * n(l) as f64 + k(r) * n(r) as f64) / 2.0;
    // On a carriage the wheels turn the carriage: the body turned that less the swivel's turn.
    let swivelled = run
        .swivel
        .map_or(0.0, |(at_start, at_end)| at_end - at_start);
    let turned = (k(r) * n(r) as f64 - k(l) * n(l) as f64) / pair.base_m - swivelled;
    let turns = turned / std::f64::consts::TAU;
    if !(0.8..1.2).contains(&turns.abs()) || travel <= 0.0 {
        bail!(
            "{}: the odometry turned {:.0} deg over {:.3} m: a UMBmark run is one square, \
             driven forward once round (360 deg either way)",
            run.name,
            turned.to_degrees(),
            travel
        );
    }
    Ok(SquareRun {
        name: run.name.clone(),
        direction: if turned < 0.0 {
            Direction::Clockwise
        } else {
            Direction::CounterClockwise
        },
        side_m: travel / 4.0,
        error_m: run.error_in_start_frame(),
        // Steered by the odometry: it came back, the robot did not (else the other way).
        driven_by_odometry: run.odometry_end.distance_to(run.start)
            < run.measured_end.distance_to(run.start),
    })
}

/// How much the factors move when one run is left out: the spread of repeated calibrations,
/// which a standard deviation from one fit understates (Censi et al. found theirs spread
/// about five times their stated σ).
#[derive(Clone, Copy, Debug, Serialize)]
pub struct Repeatability {
    /// Fits made, one with each run left out (a direction keeps at least one run).
    pub subsets: usize,
    pub e_d_min: f64,
    pub e_d_max: f64,
    pub e_b_min: f64,
    pub e_b_max: f64,
}

/// UMBmark again with each of `n` runs left out in turn (`again` given the runs kept);
/// none when no run can be spared.
fn leave_one_out(
    n: usize,
    again: impl Fn(&[usize]) -> Result<(f64, f64)>,
) -> Option<Repeatability> {
    let fits: Vec<(f64, f64)> = (0..n)
        .filter_map(|k| {
            let rest: Vec<usize> = (0..n).filter(|&i| i != k).collect();
            again(&rest).ok()
        })
        .collect();
    let span = |f: fn(&(f64, f64)) -> f64| {
        (fits.iter().map(f)).fold((f64::MAX, f64::MIN), |(lo, hi), v| (lo.min(v), hi.max(v)))
    };
    let ((e_d_min, e_d_max), (e_b_min, e_b_max)) = (span(|u| u.0), span(|u| u.1));
    (!fits.is_empty()).then_some(Repeatability {
        subsets: fits.len(),
        e_d_min,
        e_d_max,
        e_b_min,
        e_b_max,
    })
}

/// What a UMBmark calibration found and made.
#[derive(Clone, Debug, Serialize)]
pub struct UmbmarkCalibration {
    pub robot: String,
    pub method: &'static str,
    pub pair: WheelPair,
    pub umbmark: Umbmark,
    /// The factors fitted with each run left out in turn.
    pub repeatability: Option<Repeatability>,
    pub runs: Vec<SquareRun>,
    pub before: Vec<EncoderGeometry>,
    pub after: Vec<EncoderGeometry>,
}

/// Every run's wiring verdict ([`wiring::check`]), before any fit.
pub fn check_wiring(robot: &Robot, runs: &[RunEnd]) -> Result<()> {
    for r in runs {
        if let Some(agree) = &r.agreement {
            wiring::check(robot, &r.name, agree)?;
        }
    }
    Ok(())
}

/// UMBmark on `runs` of `robot`, and its encoders corrected. On a swivel carriage the two
/// factors are refined on the runs' counts ([`fit::umbmark_on_carriage`], with `noise` the end
/// poses' measuring noise), not on UMBmark's square.
pub fn calibrate_umbmark(
    robot: &Robot,
    runs: &[RunEnd],
    noise: fit::Noise,
) -> Result<UmbmarkCalibration> {
    check_wiring(robot, runs)?;
    let pair = wheel_pair(robot)?;
    let squares = (runs.iter())
        .map(|r| square_run(robot, pair, r))
        .collect::<Result<Vec<_>>>()?;
    let mut u = umbmark::umbmark(&squares, pair.base_m)?;
    let before = geometry(robot);
    let repeatability = if robot.carriage.is_some() {
        let binned = runs::binned(runs)?;
        let on = |keep: &[usize]| {
            let kept: Vec<fit::BinnedRun> = keep.iter().map(|&i| binned[i].clone()).collect();
            fit::umbmark_on_carriage(robot, &before, &kept, noise)
        };
        (u.e_d, u.e_b) = on(&(0..binned.len()).collect::<Vec<_>>())?;
        leave_one_out(binned.len(), on)
    } else {
        leave_one_out(squares.len(), |keep| {
            let kept: Vec<SquareRun> = keep.iter().map(|&i| squares[i].clone()).collect();
            umbmark::umbmark(&kept, pair.base_m).map(|u| (u.e_d, u.e_b))
        })
    };
    let mut after = before.clone();
    let (left, right, base) = umbmark::corrected(
        &u,
        before[pair.left].metres_per_count,
        before[pair.right].metres_per_count,
        pair.base_m,
    );
    after[pair.left].metres_per_count = left;
    after[pair.right].metres_per_count = right;
    // The base widened about its middle, across the rolling direction.
    let w = robot.encoders[pair.left].wheel;
    let (nx, ny) = (-w.uy, w.ux);
    let grow = (base - pair.base_m) / 2.0;
    for (i, sign) in [(pair.left, 1.0), (pair.right, -1.0)] {
        after[i].x_m += sign * grow * nx;
        after[i].y_m += sign * grow * ny;
    }
    Ok(UmbmarkCalibration {
        robot: robot.name.clone(),
        method: "umbmark",
        pair,
        umbmark: u,
        repeatability,
        runs: squares,
        before,
        after,
    })
}
