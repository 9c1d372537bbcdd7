//! The tick tracker's tests: interpolation, the start's placing and fitting again, the
//! 32-bit interpolation against its 64-bit form, and counts fed as ticks.

use super::*;

/// A place inside a count (of even edges) never reaches its upper edge: 1 - 2^-16.
const MAX_FRACTION: i64 = 0xFFFF;

#[test]
fn constant_speed_is_interpolated_exactly() {
    let mut w = TickTracker::new();
    // Edges every 1 ms, moving forward.
    for k in 1..=5u64 {
        w.tick(k * 1_000_000, 1);
    }
    assert_eq!(w.count(), 5);
    assert_eq!(w.position_q16(5_000_000), 5 << 16);
    assert_eq!(w.position_q16(5_250_000), (5 << 16) + (1 << 14));
    // Never past the next edge, however long the wheel is silent.
    assert_eq!(w.position_q16(99_000_000), (5 << 16) + MAX_FRACTION);
}

#[test]
fn backward_ticks_sit_on_the_upper_edge() {
    let mut w = TickTracker::new();
    w.tick(1_000, 1); // count 1, on edge 1
    w.tick(2_000, -1); // back over edge 1: count 0, position 1
    assert_eq!(w.count(), 0);
    assert_eq!(
        w.edge_position_q16(2_500),
        1 << 16,
        "no speed yet after a reversal"
    );
    w.tick(3_000, -1); // over edge 0: count -1, position 0
    assert_eq!(w.edge_position_q16(3_000), 0);
    assert_eq!(w.edge_position_q16(3_500), -(1 << 15));
}

#[test]
fn constant_acceleration_is_followed_between_ticks() {
    // s(t) = t² (steps, t in ms): edges at t = √k ms. Between edges the fit must land on
    // the parabola far closer than constant-speed interpolation does.
    let edge_at = |k: f64| (k.sqrt() * 1e6).round() as u64;
    let mut w = TickTracker::new();
    for k in 1..=9 {
        w.tick(edge_at(k as f64), 1);
    }
    let t = edge_at(9.5); // halfway (in distance) to edge 10
    let truth = 9.5 * 65536.0;
    let fitted = w.position_q16(t) as f64;
    // Constant speed from the last interval alone would say:
    let t8 = edge_at(8.0) as f64;
    let t9 = edge_at(9.0) as f64;
    let constant = (9.0 + (t as f64 - t9) / (t9 - t8)) * 65536.0;
    assert!(
        (fitted - truth).abs() < 0.01 * 65536.0,
        "fit {} vs {}",
        fitted / 65536.0,
        9.5
    );
    assert!((constant - truth).abs() > 3.0 * (fitted - truth).abs());
}

#[test]
fn braking_holds_at_the_predicted_stop() {
    // Intervals doubling: braking hard. Long after the last tick the estimate must hold
    // below the next edge, not run up to it.
    let mut w = TickTracker::new();
    for t in [1_000u64, 2_000, 4_000, 8_000] {
        w.tick(t, 1);
    }
    let held = w.position_q16(1_000_000);
    assert!(
        held > 4 << 16 && held < (4 << 16) + MAX_FRACTION,
        "{}",
        held as f64 / 65536.0
    );
    assert_eq!(held, w.position_q16(9_000_000), "holds once stopped");
}

#[test]
fn a_wheel_powered_on_inside_its_count_is_placed_by_its_first_ticks() {
    // 0.3 of a count in at power-on, then 1000 counts/s: ticks at 0.7, 1.7, 2.7 ms.
    let mut w = TickTracker::starting(10, 0);
    w.tick(700_000, 1);
    assert_eq!(
        w.phase_q16(),
        1 << 15,
        "one tick: not placed yet, the middle"
    );
    w.tick(1_700_000, 1);
    assert!((w.phase_q16() - 19_661).abs() <= 1, "{}", w.phase_q16()); // 0.3 count
                                                                       // Travel since power-on: 2.5 counts at 2.5 ms.
    let p = w.position_q16(2_500_000) - (10 << 16);
    assert!((p - 163_840).abs() <= 2, "{}", p as f64 / 65536.0);
}

#[test]
fn wheels_that_start_abruptly_after_a_rest_are_placed_together() {
    // At rest for 1 s, then 1000 and 600 counts/s at once from 0.35 and 0.8 of a count.
    let start = 1_000_000_000u64;
    let ticks = |phi: f64, per_s: f64| -> [u64; 2] {
        core::array::from_fn(|k| start + ((k as f64 + 1.0 - phi) / per_s * 1e9) as u64)
    };
    let mut wheels = [TickTracker::starting(0, 0), TickTracker::starting(0, 0)];
    for (w, t) in wheels
        .iter_mut()
        .zip([ticks(0.35, 1000.0), ticks(0.8, 600.0)])
    {
        for &t in &t {
            w.tick(t, 1);
        }
    }
    // Neither wheel's own ticks can place it (any start before the first tick fits).
    assert!(wheels.iter().all(|w| w.phase_q16() == 1 << 15));
    place_together(&mut wheels);
    // Common window: [0.35 ms after the start − 1 ms, ...]: each wheel within half the
    // window at its own speed, under half a count; here both land within 0.2 count.
    for (w, phi) in wheels.iter().zip([0.35, 0.8]) {
        let got = w.phase_q16() as f64 / 65536.0;
        assert!((got - phi).abs() < 0.2, "{got} vs {phi}");
    }
}

#[test]
fn an_abrupt_start_on_uneven_edges_is_placed_together_once_they_are_learned() {
    // At rest for 1 s, then at full speed at once, on encoders whose edges sit off their
    // whole-count places by a HEDS-9040's typical state widths (counts, by edge mod 4).
    let start = 1_000_000_000u64;
    let (a, b) = (
        [0.0267, -0.0289, -0.0175, 0.0196],
        [-0.0117, -0.0321, 0.0235, 0.0203],
    );
    let b2 = [0.0235, 0.0203, -0.0117, -0.0321];
    // Each of the first three lands outside its bound when the wheels are placed together
    // on even edges only (at their first ticks, before anything is learned).
    for (offsets, phases, speeds) in [
        ([a, b], [0.05, 0.05], [1300.0, 700.0]),
        ([a, b], [0.05, 0.41], [1300.0, 700.0]),
        ([a, b2], [0.23, 0.05], [1300.0, 700.0]),
        ([a, b], [0.7458, 0.5666], [1300.0, 700.0]),
        ([a, b], [0.4315, 0.8833], [700.0, 1300.0]),
        ([b, a], [0.25, 0.55], [1000.0, 900.0]),
    ] {
        // (time, wheel) of each wheel's first 300 edges, in time order.
        let mut ticks: Vec<(u64, usize)> = (0..2)
            .flat_map(|j| {
                let (off, phi, v) = (offsets[j], phases[j], speeds[j]);
                (1..=300).map(move |m: i64| {
                    let place = m as f64 + off[(m & 3) as usize];
                    (start + ((place - phi) / v * 1e9) as u64, j)
                })
            })
            .collect();
        ticks.sort();
        let mut wheels = [TickTracker::starting(0, 0), TickTracker::starting(0, 0)];
        for (t, j) in ticks {
            tick_wheel(&mut wheels, j, t, 1);
            // An update after every tick.
            learn_edges(&mut wheels);
        }
        // The window each wheel's start must lie in (s): from where its count's lower
        // edge is to its first tick's, at its first interval's speed; and their overlap.
        let window = |j: usize| {
            let (off, phi, v) = (offsets[j], phases[j], speeds[j]);
            let t1 = (1.0 + off[1] - phi) / v;
            (t1 - (1.0 + off[1] - off[0]) / v, t1)
        };
        let (lo, hi) = (window(0).0.max(window(1).0), window(0).1.min(window(1).1));
        for ((w, phi), v) in wheels.iter().zip(phases).zip(speeds) {
            assert!(
                !w.placed,
                "{phases:?}: no fit tells an abrupt start's instant"
            );
            let got = w.phase_q16() as f64 / 65536.0;
            // Within half the common window at its own speed (the bound on even edges),
            // give or take what learning leaves: 0.01 count.
            let bound = (hi - lo) / 2.0 * v + 0.01;
            assert!(
                (got - phi).abs() < bound,
                "{phases:?}: {got} vs {phi}, bound {bound}"
            );
        }
    }
}

/// Where a wheel's start from rest at power-on is placed, against where it stood: a start
/// at constant acceleration (5000 counts/s² up to 1000 counts/s) in direction `dir`,
/// `pause` seconds at a standstill after its fifth tick, on an encoder whose edges sit off
/// by a HEDS-9040's typical state widths and each code-wheel line up to ±1/60 count off,
/// at 24 power-on places. Returns the errors (counts) after 300 ticks, with an update
/// after each, and those of the fit through the first four ticks on the same learned
/// places; and whether every wheel's own fit placed it.
fn start_errors_from_rest(dir: i8, pause: f64) -> (Vec<f64>, Vec<f64>, bool) {
    let kinds = [0.0267, -0.0289, -0.0175, 0.0196];
    let mut seed = 7u64;
    let mut unit = move || {
        seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (seed >> 11) as f64 / (1u64 << 53) as f64
    };
    let (mut spread, mut first_four, mut placed) = (Vec::new(), Vec::new(), true);
    for _ in 0..24 {
        let (phi, q) = (0.05 + 0.9 * unit(), (unit() * 4.0) as i64);
        let lines: Vec<f64> = (0..200).map(|_| (unit() - 0.5) / 30.0).collect();
        // Edge e's place, counts; the k-th tick (from 1) crosses edge k forward, 1 − k
        // backward, after this much travel.
        let place = |e: i64| {
            let line = lines[((e + q).div_euclid(4) + 100) as usize];
            e as f64 + kinds[(e + q).rem_euclid(4) as usize] + line
        };
        let travel = |k: i64| {
            if dir > 0 {
                place(k) - phi
            } else {
                phi - place(1 - k)
            }
        };
        // s(t) = A t² to the top speed at 0.1 s (25 counts), then 1000 counts/s.
        let at = |s: f64| {
            if s < 25.0 {
                (s / 5000.0).sqrt()
            } else {
                0.1 + (s - 25.0) / 1000.0
            }
        };
        let mut w = TickTracker::starting(0, 0);
        let mut times = Vec::new();
        for k in 1..=300 {
            let stood = if k > 5 { pause } else { 0.0 };
            let t = ((at(travel(k)) + stood) * 1e9) as u64;
            times.push(t);
            w.tick(t, dir);
            w.learn();
        }
        placed &= w.placed;
        let got = w.phase_q16() as f64 / 65536.0;
        spread.push((got - phi).abs());
        let places = w.first_places_q16([0, 1, 2, 3]).map(|p| p << 8);
        let u = start::start_position_on_q16(0, &times[..4], &places).unwrap_or(1 << 15);
        let four = if dir > 0 { u } else { (1 << 16) - u };
        first_four.push((four as f64 / 65536.0 - phi).abs());
    }
    spread.sort_by(f64::total_cmp);
    first_four.sort_by(f64::total_cmp);
    (spread, first_four, placed)
}

#[test]
fn a_start_from_rest_is_fitted_again_through_spread_ticks() {
    for dir in [1, -1] {
        let (spread, first_four, placed) = start_errors_from_rest(dir, 0.0);
        let (median, worst) = (spread[12], spread[23]);
        // Each line's placement, magnified by the cubic's extrapolation back to rest.
        assert!(placed && median < 0.05 && worst < 0.2, "{dir}: {spread:?}");
        assert!(
            median < first_four[12] && worst < first_four[23],
            "{dir}: {spread:?} {first_four:?}"
        );
    }
}

#[test]
fn a_pause_after_the_fifth_tick_keeps_the_fit_off_the_ninth() {
    // Standing 0.2 s after the fifth tick: the ninth says nothing of the start's curve.
    let (spread, _, placed) = start_errors_from_rest(1, 0.2);
    assert!(
        placed && spread[12] < 0.05 && spread[23] < 0.25,
        "{placed} {spread:?}"
    );
}

#[test]
fn edges_learned_even_leave_a_joint_placement_on_whole_counts() {
    // The abrupt start of `wheels_that_start_abruptly_after_a_rest_are_placed_together`,
    // each wheel's learner holding offsets under `UNEVEN_Q16` (what windows learn of even
    // edges: their time stamps' rounding): placed exactly as with nothing learned.
    let start = 1_000_000_000u64;
    let ticks = |phi: f64, per_s: f64| -> [u64; 6] {
        core::array::from_fn(|k| start + ((k as f64 + 1.0 - phi) / per_s * 1e9) as u64)
    };
    let place = |offsets: [i32; 4]| {
        let mut wheels = [TickTracker::starting(0, 0), TickTracker::starting(0, 0)];
        for w in &mut wheels {
            w.learner = Learner::with_offsets_q16(offsets);
        }
        let mut all: Vec<(u64, usize)> = (0..2)
            .flat_map(|j| {
                let (phi, v) = [(0.35, 1000.0), (0.8, 600.0)][j];
                ticks(phi, v).map(|t| (t, j))
            })
            .collect();
        all.sort();
        for (t, j) in all {
            tick_wheel(&mut wheels, j, t, 1);
        }
        wheels.map(|w| w.phase_q16())
    };
    assert_eq!(place([300, -200, 100, -300]), place([0; 4]));
}

#[test]
fn corrupt_steps_are_ignored() {
    let mut w = TickTracker::new();
    w.tick(1, 3);
    w.tick(2, 0);
    assert_eq!(w.count(), 0);
    assert_eq!(w.position_q16(10), 0);
}

mod position_in_32_bits {
    use super::*;
    use proptest::prelude::*;

    /// [`TickTracker::edge_position_q16`] as it was written in 64 bits throughout.
    fn in_64_bits(w: &TickTracker, t_ns: u64) -> i64 {
        let at_edge = (w.edge << 16) + w.learner.offset_q16(w.edge);
        let Some(nz) = w.interval else {
            return at_edge;
        };
        let interval = nz.get();
        let since = t_ns.saturating_sub(w.last_t);
        if interval >= 1 << 40 {
            return at_edge;
        }
        let (dir, table) = (w.dir, &w.learner);
        let back = w.edge - dir as i64;
        let s2 = table.span_q16(back, dir);
        let next = table.span_q16(w.edge, dir);
        let x = ((since.min(interval * 8) << 16) / nz) as i64;
        let frac = match w.prev_interval {
            None => (s2 * x) >> 16,
            Some(t1) => {
                let s1 = table.span_q16(back - dir as i64, dir);
                let rho = ((interval << 16) / t1).clamp(1 << 12, 1 << 20) as i64;
                let c = (s2 - ((rho * s1) >> 16)) * rho / ((1 << 16) + rho);
                let x = if c < 0 {
                    x.min((s2 + c) * (1 << 16) / (-2 * c))
                } else {
                    x
                };
                ((s2 * x) >> 16) + ((c * (x + ((x * x) >> 16))) >> 16)
            }
        };
        at_edge + dir as i64 * frac.clamp(0, next - 1)
    }

    proptest! {
        /// The 32-bit form (64-bit products) gives what the 64-bit one gave, on any learned
        /// offsets, intervals and instant.
        #[test]
        fn the_interpolation_in_32_bits_equals_it_in_64(
            offsets in proptest::array::uniform4(-26_214i32..=26_214),
            edge in -100_000i64..100_000,
            forward in proptest::bool::ANY,
            interval in 1u64..1 << 41,
            prev in proptest::option::of(1u64..1 << 41),
            since in 0u64..1 << 43,
        ) {
            let mut w = TickTracker::starting(edge, 0);
            w.learner = Learner::with_offsets_q16(offsets);
            w.edge = edge;
            w.dir = if forward { 1 } else { -1 };
            w.last_t = 1 << 20;
            w.interval = NonZeroU64::new(interval);
            w.prev_interval = prev.and_then(NonZeroU64::new);
            let t = w.last_t + since;
            prop_assert_eq!(w.edge_position_q16(t), in_64_bits(&w, t));
        }
    }
}

mod counts_as_ticks {
    use super::super::counts_as_ticks;

    #[test]
    fn interleaves_and_catches_up() {
        let mut applied = [0i64, 5];
        let mut seen = [0i64; 2];
        let mut order = [0usize; 16];
        let mut n = 0;
        counts_as_ticks(&mut applied, &[3, 3], |j, s| {
            seen[j] += s as i64;
            order[n] = j;
            n += 1;
        });
        assert_eq!(applied, [3, 3]);
        assert_eq!(seen, [3, -2]);
        assert_eq!(&order[..n], &[0, 1, 0, 1, 0]);
    }
}

/// A wheel shaken across an edge at power-on (a motor holding it, a bump, the robot set down)
/// ticks over that edge and back: it stood by the edge, not anywhere in its count, and is
/// placed there, for the whole run (half a count off in the middle of its count, where a
/// wheel's first ticks cannot place it otherwise: a heading error for good on a differential
/// drive). Both ways.
#[test]
fn a_wheel_shaken_across_an_edge_at_power_on_is_placed_on_it() {
    // (power-on place inside count 0, the first shake's direction)
    for (p0, dir) in [(0.997f64, 1i8), (0.004, -1)] {
        let mut w = TickTracker::new();
        for (k, t_ms) in [1u64, 9, 23, 30].into_iter().enumerate() {
            w.tick(t_ms * 1_000_000, if k % 2 == 0 { dir } else { -dir });
        }
        assert_eq!(w.count(), 0);
        // Then it drives off that way from rest at 300 ms, 1 000 counts/s²: past 20 edges.
        let edge_at = |k: f64| 300_000_000 + (((k - p0).abs() / 500.0).sqrt() * 1e9) as u64;
        let edges: Vec<f64> = if dir > 0 {
            (1..=20).map(f64::from).collect()
        } else {
            (0..20).map(|k| -f64::from(k)).collect()
        };
        for &e in &edges {
            w.tick(edge_at(e), dir);
        }
        // Its travel since power-on, plus count 0, at the last edge.
        let last = *edges.last().unwrap();
        let truth = (last - p0) * 65536.0;
        let got = w.position_q16(edge_at(last)) as f64;
        assert!(
            (got - truth).abs() < 0.01 * 65536.0,
            "shaken first {dir:+}: {} counts, truth {}",
            got / 65536.0,
            truth / 65536.0
        );
    }
}

/// The same on uneven edges: once they are learned, a wheel shaken across its first edge at
/// power-on is placed again, on where that edge really is. Shaken forward first, then driven
/// forward; shaken backward first, then driven forward (the other way).
#[test]
fn a_wheel_shaken_across_an_edge_at_power_on_is_placed_on_it_once_its_edges_are_learned() {
    // Offsets of the edges off their whole-count places (counts, by edge mod 4): states 0.775
    // to 1.25 counts wide, inside a HEDS-9040's maximum (30 °e, a third of a count).
    let off = [0.1, -0.125, 0.125, -0.1];
    // (the edge shaken across, where it really is, the power-on place 0.003 count on the
    // side the first shake leaves from, the first shake's direction)
    for (edge, dir) in [(1i64, 1i8), (0, -1)] {
        let at = edge as f64 + off[edge as usize];
        let p0 = at - 0.003 * dir as f64;
        let mut w = [TickTracker::starting(0, 0)];
        for (k, t_ms) in [1u64, 5, 9, 12].into_iter().enumerate() {
            tick_wheel(
                &mut w,
                0,
                t_ms * 1_000_000,
                if k % 2 == 0 { dir } else { -dir },
            );
        }
        let whole = if dir > 0 { 1 << 16 } else { 0 };
        assert_eq!(
            w[0].phase_q16(),
            whole,
            "on the edge's whole-count place first"
        );
        // Then forward at full speed at once, 1 000 counts/s from 1 s, an update after every
        // tick: over edge 1 first (shaken backward, the wheel stands above edge 0).
        for m in 1..=300i64 {
            let place = m as f64 + off[(m & 3) as usize];
            tick_wheel(&mut w, 0, 1_000_000_000 + ((place - p0) * 1e6) as u64, 1);
            learn_edges(&mut w);
        }
        let got = w[0].phase_q16() as f64 / 65536.0;
        assert!(
            (got - at).abs() < 0.01,
            "shaken first {dir:+}: {got} vs edge {edge} at {at}"
        );
    }
}
