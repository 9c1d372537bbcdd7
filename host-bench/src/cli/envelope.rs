//! `host-bench envelope`: seed 003's speed envelope, model and measured, and its
//! arc-versus-line comparison (`eval::envelope`).

use std::io::Write;
use std::path::PathBuf;

use anyhow::{Context, Result};
use host_bench::eval::envelope::{self, Envelope};
use host_bench::formats::atomic::write_atomically;
use plotters::prelude::*;

pub fn run_envelope(json: bool, out: Option<PathBuf>) -> Result<()> {
    // Seed 003's wheels as the master drives them at power-on.
    let geometry = firmware_master::MasterConfig::DEFAULT.drive;
    let protocol::serial::DriveKind::Omni3 { d_um } = geometry.kind else {
        anyhow::bail!("the master's power-on drive is not seed 003's three omni wheels");
    };
    let e = envelope::run(d_um as f64 * 1e-6, geometry.v_max_um_s as f64 * 1e-6)?;
    if let Some(path) = &out {
        write_svg(&e, path)?;
        eprintln!("wrote {}", path.display());
    }
    if json {
        println!("{}", serde_json::to_string(&e)?);
        return Ok(());
    }
    let a = &e.arc_vs_line;
    println!(
        "three-omni drive, d = {} m, v_max = {} m/s (seed 003; \"measured\": driven flat out on \
         the simulated robot, each wheel held at its limit by the master's speed loop on seed \
         004's DC motors, timed from the ground truth)",
        e.wheel_distance_m, e.v_max_m_s
    );
    println!(
        "translation only: top {:.4} x v_max measured (model 2/sqrt3 = {:.4}), slowest \
         direction {:.4} x v_max (model 1)",
        e.translate_max_ratio, e.translate_max_ratio_model, e.translate_min_ratio
    );
    println!(
        "every wheel at v_max (seed 003 table 1, 6 cases): {:.4} x v_max measured (model 4/3 = \
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
         a chord of {:.2} d (seed 003 prints {:.3} rad and {:.3} d; its own equations give the \
         chord here)",
        a.arc_radius_m,
        a.crossover_angle_rad,
        a.crossover_chord_over_d,
        a.paper_crossover_angle_rad,
        a.paper_crossover_chord_over_d
    );
    Ok(())
}

/// The envelope as a polar picture: translation speed against direction (model line,
/// measured points) and the speed reached while spinning.
fn write_svg(e: &Envelope, path: &std::path::Path) -> Result<()> {
    let mut text = String::new();
    {
        let root = SVGBackend::with_string(&mut text, (800, 800)).into_drawing_area();
        root.fill(&WHITE)?;
        let r = 1.5 * e.v_max_m_s;
        let mut chart = ChartBuilder::on(&root)
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
        root.present()?;
    }
    write_atomically(path, |file| Ok(file.write_all(text.as_bytes())?))
        .with_context(|| format!("--out {}", path.display()))
}
