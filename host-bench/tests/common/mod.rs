//! Helpers shared by the generator and catalogue tests (`generate*.rs`, `catalogue.rs`,
//! `layouts.rs`). Each test crate uses only some of them.
#![allow(dead_code)]

use std::fs;
use std::path::{Path, PathBuf};

use host_bench::formats::robot::Robot;
use host_bench::formats::tickstream::{Event, TickStream};
use host_bench::sim::generate::{phases, GenerateOptions, PowerOnPhase};
use host_bench::sim::trajectory::Trajectory;
use robot_math::se2::{Pose2, Twist};

pub fn robot(name: &str) -> Robot {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../robots")
        .join(name);
    Robot::load(&path).unwrap()
}

pub fn scratch(test: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("generate-tests")
        .join(test);
    let _ = fs::remove_dir_all(&dir);
    fs::create_dir_all(&dir).unwrap();
    dir
}

/// The default options: random power-on phases, seed 0.
pub fn opts() -> GenerateOptions {
    GenerateOptions::default()
}

/// Every encoder powered on exactly on the edge of a count: for the tests whose closed forms
/// are written for that case (tick k at k·step/v, a peak just past edge m).
pub fn edge_aligned() -> GenerateOptions {
    GenerateOptions {
        phase: PowerOnPhase::Zero,
        ..opts()
    }
}

/// With every encoder at `phase` of a count.
pub fn at_phase(phase: f64) -> GenerateOptions {
    GenerateOptions {
        phase: PowerOnPhase::Fraction(phase),
        ..opts()
    }
}

/// Each encoder's distance inside its count at power-on (phase × step), metres.
pub fn offsets(robot: &Robot, opts: &GenerateOptions) -> Vec<f64> {
    phases(robot, opts.phase)
        .unwrap()
        .iter()
        .zip(&robot.encoders)
        .map(|(p, e)| p * e.metres_per_count)
        .collect()
}

/// Per encoder: the tick instants (ns) and steps, in stream order.
pub fn ticks_of(stream: &TickStream, encoder: u16) -> Vec<(u64, i8)> {
    stream
        .events
        .iter()
        .filter_map(|e| match *e {
            Event::Tick {
                t_ns,
                encoder: id,
                step,
            } if id == encoder => Some((t_ns, step)),
            _ => None,
        })
        .collect()
}

pub fn net(stream: &TickStream, encoder: u16) -> i64 {
    ticks_of(stream, encoder)
        .iter()
        .map(|&(_, s)| s as i64)
        .sum()
}

/// `count == floor(position / step)`, position = power-on offset + rolled distance; if
/// `position / step` is within 1e-6 of a whole number rounding may put it on either side, so
/// either neighbour is accepted.
pub fn assert_count(count: i64, position: f64, step: f64, what: &str) {
    let x = position / step;
    let expected = x.floor() as i64;
    if (x - x.round()).abs() < 1e-6 {
        let r = x.round() as i64;
        assert!(
            count == r || count == r - 1,
            "{what}: {count} counts, at {position} m = {x} steps"
        );
    } else {
        assert_eq!(count, expected, "{what}: at {position} m = {x} steps");
    }
}

/// Constant body twist from t = 0 (not from rest: exact tick instants are k·step/v).
pub struct Constant {
    pub twist: Twist,
    pub duration: f64,
}

impl Trajectory for Constant {
    fn duration(&self) -> f64 {
        self.duration
    }
    fn pose(&self, t: f64) -> Pose2 {
        Pose2::default().integrate(self.twist, t)
    }
    fn twist(&self, _: f64) -> Twist {
        self.twist
    }
}

/// Path length: ∫ |(v_x, v_y)| dt.
pub fn path_length(traj: &dyn Trajectory) -> f64 {
    integral(traj, |v| v.vx.hypot(v.vy))
}

/// ∫ f(twist(t)) dt over the trajectory, 5-point Gauss–Legendre on 1 ms pieces between
/// breakpoints (so only inside pieces: a twist that jumps at a breakpoint is fine).
pub fn integral(traj: &dyn Trajectory, f: impl Fn(Twist) -> f64) -> f64 {
    const X: [f64; 5] = [
        -0.906_179_845_938_664,
        -0.538_469_310_105_683_1,
        0.0,
        0.538_469_310_105_683_1,
        0.906_179_845_938_664,
    ];
    const W: [f64; 5] = [
        0.236_926_885_056_189_1,
        0.478_628_670_499_366_5,
        0.568_888_888_888_888_9,
        0.478_628_670_499_366_5,
        0.236_926_885_056_189_1,
    ];
    let mut total = 0.0;
    for w in cuts(traj).windows(2) {
        let n = ((w[1] - w[0]) / 1e-3).ceil().max(1.0) as usize;
        let h = (w[1] - w[0]) / n as f64;
        for j in 0..n {
            let m = w[0] + h * (j as f64 + 0.5);
            for (x, wt) in X.iter().zip(W) {
                total += 0.5 * h * wt * f(traj.twist(m + 0.5 * h * x));
            }
        }
    }
    total
}

/// 0, the breakpoints, and the duration, in order.
pub fn cuts(traj: &dyn Trajectory) -> Vec<f64> {
    let mut cuts = traj.breakpoints();
    cuts.push(0.0);
    cuts.push(traj.duration());
    cuts.sort_by(f64::total_cmp);
    cuts.dedup();
    cuts
}

pub fn twist_norm(a: Twist, b: Twist) -> f64 {
    (a.vx - b.vx)
        .abs()
        .max((a.vy - b.vy).abs())
        .max((a.omega - b.omega).abs())
}
