//! `host-bench envelope`: seed 003's speed envelope, model and measured, and its
//! arc-versus-line comparison (`eval::envelope`).

use std::path::PathBuf;

use anyhow::{Context, Result};
use host_bench::eval::envelope::{self, ArcVsLine, Envelope};
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

pub fn run_envelope(json: bool, out: Option<PathBuf>) -> Result<()> {
    // Seed 003's wheels as the master drives them at power-on.
    let geometry = firmware_master::MasterConfig::DEFAULT.drive;
    let protocol::serial::DriveKind::Omni3 { d_um } = geometry.kind else {
        anyhow::bail!("the master's power-on drive is not the three omni wheels of Yan (2013)");
    };
    // The picture is SVG: a name that says otherwise would mislead whatever opens it.
    if let Some(path) = out
        .as_ref()
        .filter(|p| p.extension().is_none_or(|e| e != "svg"))
    {
        anyhow::bail!(
            "--out {}: the envelope is drawn as SVG; name a .svg file",
            path.display()
        );
    }
    if let Some(path) = &out {
        // The PNG beside it too (the same picture, for what does not open SVG).
        for p in [path.clone(), host_bench::eval::png::beside(path)] {
            host_bench::formats::atomic::check_output(&p)
                .with_context(|| format!("--out {}", path.display()))?;
        }
    }
    let e = envelope::run(d_um as f64 * 1e-6, geometry.v_max_um_s as f64 * 1e-6)?;
    if let Some(path) = &out {
        write_svg(&e, path)?;
        eprintln!(
            "wrote {} and {}",
            path.display(),
            host_bench::eval::png::beside(path).display()
        );
    }
    if json {
        println!("{}", serde_json::to_string(&e)?);
        return Ok(());
    }
    let a = &e.arc_vs_line;
    println!(
        "three-omni drive, d = {} m, v_max = {} m/s (Yan 2013; \"measured\": driven flat out on \
         the simulated robot, each wheel held at its limit by the master's speed loop on the DC \
         motors of the carriage robot of Xu, Zhu and Hu 2015, timed from the ground truth)",
        e.wheel_distance_m, e.v_max_m_s
    );
    println!(
        "translation only: top {:.4} x v_max measured (model 2/sqrt3 = {:.4}), slowest \
         direction {:.4} x v_max (model 1)",
        e.translate_max_ratio, e.translate_max_ratio_model, e.translate_min_ratio
    );
    println!(
        "every wheel at v_max (Yan 2013, table 1, 6 cases): {:.4} x v_max measured (model 4/3 = \
         {:.4}), spinning at {:.3} rad/s",
        e.spin_translate_max_ratio,
        e.spin_translate_max_ratio_model,
        e.spin_cases
            .iter()
            .map(|c| c.measured_spin_rad_s.abs())
            .fold(0.0, f64::max)
    );
    println!(
        "arc (radius 4d = {:.2} m, with spin) beats the line below a central angle of {:.3} rad, \
         a chord of {:.2} d (Yan 2013 prints {:.3} rad and {:.3} d; its own equations give the \
         chord here)",
        a.arc_radius_m,
        a.crossover_angle_rad,
        a.crossover_chord_over_d,
        a.paper_crossover_angle_rad,
        a.paper_crossover_chord_over_d
    );
    println!(
        "driven from rest on the simulated robot, A to B at each central angle (time to cross \
         B, model in brackets; the motors' spin-up adds the same to both):"
    );
    println!(
        "{:>9}  {:>8}  {:>17}  {:>17}  {:>10}  {:>9}",
        "angle rad", "chord m", "line s", "arc s", "arc saves", "miss mm"
    );
    for r in &a.driven {
        let g = &r.goal;
        println!(
            "{:>9.3}  {:>8.3}  {:>7.3} ({:>6.3})  {:>7.3} ({:>6.3})  {:>8.3} s  {:>9.2}",
            g.angle_rad,
            g.chord_m,
            g.line_measured_s,
            g.line_model_s,
            g.arc_measured_s,
            g.arc_model_s,
            g.arc_gain_measured_s,
            g.line_miss_m.max(g.arc_miss_m) * 1e3
        );
    }
    match a.measured_crossover_angle_rad {
        Some(x) => println!("measured crossover: {x:.3} rad"),
        None => println!("measured crossover: none over these goals"),
    }
    Ok(())
}

type Area<'a> = DrawingArea<SVGBackend<'a>, plotters::coord::Shift>;

/// Left: the envelope as a polar picture. Right: the arc-versus-line paths as driven.
fn write_svg(e: &Envelope, path: &std::path::Path) -> Result<()> {
    let mut text = String::new();
    {
        let root = SVGBackend::with_string(&mut text, (1600, 800)).into_drawing_area();
        root.fill(&WHITE)?;
        let (left, right) = root.split_horizontally(800);
        draw_polar(e, &left)?;
        draw_arc_vs_line(&e.arc_vs_line, &right)?;
        root.present()?;
    }
    host_bench::eval::png::write(path, &text).with_context(|| format!("--out {}", path.display()))
}

/// Translation speed against direction (model line, measured points) and the speed reached
/// while spinning.
fn draw_polar(e: &Envelope, area: &Area) -> Result<()> {
    {
        let r = 1.5 * e.v_max_m_s;
        let mut chart = ChartBuilder::on(area)
            .caption(
                "three-omni speed envelope (m/s, body frame)",
                ("sans-serif", 22),
            )
            .margin(20)
            .x_label_area_size(40)
            .y_label_area_size(50)
            .build_cartesian_2d(-r..r, -r..r)?;
        chart.configure_mesh().x_desc("v_x").y_desc("v_y").draw()?;
        let polar = |v: f64, deg: f64| {
            let a = deg.to_radians();
            (v * a.cos(), v * a.sin())
        };
        let model: Vec<_> = e
            .directions
            .iter()
            .chain(e.directions.first())
            .map(|d| polar(d.model_m_s, d.direction_deg))
            .collect();
        chart
            .draw_series(LineSeries::new(model, BLUE.stroke_width(2)))?
            .label("translation only, model (2/sqrt3 peaks)")
            .legend(|(x, y)| PathElement::new([(x, y), (x + 20, y)], BLUE));
        chart
            .draw_series(
                e.directions
                    .iter()
                    .step_by(5)
                    .map(|d| Circle::new(polar(d.measured_m_s, d.direction_deg), 3, RED.filled())),
            )?
            .label("translation only, measured")
            .legend(|(x, y)| Circle::new((x + 10, y), 3, RED.filled()));
        let spin = e
            .spin_cases
            .iter()
            .map(|c| c.measured_speed_m_s)
            .fold(0.0, f64::max);
        let ring: Vec<_> = (0..=360).map(|deg| polar(spin, deg as f64)).collect();
        chart
            .draw_series(LineSeries::new(ring, GREEN.stroke_width(2)))?
            .label("every wheel at v_max, spinning (4/3 v_max)")
            .legend(|(x, y)| PathElement::new([(x, y), (x + 20, y)], GREEN));
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()?;
    }
    Ok(())
}

/// The field: the arc every wheel at v_max draws from A and the straight runs to goals on
/// it, as driven; B marked with both times.
fn draw_arc_vs_line(a: &ArcVsLine, area: &Area) -> Result<()> {
    let Some(longest) = a.driven.last() else {
        return Ok(());
    };
    let (mut lo, mut hi) = ((0.0f64, 0.0f64), (0.0f64, 0.0f64));
    for (x, y) in longest
        .arc_path
        .iter()
        .chain(a.driven.iter().flat_map(|r| &r.line_path))
    {
        lo = (lo.0.min(*x), lo.1.min(*y));
        hi = (hi.0.max(*x), hi.1.max(*y));
    }
    // Equal scales on both axes, with a margin.
    let span = (hi.0 - lo.0).max(hi.1 - lo.1) * 1.15;
    let mid = ((lo.0 + hi.0) / 2.0, (lo.1 + hi.1) / 2.0);
    let mut chart = ChartBuilder::on(area)
        .caption(
            "arc with spin vs straight line, driven from rest (m)",
            ("sans-serif", 22),
        )
        .margin(20)
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d(
            mid.0 - span / 2.0..mid.0 + span / 2.0,
            mid.1 - span / 2.0..mid.1 + span / 2.0,
        )?;
    chart.configure_mesh().x_desc("x").y_desc("y").draw()?;
    chart
        .draw_series(LineSeries::new(
            longest.arc_path.clone(),
            BLUE.stroke_width(2),
        ))?
        .label("arc: every wheel at v_max, radius 4d")
        .legend(|(x, y)| PathElement::new([(x, y), (x + 20, y)], BLUE));
    for (i, r) in a.driven.iter().enumerate() {
        let series =
            chart.draw_series(LineSeries::new(r.line_path.clone(), RED.stroke_width(1)))?;
        if i == 0 {
            series
                .label("line: the best direction, 2/sqrt3 v_max")
                .legend(|(x, y)| PathElement::new([(x, y), (x + 20, y)], RED));
        }
        let g = &r.goal;
        let winner = if g.arc_gain_measured_s > 0.0 {
            "arc"
        } else {
            "line"
        };
        chart.draw_series(std::iter::once(Circle::new(r.b, 4, BLACK.filled())))?;
        // A goal right of the middle is labelled above and on its left, one left of it below
        // and on its right: no label runs off the plot or over its neighbour's.
        let (x, pos) = if r.b.0 > mid.0 {
            (r.b.0 - span * 0.01, Pos::new(HPos::Right, VPos::Bottom))
        } else {
            (r.b.0 + span * 0.01, Pos::new(HPos::Left, VPos::Top))
        };
        let style = TextStyle::from(("sans-serif", 13).into_font()).pos(pos);
        chart.draw_series(std::iter::once(Text::new(
            format!(
                "{:.2} rad: arc {:.2} s, line {:.2} s ({winner})",
                g.angle_rad, g.arc_measured_s, g.line_measured_s
            ),
            (x, r.b.1),
            style,
        )))?;
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::LowerLeft)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()?;
    Ok(())
}
