//! `host-bench accuracy`: every seed case, every sensor mode, all four odometry methods, side
//! by side, with the paper's reported figure beside each case (SPEC §5, §6).
//!
//! Each case generates the exact tick stream of a seed robot along a seed trajectory
//! ([`crate::sim::generate`]) in memory and replays it ([`crate::eval::replay`]) with ideal encoders, in
//! tick-timestamp mode and as counters sampled at 1 kHz and 10 kHz. The robot files are built
//! into the binary, so the command runs from anywhere.

use std::path::Path;

use anyhow::{Context, Result};
use serde::Serialize;

use crate::eval::replay::{self, Mode, Score};
use crate::formats::robot::Robot;
use crate::sim::generate::{generate, GenerateOptions};
use crate::sim::trajectory;

/// A seed case: a trajectory, the robot that drives it, and what the paper reports.
#[derive(Clone, Copy, Debug)]
pub struct Case {
    pub trajectory: &'static str,
    /// File name in `robots/`.
    pub robot: &'static str,
    pub paper_figure: &'static str,
}

const SEED000: &str = "seed 000: <= 1.5 mm (0.18 %) on 80 cm paths, Δ 0.1-0.8 mm";

/// Every case of SPEC §5. Holonomic paths go to seed 000's omni triangle, the others to seed
/// 001's differential drive (UMBmark is a differential-drive benchmark).
pub fn cases() -> Vec<Case> {
    let c = |trajectory, robot, paper_figure| Case {
        trajectory,
        robot,
        paper_figure,
    };
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
            "seed 001: 1 cm in x, 1 cm in y",
        ),
        c(
            "seed001-straight-40m",
            "seed001.toml",
            "seed 001: 1 cm in x, 0 in y",
        ),
        c(
            "seed001-curve",
            "seed001.toml",
            "seed 001: 2.5 cm in x, 1 cm in y",
        ),
        c(
            "seed002-square",
            "seed000-0.1mm.toml",
            "seed 002: tracking only, no odometry figure",
        ),
        c(
            "seed002-diagonal",
            "seed000-0.1mm.toml",
            "seed 002: tracking only, no odometry figure",
        ),
        c(
            "seed002-circle",
            "seed001.toml",
            "seed 002: tracking only, no odometry figure",
        ),
        c(
            "umbmark-cw",
            "seed001.toml",
            "UMBmark: no figure in the seeds",
        ),
        c(
            "umbmark-ccw",
            "seed001.toml",
            "UMBmark: no figure in the seeds",
        ),
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
        "seed000-0.1mm.toml" => include_str!("../../../robots/seed000-0.1mm.toml"),
        "seed000-0.4mm.toml" => include_str!("../../../robots/seed000-0.4mm.toml"),
        "seed000-0.8mm.toml" => include_str!("../../../robots/seed000-0.8mm.toml"),
        "seed001.toml" => include_str!("../../../robots/seed001.toml"),
        _ => return None,
    })
}

/// One case in one mode.
#[derive(Clone, Debug, Serialize)]
pub struct CaseResult {
    pub case: String,
    pub robot: String,
    pub mode: String,
    pub path_length_m: f64,
    pub paper: String,
    pub algorithms: Vec<Score>,
    /// Largest distance and heading difference between fixed-point `exact` and its f64 twin
    /// over every truth row (the documented tolerance is 1 µm and 1e-6 rad).
    pub exact_vs_f64_m: f64,
    pub exact_vs_f64_rad: f64,
    /// Methods that cannot run here (e.g. `timing` on sampled counts), with the reason.
    pub skipped: Vec<Skipped>,
}

#[derive(Clone, Debug, Serialize)]
pub struct Skipped {
    pub name: String,
    pub reason: String,
}

/// Run every case in every mode. `progress` is called after each (case, mode) with a label.
pub fn run(mut progress: impl FnMut(&str)) -> Result<Vec<CaseResult>> {
    let mut results = Vec::new();
    for case in cases() {
        let text =
            robot_text(case.robot).with_context(|| format!("no built-in robot {}", case.robot))?;
        let robot = Robot::parse(text, Path::new(&format!("robots/{}", case.robot)))?;
        let traj = trajectory::build(case.trajectory)
            .with_context(|| format!("unknown trajectory {}", case.trajectory))?;
        let stream = generate(
            &robot,
            Some(&format!("../robots/{}", case.robot)),
            traj.as_ref(),
            &GenerateOptions::default(),
        )
        .with_context(|| format!("generating {} for {}", case.trajectory, robot.name))?;
        for mode in modes() {
            let mut algorithms = Vec::new();
            let mut skipped = Vec::new();
            for name in replay::ALGORITHMS {
                match replay::replay(&robot, &stream, name, mode) {
                    Ok(s) => algorithms.push(s),
                    Err(e) => skipped.push(Skipped {
                        name: name.to_string(),
                        reason: format!("{e:#}"),
                    }),
                }
            }
            let path_length_m = algorithms.first().map_or(0.0, |s| s.path_length_m);
            let (mut exact_vs_f64_m, mut exact_vs_f64_rad) = (0.0f64, 0.0f64);
            if let Some(fixed) = algorithms.iter().find(|s| s.name == "exact") {
                let twin = replay::replay(&robot, &stream, replay::ORACLE, mode)?;
                for ((_, a, _), (_, b, _)) in fixed.track.iter().zip(&twin.track) {
                    exact_vs_f64_m = exact_vs_f64_m.max(a.distance_to(*b));
                    exact_vs_f64_rad =
                        exact_vs_f64_rad.max(robot_math::se2::wrap_angle(a.theta - b.theta).abs());
                }
            }
            results.push(CaseResult {
                case: case.trajectory.into(),
                robot: robot.name.clone(),
                mode: mode.to_string(),
                path_length_m,
                exact_vs_f64_m,
                exact_vs_f64_rad,
                paper: case.paper_figure.into(),
                algorithms,
                skipped,
            });
            progress(&format!("{} on {} ({mode})", case.trajectory, robot.name));
        }
    }
    Ok(results)
}

/// The side-by-side table.
pub fn table(results: &[CaseResult]) -> String {
    let mut out = String::new();
    let names = replay::ALGORITHMS;
    out.push_str(&format!(
        "{:<24} {:<14} {:<16} {:>8}",
        "case", "robot", "mode", "path m"
    ));
    for n in names {
        out.push_str(&format!(" {:>19}", format!("{n} final/max mm")));
    }
    out.push_str("  paper\n");
    for r in results {
        out.push_str(&format!(
            "{:<24} {:<14} {:<16} {:>8.3}",
            r.case, r.robot, r.mode, r.path_length_m
        ));
        for n in names {
            let cell = match r.algorithms.iter().find(|s| s.name == *n) {
                Some(s) => format!("{:.4}/{:.4}", s.final_error_m * 1e3, s.max_error_m * 1e3),
                None => "-".into(),
            };
            out.push_str(&format!(" {cell:>19}"));
        }
        out.push_str(&format!(
            "  {}\n",
            if r.mode == "timestamps" {
                r.paper.as_str()
            } else {
                ""
            }
        ));
    }
    out.push_str(&summary(results));
    out
}

/// For each tick-timestamp row where the best baseline's median error exceeds 10 µm (below
/// that every method is near-exact and there is nothing to separate): the row and how many
/// times `exact`'s median error is below that baseline's.
pub fn median_advantage(results: &[CaseResult]) -> Vec<(&CaseResult, f64)> {
    results
        .iter()
        .filter(|r| r.mode == "timestamps")
        .filter_map(|r| {
            let exact = r.algorithms.iter().find(|s| s.name == "exact")?;
            let best = r
                .algorithms
                .iter()
                .filter(|s| s.name != "exact")
                .map(|s| s.median_error_m)
                .fold(f64::MAX, f64::min);
            (best > 10e-6).then(|| (r, best / exact.median_error_m.max(1e-12)))
        })
        .collect()
}

/// The headline comparisons, from the tick-timestamp rows.
pub fn summary(results: &[CaseResult]) -> String {
    let ts: Vec<&CaseResult> = results.iter().filter(|r| r.mode == "timestamps").collect();
    let exact = |r: &CaseResult| r.algorithms.iter().find(|s| s.name == "exact").cloned();
    let worst_share = ts
        .iter()
        .filter_map(|r| exact(r).map(|e| e.final_error_m / r.path_length_m))
        .fold(0.0f64, f64::max);
    let mut ratios: Vec<f64> = median_advantage(results)
        .into_iter()
        .map(|(_, ratio)| ratio)
        .collect();
    ratios.sort_by(f64::total_cmp);
    let (dev_m, dev_rad) = results.iter().fold((0.0f64, 0.0f64), |(m, r), c| {
        (m.max(c.exact_vs_f64_m), r.max(c.exact_vs_f64_rad))
    });
    let mut out = format!(
        "\nexact, tick time stamps: final error at most {:.4} % of the path on every case\n\
         exact, fixed point vs its f64 twin: at most {:.3} um and {:.1e} rad apart, every case and mode\n",
        worst_share * 100.0,
        dev_m * 1e6,
        dev_rad
    );
    if let (Some(lo), Some(mid)) = (ratios.first(), ratios.get(ratios.len() / 2)) {
        out.push_str(&format!(
            "exact, tick time stamps: median error {lo:.0}x (worst case) to {mid:.0}x (median case) below the best \
             baseline, on the {} cases where that baseline's median exceeds 10 um\n",
            ratios.len()
        ));
    }
    out
}
