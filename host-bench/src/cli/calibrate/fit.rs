//! `calibrate --method fit`: the fit, its report, and every run (and the held-out ones)
//! replayed on the nominal and the corrected robot.

use std::collections::BTreeMap;

use anyhow::Result;
use host_bench::calibrate::fit::{self, Param};
use host_bench::calibrate::geometry;
use host_bench::calibrate::runs::{self, RunEnd};
use host_bench::formats::robot::Robot;
use robot_math::Pose2;
use serde::Serialize;

use super::CalibrateArgs;

/// One run's end error on the nominal robot and on the corrected one, metres and radians.
#[derive(Serialize)]
struct RunError {
    name: String,
    /// Whether it was one of the runs fitted (else held out, `--check`).
    fitted: bool,
    before_m: f64,
    after_m: f64,
    heading_before_rad: f64,
    heading_after_rad: f64,
}

#[derive(Serialize)]
struct Report {
    robot: String,
    method: &'static str,
    #[serde(flatten)]
    fit: fit::Fit,
    runs: Vec<RunError>,
    out: Option<String>,
}

pub(super) fn run(
    a: &CalibrateArgs,
    text: &str,
    robot: &Robot,
    measured: &BTreeMap<String, Pose2>,
    all: &[RunEnd],
) -> Result<super::Calibrated> {
    let noise = super::noise(a)?;
    host_bench::calibrate::check_wiring(robot, all)?;
    let binned = runs::binned(all)?;
    let nominal = geometry(robot);
    let f = fit::fit(robot, &nominal, &binned, noise)?;
    let note = [format!(
        "Calibrated by host-bench calibrate (fit) from {}: {} runs, residual RMS {:.3} before, {:.3} after (in measuring noise).",
        a.robot.display(),
        all.len(),
        f.rms_before,
        f.rms_after
    )];
    let fitted_text = Robot::with_encoders(text, &a.robot, &f.after, &note)?;
    let fitted = Robot::parse(&fitted_text, &a.robot)?;
    // Every run, fitted and held out, replayed per tick on both robots.
    let mut errors = Vec::new();
    let mut checks = Vec::new();
    for path in &a.check {
        checks.extend(runs::read_runs(path, robot, measured)?);
    }
    for (r, fitted_run) in all
        .iter()
        .map(|r| (r, true))
        .chain(checks.iter().map(|r| (r, false)))
    {
        let Some(path) = r.stream.as_deref() else {
            continue;
        };
        let again = runs::stream_run(path, &fitted, r.by_hand.then_some(r.measured_end))?;
        let heading =
            |e: &RunEnd| robot_math::se2::wrap_angle(e.measured_end.theta - e.odometry_end.theta);
        errors.push(RunError {
            name: r.name.clone(),
            fitted: fitted_run,
            before_m: r.measured_end.distance_to(r.odometry_end),
            after_m: again.measured_end.distance_to(again.odometry_end),
            heading_before_rad: heading(r),
            heading_after_rad: heading(&again),
        });
    }
    let report = Report {
        robot: robot.name.clone(),
        method: "fit",
        fit: f,
        runs: errors,
        out: a.out.as_ref().map(|p| p.display().to_string()),
    };
    Ok(super::Calibrated {
        json: serde_json::to_value(&report)?,
        text: text_report(&report),
        fitted: fitted_text,
    })
}

fn text_report(r: &Report) -> String {
    let f = &r.fit;
    let mut s = format!(
        "fit on robot {}: {} parameters, {} iterations in {:.3} s, residual RMS {:.3} before, {:.3} after (in measuring noise)\n",
        r.robot,
        f.params.len(),
        f.iterations,
        f.fit_seconds,
        f.rms_before,
        f.rms_after
    );
    s += "encoder     parameter          nominal          fitted           sigma      one run left out\n";
    for p in &f.params {
        let (unit, k) = match p.param {
            Param::Lever | Param::Spacing => ("mm", 1e3),
            Param::DiameterRatio | Param::SpacingRatio => ("", 1.0),
            Param::Direction => ("deg", 180.0 / std::f64::consts::PI),
            Param::Scale => ("um", 1e6),
        };
        let what = match p.param {
            // How far it moved across its rolling direction.
            Param::Lever => "lever shift",
            Param::Spacing => "half spacing",
            Param::DiameterRatio => "E_d",
            Param::SpacingRatio => "E_b",
            Param::Direction => "direction",
            Param::Scale => "travel/count",
        };
        let repeat = match (p.repeat_min, p.repeat_max) {
            (Some(lo), Some(hi)) => format!("{:.5} to {:.5}", lo * k, hi * k),
            _ => "-".to_string(),
        };
        s += &format!(
            "{:<11} {:<14} {:>12.5} {unit:<3} {:>12.5} {unit:<3} {:>10.5} {unit:<3}  {repeat}\n",
            p.encoder,
            what,
            p.before * k,
            p.after * k,
            p.sigma * k
        );
    }
    s += &format!("conditioning    {:.3e} (largest over smallest singular value, each parameter in its own scale)\n", f.condition);
    if f.subsets > 0 {
        s += &format!(
            "repeatability   {} fits with one run left out, in {:.3} s (the right-hand column)\n",
            f.subsets, f.subsets_seconds
        );
    }
    if f.unresolved.is_empty() {
        s += "unresolved      none: the runs tell every parameter apart\n";
    } else {
        for u in &f.unresolved {
            let parts: Vec<String> = u.iter().map(|(n, w)| format!("{w:+.2} {n}")).collect();
            s += &format!("unresolved      {}\n", parts.join(", "));
        }
        for a in &f.advice {
            s += &format!("to resolve      {a}\n");
        }
    }
    for e in &r.runs {
        s += &format!(
            "{} {:>10.3} mm {:>+9.4} deg on the nominal robot, {:>8.3} mm {:>+9.4} deg corrected   {}\n",
            if e.fitted { "fitted " } else { "checked" },
            e.before_m * 1e3,
            e.heading_before_rad.to_degrees(),
            e.after_m * 1e3,
            e.heading_after_rad.to_degrees(),
            e.name
        );
    }
    if let Some(out) = &r.out {
        s += &format!("wrote {out}\n");
    }
    s
}
