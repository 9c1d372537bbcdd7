//! `host-bench pursuit-sweep`: seed 004's pursuit period, emulated and from the paper's own
//! equations (`eval::pursuit_sweep`), as a table and a plot.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use host_bench::eval::pursuit_sweep::{run, Sweep, PERIODS_S};
use plotters::prelude::*;

/// The periods whose paths the plot draws.
const DRAWN_S: [f64; 3] = [0.4, 1.0, 1.5];

pub fn run_pursuit_sweep(json: bool, duration: f64, out: Option<PathBuf>) -> Result<()> {
    anyhow::ensure!(
        duration.is_finite() && (10.0..=3600.0).contains(&duration),
        "--duration must be 10 s to 3600 s (the target stops after 7.1 s; the hold is scored \
         from 1 s later)"
    );
    // Checked before the sweep (minutes at a long --duration), not after it.
    if let Some(path) = &out {
        anyhow::ensure!(
            path.extension().is_some_and(|e| e == "svg"),
            "--out {}: the plot is drawn as SVG; name a .svg file",
            path.display()
        );
        // The PNG beside it too (the same picture, for what does not open SVG).
        for p in [path.clone(), host_bench::eval::png::beside(path)] {
            host_bench::formats::atomic::check_output(&p)
                .with_context(|| format!("--out {}", path.display()))?;
        }
    }
    let sweep = run(&PERIODS_S, duration)?;
    if let Some(path) = &out {
        write_svg(&sweep, path)?;
        eprintln!(
            "wrote {} and {}",
            path.display(),
            host_bench::eval::png::beside(path).display()
        );
    }
    if json {
        println!("{}", serde_json::json!({ "rows": sweep.rows }));
        return Ok(());
    }
    println!(
        "seed004-pursuit, {duration} s. While the target moves: jitter = turning of the \
         direction of travel (rad/s), tracking = RMS distance to the target. Once it stopped \
         (+1 s): distance RMS / max and turning. paper: the equations (9)-(14) of Xu, Zhu and \
         Hu (2015) for the same period (a point stepping V_t·tau, no dynamics)."
    );
    println!(
        "{:>5}  {:>7}  {:>11}  {:>11}  {:>11}  {:>8}  {:>7} | {:>7}  {:>11}  {:>11}  law",
        "tau s",
        "jitter",
        "tracking m",
        "hold rms mm",
        "hold max mm",
        "hold rad/s",
        "path m",
        "paper jitter",
        "paper track m",
        "paper hold max mm"
    );
    let opt = |v: Option<f64>, scale: f64, prec: usize| {
        v.map_or("-".to_string(), |v| format!("{:.*}", prec, v * scale))
    };
    for r in &sweep.rows {
        println!(
            "{:>5.1}  {:>7.3}  {:>11.3}  {:>11.1}  {:>11.1}  {:>8.2}  {:>7.3} | {:>12}  {:>13}  {:>17}  {}",
            r.tau_s,
            r.jitter,
            r.tracking_rms_m,
            r.hold_rms_m * 1e3,
            r.hold_max_m * 1e3,
            r.hold_jitter,
            r.path_length_m,
            opt(r.paper_jitter, 1.0, 3),
            opt(r.paper_tracking_rms_m, 1.0, 3),
            opt(r.paper_hold_max_m, 1e3, 1),
            r.law
        );
    }
    Ok(())
}

/// Left: the field, the target's line and the paths of a few periods (emulated solid, the
/// paper's polyline thin). Right: the overshoot at the stopped target and the turning while
/// it moves, against τ, emulated and paper.
fn write_svg(sweep: &Sweep, path: &Path) -> Result<()> {
    let mut text = String::new();
    {
        let root = SVGBackend::with_string(&mut text, (1400, 700)).into_drawing_area();
        root.fill(&WHITE)?;
        let (left, right) = root.split_horizontally(700);
        draw_paths(sweep, &left)?;
        let (top, bottom) = right.split_vertically(350);
        let periods: Vec<_> = sweep.rows.iter().filter(|r| r.tau_s > 0.0).collect();
        let series = |f: &dyn Fn(&host_bench::eval::pursuit_sweep::Row) -> Option<f64>| {
            periods
                .iter()
                .filter_map(|r| f(r).map(|v| (r.tau_s, v)))
                .collect::<Vec<_>>()
        };
        let hold = series(&|r| Some(r.hold_max_m));
        let paper_hold = series(&|r| r.paper_hold_max_m);
        let jitter = series(&|r| Some(r.jitter));
        let paper_jitter = series(&|r| r.paper_jitter);
        against_tau(
            &top,
            "overshoot at the stopped target (max distance, m)",
            &hold,
            &paper_hold,
            Some(sweep.rows[0].hold_max_m),
        )?;
        against_tau(
            &bottom,
            "turning while the target moves (rad/s)",
            &jitter,
            &paper_jitter,
            Some(sweep.rows[0].jitter),
        )?;
        root.present()?;
    }
    host_bench::eval::png::write(path, &text).with_context(|| format!("--out {}", path.display()))
}

fn draw_paths(sweep: &Sweep, area: &DrawingArea<SVGBackend, plotters::coord::Shift>) -> Result<()> {
    let mut chart = ChartBuilder::on(area)
        .caption(
            "Euler pursuit (Xu, Zhu and Hu 2015): paths (m)",
            ("sans-serif", 20),
        )
        .margin(15)
        .x_label_area_size(35)
        .y_label_area_size(45)
        .build_cartesian_2d(-0.5..3.5, -0.5..3.5)?;
    chart.configure_mesh().x_desc("x").y_desc("y").draw()?;
    chart
        .draw_series(LineSeries::new(
            sweep.target.to_vec(),
            BLACK.stroke_width(3),
        ))?
        .label("target's line (stops at the end)")
        .legend(|(x, y)| PathElement::new([(x, y), (x + 20, y)], BLACK));
    let colours = [BLUE, RED, MAGENTA];
    for (i, tau) in DRAWN_S.iter().enumerate() {
        let Some(k) = sweep.rows.iter().position(|r| (r.tau_s - tau).abs() < 1e-9) else {
            continue;
        };
        let c = colours[i % colours.len()];
        let (emulated, paper) = &sweep.paths[k];
        chart
            .draw_series(LineSeries::new(emulated.clone(), c.stroke_width(2)))?
            .label(format!("tau {tau} s, emulated"))
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], c.stroke_width(2)));
        chart
            .draw_series(LineSeries::new(paper.clone(), c.mix(0.5).stroke_width(1)))?
            .label(format!("tau {tau} s, paper's equations"))
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], c.mix(0.5)));
    }
    if let Some((ours, _)) = sweep.paths.first().filter(|_| sweep.rows[0].tau_s == 0.0) {
        chart
            .draw_series(LineSeries::new(ours.clone(), GREEN.stroke_width(2)))?
            .label("ours (tau 0)")
            .legend(|(x, y)| PathElement::new([(x, y), (x + 20, y)], GREEN));
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::LowerRight)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()?;
    Ok(())
}

fn against_tau(
    area: &DrawingArea<SVGBackend, plotters::coord::Shift>,
    caption: &str,
    emulated: &[(f64, f64)],
    paper: &[(f64, f64)],
    ours: Option<f64>,
) -> Result<()> {
    let top = emulated
        .iter()
        .chain(paper)
        .map(|p| p.1)
        .chain(ours)
        .fold(0.0, f64::max)
        * 1.15;
    let mut chart = ChartBuilder::on(area)
        .caption(caption, ("sans-serif", 18))
        .margin(15)
        .x_label_area_size(35)
        .y_label_area_size(55)
        .build_cartesian_2d(0.0..1.6, 0.0..top.max(1e-3))?;
    chart.configure_mesh().x_desc("tau (s)").draw()?;
    chart
        .draw_series(LineSeries::new(emulated.to_vec(), BLUE.stroke_width(2)))?
        .label("emulated")
        .legend(|(x, y)| PathElement::new([(x, y), (x + 20, y)], BLUE));
    chart.draw_series(emulated.iter().map(|&p| Circle::new(p, 3, BLUE.filled())))?;
    chart
        .draw_series(LineSeries::new(paper.to_vec(), RED.stroke_width(1)))?
        .label("paper's equations")
        .legend(|(x, y)| PathElement::new([(x, y), (x + 20, y)], RED));
    if let Some(v) = ours {
        chart
            .draw_series(std::iter::once(Cross::new(
                (0.0, v),
                6,
                GREEN.stroke_width(2),
            )))?
            .label("ours (tau 0)")
            .legend(|(x, y)| Cross::new((x + 10, y), 5, GREEN));
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperLeft)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()?;
    Ok(())
}
