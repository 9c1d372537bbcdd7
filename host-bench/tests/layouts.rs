//! Our robot layouts beyond the seeds' (robots/skewed3.toml, omni4-ls.toml, diff-wide.toml):
//! they load as written, and generate streams whose counts match the rolled distances.

mod common;

use std::path::Path;

use common::*;
use host_bench::formats::robot::Robot;
use host_bench::sim::generate::{check_drive, generate, is_differential};
use host_bench::sim::trajectory::{build, named};
use robot_math::wheelset::{SolveMode, WheelSolver};

#[test]
fn our_layouts_load_with_their_geometry() {
    let skewed = robot("skewed3.toml");
    assert_eq!(skewed.encoders.len(), 3);
    assert!(skewed.encoders.iter().all(|e| e.metres_per_count == 0.0001));
    // Not 120° apart, not tangent: the polar angles' gaps and the rolling directions' offsets
    // from the tangent are all different.
    let polar: Vec<f64> = skewed
        .encoders
        .iter()
        .map(|e| e.wheel.y.atan2(e.wheel.x).to_degrees())
        .collect();
    let gaps = [
        polar[1] - polar[0],
        360.0 + polar[2] - polar[1],
        polar[0] - polar[2],
    ];
    let widest = gaps.iter().cloned().fold(0.0, f64::max);
    let narrowest = gaps.iter().cloned().fold(360.0, f64::min);
    assert!(widest - narrowest > 30.0, "{gaps:?}");
    for e in &skewed.encoders {
        let w = e.wheel;
        let radius = w.x.hypot(w.y);
        let tangential = (w.x * w.uy - w.y * w.ux) / radius; // cos of the offset
        assert!(tangential < 0.97, "{}: cos {tangential}", e.name);
    }
    let omni4 = robot("omni4-ls.toml");
    assert_eq!(omni4.encoders.len(), 4);
    assert!(omni4.encoders.iter().all(|e| e.metres_per_count == 0.0002));
    let diff = robot("diff-wide.toml");
    assert!(diff.encoders.iter().all(|e| e.metres_per_count == 0.00025));
    let (l, r) = (diff.encoders[0].wheel, diff.encoders[1].wheel);
    assert!(((l.y - r.y) - 0.42).abs() < 1e-12, "track");
    assert!(
        ((l.y + r.y) / 2.0 - 0.03).abs() < 1e-12,
        "reference point off the midpoint"
    );

    assert!(!is_differential(&skewed) && !is_differential(&omni4) && is_differential(&diff));
    let mode = |r: &Robot| WheelSolver::new(&r.encoder_wheels()).unwrap().mode();
    assert_eq!(mode(&skewed), SolveMode::Exact);
    assert_eq!(mode(&omni4), SolveMode::LeastSquares);
    assert_eq!(mode(&diff), SolveMode::Axle);
}

#[test]
fn each_layout_generates_streams_that_count_what_the_wheels_roll() {
    for (file, trajectories) in [
        (
            "skewed3.toml",
            &["twist-sideways-spin", "seed000-bezier-90deg"][..],
        ),
        (
            "omni4-ls.toml",
            &["twist-sideways-spin", "seed000-bezier-90deg"][..],
        ),
        ("diff-wide.toml", &["twist-arcs", "seed002-circle"][..]),
    ] {
        let r = robot(file);
        let off = offsets(&r, &opts());
        for name in trajectories {
            assert!(
                check_drive(&r, named(name).unwrap().drive).is_ok(),
                "{file} {name}"
            );
            let traj = build(name).unwrap();
            let stream = generate(
                &r,
                Some(&format!("../robots/{file}")),
                traj.as_ref(),
                &opts(),
            )
            .unwrap();
            assert!(stream.events.windows(2).all(|w| w[0].t_ns() <= w[1].t_ns()));
            for (i, enc) in r.encoders.iter().enumerate() {
                let rolled = integral(traj.as_ref(), |tw| enc.wheel.rolling_speed(tw));
                assert!(rolled.abs() > 0.05, "{file} {name} encoder {i}: {rolled} m");
                assert_count(
                    net(&stream, i as u16),
                    off[i] + rolled,
                    enc.metres_per_count,
                    &format!("{file} {name} encoder {i}"),
                );
            }
        }
    }
    // The differential layout refuses a holonomic trajectory.
    let diff = robot("diff-wide.toml");
    assert!(check_drive(&diff, named("twist-sideways-spin").unwrap().drive).is_err());
}

#[test]
fn an_axle_off_the_reference_point_cannot_follow_a_turn_without_sideways_velocity() {
    // diff-wide with its axle 3 cm behind the reference point: turning with v_y = 0 at the
    // reference point would slide the axle sideways (at 0.03·ω), which its wheels cannot do,
    // so generate refuses it; straight ahead is fine.
    let text = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../robots/diff-wide.toml"),
    )
    .unwrap()
    .replace("x_m = 0.0", "x_m = -0.03");
    let behind = Robot::parse(&text, Path::new("behind.toml")).unwrap();
    assert!(behind.encoders.iter().all(|e| e.wheel.x == -0.03));
    let e = generate(
        &behind,
        None,
        build("twist-arcs").unwrap().as_ref(),
        &opts(),
    )
    .unwrap_err();
    let msg = e.to_string();
    assert!(msg.contains("axle") && msg.contains("sideways"), "{msg}");
    assert!(generate(
        &behind,
        None,
        build("seed000-line").unwrap().as_ref(),
        &opts()
    )
    .is_ok());
}
