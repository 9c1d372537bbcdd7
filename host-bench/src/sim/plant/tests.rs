//! The plant against its own integrator and the slave's: steps, the angles it hands on, a
//! parked robot, edge timing (ideal and uneven), the carriage.

use super::*;
use robot_math::carriage::{CarriageGeometry, CarriageOdometry};
use std::f64::consts::PI;

fn omni() -> robot_math::omni3::Omni3 {
    robot_math::omni3::Omni3::new(0.22, 1.0).unwrap()
}

pub(super) fn cfg() -> PlantConfig {
    PlantConfig {
        drive: DriveKinematics::Omni3(omni()),
        motor: DcMotor::SEED_004.frictionless(),
        motor_metres_per_count: Some(1e-4),
        sensors: MeasuringSensors::SEED_004,
    }
}

fn duty_for(_: &Plant, t: Twist) -> [i16; 3] {
    // Open loop: the motor constant alone (the tests below score the sensors, not speed).
    let full = DcMotor::SEED_004.frictionless().steady_speed(1.0);
    omni()
        .wheel_speeds(t)
        .map(|w| (w / full * 1000.0).round() as i16)
}

#[test]
fn the_angles_a_step_ends_with_stay_the_sines_and_cosines_of_its_headings() {
    // Turning both ways for 5000 steps (the body and the swinging carriage): the angles
    // each step hands the next, turned from its start's, stay within a few last bits of
    // `sin_cos` of the headings. Never computed in full, the turns' roundings drift past
    // that (to 6·10^-15 here).
    let mut p = Plant::new(cfg(), Pose2::default(), PI / 2.0, [0.0; 2]);
    let mut worst = 0.0f64;
    for k in 0..5000 {
        let t = k as f64 * 1e-3;
        // Below a milliradian a step, where the turns are series, not `sin_cos`.
        let spin = if (k / 700) % 2 == 0 { 0.8 } else { -0.6 };
        p.set_duty(duty_for(&p, Twist::new(0.3, 0.2 * (3.0 * t).sin(), spin)));
        p.advance(1e-3, 1e-3);
        let full = Trig::of(&p.cfg, &p.state);
        for (a, b) in [
            (p.trig.theta.0, full.theta.0),
            (p.trig.theta.1, full.theta.1),
            (p.trig.phi.0, full.phi.0),
            (p.trig.phi.1, full.phi.1),
        ] {
            worst = worst.max((a - b).abs());
        }
    }
    assert!(worst < 2e-15, "{worst}");
}

#[test]
fn a_parked_robot_steps_exactly_as_the_integrator_would_step_it() {
    // Parked at the start, held by the stiction at a small duty, driven off, coasting to a
    // stop against the friction, parked, driven off again and parked: the plant that skips
    // the parked steps and one that integrates every step agree to the bit at every step,
    // in the state, the angles, the positions, the edges, the speeds, the path and the
    // clock. Also from a start pose of negative zeros, which a skipped step would keep
    // and the integrator's sums would not.
    let cfg = PlantConfig {
        motor: DcMotor::SEED_004,
        ..cfg()
    };
    let bits = |p: &Plant| -> Vec<u64> {
        let y = &p.state;
        [y.body.x, y.body.y, y.body.theta, y.phi]
            .into_iter()
            .chain(y.rolled)
            .chain(y.driven)
            .chain([p.trig.theta.0, p.trig.theta.1, p.trig.phi.0, p.trig.phi.1])
            .chain(p.positions)
            .chain(p.wheel_speed)
            .chain([p.path_length, p.t])
            .map(f64::to_bits)
            .collect()
    };
    let edge_bits = |p: &mut Plant| -> Vec<(u64, usize, i64)> {
        p.take_edges()
            .into_iter()
            .map(|(t, j, c)| (t.to_bits(), j, c))
            .collect()
    };
    for (start, swivel) in [
        (Pose2::new(0.3, -0.2, 0.7), 1.1),
        (Pose2::new(-0.0, -0.0, -0.0), -0.0),
    ] {
        let (mut fast, mut full) = (
            Plant::new(cfg, start, swivel, [0.3, 0.6]),
            Plant::new(cfg, start, swivel, [0.3, 0.6]),
        );
        let drive = duty_for(&fast, Twist::new(0.2, 0.1, 0.5));
        let (mut parked, mut held_at_duty) = (0, 0);
        for k in 0..1500 {
            let duty = match k {
                // 5 %: past the driver's dead band, short of the wheels' breakaway.
                50..150 => [50, -50, 50],
                150..250 | 700..1000 => drive,
                _ => [0; 3],
            };
            fast.set_duty(duty);
            full.set_duty(duty);
            if fast.held_still() {
                parked += 1;
                held_at_duty += usize::from(duty != [0; 3]);
            }
            fast.step(1e-3);
            full.step_moving(1e-3);
            assert_eq!(bits(&fast), bits(&full), "step {k}");
            assert_eq!(edge_bits(&mut fast), edge_bits(&mut full), "step {k}");
        }
        // Parked at the start, at the small duty, and for hundreds of steps after each
        // coast to a stop.
        assert_eq!(held_at_duty, 100);
        assert!(parked > 500, "{parked}");
        assert!(full.path_length() > 0.03, "{}", full.path_length());
    }
}

#[test]
fn edges_of_wheels_starting_from_rest_are_timed_to_well_under_a_microsecond() {
    // From rest, full duty forward: the wheels' first counts come while they accelerate
    // hardest, where a straight line through each step's ends misplaces them most. The
    // emulator's 1 ms steps' edges must match those of 1 µs steps.
    let edges = |step: f64| {
        let mut p = Plant::new(cfg(), Pose2::default(), 0.0, [0.3, 0.7]);
        p.set_duty(duty_for(&p, Twist::new(0.5, 0.0, 0.0)));
        p.advance(0.05, step);
        p.take_edges()
    };
    let (coarse, fine) = (edges(1e-3), edges(1e-6));
    assert!(coarse.len() > 50, "{}", coarse.len());
    assert_eq!(coarse.len(), fine.len());
    let worst = coarse
        .iter()
        .zip(&fine)
        .map(|(a, b)| {
            assert_eq!((a.1, a.2), (b.1, b.2));
            (a.0 - b.0).abs()
        })
        .fold(0.0, f64::max);
    eprintln!("worst edge {:.3} ns off", worst * 1e9);
    assert!(worst < 0.05e-6, "{worst} s");
}

#[test]
fn uneven_edges_are_crossed_where_the_map_puts_them() {
    // The same run with a datasheet's maximum edges, without the capture latency: each
    // edge the plant reports is crossed where its map puts it (the wheel's position at
    // that instant, from fine steps, is on the edge), its count is the map's, and the
    // counts agree with the edges.
    use crate::sim::generate::{EdgeErrors, EdgeMap};
    let errors = EdgeErrors {
        capture_jitter_ns: 0,
        ..EdgeErrors::HEDS_9040_MAX
    };
    let per_count = cfg().sensors.metres_per_count();
    let maps = || core::array::from_fn(|j| EdgeMap::draw(&errors, 5, j, per_count[j]));
    let mut p = Plant::new(cfg(), Pose2::default(), 0.0, [0.3, 0.7]).with_edges(maps());
    p.set_duty(duty_for(&p, Twist::new(0.5, 0.0, 0.0)));
    p.advance(0.05, 1e-3);
    let edges = p.take_edges();
    assert!(edges.len() > 50, "{}", edges.len());
    let maps: [EdgeMap; 2] = maps();
    let mut fine = Plant::new(cfg(), Pose2::default(), 0.0, [0.3, 0.7]).with_edges(maps.clone());
    fine.set_duty(duty_for(&fine, Twist::new(0.5, 0.0, 0.0)));
    let mut uneven = false;
    for &(t, j, count) in &edges {
        fine.advance(t - fine.time(), 1e-6);
        // Within a thousandth of a count of one of the map's edges (the edge's time is
        // the coarse run's, well under a microsecond off).
        let position = fine.positions[j];
        let crossed = maps[j].count_at(position + 1e-3) - maps[j].count_at(position - 1e-3);
        assert!(crossed == 1, "encoder {j} at {t} s: {position} is no edge");
        assert_eq!(
            maps[j].count_at(position + 1e-3),
            count,
            "encoder {j} at {t} s"
        );
        uneven |= (position - position.round()).abs() > 0.05;
    }
    assert!(uneven, "every edge on a whole count: the map was not used");
    assert_eq!(
        p.encoder_counts(),
        core::array::from_fn(|j| { edges.iter().rfind(|e| e.1 == j).map_or(0, |e| e.2) })
    );
}

#[test]
fn translating_sideways_swings_the_carriage_behind() {
    // Carriage starts pointing +x; the body then translates along +y: the carriage must
    // end up heading +y (swivel +90° with body heading 0).
    let mut p = Plant::new(cfg(), Pose2::default(), 0.01, [0.0; 2]);
    p.set_duty(duty_for(&p, Twist::new(0.0, 0.3, 0.0)));
    p.advance(3.0, 1e-4);
    // Per-mille duties leave the wheels a hair off a pure translation: milliradians.
    assert!((p.swivel() - PI / 2.0).abs() < 5e-3, "{}", p.swivel());
    assert!(p.body().theta.abs() < 1e-2, "{}", p.body().theta);
}

#[test]
fn carriage_odometry_on_the_plant_tracks_truth() {
    // The estimator fed with the plant's exact (unquantised) rolling distances and swivel
    // must reproduce the truth to numerical precision: plant and estimator agree on the
    // geometry, so any gap here is an integration error in one of them.
    let g = CarriageGeometry::SEED_004;
    let mut p = Plant::new(cfg(), Pose2::default(), PI / 2.0, [0.0; 2]);
    let mut est = robot_math::Pose2::default();
    let mut odo = CarriageOdometry::new(
        CarriageGeometry {
            metres_per_count: [1e-9, 1e-9],
            ..g
        },
        Pose2::default(),
        [0, 0],
        g.abs_code(PI / 2.0),
    );
    for k in 0..4000 {
        let t = k as f64 * 1e-3;
        p.set_duty(duty_for(
            &p,
            Twist::new(0.3 * (t).cos(), 0.4, 0.2 * (2.0 * t).sin()),
        ));
        p.advance(1e-3, 1e-4);
        let counts = p.state.rolled.map(|r| (r / 1e-9).round() as i64);
        est = odo.update(counts, g.abs_code(p.swivel()));
    }
    let truth = p.body();
    assert!(est.distance_to(truth) < 1e-5, "{est:?} vs {truth:?}");
    // Heading comes through the 8-bit absolute encoder: half a step at most.
    assert!(wrap_angle(est.theta - truth.theta).abs() <= g.abs_step() / 2.0 + 1e-9);
}

#[test]
fn on_exact_wheel_positions_the_slaves_integrator_follows_the_plant() {
    // The slave's fixed-point integrator (robot-math's `CarriageExact`, what `exact` runs
    // on seed 004) fed the plant's *unquantised* wheel positions (Q16 counts, 0.5 nm) at
    // the slave's 1 kHz, on a 4 s course that swings the carriage round and turns the
    // body: what is left is the carriage model, the per-update arc and the fixed point,
    // with no counts, power-on phase or interpolation. Measured 0.20 µm at worst here
    // (the arc per update: the curvature changes within a millisecond; 3 nm at 10 kHz),
    // 0.02 µm on seed004-pursuit. And the swivel angle, read through 8 or 16 bits, moves
    // the body's heading only, never its position.
    use robot_math::carriage::CarriageExact;
    let g8 = CarriageGeometry::SEED_004;
    let g16 = CarriageGeometry { abs_bits: 16, ..g8 };
    let mut p = Plant::new(cfg(), Pose2::default(), PI / 2.0, [0.0; 2]);
    let start = |g: &CarriageGeometry| {
        CarriageExact::new(g, Pose2::default(), [0, 0], g.abs_code(PI / 2.0)).unwrap()
    };
    let (mut slave8, mut slave16) = (start(&g8), start(&g16));
    let k = g8.metres_per_count;
    let (mut worst, mut est8, mut est16) = (0.0f64, Pose2::default(), Pose2::default());
    for step in 0..4000 {
        let t = step as f64 * 1e-3;
        p.set_duty(duty_for(
            &p,
            Twist::new(0.3 * t.cos(), 0.4, 0.2 * (2.0 * t).sin()),
        ));
        p.advance(1e-3, 1e-4);
        let q16: [i64; 4] = core::array::from_fn(|j| match j {
            0 | 1 => (p.state.rolled[j] / k[j] * 65536.0).round() as i64,
            _ => 0,
        });
        est8 = slave8.update_q16(&q16, g8.abs_code(p.swivel())).to_pose2();
        est16 = slave16
            .update_q16(&q16, g16.abs_code(p.swivel()))
            .to_pose2();
        worst = worst.max(est8.distance_to(p.body()));
    }
    let truth = p.body();
    assert!(p.path_length() > 1.5, "{}", p.path_length());
    assert!(worst < 0.5e-6, "{worst:e} m");
    assert_eq!((est8.x, est8.y), (est16.x, est16.y));
    for (est, g) in [(est8, g8), (est16, g16)] {
        let e = wrap_angle(est.theta - truth.theta).abs();
        assert!(
            e <= g.abs_step() / 2.0 + 1e-7,
            "{} bits: {e:e} rad",
            g.abs_bits
        );
    }
}
