//! `emulate`'s sweep mode: N runs with consecutive seeds and the spread of their errors.

use host_bench::sim::emulator::{self, Scenario};

/// Most runs in one sweep: a spread over 1000 seeds has its p95 to 0.1 %; more is work a
/// typo asked for.
pub const MAX_SWEEP_RUNS: u32 = 1000;

pub fn run_sweep(
    scenario: &Scenario,
    opts: &emulator::Options,
    n: u32,
    json: bool,
) -> anyhow::Result<()> {
    anyhow::ensure!(
        (1..=MAX_SWEEP_RUNS).contains(&n),
        "--sweep must be 1 to {MAX_SWEEP_RUNS} runs, got {n}"
    );
    anyhow::ensure!(
        n as f64 * opts.duration <= emulator::MAX_DURATION_S,
        "--sweep {n} runs of {} s: at most {} simulated seconds in all (a week)",
        opts.duration,
        emulator::MAX_DURATION_S
    );
    anyhow::ensure!(
        opts.seed.checked_add(n as u64 - 1).is_some(),
        "--seed {} --sweep {n}: the last seed would pass 2^64 - 1",
        opts.seed
    );
    let mut summaries = Vec::new();
    for k in 0..n as u64 {
        let mut o = opts.clone();
        o.seed = opts.seed + k;
        let s = emulator::run(scenario, &o)?.summary;
        if !json {
            println!(
                "seed {:>4}: final error {:7.3} mm, max {:7.3} mm, heading {:+7.3} deg, encoder phases {:.2}/{:.2}, {:5.1} mm from goal, rejected frames {}{}",
                s.seed,
                s.final_error_m * 1e3,
                s.max_error_m * 1e3,
                s.final_heading_error_rad.to_degrees(),
                s.encoder_phase[0],
                s.encoder_phase[1],
                s.distance_to_goal_m * 1e3,
                s.spi_frames_rejected + s.serial_frames_rejected,
                match (s.tracking_rms_m, s.tracking_max_m) {
                    (Some(r), Some(m)) =>
                        format!(", tracking RMS {:.2} / max {:.2} mm", r * 1e3, m * 1e3),
                    _ => String::new(),
                }
            );
        }
        summaries.push(s);
    }
    let stat = |f: fn(&emulator::Summary) -> f64| {
        let mut v: Vec<f64> = summaries.iter().map(f).collect();
        v.sort_by(f64::total_cmp);
        (v[0], v[v.len() / 2], v[v.len() - 1])
    };
    let fe = stat(|s| s.final_error_m);
    let me = stat(|s| s.max_error_m);
    let he = stat(|s| s.final_heading_error_rad.abs());
    // Seed 002's tracking error, for a tracked path (NaN otherwise; then left out).
    let tracking = summaries[0].tracking_rms_m.is_some();
    let tr = stat(|s| s.tracking_rms_m.unwrap_or(f64::NAN));
    let tm = stat(|s| s.tracking_max_m.unwrap_or(f64::NAN));
    if json {
        let spread = |(min, median, max): (f64, f64, f64)| serde_json::json!({"min": min, "median": median, "max": max});
        println!(
            "{}",
            serde_json::json!({
                "scenario": scenario.name,
                "runs": summaries,
                "final_error_m": spread(fe),
                "max_error_m": spread(me),
                "abs_final_heading_error_rad": spread(he),
                "tracking_rms_m": tracking.then(|| spread(tr)),
                "tracking_max_m": tracking.then(|| spread(tm)),
            })
        );
    } else {
        println!(
            "{} runs of {}: final error min {:.3} / median {:.3} / max {:.3} mm; max error up to {:.3} mm; |heading error| up to {:.3} deg",
            n,
            scenario.name,
            fe.0 * 1e3,
            fe.1 * 1e3,
            fe.2 * 1e3,
            me.2 * 1e3,
            he.2.to_degrees()
        );
        if tracking {
            println!(
                "tracked point vs the path (from 1 s on): RMS median {:.2} / max {:.2} mm; max error median {:.2} / max {:.2} mm",
                tr.1 * 1e3,
                tr.2 * 1e3,
                tm.1 * 1e3,
                tm.2 * 1e3
            );
        }
    }
    let idle: Vec<u64> = summaries
        .iter()
        .filter(|s| emulator::nothing_scored(s).is_some())
        .map(|s| s.seed)
        .collect();
    anyhow::ensure!(
        idle.is_empty(),
        "nothing scored in {} of the {n} runs (seeds {:?}): the robot did not move",
        idle.len(),
        idle
    );
    Ok(())
}
