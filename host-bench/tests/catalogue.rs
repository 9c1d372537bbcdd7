//! The trajectory catalogue: lengths, starts and ends, twists that are the derivative of the
//! poses, closed paths.

mod common;

use std::f64::consts::{PI, TAU};

use common::*;
use host_bench::sim::trajectory::{self, build, catalogue, Drive};
use robot_math::se2::{Pose2, Twist};

#[test]
fn catalogue_lengths_match_the_papers() {
    // Name, expected length (m): seed 000 80 cm; seed 001 284 cm, 40 m, 280 cm; seed 002 1 m
    // square, its diagonal, a 0.5 m-radius circle; UMBmark 4 × 4 m.
    let expected = [
        ("seed000-line", 0.80),
        ("seed000-bezier-0deg", 0.80),
        ("seed000-bezier-90deg", 0.80),
        ("seed000-bezier-180deg", 0.80),
        ("seed000-two-beziers", 0.80),
        ("seed001-figure-eight", 2.84),
        ("seed001-straight-40m", 40.0),
        ("seed001-curve", 2.80),
        ("seed002-square", 4.0),
        ("seed002-diagonal", std::f64::consts::SQRT_2),
        ("seed002-circle", PI),
        ("umbmark-cw", 16.0),
        ("umbmark-ccw", 16.0),
    ];
    let names: Vec<&str> = catalogue().iter().map(|n| n.name).collect();
    assert_eq!(names, expected.map(|(n, _)| n).to_vec());
    for (name, length) in expected {
        let traj = build(name).unwrap();
        let l = path_length(traj.as_ref());
        println!(
            "{name:24} length {l:9.6} m  duration {:8.4} s",
            traj.duration()
        );
        assert!(
            (l - length).abs() < 1e-9 * length.max(1.0),
            "{name}: length {l}, expected {length}"
        );
    }
    assert!(build("no-such-trajectory").is_none());
}

#[test]
fn every_catalogue_trajectory_starts_at_rest_and_moves_smoothly() {
    for named in catalogue() {
        let name = named.name;
        let traj = build(name).unwrap();
        let t_end = traj.duration();
        assert!(t_end > 0.0 && t_end.is_finite(), "{name}");
        assert_eq!(traj.pose(0.0), Pose2::default(), "{name}");
        assert!(
            twist_norm(traj.twist(0.0), Twist::default()) < 1e-12,
            "{name}"
        );
        assert!(
            twist_norm(traj.twist(t_end), Twist::default()) < 1e-12,
            "{name}"
        );
        // Continuous twist: at every breakpoint and at 97 other instants.
        let mut probes = traj.breakpoints();
        probes.extend((1..98).map(|k| t_end * k as f64 / 98.0));
        for &t in &probes {
            let (a, b) = (traj.twist(t - 1e-7), traj.twist(t + 1e-7));
            assert!(twist_norm(a, b) < 1e-5, "{name} at {t}: {a:?} vs {b:?}");
            // The twist is the derivative of the pose (body frame).
            let h = 1e-6;
            let (p0, p1, p) = (traj.pose(t - h), traj.pose(t + h), traj.pose(t));
            let (wx, wy) = ((p1.x - p0.x) / (2.0 * h), (p1.y - p0.y) / (2.0 * h));
            let (s, c) = p.theta.sin_cos();
            let numeric = Twist::new(
                c * wx + s * wy,
                -s * wx + c * wy,
                (p1.theta - p0.theta) / (2.0 * h),
            );
            let tw = traj.twist(t);
            assert!(
                twist_norm(numeric, tw) < 1e-6,
                "{name} at {t}: {numeric:?} vs {tw:?}"
            );
            if named.drive == Drive::Differential {
                assert_eq!(tw.vy, 0.0, "{name} at {t}");
            }
            // Plausible speeds.
            assert!(tw.vx.hypot(tw.vy) <= 0.4 + 1e-12, "{name} at {t}");
        }
    }
}

#[test]
fn integrating_the_twist_lands_on_the_pose() {
    for named in catalogue() {
        let traj = build(named.name).unwrap();
        let t_end = traj.duration();
        let n = (t_end / 1e-3).ceil() as usize;
        let h = t_end / n as f64;
        let mut p = traj.pose(0.0);
        for j in 0..n {
            // Midpoint twist through the SE(2) exponential: second order.
            p = p.integrate(traj.twist((j as f64 + 0.5) * h), h);
        }
        let q = traj.pose(t_end);
        assert!(
            p.distance_to(q) < 1e-5 && (p.theta - q.theta).abs() < 1e-6,
            "{}: integrated {p:?}, pose {q:?}",
            named.name
        );
    }
}

#[test]
fn closed_paths_return_to_their_start() {
    for (name, turn) in [
        ("seed002-circle", TAU),
        ("seed002-square", 0.0),
        ("seed001-figure-eight", 0.0),
        ("umbmark-ccw", TAU),
        ("umbmark-cw", -TAU),
    ] {
        let traj = build(name).unwrap();
        let (a, b) = (traj.pose(0.0), traj.pose(traj.duration()));
        assert!(a.distance_to(b) < 1e-9, "{name}: {a:?} -> {b:?}");
        assert!(
            (b.theta - a.theta - turn).abs() < 1e-9,
            "{name}: {a:?} -> {b:?}"
        );
    }
    // Half way round the circle is the far side: (0, 2R), heading π.
    let circle = build("seed002-circle").unwrap();
    let mid = circle.pose(circle.duration() / 2.0);
    let r = trajectory::SEED002_CIRCLE_RADIUS_M;
    assert!(mid.distance_to(Pose2::new(0.0, 2.0 * r, PI)) < 1e-9 && (mid.theta - PI).abs() < 1e-9);
}

#[test]
fn seed000_headings_turn_as_named() {
    for (name, turn) in [
        ("seed000-bezier-0deg", 0.0),
        ("seed000-bezier-90deg", PI / 2.0),
        ("seed000-bezier-180deg", PI),
        ("seed000-two-beziers", 0.0),
    ] {
        let traj = build(name).unwrap();
        let end = traj.pose(traj.duration());
        assert!((end.theta - turn).abs() < 1e-12, "{name}: {end:?}");
        // Heading linear in distance: at half the length, half the turn.
        assert_eq!(
            trajectory::named(name).unwrap().drive,
            Drive::Holonomic,
            "{name}"
        );
    }
}
