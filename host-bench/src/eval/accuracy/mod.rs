//! `host-bench accuracy`: every case, every sensor mode, all four odometry methods, side by
//! side, over many power-on phases, with the paper's reported figure beside each seed case
//! (SPEC §5, §6).
//!
//! Each case generates the exact tick stream of a robot along a trajectory
//! ([`crate::sim::generate`]) in memory, once per power-on seed (every encoder starts at a
//! random point inside its count, as a real one does), and replays it ([`crate::eval::replay`])
//! in tick-timestamp mode and as counters sampled at 1 kHz and 10 kHz. Each method's final,
//! median and maximum errors are reported as their median, p95 and max over the seeds
//! ([`spread`]); the criteria ([`table`]) hold over every seed. The robot files are built
//! into the binary, so the command runs from anywhere.

use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

use anyhow::{Context, Result};
use serde::Serialize;

use crate::eval::replay::{self, Mode, Score};
use crate::formats::robot::Robot;
use crate::formats::tickstream::TickStream;
use crate::sim::generate::{generate_phases, EdgeErrors, GenerateOptions, PowerOnPhase};
use crate::sim::trajectory::{self, Trajectory};

pub mod moving;
pub mod spread;
pub mod table;

pub use spread::{MethodSpread, Spread};
pub use table::{median_advantage, summary, table};

/// Power-on seeds per case unless told otherwise.
pub const DEFAULT_SEEDS: u64 = 8;

/// A seed case: a trajectory, the robot that drives it, and what the paper reports.
#[derive(Clone, Copy, Debug)]
pub struct Case {
    pub trajectory: &'static str,
    /// File name in `robots/`.
    pub robot: &'static str,
    pub paper_figure: &'static str,
    /// How the motion starts: what the power-on phase estimate can know.
    pub start: Start,
}

/// How a case's motion starts, which decides what its first ticks can tell (docs/odometry.md,
/// "Where a wheel starts inside its count").
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Start {
    /// Moving from power-on, or starting from rest with a continuous speed: each wheel's first
    /// ticks place it.
    Placed,
    /// At rest, then at full speed at once: no wheel can tell when it started; they are
    /// placed together, to within half a count of the fastest wheel ([`abrupt_start_bound`]).
    AbruptAfterRest,
    /// At rest, then the velocity steps at the start, again while moving (wheels reversing at
    /// a corner) and at the stop: no bound is proven beyond the suite's 0.02 % of the path
    /// (the start's alone does not cover the later steps).
    Stepped,
}

const SEED000: &str = "the tick-timing paper: <= 1.5 mm (0.18 %) on 80 cm paths, Δ 0.1-0.8 mm";
const TRACKING_ONLY: &str =
    "Dehghan Banadaki, Nili Ahmadabadi and Moaveni Sabet 2005: tracking only, no odometry figure";
const OURS: &str = "ours: abrupt twists, other layouts";

/// Every case of SPEC §5 (holonomic paths on seed 000's omni triangle, the others on seed
/// 001's differential drive; UMBmark is a differential-drive benchmark), then ours: motion
/// made of constant twists that change abruptly, starts after a rest, and layouts that are not
/// the seeds' (a skewed 3-wheel omni, a 4-wheel least-squares layout, a wider axle off the
/// reference point).
pub fn cases() -> Vec<Case> {
    let c = |trajectory, robot, paper_figure| Case {
        trajectory,
        robot,
        paper_figure,
        start: Start::Placed,
    };
    let ours = |trajectory, robot| c(trajectory, robot, OURS);
    vec![
        c("seed000-line", "seed000-0.1mm.toml", SEED000),
        c("seed000-bezier-0deg", "seed000-0.1mm.toml", SEED000),
        c("seed000-bezier-90deg", "seed000-0.1mm.toml", SEED000),
        c("seed000-bezier-90deg", "seed000-0.4mm.toml", SEED000),
        c("seed000-bezier-90deg", "seed000-0.8mm.toml", SEED000),
        c("seed000-bezier-180deg", "seed000-0.1mm.toml", SEED000),
        c("seed000-two-beziers", "seed000-0.1mm.toml", SEED000),
        c(
            "seed001-figure-eight",
            "seed001.toml",
            "Batbayar and Zoljargal 2013: 1 cm in x, 1 cm in y",
        ),
        c(
            "seed001-straight-40m",
            "seed001.toml",
            "Batbayar and Zoljargal 2013: 1 cm in x, 0 in y",
        ),
        c(
            "seed001-curve",
            "seed001.toml",
            "Batbayar and Zoljargal 2013: 2.5 cm in x, 1 cm in y",
        ),
        c("seed002-square", "seed000-0.1mm.toml", TRACKING_ONLY),
        // At rest, then 0.4 m/s at once, turned 90° at each corner, stopped at once.
        Case {
            start: Start::Stepped,
            ..c("seed002-square-steps", "seed000-0.1mm.toml", TRACKING_ONLY)
        },
        c("seed002-diagonal", "seed000-0.1mm.toml", TRACKING_ONLY),
        c("seed002-circle", "seed001.toml", TRACKING_ONLY),
        c(
            "umbmark-cw",
            "seed001.toml",
            "UMBmark: no figure in the papers",
        ),
        c(
            "umbmark-ccw",
            "seed001.toml",
            "UMBmark: no figure in the papers",
        ),
        ours("twist-arcs", "diff-wide.toml"),
        ours("twist-s-spin-reverse", "seed001.toml"),
        ours("twist-s-spin-reverse", "diff-wide.toml"),
        ours("twist-sideways-spin", "skewed3.toml"),
        ours("twist-sideways-spin", "omni4-ls.toml"),
        ours("twist-sideways-spin", "seed000-0.4mm.toml"),
        ours("seed000-bezier-180deg", "skewed3.toml"),
        ours("seed002-square", "omni4-ls.toml"),
        ours("rest-then-smooth-line", "skewed3.toml"),
        Case {
            start: Start::AbruptAfterRest,
            ..ours("rest-then-arcs", "diff-wide.toml")
        },
        Case {
            start: Start::AbruptAfterRest,
            ..ours("rest-then-arcs", "seed001.toml")
        },
    ]
}

/// The sensor modes every case runs in.
pub fn modes() -> [Mode; 3] {
    [
        Mode::Timestamps,
        Mode::Counts { rate_hz: 1_000.0 },
        Mode::Counts { rate_hz: 10_000.0 },
    ]
}

fn robot_text(file: &str) -> Option<&'static str> {
    Some(match file {
        "seed000-0.1mm.toml" => include_str!("../../../../robots/seed000-0.1mm.toml"),
        "seed000-0.4mm.toml" => include_str!("../../../../robots/seed000-0.4mm.toml"),
        "seed000-0.8mm.toml" => include_str!("../../../../robots/seed000-0.8mm.toml"),
        "seed001.toml" => include_str!("../../../../robots/seed001.toml"),
        "skewed3.toml" => include_str!("../../../../robots/skewed3.toml"),
        "omni4-ls.toml" => include_str!("../../../../robots/omni4-ls.toml"),
        "diff-wide.toml" => include_str!("../../../../robots/diff-wide.toml"),
        _ => return None,
    })
}

/// The built-in robot `case` runs on.
pub fn robot(case: &Case) -> Result<Robot> {
    let text =
        robot_text(case.robot).with_context(|| format!("no built-in robot {}", case.robot))?;
    Ok(Robot::parse(
        text,
        Path::new(&format!("robots/{}", case.robot)),
    )?)
}

/// What `accuracy --out` names a case's files in one mode, before the method and extension:
/// `CASE-ROBOT-MODE`, the mode's `@` as `-` (`rest-then-arcs-seed001-counts-10000Hz`).
pub fn file_stem(case: &str, robot: &str, mode: &str) -> String {
    format!("{case}-{robot}-{}", mode.replace('@', "-"))
}

/// One case in one mode, over every seed.
#[derive(Clone, Debug, Serialize)]
pub struct CaseResult {
    pub case: String,
    pub robot: String,
    pub mode: String,
    pub path_length_m: f64,
    pub paper: String,
    /// Power-on seeds run (0, 1, ... seeds − 1), and how the phases were drawn.
    pub seeds: u64,
    pub phase: String,
    /// Where the encoders put their edges ([`EdgeErrors`]: ideal, or a datasheet's column),
    /// each seed's encoders drawn from it.
    pub edges: String,
    pub start: Start,
    pub algorithms: Vec<MethodSpread>,
    /// Over the seeds, the smallest ratio of the best baseline's median error to `exact`'s
    /// (each seed compared with itself), where that baseline's exceeds 10 µm on every seed.
    pub exact_advantage_worst_seed: Option<f64>,
    /// The same ratio for the error while moving ([`moving`]: the relative pose error over
    /// [`moving::SEGMENT_M`] of path, from the instant every wheel is placed), where the best
    /// baseline's exceeds 10 µm on every seed.
    pub exact_moving_advantage_worst_seed: Option<f64>,
    /// The instant every wheel had its first [`robot_math::ticks::PLACING_TICKS`] ticks, s:
    /// where the error while moving is measured from (latest over the seeds).
    pub placed_after_s: Option<f64>,
    /// Every wheel unknown by up to a count until its first ticks: the position error that
    /// stands for (Σ_j of the largest body displacement a count of wheel j gives), the floor
    /// of every method's maximum error on a coarse robot.
    pub start_bound_m: f64,
    /// Every wheel anywhere inside its count at power-on and exact from then on: the pose is off
    /// by one rigid transform, at most `dq + path·hq` away at the path's end ([`quantisation`]).
    /// The start of a wheel from rest is not in its ticks (docs/odometry.md), so this is the
    /// bound on the error from power-on that no placement can beat in general.
    pub start_drift_bound_m: f64,
    /// With [`Start::AbruptAfterRest`]: the bound on the final error that placing the wheels
    /// together leaves ([`abrupt_start_bound`]).
    pub abrupt_start_bound_m: Option<f64>,
    /// Largest distance and heading difference between fixed-point `exact` and its f64 twin
    /// over every truth row of every seed (the documented tolerance is 1 µm and 1e-6 rad).
    pub exact_vs_f64_m: f64,
    pub exact_vs_f64_rad: f64,
    /// Methods that cannot run here (e.g. `timing` on sampled counts), with the reason.
    pub skipped: Vec<Skipped>,
}

impl CaseResult {
    pub fn method(&self, name: &str) -> Option<&MethodSpread> {
        self.algorithms.iter().find(|s| s.name == name)
    }
}

#[derive(Clone, Debug, Serialize)]
pub struct Skipped {
    pub name: String,
    pub reason: String,
}

/// Every seed of one case, each in every mode.
type CaseRuns = Vec<Vec<Run>>;

/// One seed of one case in one mode.
struct Run {
    scores: Vec<Score>,
    /// Each score's median error while moving ([`moving::median_moving_error`]).
    moving: Vec<Option<f64>>,
    placed_after_s: Option<f64>,
    skipped: Vec<Skipped>,
    vs_f64: (f64, f64),
}

/// Run every case in every mode over `seeds` power-on seeds (on every core), the encoders'
/// edges placed as `edges` says (each seed's drawn from it). `progress` is called after each
/// (case, seed) with a label.
pub fn run(
    seeds: u64,
    edges: EdgeErrors,
    even_edges: bool,
    progress: impl FnMut(&str) + Send,
) -> Result<Vec<CaseResult>> {
    let seeds = seeds.max(1);
    let cases = cases();
    let mut loaded = Vec::new();
    for case in &cases {
        let robot = robot(case)?;
        trajectory::build(case.trajectory)
            .with_context(|| format!("unknown trajectory {}", case.trajectory))?;
        loaded.push(robot);
    }
    // Jobs are cases; each generates its streams a few seeds at a time and replays each in
    // every mode.
    let jobs = cases.len();
    let next = AtomicUsize::new(0);
    let done: Mutex<Vec<Option<Result<CaseRuns>>>> = Mutex::new((0..jobs).map(|_| None).collect());
    let progress = Mutex::new(progress);
    let workers = std::thread::available_parallelism()
        .map_or(1, |n| n.get())
        .min(jobs);
    std::thread::scope(|scope| {
        for _ in 0..workers {
            scope.spawn(|| loop {
                let job = next.fetch_add(1, Ordering::Relaxed);
                if job >= jobs {
                    break;
                }
                let c = job;
                let out = run_case(&cases[c], &loaded[c], seeds, edges, even_edges);
                if let Ok(mut d) = done.lock() {
                    d[job] = Some(out);
                }
                if let Ok(mut p) = progress.lock() {
                    (*p)(&format!(
                        "{} on {} ({seeds} seeds)",
                        cases[c].trajectory, loaded[c].name
                    ));
                }
            });
        }
    });
    let mut done = done
        .into_inner()
        .map_err(|_| anyhow::anyhow!("a worker panicked"))?;
    let mut results = Vec::new();
    for (c, case) in cases.iter().enumerate() {
        let per_seed = done[c].take().context("a worker stopped early")??;
        let robot = &loaded[c];
        let traj = trajectory::build(case.trajectory).context("built above")?;
        for (m, mode) in modes().into_iter().enumerate() {
            let runs: Vec<&Run> = per_seed.iter().map(|r| &r[m]).collect();
            let mut r = aggregate(case, robot, traj.as_ref(), mode, seeds, &runs)?;
            r.edges = edges.to_string();
            if even_edges {
                r.edges.push_str("; `exact` taking them a count apart");
            }
            results.push(r);
        }
    }
    Ok(results)
}

/// Seeds generated in one pass: the default count. A pass holds its streams, and may make at
/// most 2·10⁶ ticks by the generator's bound (the longest case, seed000-line on 0.1 mm counts,
/// passed it at 60 seeds in one pass), so more seeds go in more passes and memory stays that of
/// one pass.
const SEEDS_PER_PASS: u64 = 8;

/// Seeds `0..seeds` of `case`: their streams, generated [`SEEDS_PER_PASS`] at a time (a
/// seed's stream is the same whichever pass makes it), each replayed in every mode.
fn run_case(
    case: &Case,
    robot: &Robot,
    seeds: u64,
    edges: EdgeErrors,
    even_edges: bool,
) -> Result<CaseRuns> {
    let traj = trajectory::build(case.trajectory)
        .with_context(|| format!("unknown trajectory {}", case.trajectory))?;
    let mut runs = Vec::new();
    for first in (0..seeds).step_by(SEEDS_PER_PASS as usize) {
        let phases: Vec<PowerOnPhase> = (first..seeds.min(first + SEEDS_PER_PASS))
            .map(|seed| PowerOnPhase::Random { seed })
            .collect();
        let streams = generate_phases(
            robot,
            Some(&format!("../robots/{}", case.robot)),
            traj.as_ref(),
            &GenerateOptions {
                edges,
                ..GenerateOptions::default()
            },
            &phases,
        )
        .with_context(|| format!("generating {} for {}", case.trajectory, robot.name))?;
        for (k, s) in streams.iter().enumerate() {
            // Seed 0's tracks are drawn (`accuracy --out`); the others are let go.
            runs.push(run_seed(robot, s, first + k as u64 == 0, even_edges)?);
        }
    }
    Ok(runs)
}

/// One seed's stream, replayed in every mode; `keep_tracks` for the seed the pictures draw;
/// `even_edges`: `exact` (and its twin) take every edge a count after the last instead of
/// learning them, with time stamps.
fn run_seed(
    robot: &Robot,
    stream: &TickStream,
    keep_tracks: bool,
    even_edges: bool,
) -> Result<Vec<Run>> {
    let placed_after_s = moving::placed_after_s(stream);
    let mut out = Vec::new();
    for mode in modes() {
        let (mut scores, mut skipped) = (Vec::new(), Vec::new());
        let even = even_edges && mode == Mode::Timestamps;
        let as_run = |name: &str| match even && name.starts_with("exact") {
            true => format!("{name}{}", replay::EVEN_EDGES),
            false => name.to_string(),
        };
        for name in replay::ALGORITHMS {
            match replay::replay(robot, stream, &as_run(name), mode) {
                // Under its own name in the tables: the edges line says it does not learn.
                Ok(s) => scores.push(Score {
                    name: name.to_string(),
                    ..s
                }),
                Err(e) => skipped.push(Skipped {
                    name: name.to_string(),
                    reason: format!("{e:#}"),
                }),
            }
        }
        let mut vs_f64 = (0.0f64, 0.0f64);
        if let Some(fixed) = scores.iter().find(|s| s.name == "exact") {
            let twin = replay::replay(robot, stream, &as_run(replay::ORACLE), mode)?;
            for ((_, a, _), (_, b, _)) in fixed.track.iter().zip(&twin.track) {
                vs_f64.0 = vs_f64.0.max(a.distance_to(*b));
                vs_f64.1 = vs_f64
                    .1
                    .max(robot_math::se2::wrap_angle(a.theta - b.theta).abs());
            }
        }
        let moving = scores
            .iter()
            .map(|s| {
                placed_after_s.and_then(|t| moving::median_moving_error(s, t, moving::SEGMENT_M))
            })
            .collect();
        // Each track (a pose pair per truth row) is read above and, for one seed, by the
        // pictures: kept for every seed, 60 of them took 2.8 GB.
        if !keep_tracks {
            for s in &mut scores {
                s.track = Vec::new();
            }
        }
        out.push(Run {
            scores,
            moving,
            placed_after_s,
            skipped,
            vs_f64,
        });
    }
    Ok(out)
}

fn aggregate(
    case: &Case,
    robot: &Robot,
    traj: &dyn Trajectory,
    mode: Mode,
    seeds: u64,
    runs: &[&Run],
) -> Result<CaseResult> {
    let first = runs.first().context("no seeds")?;
    let algorithms: Vec<MethodSpread> = first
        .scores
        .iter()
        .map(|s| {
            let (scores, moving) = runs
                .iter()
                .filter_map(|r| {
                    let i = r.scores.iter().position(|x| x.name == s.name)?;
                    Some((r.scores[i].clone(), r.moving[i]))
                })
                .unzip();
            MethodSpread::of(scores, moving)
        })
        .collect();
    let path_length_m = first.scores.first().map_or(0.0, |s| s.path_length_m);
    let advantage = worst_seed_advantage(runs, |r, i| Some(r.scores[i].median_error_m));
    let moving_advantage = worst_seed_advantage(runs, |r, i| r.moving[i]);
    let (dq, hq) = quantisation(robot)?;
    Ok(CaseResult {
        case: case.trajectory.into(),
        robot: robot.name.clone(),
        mode: mode.to_string(),
        path_length_m,
        paper: case.paper_figure.into(),
        seeds,
        phase: "random".into(),
        edges: EdgeErrors::IDEAL.to_string(),
        start: case.start,
        algorithms,
        exact_advantage_worst_seed: advantage,
        exact_moving_advantage_worst_seed: moving_advantage,
        placed_after_s: runs
            .iter()
            .filter_map(|r| r.placed_after_s)
            .max_by(f64::total_cmp),
        start_bound_m: dq,
        start_drift_bound_m: dq + path_length_m * hq,
        abrupt_start_bound_m: (case.start == Start::AbruptAfterRest)
            .then(|| abrupt_start_bound(robot, traj, path_length_m))
            .transpose()?,
        exact_vs_f64_m: runs.iter().map(|r| r.vs_f64.0).fold(0.0, f64::max),
        exact_vs_f64_rad: runs.iter().map(|r| r.vs_f64.1).fold(0.0, f64::max),
        skipped: first.skipped.clone(),
    })
}

/// Each seed against itself: the smallest ratio, over the seeds, of the best baseline's
/// `error` to `exact`'s. `None` unless on every seed both are known and the best baseline's
/// exceeds 10 µm (below that every method is near-exact and a ratio says nothing).
fn worst_seed_advantage(runs: &[&Run], error: impl Fn(&Run, usize) -> Option<f64>) -> Option<f64> {
    let mut worst: Option<f64> = None;
    for r in runs {
        let exact = r.scores.iter().position(|s| s.name == "exact")?;
        let mut best = f64::MAX;
        for (i, s) in r.scores.iter().enumerate() {
            if s.name != "exact" {
                best = best.min(error(r, i)?);
            }
        }
        if best <= 10e-6 {
            return None;
        }
        let ratio = best / error(r, exact)?.max(1e-12);
        worst = Some(worst.map_or(ratio, |w| w.min(ratio)));
    }
    worst
}

/// `(dq, hq)`: the largest body displacement (m) and turn (rad) that one count of every
/// wheel at once can stand for, Σ_j over the wheels (the pseudo-inverse times the travel per
/// count).
pub fn quantisation(robot: &Robot) -> Result<(f64, f64)> {
    let solver = robot_math::wheelset::WheelSolver::new(&robot.encoder_wheels())
        .map_err(|e| anyhow::anyhow!("robot {}: {e:?}", robot.name))?;
    let p = solver.pseudo_inverse();
    let (mut dq, mut hq) = (0.0, 0.0);
    for (j, e) in robot.encoders.iter().enumerate() {
        let k = e.metres_per_count;
        dq += (p[0][j] * k).abs().max((p[1][j] * k).abs());
        hq += (p[2][j] * k).abs();
    }
    Ok((dq, hq))
}

/// What placing the wheels together leaves after an abrupt start from rest: every wheel's
/// error is its own speed times one common time error δt, at most half the fastest wheel's
/// first interval (1 / (2 f_max), f_max its counts per second), so the pose is the robot's own
/// pose δt earlier or later: off by |v|·δt along the path and turned by |ω|·δt, which the
/// `path` after it carries as |ω|·δt·path. Bound: (|v| + |ω|·path)·δt, with the twist right
/// after the start.
pub fn abrupt_start_bound(robot: &Robot, traj: &dyn Trajectory, path: f64) -> Result<f64> {
    let mut breaks = traj.breakpoints();
    breaks.sort_by(f64::total_cmp);
    let moving = |w: robot_math::se2::Twist| w.vx != 0.0 || w.vy != 0.0 || w.omega != 0.0;
    let twist = std::iter::once(0.0)
        .chain(breaks)
        .map(|b| traj.twist(b + 1e-9))
        .find(|&w| moving(w))
        .context("the trajectory never moves")?;
    let f_max = robot
        .encoder_wheels()
        .iter()
        .zip(&robot.encoders)
        .map(|(w, e)| {
            let r = w.row();
            (r[0] * twist.vx + r[1] * twist.vy + r[2] * twist.omega).abs() / e.metres_per_count
        })
        .fold(0.0, f64::max);
    anyhow::ensure!(f_max > 0.0, "no encoder turns at the start");
    let dt = 0.5 / f_max;
    Ok((twist.vx.hypot(twist.vy) + twist.omega.abs() * path) * dt)
}
