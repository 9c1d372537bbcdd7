//! The trajectory catalogue: lengths, starts and ends, twists that are the derivative of the
//! poses, closed paths, and our constant-twist segments against circle geometry.

mod common;

use std::f64::consts::{PI, SQRT_2, TAU};

use common::*;
use host_bench::sim::trajectory::{self, build, catalogue, Drive};
use robot_math::se2::{Pose2, Twist};

/// Our own trajectories (no paper has them): constant twists, or rest then a start.
fn is_ours(name: &str) -> bool {
    trajectory::named(name).unwrap().paper == "ours"
}

#[test]
fn catalogue_lengths_match_the_papers_and_ours() {
    // Name, expected length (m): seed 000 80 cm; seed 001 284 cm, 40 m, 280 cm; seed 002 1 m
    // square, its diagonal, a 0.5 m-radius circle; UMBmark 4 × 4 m. Ours: the sums of their
    // segments' speed × duration.
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
        ("seed002-square-steps", 4.0),
        ("seed002-diagonal", SQRT_2),
        ("seed002-circle", PI),
        ("umbmark-cw", 16.0),
        ("umbmark-ccw", 16.0),
        ("twist-arcs", 0.4 * 1.5 + 0.3 * 2.0 + 0.5 * 1.6),
        ("twist-sideways-spin", 0.4 * 1.8 + 2.0 * 0.3 * SQRT_2 * 1.5),
        ("twist-s-spin-reverse", 0.4 * 1.5 * 2.0 + 0.3 * 2.0),
        ("rest-then-arcs", 2.0),
        ("rest-then-smooth-line", 0.4 * 0.8 / 2.0 + 0.4 * 3.0),
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
        if is_ours(name) {
            assert!((1.0..=3.0).contains(&length), "{name}: {length} m");
        }
    }
    assert!(build("no-such-trajectory").is_none());
}

#[test]
fn every_catalogue_trajectory_starts_at_the_origin_and_the_papers_start_and_end_at_rest() {
    for named in catalogue() {
        let name = named.name;
        let traj = build(name).unwrap();
        let t_end = traj.duration();
        assert!(t_end > 0.0 && t_end.is_finite(), "{name}");
        assert_eq!(traj.pose(0.0), Pose2::default(), "{name}");
        let (start, end) = (traj.twist(0.0), traj.twist(t_end));
        if is_ours(name) {
            // Every one of ours is still moving at the end.
            assert!(twist_norm(end, Twist::default()) > 0.1, "{name}: {end:?}");
        } else {
            assert!(twist_norm(start, Twist::default()) < 1e-12, "{name}");
            assert!(twist_norm(end, Twist::default()) < 1e-12, "{name}");
        }
    }
}

#[test]
fn every_twist_is_the_derivative_of_its_pose_and_jumps_only_at_breakpoints() {
    for named in catalogue() {
        let name = named.name;
        let traj = build(name).unwrap();
        let t_end = traj.duration();
        let breaks = traj.breakpoints();
        // Either side of every breakpoint: the one-sided twists are the limits there.
        for &b in &breaks {
            let (before, after) = (traj.twist_before(b), traj.twist(b));
            let (a, c) = (traj.twist(b - 1e-7), traj.twist(b + 1e-7));
            assert!(
                twist_norm(before, a) < 1e-5,
                "{name} at {b}: {before:?} vs {a:?}"
            );
            assert!(
                twist_norm(after, c) < 1e-5,
                "{name} at {b}: {after:?} vs {c:?}"
            );
            if named.drive == Drive::Differential {
                assert_eq!((before.vy, after.vy), (0.0, 0.0), "{name} at {b}");
            }
        }
        // Inside the pieces: continuous, and the derivative of the pose (body frame).
        let h = 1e-6;
        for t in (1..98).map(|k| t_end * k as f64 / 98.0) {
            if breaks.iter().any(|b| (b - t).abs() < 3.0 * h) {
                continue;
            }
            let (a, b) = (traj.twist(t - 1e-7), traj.twist(t + 1e-7));
            assert!(twist_norm(a, b) < 1e-5, "{name} at {t}: {a:?} vs {b:?}");
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
            // Plausible speeds: up to 0.5 m/s; ours turn at most 2 rad/s (the seed paths'
            // curvature sets theirs: the figure-eight's tight lobes turn faster).
            assert!(tw.vx.hypot(tw.vy) <= 0.5 + 1e-12, "{name} at {t}");
            if is_ours(name) {
                assert!(tw.omega.abs() <= 2.0 + 1e-12, "{name} at {t}");
            }
        }
    }
}

#[test]
fn integrating_the_twist_lands_on_the_pose() {
    for named in catalogue() {
        let traj = build(named.name).unwrap();
        let mut p = traj.pose(0.0);
        // Piece by piece, so that no step straddles a jump of the twist.
        for w in cuts(traj.as_ref()).windows(2) {
            let n = ((w[1] - w[0]) / 1e-3).ceil() as usize;
            let h = (w[1] - w[0]) / n as f64;
            for j in 0..n {
                // Midpoint twist through the SE(2) exponential: second order.
                p = p.integrate(traj.twist(w[0] + (j as f64 + 0.5) * h), h);
            }
        }
        let q = traj.pose(traj.duration());
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
        assert_eq!(
            trajectory::named(name).unwrap().drive,
            Drive::Holonomic,
            "{name}"
        );
    }
}

// ---------------------------------------------------------------------------------------------
// Our constant-twist segments.

/// Where a constant twist (v_x, v_y, ω) takes pose `p` in `t` seconds, by circle geometry:
/// the body turns about its instantaneous centre, at (−v_y, v_x)/ω in the body frame.
fn by_geometry(p: Pose2, (vx, vy, w): (f64, f64, f64), t: f64) -> Pose2 {
    let rot = |a: f64, (x, y): (f64, f64)| (a.cos() * x - a.sin() * y, a.sin() * x + a.cos() * y);
    if w == 0.0 {
        let (dx, dy) = rot(p.theta, (vx * t, vy * t));
        return Pose2::new(p.x + dx, p.y + dy, p.theta);
    }
    let (cx, cy) = rot(p.theta, (-vy / w, vx / w));
    let (rx, ry) = rot(p.theta + w * t, (vy / w, -vx / w));
    Pose2::new(p.x + cx + rx, p.y + cy + ry, p.theta + w * t)
}

fn chain(segments: &[(f64, (f64, f64, f64))]) -> Vec<Pose2> {
    let mut poses = vec![Pose2::default()];
    for &(t, tw) in segments {
        poses.push(by_geometry(*poses.last().unwrap(), tw, t));
    }
    poses
}

fn assert_near(a: Pose2, b: Pose2, what: &str) {
    assert!(
        a.distance_to(b) < 1e-12 && (a.theta - b.theta).abs() < 1e-12,
        "{what}: {a:?} vs {b:?}"
    );
}

const ARCS: [(f64, (f64, f64, f64)); 3] = [
    (1.5, (0.4, 0.0, 0.8)),
    (2.0, (0.3, 0.0, -1.0)),
    (1.6, (0.5, 0.0, 0.5)),
];

#[test]
fn constant_twist_trajectories_pass_through_the_poses_circle_geometry_gives() {
    let sideways = [
        (1.8, (0.0, 0.4, 0.0)),
        (1.2, (0.0, 0.0, 1.5)),
        (1.5, (0.3, -0.3, 0.8)),
        (1.5, (-0.3, 0.3, -0.8)),
    ];
    let s_spin = [
        (1.5, (0.4, 0.0, 1.0)),
        (1.5, (0.4, 0.0, -1.0)),
        (1.0, (0.0, 0.0, 2.0)),
        (2.0, (-0.3, 0.0, 0.0)),
    ];
    for (name, segments) in [
        ("twist-arcs", &ARCS[..]),
        ("twist-sideways-spin", &sideways[..]),
        ("twist-s-spin-reverse", &s_spin[..]),
    ] {
        let traj = build(name).unwrap();
        let poses = chain(segments);
        let mut t = 0.0;
        for (k, &(d, (vx, vy, w))) in segments.iter().enumerate() {
            assert_near(
                traj.pose(t),
                poses[k],
                &format!("{name} start of segment {k}"),
            );
            // Half way along, the twist is the segment's, and so is the pose.
            let mid = by_geometry(poses[k], (vx, vy, w), d / 2.0);
            assert_near(traj.pose(t + d / 2.0), mid, &format!("{name} segment {k}"));
            assert_eq!(traj.twist(t + d / 2.0), Twist::new(vx, vy, w), "{name} {k}");
            // Moving from its first instant: the twist at t is the new segment's.
            assert_eq!(traj.twist(t), Twist::new(vx, vy, w), "{name} {k}");
            if k > 0 {
                let (pvx, pvy, pw) = segments[k - 1].1;
                assert_eq!(traj.twist_before(t), Twist::new(pvx, pvy, pw), "{name} {k}");
            }
            t += d;
        }
        assert!((traj.duration() - t).abs() < 1e-12, "{name}");
        assert_near(traj.pose(t), *poses.last().unwrap(), name);
    }
    // The sideways run's reversal retraces the diagonal: it ends where the spin ended.
    let traj = build("twist-sideways-spin").unwrap();
    assert_near(
        traj.pose(traj.duration()),
        Pose2::new(0.0, 0.72, 1.8),
        "twist-sideways-spin end",
    );
}

#[test]
fn rest_then_arcs_is_twist_arcs_half_a_second_late() {
    let arcs = build("twist-arcs").unwrap();
    let late = build("rest-then-arcs").unwrap();
    assert!((late.duration() - arcs.duration() - 0.5).abs() < 1e-12);
    for k in 0..=50 {
        let t = 0.5 * k as f64 / 50.0;
        assert_eq!(late.pose(t), Pose2::default(), "at {t}");
        assert_eq!(late.twist_before(t), Twist::default(), "at {t}");
    }
    // Abruptly at full speed.
    assert_eq!(late.twist(0.5), Twist::new(0.4, 0.0, 0.8));
    for k in 0..=100 {
        let t = arcs.duration() * k as f64 / 100.0;
        let (a, b) = (arcs.pose(t), late.pose(t + 0.5));
        assert!(
            a.distance_to(b) < 1e-12 && (a.theta - b.theta).abs() < 1e-12,
            "at {t}"
        );
    }
}

#[test]
fn rest_then_smooth_line_starts_smoothly_after_its_rest() {
    let traj = build("rest-then-smooth-line").unwrap();
    let b = traj.breakpoints();
    assert!(b.len() == 2 && (b[0] - 0.4).abs() < 1e-15 && (b[1] - 1.2).abs() < 1e-15);
    // At rest until 0.4 s, then the speed rises with zero acceleration at both ends of the
    // 0.8 s ramp (as the seed paths' ramps), and cruises at 0.4 m/s to the end.
    assert_eq!(traj.twist(0.4), Twist::default());
    let accel = |t: f64| (traj.twist(t + 1e-6).vx - traj.twist(t - 1e-6).vx) / 2e-6;
    assert!(accel(0.4 + 2e-6).abs() < 1e-4 && accel(1.2 - 2e-6).abs() < 1e-4);
    assert!(
        (traj.twist(0.8).vx - 0.2).abs() < 1e-15,
        "half way up: half speed"
    );
    assert!(twist_norm(traj.twist(1.2), Twist::new(0.4, 0.0, 0.0)) < 1e-15);
    assert_eq!(traj.twist(traj.duration()), Twist::new(0.4, 0.0, 0.0));
    let end = traj.pose(traj.duration());
    assert!(
        (end.x - 1.36).abs() < 1e-12 && end.y == 0.0 && end.theta == 0.0,
        "{end:?}"
    );
}
