use super::*;
use crate::carriage::{CarriageExact, CarriageGeometry};
use crate::exact::{ExactParams, FixedPose, MAX_ENCODERS};
use crate::se2::wrap_angle;
use crate::wheel::Wheel;
use crate::wheelset::GeometryError;
use crate::{Pose2, Twist};
use core::f64::consts::PI;

const K: f64 = 1e-4;

fn diff_axle() -> Layout {
    Layout::from_geometry(
        &[
            (Wheel::at(0.0, 0.15, 0.0), K),
            (Wheel::at(0.0, -0.15, 0.0), K),
        ],
        None,
        None,
    )
    .unwrap()
}

/// Seed 000's symmetric triangle: every wheel turns the body by the same angle per tick.
fn triangle() -> Layout {
    let w: [(Wheel, f64); 3] = core::array::from_fn(|i| {
        let a = i as f64 * 2.0 * PI / 3.0;
        let r = 0.2 / 3f64.sqrt();
        (
            Wheel::at(r * a.cos(), r * a.sin(), a + PI / 2.0 + PI / 4.0),
            K,
        )
    });
    Layout::from_geometry(&w, None, None).unwrap()
}

fn seed_004() -> Layout {
    Layout::seed_004()
}

#[test]
fn method_names_round_trip_and_unknown_names_are_refused() {
    for m in Method::ALL {
        assert_eq!(Method::from_name(m.name()), Some(m));
        assert!(Method::NAMES.contains(m.name()));
    }
    assert_eq!(Method::from_name("exact-f64"), None);
    assert_eq!(Method::from_name("Exact"), None);
    assert_eq!(Method::Exact.arithmetic(), Arithmetic::Integer);
    assert_eq!(Method::Timing.arithmetic(), Arithmetic::Float);
}

#[test]
fn layout_errors_name_the_problem() {
    let w = (Wheel::at(0.0, 0.1, 0.0), K);
    let one = Layout::from_geometry(&[w], None, None);
    assert_eq!(one.unwrap_err(), LayoutError::EncoderCount(1));
    let five = Layout::from_geometry(&[w; 5], None, None);
    assert_eq!(five.unwrap_err(), LayoutError::EncoderCount(5));
    let parallel = [
        (Wheel::at(0.1, 0.0, 0.0), K),
        (Wheel::at(0.0, 0.1, 0.0), K),
        (Wheel::at(-0.1, -0.1, 0.0), K),
    ];
    assert_eq!(
        Layout::from_geometry(&parallel, None, None).unwrap_err(),
        LayoutError::Degenerate(GeometryError::Degenerate)
    );
    let tandem = [
        (Wheel::at(0.1, 0.0, 0.0), K),
        (Wheel::at(-0.1, 0.0, 0.0), K),
    ];
    assert_eq!(
        Layout::from_geometry(&tandem, None, None).unwrap_err(),
        LayoutError::Degenerate(GeometryError::NotOnOneAxle)
    );
    let axle = |k: f64| {
        [
            (Wheel::at(0.0, 0.1, 0.0), k),
            (Wheel::at(0.0, -0.1, 0.0), k),
        ]
    };
    assert_eq!(
        Layout::from_geometry(&axle(1e6), None, None).unwrap_err(),
        LayoutError::OutOfFixedPointRange
    );
    assert_eq!(
        Layout::from_geometry(&axle(-K), None, None).unwrap_err(),
        LayoutError::MetresPerCount { encoder: 0 }
    );
    let abs = Some(AbsLayout::E6CP_AG5C);
    assert_eq!(
        Layout::from_geometry(&axle(K), Some(0.06), None).unwrap_err(),
        LayoutError::CarriageNeedsAbsoluteEncoder
    );
    let tri: [(Wheel, f64); 3] = core::array::from_fn(|j| (triangle().wheels()[j], K));
    assert_eq!(
        Layout::from_geometry(&tri, Some(0.06), abs).unwrap_err(),
        LayoutError::CarriageEncoders(3)
    );
    assert_eq!(
        Layout::from_geometry(&axle(K), Some(f64::NAN), abs).unwrap_err(),
        LayoutError::CarriageTrail
    );
    // Past 128 m; and under it, but moving the pivot 0.5 m sideways per count (1 mm counts
    // on a 0.2 m axle, 100 m behind): the fixed-point carriage's constants would not fit.
    assert_eq!(
        Layout::from_geometry(&axle(K), Some(200.0), abs).unwrap_err(),
        LayoutError::CarriageTrail
    );
    assert_eq!(
        Layout::from_geometry(&axle(1e-3), Some(100.0), abs).unwrap_err(),
        LayoutError::CarriageTrail
    );
    assert!(Layout::from_geometry(&axle(K), Some(10.0), abs).is_ok());
    let bad_bits = Some(AbsLayout {
        bits: 17,
        ..AbsLayout::E6CP_AG5C
    });
    assert_eq!(
        Layout::from_geometry(&axle(K), Some(0.06), bad_bits).unwrap_err(),
        LayoutError::AbsBits(17)
    );
    // Parts that do not fit together.
    let l = diff_axle();
    let three = ExactParams::from_raw(3, [0; 4], [0; 4], [1, 1, 1, 0]).unwrap();
    assert_eq!(
        Layout::from_parts(2, *l.wheels(), *l.metres_per_count(), three, None, None).unwrap_err(),
        LayoutError::ConstantsMismatch(3)
    );
    // Every error displays as a sentence.
    assert!(format!("{}", LayoutError::EncoderCount(5)).contains("2 to 4"));
}

#[test]
fn a_layout_rebuilt_from_its_parts_is_the_same_bits() {
    for l in [diff_axle(), triangle(), seed_004()] {
        let e = l.exact();
        let exact = ExactParams::from_raw(l.encoders(), e.kx(), e.ky(), e.kth()).unwrap();
        assert_eq!(exact, *e);
        let back = Layout::from_parts(
            l.encoders() as u8,
            *l.wheels(),
            *l.metres_per_count(),
            exact,
            l.carriage(),
            l.abs(),
        )
        .unwrap();
        assert_eq!(back, l);
    }
    // Raw constants out of range, or set past the encoders, are refused.
    assert!(ExactParams::from_raw(2, [1 << 40, 0, 0, 0], [0; 4], [0; 4]).is_err());
    assert!(ExactParams::from_raw(2, [0, 0, 5, 0], [0; 4], [0; 4]).is_err());
    assert!(ExactParams::from_raw(2, [i64::MIN, 0, 0, 0], [0; 4], [0; 4]).is_err());
    // Turn per count has its own, wider bound: a quarter turn.
    assert!(ExactParams::from_raw(2, [0; 4], [0; 4], [(1 << 46) - 1, 0, 0, 0]).is_ok());
    assert!(ExactParams::from_raw(2, [0; 4], [0; 4], [1 << 46, 0, 0, 0]).is_err());
}

#[test]
fn coarse_encoders_on_a_short_axle_are_a_layout_every_method_runs() {
    // docs/tick-stream.md's example robot: 1 cm counts, 0.2 m apart, 0.05 rad per count
    // (past the 2^40 bound turn constants once had).
    let coarse = 0.01;
    let layout = Layout::from_geometry(
        &[
            (Wheel::at(0.0, 0.1, 0.0), coarse),
            (Wheel::at(0.0, -0.1, 0.0), coarse),
        ],
        None,
        None,
    )
    .unwrap();
    let tw = Twist::new(0.4, 0.0, 0.8);
    for sensors in [SensorKind::Counts, SensorKind::Ticks] {
        for method in Method::ALL {
            if method == Method::Timing && sensors == SensorKind::Counts {
                continue;
            }
            let (e, th) = drive(&layout, method, sensors, tw);
            // Within two counts of travel and of turn.
            assert!(
                e < 2.0 * coarse && th < 2.0 * coarse / 0.2,
                "{method} {sensors:?}: {e} m, {th} rad"
            );
        }
    }
}

/// A count sequence with uneven steps on both wheels and a swinging swivel.
fn carriage_run() -> impl Iterator<Item = ([i64; 2], u16)> {
    let (mut c0, mut c1) = (0i64, 0i64);
    (0..5_000i64).map(move |k| {
        c0 += 1 + (k % 7 == 0) as i64 - (k % 11 == 0) as i64;
        c1 += 1 + (k % 5 == 0) as i64;
        ([c0, c1], (64 + (k / 300) % 40) as u16)
    })
}

#[test]
fn seed_004_exact_is_bit_identical_to_carriage_exact() {
    let g = CarriageGeometry::SEED_004;
    let abs = AbsLayout::E6CP_AG5C;
    // The absolute encoder's raw output for a position (inverted Gray on the pins).
    let raw = |p: u16| !crate::sensors::binary_to_gray(p) & 0xFF;
    let start = Pose2::new(0.3, -0.2, 0.1);
    let mut old = CarriageExact::new(&g, start, [3, -4], 64).unwrap();
    let mut new = Odometry::new(
        &seed_004(),
        Method::Exact,
        SensorKind::Counts,
        FixedPose::from_pose2(start),
        0,
        [3, -4, 0, 0],
        Some(raw(64)),
    )
    .unwrap();
    assert_eq!(abs.decode(raw(77)), 77);
    for (i, (c, code)) in carriage_run().enumerate() {
        let c = [c[0] + 3, c[1] - 4];
        new.set_counts(&[c[0], c[1]]);
        new.set_abs(raw(code));
        let t = i as u64 * 1_000_000;
        assert_eq!(new.update(t), old.update(c, code), "update {i}");
        if i == 2_500 {
            let p = FixedPose::from_micrometres(1_000_000, 2_000_000, 1 << 30);
            new.set_pose(p, t);
            old.update(c, code);
            old.set_body(p, code);
        }
    }
}

/// Tick instants of body-fixed wheels under a constant twist: wheel j ticks at k·Δ/|s_j|.
/// Feeds `ev` (time-stamped ticks) to `odo` and updates it every millisecond for 1 s, with the
/// counts so far (and `abs`, if given) as the board's 1 kHz update does. Returns the counts.
fn run_1khz(odo: &mut Odometry, ev: &[(u64, usize, i8)], abs: Option<u16>) -> [i64; MAX_ENCODERS] {
    let mut counts = [0i64; MAX_ENCODERS];
    let mut next = 0;
    for ms in 1..=1000u64 {
        let t = ms * 1_000_000;
        while next < ev.len() && ev[next].0 <= t {
            let (te, j, s) = ev[next];
            odo.tick(te, j, s);
            counts[j] += s as i64;
            next += 1;
        }
        odo.set_counts(&counts);
        if let Some(raw) = abs {
            odo.set_abs(raw);
        }
        odo.update(t);
    }
    counts
}

fn ticks_for(layout: &Layout, tw: Twist, t_end: f64) -> Vec<(u64, usize, i8)> {
    let mut ev = Vec::new();
    for j in 0..layout.encoders() {
        let s = layout.wheels()[j].rolling_speed(tw);
        let delta = layout.metres_per_count()[j];
        if s.abs() < 1e-12 {
            continue;
        }
        let mut k = 1u64;
        while k as f64 * delta / s.abs() <= t_end {
            let t = k as f64 * delta / s.abs();
            ev.push(((t * 1e9).round() as u64, j, if s > 0.0 { 1 } else { -1 }));
            k += 1;
        }
    }
    ev.sort();
    ev
}

/// Drive `layout` (body-fixed wheels) through a constant twist with `method`, in both sensor
/// kinds, updating at 1 kHz; returns the worst final position and heading errors.
fn drive(layout: &Layout, method: Method, sensors: SensorKind, tw: Twist) -> (f64, f64) {
    let start = Pose2::new(0.5, -0.25, 0.4);
    let t_end = 1.0;
    let mut odo = Odometry::new(
        layout,
        method,
        sensors,
        FixedPose::from_pose2(start),
        0,
        [0; MAX_ENCODERS],
        None,
    )
    .unwrap();
    let counts = run_1khz(&mut odo, &ticks_for(layout, tw, t_end), None);
    assert_eq!(odo.counts(), counts, "{method} {sensors:?}");
    let p = odo.pose().to_pose2();
    let want = start.integrate(tw, t_end);
    (p.distance_to(want), wrap_angle(p.theta - want.theta).abs())
}

#[test]
fn every_method_follows_a_diff_axle_and_a_triangle_in_both_sensor_kinds() {
    let cases = [
        (diff_axle(), Twist::new(0.4, 0.0, 0.8)),
        (triangle(), Twist::new(0.3, -0.2, 0.7)),
    ];
    for (layout, tw) in cases {
        for sensors in [SensorKind::Counts, SensorKind::Ticks] {
            for method in Method::ALL {
                if method == Method::Timing && sensors == SensorKind::Counts {
                    continue;
                }
                if method == Method::Lut
                    && layout.differential_drive().is_none()
                    && cfg!(not(feature = "lut-n"))
                {
                    continue;
                }
                let (e, th) = drive(&layout, method, sensors, tw);
                // 0.4 m of path; exact is within a few counts, the baselines within mm.
                let bound = if method == Method::Exact {
                    5.0 * K
                } else {
                    5e-3
                };
                assert!(
                    e < bound && th < 0.02,
                    "{method} {sensors:?}: {e} m, {th} rad"
                );
            }
        }
    }
}

#[test]
fn every_method_follows_the_carriage() {
    // The carriage drives a circle as a differential drive while the swivel holds β: the body
    // follows rigidly, its heading φ − β.
    let layout = seed_004();
    let g = CarriageGeometry::SEED_004;
    let code = 32u16; // β = 45°
    let raw = !crate::sensors::binary_to_gray(code) & 0xFF;
    let beta = g.swivel_angle(code);
    let body0 = Pose2::new(0.2, 0.1, -0.3);
    let c0 = g.carriage_pose(body0, beta);
    let tw = Twist::new(0.3, 0.0, 0.6);
    for sensors in [SensorKind::Counts, SensorKind::Ticks] {
        for method in Method::ALL {
            if method == Method::Timing && sensors == SensorKind::Counts {
                continue;
            }
            let mut odo = Odometry::new(
                &layout,
                method,
                sensors,
                FixedPose::from_pose2(body0),
                0,
                [0; MAX_ENCODERS],
                Some(raw),
            )
            .unwrap();
            run_1khz(&mut odo, &ticks_for(&layout, tw, 1.0), Some(raw));
            let want = g.body_pose(c0.integrate(tw, 1.0), beta);
            let p = odo.pose().to_pose2();
            let bound = if method == Method::Exact { 1e-4 } else { 5e-3 };
            assert!(
                p.distance_to(want) < bound && wrap_angle(p.theta - want.theta).abs() < 0.02,
                "{method} {sensors:?}: {p:?} vs {want:?}"
            );
        }
    }
}

#[test]
fn switching_continues_from_the_pose_and_set_pose_restarts() {
    for layout in [diff_axle(), seed_004()] {
        let mut odo = Odometry::new(
            &layout,
            Method::Exact,
            SensorKind::Ticks,
            FixedPose::default(),
            0,
            [0; MAX_ENCODERS],
            Some(0xFF),
        )
        .unwrap();
        let mut t = 0;
        for k in 1..200u64 {
            t = k * 100_000;
            odo.tick(t, 0, 1);
            odo.tick(t + 10, 1, 1);
        }
        let before = odo.update(t + 20);
        for m in [Method::Arc, Method::Lut, Method::Timing, Method::Exact] {
            odo.switch(m, t + 20).unwrap();
            assert_eq!(odo.method(), m);
            let after = odo.update(t + 20).to_pose2();
            // The float methods round-trip the pose through f64 (a picometre); seed 001's
            // coordinates are whole 10^-8 m.
            assert!(
                after.distance_to(before.to_pose2()) < 2e-8,
                "{m}: {after:?}"
            );
        }
        let target = FixedPose::from_micrometres(-3_000_000, 1_500_000, 0x4000_0000);
        for m in Method::ALL {
            odo.switch(m, t + 20).unwrap();
            odo.set_pose(target, t + 20);
            assert_eq!(odo.pose(), target);
            let p = odo.update(t + 20).to_pose2();
            assert!(p.distance_to(target.to_pose2()) < 2e-8, "{m}: {p:?}");
        }
    }
}

#[test]
fn unsupported_cases_are_refused_with_a_reason() {
    let start = FixedPose::default();
    let new = |l: &Layout, m, s| Odometry::new(l, m, s, start, 0, [0; 4], None).err();
    assert_eq!(
        new(&diff_axle(), Method::Timing, SensorKind::Counts),
        Some(Unsupported::TimingNeedsTicks)
    );
    // Unequal turn steps: seed 001's heading cannot be a count of one step.
    let skew = Layout::from_geometry(
        &[
            (Wheel::at(0.1, 0.0, PI / 2.0), K),
            (Wheel::at(-0.1, 0.05, 2.0), K),
            (Wheel::at(0.0, -0.1, 0.3), 2.0 * K),
        ],
        None,
        None,
    )
    .unwrap();
    let want_skew = if cfg!(feature = "lut-n") {
        Unsupported::LutLayout(crate::lut::LutNError::UnequalTurnSteps)
    } else {
        Unsupported::LutTablesNotBuilt
    };
    assert_eq!(new(&skew, Method::Lut, SensorKind::Ticks), Some(want_skew));
    let tri = new(&triangle(), Method::Lut, SensorKind::Ticks);
    assert_eq!(tri.is_none(), cfg!(feature = "lut-n"), "{tri:?}");
    // A refused switch keeps the running method.
    let mut odo = Odometry::new(
        &diff_axle(),
        Method::Arc,
        SensorKind::Counts,
        start,
        0,
        [0; 4],
        None,
    )
    .unwrap();
    let mut untouched = odo.clone();
    assert_eq!(
        odo.switch(Method::Timing, 5),
        Err(Unsupported::TimingNeedsTicks)
    );
    assert_eq!(odo.method(), Method::Arc);
    // ... and its state: the float states are written where they live, so the refusal must
    // come before anything is written.
    untouched.update(5);
    let mut refused = odo.clone();
    for o in [&mut refused, &mut untouched] {
        o.set_counts(&[400, 380]);
    }
    assert_eq!(refused.update(15), untouched.update(15));
    // Readings of the other sensor kind, unknown encoders and corrupt steps move nothing.
    odo.tick(10, 0, 1);
    let mut ticks = Odometry::new(
        &diff_axle(),
        Method::Exact,
        SensorKind::Ticks,
        start,
        0,
        [0; 4],
        None,
    )
    .unwrap();
    ticks.set_counts(&[100, 100]);
    ticks.tick(10, 2, 1);
    ticks.tick(10, 0, 3);
    assert_eq!(odo.counts(), [0; 4]);
    assert_eq!(ticks.counts(), [0; 4]);
    assert_eq!(ticks.update(20), start);
}

#[test]
fn the_estimator_fits_the_slaves_ram() {
    let size = core::mem::size_of::<Odometry>();
    let layout = core::mem::size_of::<Layout>();
    eprintln!("size_of Odometry = {size} B, Layout = {layout} B");
    assert!(layout <= 512, "{layout}");
    if cfg!(not(feature = "lut-n")) {
        // Host sizes (8-byte usize); the board's are a little smaller. 2 KiB until the slave
        // learned its encoders' edges (each tracker's window and table, and the edge rings'
        // sixteen slots: 2 584 B on 2026-11-29); the image's statics are gated by `.ci/run`.
        assert!(size <= 3072, "{size}");
    }
}

#[test]
fn seed_004_constants_are_what_the_geometry_gives() {
    let derived = Layout::from_carriage(&CarriageGeometry::SEED_004, AbsLayout::E6CP_AG5C).unwrap();
    assert_eq!(Layout::SEED_004, derived);
    assert_eq!(
        Layout::seed_004().differential_drive().map(|d| d.1),
        Some(0.2)
    );
}

/// Counts mode started away from zero: an update (or set-pose) before the first counts are
/// sampled must not integrate a move back to zero (found in review: the positions `exact`
/// reads once started at zero while the integrator started at the counts).
#[test]
fn counts_mode_started_at_nonzero_counts_stands_still_until_they_move() {
    let start = [1000, -1000, 0, 0];
    let mut o = Odometry::new(
        &diff_axle(),
        Method::Exact,
        SensorKind::Counts,
        FixedPose::default(),
        0,
        start,
        None,
    )
    .unwrap();
    assert_eq!(o.update(1_000_000), FixedPose::default());
    let here = FixedPose::from_micrometres(5, 7, 0);
    o.set_pose(here, 2_000_000);
    o.set_counts(&start);
    assert_eq!(o.update(3_000_000), here);
}

/// `CarriageExact` is public: an absurd trail handed to it directly is refused, not
/// overflowed (the bound `Layout` checks is checked there too).
#[test]
fn a_carriage_trail_past_the_bound_is_refused_by_the_integrator_itself() {
    use crate::carriage::CarriageGeometry;
    let g = CarriageGeometry {
        trail: 1e7,
        wheel_base: 0.02,
        metres_per_count: [0.01; 2],
        ..CarriageGeometry::SEED_004
    };
    assert!(CarriageExact::new(&g, crate::Pose2::default(), [0, 0], 0).is_none());
}
