//! The tick generator with seed 004's swivel carriage: wheel counts, the swivel angle, and
//! robot-math's carriage odometry on the generated streams.

mod common;

use common::*;
use host_bench::formats::robot::{AbsMeasures, Robot};
use host_bench::formats::tickstream::{Event, TickStream};
use host_bench::sim::generate::generate;
use host_bench::sim::trajectory::{self, build};
use robot_math::carriage::CarriageOdometry;
use robot_math::se2::{wrap_angle, Pose2};

/// Abs rows decoded to positions: (t_ns, position).
fn swivel_positions(r: &Robot, stream: &TickStream) -> Vec<(u64, u16)> {
    let a = r.absolute_encoder(AbsMeasures::CarriageSwivel).unwrap();
    stream
        .events
        .iter()
        .filter_map(|e| match *e {
            Event::Abs { t_ns, code, .. } => Some((t_ns, a.decode(code as u16))),
            _ => None,
        })
        .collect()
}

#[test]
fn carriage_on_a_straight_line_rolls_both_wheels_the_full_length() {
    // Moving straight ahead from rest the carriage stays aligned: both wheels roll the
    // 80 cm (from their random power-on phases), the swivel reads 0 throughout (raw 0xFF:
    // Gray, active-low).
    let r = robot("seed004.toml");
    let traj = build("seed000-line").unwrap();
    let stream = generate(&r, None, traj.as_ref(), &opts()).unwrap();
    let off = offsets(&r, &opts());
    for (i, enc) in r.encoders.iter().enumerate() {
        assert_count(
            net(&stream, i as u16),
            off[i] + trajectory::SEED000_LENGTH_M,
            enc.metres_per_count,
            &format!("encoder {i}"),
        );
    }
    assert!(stream
        .events
        .iter()
        .all(|e| !matches!(e, Event::Abs { code, .. } if *code != 0xFF)));
}

#[test]
fn carriage_swings_behind_a_sideways_motion() {
    // Translating at 45° with the body heading fixed, the caster swings from 0 to 45°:
    // position 32 of 256 at the end; it only ever swings one way.
    let r = robot("seed004.toml");
    let traj = build("seed002-diagonal").unwrap();
    let stream = generate(&r, None, traj.as_ref(), &opts()).unwrap();
    let pos = swivel_positions(&r, &stream);
    assert_eq!(pos[0].1, 0);
    assert_eq!(pos.last().unwrap().1, 32);
    assert!(pos.windows(2).all(|w| w[1].1 >= w[0].1));
    // The left wheel rolls less than the right while the carriage turns left.
    assert!(net(&stream, 0) < net(&stream, 1));
}

#[test]
fn carriage_odometry_on_generated_streams_follows_the_truth() {
    // Seed 004's arc odometry (robot-math) run on the generated counts and swivel codes lands
    // on the truth: it only can if the carriage in the generator obeys the same no-slip caster
    // geometry. Errors come from the 1.4° swivel quantisation (heading, not accumulating) and
    // the 33 µm counts.
    let r = robot("seed004.toml");
    let geom = r.carriage_geometry().unwrap();
    for name in [
        "seed002-circle",
        "seed002-square",
        "seed000-bezier-90deg",
        "seed001-figure-eight",
    ] {
        let traj = build(name).unwrap();
        let stream = generate(&r, None, traj.as_ref(), &opts()).unwrap();
        let a = r.absolute_encoder(AbsMeasures::CarriageSwivel).unwrap();
        let mut counts = [0i64; 2];
        let mut odo: Option<CarriageOdometry> = None;
        let mut last_truth = None;
        let (mut worst_xy, mut worst_theta) = (0.0f64, 0.0f64);
        for e in &stream.events {
            match *e {
                Event::Tick { encoder, step, .. } => counts[encoder as usize] += step as i64,
                Event::Truth {
                    t_ns,
                    x_m,
                    y_m,
                    theta_rad,
                } => last_truth = Some((t_ns, Pose2::new(x_m, y_m, theta_rad))),
                Event::Abs { t_ns, code, .. } => {
                    let code = a.decode(code as u16);
                    let o = odo.get_or_insert_with(|| {
                        CarriageOdometry::new(geom, traj.pose(0.0), counts, code)
                    });
                    let p = o.update(counts, code);
                    if let Some((tt, truth)) = last_truth {
                        if tt == t_ns {
                            worst_xy = worst_xy.max(p.distance_to(truth));
                            worst_theta = worst_theta.max(wrap_angle(p.theta - truth.theta).abs());
                        }
                    }
                }
            }
        }
        println!("{name}: worst position error {worst_xy:.6} m, heading {worst_theta:.5} rad");
        assert!(worst_xy < 3e-3, "{name}: position error {worst_xy} m");
        assert!(
            worst_theta <= geom.abs_step() / 2.0 + 1e-3,
            "{name}: heading error {worst_theta}"
        );
    }
}
