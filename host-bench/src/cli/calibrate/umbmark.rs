//! `calibrate --method umbmark`: the report, and the runs replayed on the corrected robot.

use anyhow::Result;
use host_bench::calibrate::runs::{self, RunEnd};
use host_bench::calibrate::{self, umbmark};
use host_bench::formats::robot::Robot;
use serde::Serialize;

use super::CalibrateArgs;

/// The calibration and what it does to the runs it came from.
#[derive(Serialize)]
struct Report {
    #[serde(flatten)]
    calibration: calibrate::UmbmarkCalibration,
    /// The tick-stream runs replayed on the corrected robot: each one's return error, and
    /// UMBmark's E_max,syst over them (none for emulated runs: drive those again).
    runs_after: Vec<umbmark::SquareRun>,
    e_max_syst_after_m: Option<f64>,
    out: Option<String>,
}

pub(super) fn run(
    a: &CalibrateArgs,
    text: &str,
    robot: &Robot,
    all: &[RunEnd],
) -> Result<super::Calibrated> {
    let c = calibrate::calibrate_umbmark(robot, all, super::noise(a)?)?;
    let u = &c.umbmark;
    let note = [
        format!(
            "Calibrated by host-bench calibrate (UMBmark) from {}: E_d = {:.6} (right wheel / left), E_b = {:.6} (true wheel base / nominal),",
            a.robot.display(),
            u.e_d,
            u.e_b
        ),
        format!(
            "from {} clockwise and {} counter-clockwise squares of {:.3} m (E_max,syst {:.2} mm before).",
            u.runs_cw,
            u.runs_ccw,
            u.side_m,
            u.e_max_syst_m * 1e3
        ),
    ];
    let fitted_text = Robot::with_encoders(text, &a.robot, &c.after, &note)?;
    let fitted = Robot::parse(&fitted_text, &a.robot)?;
    // The stream runs again, on the corrected robot.
    let pair = calibrate::wheel_pair(&fitted)?;
    let mut runs_after = Vec::new();
    for r in all.iter().filter(|r| r.stream.is_some()) {
        let path = r.stream.as_deref().expect("filtered");
        let again = runs::stream_run(path, &fitted, r.by_hand.then_some(r.measured_end))?;
        runs_after.push(calibrate::square_run(&fitted, pair, &again)?);
    }
    let e_max_syst_after_m = (!runs_after.is_empty())
        .then(|| umbmark::umbmark(&runs_after, pair.base_m).ok())
        .flatten()
        .map(|u| u.e_max_syst_m);
    let report = Report {
        calibration: c,
        runs_after,
        e_max_syst_after_m,
        out: a.out.as_ref().map(|p| p.display().to_string()),
    };
    Ok(super::Calibrated {
        json: serde_json::to_value(&report)?,
        text: text_report(&report),
        fitted: fitted_text,
    })
}

fn text_report(r: &Report) -> String {
    let c = &r.calibration;
    let u = &c.umbmark;
    let mm = |v: (f64, f64)| format!("({:+8.2}, {:+8.2}) mm", v.0 * 1e3, v.1 * 1e3);
    let mut s = format!(
        "UMBmark on robot {}: {} clockwise and {} counter-clockwise squares of {:.3} m, wheel base {:.4} m\n",
        c.robot, u.runs_cw, u.runs_ccw, u.side_m, c.pair.base_m
    );
    for (k, run) in c.runs.iter().enumerate() {
        let after = r
            .runs_after
            .iter()
            .find(|a| a.name == run.name)
            .map_or(String::new(), |a| format!("   after {}", mm(a.error_m)));
        let way = match run.direction {
            umbmark::Direction::Clockwise => "cw ",
            umbmark::Direction::CounterClockwise => "ccw",
        };
        // Steered by its odometry (UMBmark's way), or a true square the odometry followed.
        let kind = if run.driven_by_odometry {
            "steered"
        } else {
            "true sq"
        };
        s += &format!(
            "run {:<3} {way} {kind} {}{after}   {}\n",
            k + 1,
            mm(run.error_m),
            run.name
        );
    }
    s += &format!(
        "centroids       clockwise {}, counter-clockwise {}\n",
        mm(u.centroid_cw_m),
        mm(u.centroid_ccw_m)
    );
    s += &format!("E_max,syst      {:.2} mm", u.e_max_syst_m * 1e3);
    if let Some(after) = r.e_max_syst_after_m {
        s += &format!(
            " before, {:.2} mm after ({:.0}x less: these runs replayed on the corrected robot)",
            after * 1e3,
            u.e_max_syst_m / after.max(1e-12)
        );
    }
    s += "\n";
    s += &format!(
        "alpha, beta     {:+.4} deg a corner, {:+.4} deg a leg\n",
        u.alpha_rad.to_degrees(),
        u.beta_rad.to_degrees()
    );
    s += &format!(
        "E_d, E_b        {:.6} (right wheel's diameter over the left's), {:.6} (true wheel base over nominal); UMBmark's first-order formulas: {:.6}, {:.6}\n",
        u.e_d, u.e_b, u.e_d_first_order, u.e_b_first_order
    );
    if let Some(r) = &c.repeatability {
        s += &format!(
            "repeatability   each run left out in turn ({} fits): E_d {:.6} to {:.6}, E_b {:.6} to {:.6}\n",
            r.subsets, r.e_d_min, r.e_d_max, r.e_b_min, r.e_b_max
        );
    }
    let (l, rr) = (c.pair.left, c.pair.right);
    s += &format!(
        "corrected       left {:.4} um/count (was {:.4}), right {:.4} um/count (was {:.4}), wheel base {:.5} m (was {:.5})\n",
        c.after[l].metres_per_count * 1e6,
        c.before[l].metres_per_count * 1e6,
        c.after[rr].metres_per_count * 1e6,
        c.before[rr].metres_per_count * 1e6,
        c.pair.base_m * u.e_b,
        c.pair.base_m
    );
    if let Some(out) = &r.out {
        s += &format!("wrote {out}\n");
    }
    s
}
