//! The exact tick generator: tick instants against closed forms, counts against closed-form
//! rolled distances, reversals, ordering, rows, refusals, and a round trip through a
//! tick-stream file. (The catalogue's shapes: `catalogue.rs`; seed 004's carriage:
//! `generate_carriage.rs`; power-on phases: `generate_phase.rs`; our robots: `layouts.rs`.)

mod common;

use std::f64::consts::{PI, TAU};
use std::fs;
use std::path::Path;

use common::*;
use host_bench::formats::robot::{AbsMeasures, Robot};
use host_bench::formats::tickstream::{self, Event};
use host_bench::sim::generate::{
    abs_code, check_drive, generate, is_differential, GenerateOptions,
};
use host_bench::sim::trajectory::{self, build, catalogue, Drive, Trajectory};
use robot_math::se2::{wrap_angle, Pose2, Twist};

// ---------------------------------------------------------------------------------------------
// Hand-made trajectories with closed forms.

/// Back and forth along body x: x(t) = A·sin(2πft), heading 0.
struct Shuttle {
    amplitude: f64,
    freq: f64,
    duration: f64,
}

impl Shuttle {
    fn x(&self, t: f64) -> f64 {
        self.amplitude * (TAU * self.freq * t).sin()
    }
}

impl Trajectory for Shuttle {
    fn duration(&self) -> f64 {
        self.duration
    }
    fn pose(&self, t: f64) -> Pose2 {
        Pose2::new(self.x(t), 0.0, 0.0)
    }
    fn twist(&self, t: f64) -> Twist {
        let w = TAU * self.freq;
        Twist::new(self.amplitude * w * (w * t).cos(), 0.0, 0.0)
    }
}

// ---------------------------------------------------------------------------------------------
// The generator.

#[test]
fn constant_speed_line_ticks_at_k_step_over_v_to_one_ns() {
    // Encoders powered on exactly on an edge, so that tick k is at k·step/v
    // (generate_phase.rs checks the other phases: tick k at (k − φ)·step/v).
    // Differential robot: both wheels roll at v along +x.
    let r = robot("seed001.toml");
    let v = 0.37;
    let traj = Constant {
        twist: Twist::new(v, 0.0, 0.0),
        duration: 2.5,
    };
    let stream = generate(&r, None, &traj, &edge_aligned()).unwrap();
    for (i, enc) in r.encoders.iter().enumerate() {
        let step = enc.metres_per_count;
        let ticks = ticks_of(&stream, i as u16);
        assert_eq!(ticks.len() as i64, (v * 2.5 / step).floor() as i64);
        for (k, &(t_ns, s)) in ticks.iter().enumerate() {
            assert_eq!(s, 1);
            let exact_ns = (k + 1) as f64 * step / v * 1e9;
            // Rounded to the nearest ns from an instant found to 1 ps.
            assert!(
                (t_ns as f64 - exact_ns).abs() <= 0.51,
                "encoder {i} tick {}: {t_ns} ns, exact {exact_ns}",
                k + 1
            );
        }
    }

    // Omni robot: move along wheel A's rolling direction; A rolls at v, B and C at
    // v·cos 120° = −v/2 (backwards), and every instant is k·step/|speed|.
    let r = robot("seed000-0.4mm.toml");
    let a = r.encoders[0].wheel;
    let traj = Constant {
        twist: Twist::new(v * a.ux, v * a.uy, 0.0),
        duration: 1.3,
    };
    let stream = generate(&r, None, &traj, &edge_aligned()).unwrap();
    for (i, enc) in r.encoders.iter().enumerate() {
        let speed = enc.wheel.rolling_speed(traj.twist);
        let step = enc.metres_per_count;
        let ticks = ticks_of(&stream, i as u16);
        assert_count(net(&stream, i as u16), speed * 1.3, step, enc.name.as_str());
        for (k, &(t_ns, s)) in ticks.iter().enumerate() {
            assert_eq!(s as f64, speed.signum());
            // Forward: edge k+1 at (k+1)·step/v. Backward: count −(k+1) starts when the
            // distance falls below −k·step (floor), i.e. at k·step/|v|.
            let edges = if speed > 0.0 { k + 1 } else { k } as f64;
            let exact_ns = edges * step / speed.abs() * 1e9;
            assert!(
                (t_ns as f64 - exact_ns).abs() <= 0.51,
                "encoder {i} tick {k}: {t_ns} ns, exact {exact_ns}"
            );
        }
    }
}

#[test]
fn a_long_constant_speed_run_does_not_drift() {
    // 100 s at 0.4 m/s (seed 001's 40 m) with 0.4 mm counts: 100 000 ticks per wheel, the last
    // still within half a nanosecond of k·step/v (the running distance is summed with
    // compensation over 100 000 intervals). Edge-aligned at power-on for that closed form.
    let r = robot("seed001.toml");
    let v = 0.4;
    let traj = Constant {
        twist: Twist::new(v, 0.0, 0.0),
        duration: 100.0 + 1e-6,
    };
    let start = std::time::Instant::now();
    let stream = generate(&r, None, &traj, &edge_aligned()).unwrap();
    println!("40 m, 2 wheels: {:?}", start.elapsed());
    let step = r.encoders[0].metres_per_count;
    let ticks = ticks_of(&stream, 0);
    assert_eq!(ticks.len(), 100_000);
    let worst = ticks
        .iter()
        .enumerate()
        .map(|(k, &(t_ns, _))| (t_ns as f64 - (k + 1) as f64 * step / v * 1e9).abs())
        .fold(0.0, f64::max);
    assert!(worst <= 0.51, "worst tick error {worst} ns");
}

#[test]
fn total_ticks_equal_floor_of_the_closed_form_rolled_distance() {
    // Random power-on phases (the default): the count is floor((φ·step + rolled) / step).
    // Differential robot, heading along the path: a wheel at y_i rolls L − y_i·Δθ.
    let diff = robot("seed001.toml");
    let off = offsets(&diff, &opts());
    let cases = [
        (
            "seed002-circle",
            TAU * trajectory::SEED002_CIRCLE_RADIUS_M,
            TAU,
        ),
        (
            "seed001-figure-eight",
            trajectory::SEED001_FIGURE_EIGHT_M,
            0.0,
        ),
        ("seed001-curve", trajectory::SEED001_CURVE_M, PI / 2.0),
        ("umbmark-ccw", 4.0 * trajectory::UMBMARK_SIDE_M, TAU),
        ("umbmark-cw", 4.0 * trajectory::UMBMARK_SIDE_M, -TAU),
    ];
    for (name, length, turn) in cases {
        let traj = build(name).unwrap();
        let stream = generate(&diff, None, traj.as_ref(), &opts()).unwrap();
        for (i, enc) in diff.encoders.iter().enumerate() {
            let rolled = length - enc.wheel.y * turn;
            assert_count(
                net(&stream, i as u16),
                off[i] + rolled,
                enc.metres_per_count,
                &format!("{name} encoder {i}"),
            );
        }
    }
    // Omni robot on a line along +x with a fixed heading: wheel i rolls u_ix·L.
    let omni = robot("seed000-0.1mm.toml");
    let off = offsets(&omni, &opts());
    let traj = build("seed000-line").unwrap();
    let stream = generate(&omni, None, traj.as_ref(), &opts()).unwrap();
    for (i, enc) in omni.encoders.iter().enumerate() {
        let rolled = enc.wheel.ux * trajectory::SEED000_LENGTH_M;
        assert_count(
            net(&stream, i as u16),
            off[i] + rolled,
            enc.metres_per_count,
            &format!("seed000-line encoder {i}"),
        );
    }
    // Omni robot turning 180° along a Bézier: seed 000's three rolling directions sum to zero
    // and the wheels have equal levers, so the three rolled distances add up to 3·lever·Δθ
    // whatever the path.
    let traj = build("seed000-bezier-180deg").unwrap();
    let stream = generate(&omni, None, traj.as_ref(), &opts()).unwrap();
    let lever: f64 = omni.encoders[0].wheel.row()[2];
    let total: i64 = (0..3).map(|i| net(&stream, i)).sum();
    let step = omni.encoders[0].metres_per_count;
    let expected = (3.0 * lever * PI + off.iter().sum::<f64>()) / step;
    assert!(
        (total as f64 - expected).abs() <= 3.0,
        "sum of counts {total}, expected {expected}"
    );
}

#[test]
fn every_catalogue_trajectory_generates_for_every_robot_it_suits() {
    // Counts against the rolled distance integrated here independently (Gauss–Legendre on
    // 1 ms pieces of the rolling speed) from the random power-on phases, time order, and the
    // last truth row.
    for robot_file in ["seed000-0.8mm.toml", "seed001.toml"] {
        let r = robot(robot_file);
        let off = offsets(&r, &opts());
        for named in catalogue() {
            let traj = build(named.name).unwrap();
            if check_drive(&r, named.drive).is_err() {
                assert!(generate(&r, None, traj.as_ref(), &opts()).is_err());
                continue;
            }
            let start = std::time::Instant::now();
            let stream = generate(&r, None, traj.as_ref(), &opts()).unwrap();
            println!(
                "{robot_file:20} {:24} {:8} events in {:?}",
                named.name,
                stream.events.len(),
                start.elapsed()
            );
            assert!(stream.events.windows(2).all(|w| w[0].t_ns() <= w[1].t_ns()));
            for (i, enc) in r.encoders.iter().enumerate() {
                let rolled = integral(traj.as_ref(), |tw| enc.wheel.rolling_speed(tw));
                assert_count(
                    net(&stream, i as u16),
                    off[i] + rolled,
                    enc.metres_per_count,
                    &format!("{robot_file} {} encoder {i}", named.name),
                );
            }
            let end_ns = (traj.duration() * 1e9).round() as u64;
            assert_eq!(stream.events.last().unwrap().t_ns(), end_ns);
            let last_truth = stream
                .events
                .iter()
                .rev()
                .find(|e| matches!(e, Event::Truth { .. }));
            assert_eq!(last_truth.unwrap().t_ns(), end_ns);
        }
    }
}

#[test]
fn reversing_wheel_counts_are_the_floor_of_its_distance_at_all_times() {
    let r = robot("seed001.toml");
    let traj = Shuttle {
        amplitude: 0.0123,
        freq: 1.7,
        duration: 2.3,
    };
    // Random power-on phases: each wheel's count is floor((φ·step + x) / step).
    let stream = generate(&r, None, &traj, &opts()).unwrap();
    let off = offsets(&r, &opts());
    let step = r.encoders[0].metres_per_count;
    for (i, off) in off.iter().enumerate() {
        let ticks = ticks_of(&stream, i as u16);
        assert!(ticks.iter().any(|&(_, s)| s == 1) && ticks.iter().any(|&(_, s)| s == -1));
        // Probe a few thousand instants away from tick times.
        let mut checked = 0;
        for k in 0..4000 {
            let t_ns = (k as f64 * 2.3e9 / 4000.0 + 123.0) as u64;
            if ticks.iter().any(|&(t, _)| t.abs_diff(t_ns) < 3) {
                continue;
            }
            let count: i64 = ticks
                .iter()
                .take_while(|&&(t, _)| t <= t_ns)
                .map(|&(_, s)| s as i64)
                .sum();
            let expected = ((off + traj.x(t_ns as f64 * 1e-9)) / step).floor() as i64;
            assert_eq!(count, expected, "encoder {i} at {t_ns} ns");
            checked += 1;
        }
        assert!(checked > 3900);
    }
    // Both wheels of a differential robot roll the same here: at the same phase they tick
    // together.
    let same = generate(&r, None, &traj, &at_phase(0.3)).unwrap();
    assert_eq!(ticks_of(&same, 0), ticks_of(&same, 1));
}

#[test]
fn accelerating_wheel_ticks_at_the_closed_form_instants() {
    // x(t) = A·sin(wt): while it rises, edge m is crossed where φ·step + x = m·step, at
    // asin((m − φ)·step/A)/w (random power-on phase φ).
    let r = robot("seed001.toml");
    let traj = Shuttle {
        amplitude: 0.0123,
        freq: 1.7,
        duration: 0.1,
    };
    let stream = generate(&r, None, &traj, &opts()).unwrap();
    let off = offsets(&r, &opts())[0];
    let step = r.encoders[0].metres_per_count;
    let w = TAU * traj.freq;
    let ticks = ticks_of(&stream, 0);
    assert_eq!(
        ticks.len() as i64,
        ((off + traj.x(0.1)) / step).floor() as i64
    );
    for (k, &(t_ns, s)) in ticks.iter().enumerate() {
        assert_eq!(s, 1);
        let exact_ns = (((k + 1) as f64 * step - off) / traj.amplitude).asin() / w * 1e9;
        assert!(
            (t_ns as f64 - exact_ns).abs() <= 0.51,
            "tick {}: {t_ns} ns, exact {exact_ns}",
            k + 1
        );
    }
}

#[test]
fn a_reversal_just_past_an_edge_ticks_there_and_back() {
    // The wheel peaks 2 nm past edge 30 and comes back: +1 and -1 about 0.1 ms apart, both
    // inside one 1 ms integration interval, at the closed-form instants. The encoder powers
    // on exactly on an edge, so that the peak is 2 nm past one.
    let r = robot("seed001.toml");
    let step = r.encoders[0].metres_per_count;
    let traj = Shuttle {
        amplitude: 30.0 * step + 2e-9,
        freq: 1.7,
        duration: 0.16,
    };
    let stream = generate(&r, None, &traj, &edge_aligned()).unwrap();
    let w = TAU * traj.freq;
    let ticks = ticks_of(&stream, 0);
    assert_eq!(ticks.len(), 31, "{:?}", &ticks[28..]);
    let up = (30.0 * step / traj.amplitude).asin() / w * 1e9;
    let down = PI / w * 1e9 - up;
    assert!(down - up > 5e4 && down - up < 2e5, "{up} {down}");
    let (t_up, s_up) = ticks[29];
    let (t_down, s_down) = ticks[30];
    assert_eq!((s_up, s_down), (1, -1));
    assert!((t_up as f64 - up).abs() <= 0.51, "{t_up} vs {up}");
    assert!((t_down as f64 - down).abs() <= 0.51, "{t_down} vs {down}");
    assert_eq!(net(&stream, 0), 29);
}

#[test]
fn events_are_time_ordered_and_rows_are_where_they_should_be() {
    let r = robot("seed001.toml");
    for name in ["seed002-circle", "umbmark-cw", "seed001-figure-eight"] {
        let traj = build(name).unwrap();
        let stream = generate(&r, Some("../robots/seed001.toml"), traj.as_ref(), &opts()).unwrap();
        assert!(stream.events.windows(2).all(|w| w[0].t_ns() <= w[1].t_ns()));
        let end_ns = (traj.duration() * 1e9).round() as u64;
        let truth: Vec<(u64, f64, f64, f64)> = stream
            .events
            .iter()
            .filter_map(|e| match *e {
                Event::Truth {
                    t_ns,
                    x_m,
                    y_m,
                    theta_rad,
                } => Some((t_ns, x_m, y_m, theta_rad)),
                _ => None,
            })
            .collect();
        // 100 Hz from 0, plus one at the end.
        let on_grid = (traj.duration() * 100.0).floor() as usize + 1;
        assert!(
            truth.len() == on_grid || truth.len() == on_grid + 1,
            "{name}"
        );
        assert_eq!(truth[0], (0, 0.0, 0.0, 0.0));
        assert_eq!(truth[1].0, 10_000_000);
        let last = *truth.last().unwrap();
        assert_eq!(last.0, end_ns);
        let p = traj.pose(end_ns as f64 * 1e-9);
        assert_eq!((last.1, last.2, last.3), (p.x, p.y, p.theta));
        assert!(stream
            .events
            .iter()
            .all(|e| e.t_ns() <= end_ns && !matches!(e, Event::Abs { .. })));
        assert_eq!(stream.robot.as_deref(), Some("../robots/seed001.toml"));
    }
}

#[test]
fn absolute_encoder_on_the_body_heading_reads_the_heading() {
    // seed000's wheels plus an 8-bit Gray, inverted absolute encoder on the body heading.
    let base = fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../robots/seed000-0.4mm.toml"),
    )
    .unwrap();
    let text = format!(
        "{base}\n[[absolute_encoders]]\nname = \"heading\"\nbits = 8\ncode = \"gray\"\n\
         inverted = true\nmeasures = \"body_heading\"\n"
    );
    let r = Robot::parse(&text, Path::new("heading.toml")).unwrap();
    let a = r
        .absolute_encoder(AbsMeasures::BodyHeading)
        .unwrap()
        .clone();
    let traj = build("seed000-bezier-180deg").unwrap();
    let stream = generate(&r, None, traj.as_ref(), &opts()).unwrap();
    let reads: Vec<(u64, u32)> = stream
        .events
        .iter()
        .filter_map(|e| match *e {
            Event::Abs { t_ns, code, .. } => Some((t_ns, code)),
            _ => None,
        })
        .collect();
    // 1 kHz plus the end.
    let on_grid = (traj.duration() * 1000.0).floor() as usize + 1;
    assert!(reads.len() == on_grid || reads.len() == on_grid + 1);
    for &(t_ns, code) in &reads {
        let theta = traj.pose(t_ns as f64 * 1e-9).theta;
        let pos = a.decode(code as u16) as f64;
        let err = wrap_angle(pos * a.step_rad() - theta);
        assert!(err.abs() <= a.step_rad() / 2.0 + 1e-12, "{t_ns}: {code}");
        assert_eq!(code, abs_code(&a, theta));
    }
    // Start: position 0 (all outputs high: inverted). End: heading π = position 128.
    assert_eq!(reads[0].1, 0xFF);
    assert_eq!(a.decode(reads.last().unwrap().1 as u16), 128);
}

#[test]
fn unsupported_robots_and_trajectories_are_refused() {
    let diff = robot("seed001.toml");
    assert!(is_differential(&diff));
    assert!(!is_differential(&robot("seed000-0.1mm.toml")));
    let holo = build("seed000-bezier-90deg").unwrap();
    let e = generate(&diff, None, holo.as_ref(), &opts()).unwrap_err();
    assert!(e.to_string().contains("sideways"), "{e}");
    assert!(check_drive(&diff, Drive::Holonomic).is_err());
    assert!(check_drive(&diff, Drive::Differential).is_ok());
    assert!(check_drive(&robot("seed000-0.8mm.toml"), Drive::Holonomic).is_ok());

    let circle = build("seed002-circle").unwrap();
    let e = generate(&robot("seed003.toml"), None, circle.as_ref(), &opts()).unwrap_err();
    assert!(e.to_string().contains("no incremental encoders"), "{e}");
    let bad = GenerateOptions {
        truth_rate_hz: 0.0,
        ..opts()
    };
    assert!(generate(&diff, None, circle.as_ref(), &bad).is_err());
}

#[test]
fn generated_stream_round_trips_through_a_file() {
    let r = robot("seed001.toml");
    let traj = build("seed002-circle").unwrap();
    let stream = generate(&r, Some("../robots/seed001.toml"), traj.as_ref(), &opts()).unwrap();
    assert!(stream.events.len() > 10_000);
    let dir = scratch("round-trip");
    for name in ["circle.csv", "circle.csv.gz"] {
        let path = dir.join(name);
        tickstream::write(&path, &stream).unwrap();
        let back = tickstream::read(&path).unwrap();
        assert_eq!(back, stream, "{name}");
    }
}
