//! Encoders as they are: the generator's edges where the drawn edge map says, within the
//! datasheet's bounds, and the capture latency late but never out of order.

mod common;

use common::*;
use host_bench::formats::tickstream::Event;
use host_bench::sim::generate::{
    generate, phases, EdgeErrors, EdgeMap, GenerateOptions, PowerOnPhase,
};
use robot_math::se2::Twist;

fn with_edges(name: &str, seed: u64) -> GenerateOptions {
    GenerateOptions {
        phase: PowerOnPhase::Random { seed },
        edges: EdgeErrors::preset(name).unwrap(),
        ..opts()
    }
}

/// Both wheels of seed 001's differential drive at `v` along +x for `secs`.
fn straight(v: f64, secs: f64) -> Constant {
    Constant {
        twist: Twist::new(v, 0.0, 0.0),
        duration: secs,
    }
}

#[test]
fn ticks_land_where_the_edge_map_puts_the_edges() {
    // At constant speed from power-on, count k's edge is crossed after
    // (edge(k) − start)·step of travel: start = edge(0) + φ·(edge(1) − edge(0)).
    let r = robot("seed001.toml");
    let v = 0.31;
    for (name, seed) in [("typical-cycle", 4), ("max-cycle", 9)] {
        let opts = with_edges(name, seed);
        let stream = generate(&r, None, &straight(v, 1.5), &opts).unwrap();
        let phase = phases(&r, opts.phase).unwrap();
        for (i, enc) in r.encoders.iter().enumerate() {
            let map = EdgeMap::draw(&opts.edges, seed, i, enc.metres_per_count);
            let start = map.edge(0) + phase[i] * (map.edge(1) - map.edge(0));
            let step = enc.metres_per_count;
            let ticks = ticks_of(&stream, i as u16);
            assert!(ticks.len() > 1000, "{}", ticks.len());
            for (k, &(t_ns, s)) in ticks.iter().enumerate() {
                assert_eq!(s, 1);
                let exact_ns = (map.edge(k as i64 + 1) - start) * step / v * 1e9;
                assert!(
                    (t_ns as f64 - exact_ns).abs() <= 0.51,
                    "{name} encoder {i} tick {}: {t_ns} ns, edge at {exact_ns}",
                    k + 1
                );
            }
        }
    }
}

#[test]
fn states_and_cycles_stay_within_the_datasheet() {
    // Constant speed: each interval is a state's width, four of them a cycle.
    let r = robot("seed001.toml");
    let v = 0.25;
    for (name, state_max, cycle_max) in [("typical-cycle", 5.0, 3.0), ("max-cycle", 30.0, 5.5)] {
        let mut widest: f64 = 0.0;
        for seed in 0..6 {
            let stream = generate(&r, None, &straight(v, 0.6), &with_edges(name, seed)).unwrap();
            for (i, enc) in r.encoders.iter().enumerate() {
                let count_ns = enc.metres_per_count / v * 1e9;
                let t: Vec<f64> = ticks_of(&stream, i as u16)
                    .iter()
                    .map(|&(t, _)| t as f64)
                    .collect();
                for w in t.windows(5) {
                    let state = (w[1] - w[0]) / count_ns * 90.0;
                    let cycle = (w[4] - w[0]) / count_ns * 90.0;
                    // Within a nanosecond's rounding of the bounds; a state across two lines
                    // takes their placement too.
                    let bound = state_max + cycle_max + 0.01;
                    assert!((state - 90.0).abs() <= bound, "{name}: state {state}");
                    assert!(
                        (cycle - 360.0).abs() <= cycle_max + 0.01,
                        "{name}: cycle {cycle}"
                    );
                    widest = widest.max((state - 90.0).abs());
                }
            }
        }
        // The draw goes to the datasheet's figure, not a fraction of it.
        assert!(
            widest > 0.8 * state_max,
            "{name}: widest state error {widest} °e"
        );
    }
}

#[test]
fn capture_latency_is_late_bounded_and_in_order() {
    let r = robot("seed001.toml");
    let v = 0.4;
    let seed = 2;
    let late = with_edges("typical", seed);
    let on_time = GenerateOptions {
        edges: EdgeErrors {
            capture_jitter_ns: 0,
            ..late.edges
        },
        ..late
    };
    let exact = generate(&r, None, &straight(v, 1.0), &on_time).unwrap();
    let late = generate(&r, None, &straight(v, 1.0), &late).unwrap();
    let jitter = EdgeErrors::HEDS_9040_TYPICAL.capture_jitter_ns;
    let mut delays = Vec::new();
    for i in 0..r.encoders.len() as u16 {
        // The same edges, stamped late.
        let (a, b) = (ticks_of(&exact, i), ticks_of(&late, i));
        assert_eq!(a.len(), b.len());
        assert!(
            b.windows(2).all(|w| w[0].0 <= w[1].0),
            "encoder {i} out of order"
        );
        for (&(t0, _), &(t1, _)) in a.iter().zip(&b) {
            delays.push(t1 as i64 - t0 as i64);
        }
    }
    assert!(
        delays.iter().all(|&d| (0..=jitter as i64).contains(&d)),
        "a delay outside [0, {jitter}] ns"
    );
    let (lo, hi) = (delays.iter().min().unwrap(), delays.iter().max().unwrap());
    assert!(
        hi - lo > jitter as i64 * 9 / 10,
        "latency barely varies: {lo}..{hi} ns"
    );
    // The stream says what made its edges.
    assert!(
        late.comments
            .iter()
            .any(|c| c.starts_with("encoder edges: HEDS-9040 typical")),
        "{:?}",
        late.comments
    );
    assert!(late.events.iter().any(|e| matches!(e, Event::Tick { .. })));
}

#[test]
fn an_unknown_preset_is_refused_with_the_choices() {
    let e = EdgeErrors::preset("typcial").unwrap_err().to_string();
    assert!(e.contains("must be ideal, typical, max"), "{e}");
}

#[test]
fn exact_learning_its_edges_holds_on_uneven_ones() {
    // An arc at constant twist from power-on on the datasheet's maximum cycle errors: `exact`
    // taking the edges a count apart (`exact+even`) against `exact` learning them (and placing
    // each wheel's start again on them), over seeds; and the learner's integer arithmetic against
    // its f64 twin fed the same learned positions.
    use host_bench::eval::replay::{replay, Mode};
    let r = robot("seed001.toml");
    let arc = Constant {
        twist: Twist::new(0.3, 0.0, 0.4),
        duration: 4.0,
    };
    let (mut plain, mut learned) = (Vec::new(), Vec::new());
    for seed in 0..6 {
        let stream = generate(&r, None, &arc, &with_edges("max-cycle", seed)).unwrap();
        let score = |name: &str| replay(&r, &stream, name, Mode::Timestamps).unwrap();
        let (p, l) = (score("exact+even"), score("exact"));
        let twin = score("exact-f64");
        assert!(
            (l.max_error_m - twin.max_error_m).abs() < 1e-6,
            "seed {seed}: {} vs its twin {}",
            l.max_error_m,
            twin.max_error_m
        );
        plain.push(p.median_error_m);
        learned.push(l.median_error_m);
    }
    let worst = |v: &[f64]| v.iter().cloned().fold(0.0, f64::max);
    assert!(
        worst(&learned) < 0.25 * worst(&plain),
        "median error, worst seed: learned {learned:?} against {plain:?}"
    );
}
