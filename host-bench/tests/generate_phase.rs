//! Power-on phases: each encoder starts somewhere inside a count, so its first
//! forward tick comes after (1 − φ)·step of travel, its first backward one after φ·step, and
//! its count is floor((φ·step + rolled) / step).

mod common;

use std::f64::consts::TAU;

use common::*;
use host_bench::formats::tickstream::{Event, TickStream};
use host_bench::sim::generate::{generate, phases, GenerateOptions, PowerOnPhase};
use host_bench::sim::trajectory::{self, build};
use robot_math::se2::Twist;

fn with(phase: PowerOnPhase) -> GenerateOptions {
    GenerateOptions { phase, ..opts() }
}

#[test]
fn at_fraction_f_the_first_forward_tick_comes_after_one_minus_f_steps() {
    // Constant speed from t = 0: forward tick k at (k − f)·step/v, backward tick k at
    // (k − 1 + f)·step/|v|, each to the nanosecond.
    let v = 0.37;
    for f in [0.0, 0.25, 0.5, 0.734512, 0.999] {
        // seed 001: both wheels forward at v. seed 000: along wheel A, which rolls at v while
        // B and C roll backwards at v/2.
        let diff = robot("seed001.toml");
        let omni = robot("seed000-0.4mm.toml");
        let a = omni.encoders[0].wheel;
        for (r, twist, duration) in [
            (&diff, Twist::new(v, 0.0, 0.0), 0.2),
            (&omni, Twist::new(v * a.ux, v * a.uy, 0.0), 0.3),
        ] {
            let traj = Constant { twist, duration };
            let stream = generate(r, None, &traj, &at_phase(f)).unwrap();
            for (i, enc) in r.encoders.iter().enumerate() {
                let speed = enc.wheel.rolling_speed(twist);
                let step = enc.metres_per_count;
                let ticks = ticks_of(&stream, i as u16);
                let what = format!("{} encoder {i} at phase {f}", r.name);
                assert_count(
                    net(&stream, i as u16),
                    f * step + speed * duration,
                    step,
                    &what,
                );
                assert!(ticks.len() > 50, "{what}");
                for (k, &(t_ns, s)) in ticks.iter().enumerate() {
                    let k = (k + 1) as f64;
                    let travel = if speed > 0.0 { k - f } else { k - 1.0 + f } * step;
                    let exact_ns = travel / speed.abs() * 1e9;
                    assert_eq!(s as f64, speed.signum(), "{what}");
                    assert!(
                        (t_ns as f64 - exact_ns).abs() <= 0.51,
                        "{what}, tick {k}: {t_ns} ns, exact {exact_ns}"
                    );
                }
            }
        }
    }
}

/// FNV-1a over the events' `Debug` text: a fingerprint of a whole stream's rows.
fn fingerprint(stream: &TickStream) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for e in &stream.events {
        for b in format!("{e:?}").bytes() {
            h ^= b as u64;
            h = h.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
    h
}

#[test]
fn zero_reproduces_the_edge_aligned_generator_bit_for_bit() {
    // Fingerprints of edge-aligned streams: a body-fixed axle, the omni triangle, and the
    // carriage with its absolute encoder. `PowerOnPhase::Zero` must give the same rows as the
    // generator before power-on phases (commit cb2dc06) did, but for the rolled distance now
    // being the exact integral of the speed interpolant (`generate/cheb.rs`) where it was
    // 5-point quadrature: against cb2dc06's streams 1, 4 and 311 tick instants of these three
    // moved by 1 ns (an instant within rounding of a half nanosecond), nothing else. The root
    // finder's convergence test taken before its bracket test (one Newton step per tick where
    // it used to bisect some 30 times) moved 0, 2 and 57 rows more, each by 1 ns: both stop
    // within 1 ps of the root, and these instants lie that close to a half nanosecond.
    for (file, name, events, expected) in [
        (
            "seed001.toml",
            "seed002-circle",
            16574,
            0x19a1_2e95_b9b4_64c3u64,
        ),
        (
            "seed000-0.1mm.toml",
            "seed000-bezier-90deg",
            16988,
            0xab8f_44a6_3dce_bcc3,
        ),
        (
            "seed004.toml",
            "seed002-square",
            262938,
            0x423e_6816_189c_d528,
        ),
    ] {
        let r = robot(file);
        let traj = build(name).unwrap();
        let zero = generate(&r, None, traj.as_ref(), &edge_aligned()).unwrap();
        assert_eq!(zero.events.len(), events, "{file} {name}");
        assert_eq!(fingerprint(&zero), expected, "{file} {name}");
        // A fraction of 0 is the same start.
        let f0 = generate(&r, None, traj.as_ref(), &at_phase(0.0)).unwrap();
        assert_eq!(f0.events, zero.events, "{file} {name}");
    }
}

#[test]
fn random_phases_are_reproducible_from_the_seed_and_written_into_the_stream() {
    let r = robot("seed000-0.4mm.toml");
    let traj = build("seed002-diagonal").unwrap();
    let run = |seed| {
        generate(
            &r,
            None,
            traj.as_ref(),
            &with(PowerOnPhase::Random { seed }),
        )
    };
    let (a, b, c) = (run(7).unwrap(), run(7).unwrap(), run(8).unwrap());
    assert_eq!(a, b);
    assert_ne!(a.events, c.events);
    let p7 = phases(&r, PowerOnPhase::Random { seed: 7 }).unwrap();
    let p8 = phases(&r, PowerOnPhase::Random { seed: 8 }).unwrap();
    assert_eq!(p7.len(), 3);
    assert!(p7.iter().chain(&p8).all(|p| (0.0..1.0).contains(p)));
    assert!(p7[0] != p7[1] && p7[1] != p7[2] && p7[0] != p7[2], "{p7:?}");
    assert!(p7.iter().zip(&p8).all(|(x, y)| x != y), "{p7:?} {p8:?}");
    // The comment line names the rule and every encoder's phase.
    let line = a
        .comments
        .iter()
        .find(|c| c.starts_with("power-on phase:"))
        .unwrap();
    let expected = format!(
        "power-on phase: random seed 7; encoder 0 (A) at {:.6} of a count, encoder 1 (B) at \
         {:.6} of a count, encoder 2 (C) at {:.6} of a count",
        p7[0], p7[1], p7[2]
    );
    assert_eq!(line, &expected);
    // The default is random with seed 0.
    assert_eq!(
        GenerateOptions::default().phase,
        PowerOnPhase::Random { seed: 0 }
    );
    assert_eq!(PowerOnPhase::default(), PowerOnPhase::Random { seed: 0 });
}

#[test]
fn random_phases_are_uniform_and_independent_per_encoder() {
    // Over 2000 seeds each encoder's phase covers [0, 1) evenly (mean 1/2, a tenth of them
    // in each tenth of the range, within sampling noise) and is uncorrelated with the others'.
    let r = robot("seed000-0.4mm.toml");
    let n = 2000;
    let all: Vec<Vec<f64>> = (0..n)
        .map(|seed| phases(&r, PowerOnPhase::Random { seed }).unwrap())
        .collect();
    for i in 0..3 {
        let xs: Vec<f64> = all.iter().map(|p| p[i]).collect();
        let mean = xs.iter().sum::<f64>() / n as f64;
        assert!((mean - 0.5).abs() < 0.03, "encoder {i}: mean {mean}");
        for tenth in 0..10 {
            let lo = tenth as f64 / 10.0;
            let count = xs.iter().filter(|&&x| x >= lo && x < lo + 0.1).count();
            assert!(
                (150..=250).contains(&count),
                "encoder {i}, tenth {tenth}: {count}"
            );
        }
        for j in 0..i {
            let cov = all.iter().map(|p| (p[i] - 0.5) * (p[j] - 0.5)).sum::<f64>() / n as f64;
            // Correlation = cov / (1/12); its noise is about 1/sqrt(n) = 0.022.
            assert!(
                (cov * 12.0).abs() < 0.08,
                "encoders {i}, {j}: correlation {}",
                cov * 12.0
            );
        }
    }
    // Encoder i's phase depends on the seed and i only: a robot with fewer encoders gets the
    // same first phases.
    let two = robot("seed001.toml");
    for seed in [0, 1, 99] {
        let p2 = phases(&two, PowerOnPhase::Random { seed }).unwrap();
        let p3 = phases(&r, PowerOnPhase::Random { seed }).unwrap();
        assert_eq!(p2[..], p3[..2]);
    }
}

#[test]
fn total_counts_are_the_floor_of_the_phase_plus_the_rolled_distance() {
    // seed 001 round the circle (a wheel at y rolls 2πR − y·2π) and seed 000 along the line
    // (wheel i rolls u_ix·L), for several seeds and fractions. The stream's own comment lines
    // give the same counts.
    let diff = robot("seed001.toml");
    let omni = robot("seed000-0.4mm.toml");
    let circle = build("seed002-circle").unwrap();
    let line = build("seed000-line").unwrap();
    let r_circle = trajectory::SEED002_CIRCLE_RADIUS_M;
    let options = [
        PowerOnPhase::Random { seed: 0 },
        PowerOnPhase::Random { seed: 1 },
        PowerOnPhase::Random { seed: 12345 },
        PowerOnPhase::Fraction(0.5),
        PowerOnPhase::Fraction(0.9),
    ];
    for phase in options {
        let o = with(phase);
        for (r, traj) in [(&diff, &circle), (&omni, &line)] {
            let stream = generate(r, None, traj.as_ref(), &o).unwrap();
            let off = offsets(r, &o);
            for (i, enc) in r.encoders.iter().enumerate() {
                let rolled = if r.name == "seed001" {
                    TAU * r_circle - enc.wheel.y * TAU
                } else {
                    enc.wheel.ux * trajectory::SEED000_LENGTH_M
                };
                let what = format!("{} encoder {i}, {phase}", r.name);
                let count = net(&stream, i as u16);
                assert_count(count, off[i] + rolled, enc.metres_per_count, &what);
                let own = format!("encoder {i} ({}): rolled ", enc.name);
                let c = stream
                    .comments
                    .iter()
                    .find(|c| c.starts_with(&own))
                    .unwrap();
                assert!(c.ends_with(&format!(", {count} counts")), "{what}: {c}");
            }
        }
    }
}

#[test]
fn only_an_encoder_on_an_edge_ticks_the_instant_it_backs_away() {
    // The 1 m square with a fixed heading: wheels A and C of seed 000 start by rolling
    // backwards. From an edge (φ = 0) they tick −1 at t = 0, the special case every stream
    // used to start with; from mid-count only after half a count of travel.
    let r = robot("seed000-0.4mm.toml");
    let traj = build("seed002-square").unwrap();
    let first_tick = |o: &GenerateOptions| {
        let stream = generate(&r, None, traj.as_ref(), o).unwrap();
        stream
            .events
            .iter()
            .find_map(|e| match e {
                Event::Tick { t_ns, .. } => Some(*t_ns),
                _ => None,
            })
            .unwrap()
    };
    assert_eq!(first_tick(&edge_aligned()), 0);
    assert!(first_tick(&at_phase(0.5)) > 1_000_000);
    assert!(first_tick(&opts()) > 0);
}

#[test]
fn a_fraction_outside_zero_to_one_is_refused() {
    let r = robot("seed001.toml");
    let traj = build("seed000-line").unwrap();
    for f in [1.0, 1.5, -0.1, f64::NAN, f64::INFINITY] {
        let e = phases(&r, PowerOnPhase::Fraction(f)).unwrap_err();
        assert!(e.to_string().contains("[0, 1)"), "{f}: {e}");
        let e = generate(&r, None, traj.as_ref(), &at_phase(f)).unwrap_err();
        assert!(e.to_string().contains("power-on phase"), "{f}: {e}");
    }
    assert_eq!(
        phases(&r, PowerOnPhase::Fraction(0.999_999)).unwrap(),
        vec![0.999_999; 2]
    );
}
