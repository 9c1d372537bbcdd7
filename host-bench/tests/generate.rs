//! The trajectory catalogue and the exact tick generator: tick instants against closed forms,
//! counts against closed-form rolled distances, reversals, ordering, the catalogue's shapes
//! and lengths, and a round trip through a tick-stream file.

use std::f64::consts::{PI, TAU};
use std::fs;
use std::path::{Path, PathBuf};

use host_bench::formats::robot::{AbsMeasures, Robot};
use host_bench::formats::tickstream::{self, Event, TickStream};
use host_bench::sim::generate::{
    abs_code, check_drive, generate, is_differential, GenerateOptions,
};
use host_bench::sim::trajectory::{self, build, catalogue, Drive, Trajectory};
use robot_math::carriage::CarriageOdometry;
use robot_math::se2::{wrap_angle, Pose2, Twist};

fn robot(name: &str) -> Robot {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../robots")
        .join(name);
    Robot::load(&path).unwrap()
}

fn scratch(test: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("generate-tests")
        .join(test);
    let _ = fs::remove_dir_all(&dir);
    fs::create_dir_all(&dir).unwrap();
    dir
}

fn opts() -> GenerateOptions {
    GenerateOptions::default()
}

/// Per encoder: the tick instants (ns) and steps, in stream order.
fn ticks_of(stream: &TickStream, encoder: u16) -> Vec<(u64, i8)> {
    stream
        .events
        .iter()
        .filter_map(|e| match *e {
            Event::Tick {
                t_ns,
                encoder: id,
                step,
            } if id == encoder => Some((t_ns, step)),
            _ => None,
        })
        .collect()
}

fn net(stream: &TickStream, encoder: u16) -> i64 {
    ticks_of(stream, encoder)
        .iter()
        .map(|&(_, s)| s as i64)
        .sum()
}

/// `count == floor(rolled / step)`; if `rolled / step` is within 1e-6 of a whole number
/// rounding may put it on either side, so either neighbour is accepted.
fn assert_count(count: i64, rolled: f64, step: f64, what: &str) {
    let x = rolled / step;
    let expected = x.floor() as i64;
    if (x - x.round()).abs() < 1e-6 {
        let r = x.round() as i64;
        assert!(
            count == r || count == r - 1,
            "{what}: {count} counts, rolled {rolled} m = {x} steps"
        );
    } else {
        assert_eq!(count, expected, "{what}: rolled {rolled} m = {x} steps");
    }
}

// ---------------------------------------------------------------------------------------------
// Hand-made trajectories with closed forms.

/// Constant body twist from t = 0 (not from rest: exact tick instants are k·step/v).
struct Constant {
    twist: Twist,
    duration: f64,
}

impl Trajectory for Constant {
    fn duration(&self) -> f64 {
        self.duration
    }
    fn pose(&self, t: f64) -> Pose2 {
        Pose2::default().integrate(self.twist, t)
    }
    fn twist(&self, _: f64) -> Twist {
        self.twist
    }
}

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
    // Differential robot: both wheels roll at v along +x.
    let r = robot("seed001.toml");
    let v = 0.37;
    let traj = Constant {
        twist: Twist::new(v, 0.0, 0.0),
        duration: 2.5,
    };
    let stream = generate(&r, None, &traj, &opts()).unwrap();
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
    let stream = generate(&r, None, &traj, &opts()).unwrap();
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
    // compensation over 100 000 intervals).
    let r = robot("seed001.toml");
    let v = 0.4;
    let traj = Constant {
        twist: Twist::new(v, 0.0, 0.0),
        duration: 100.0 + 1e-6,
    };
    let start = std::time::Instant::now();
    let stream = generate(&r, None, &traj, &opts()).unwrap();
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
    // Differential robot, heading along the path: a wheel at y_i rolls L − y_i·Δθ.
    let diff = robot("seed001.toml");
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
                rolled,
                enc.metres_per_count,
                &format!("{name} encoder {i}"),
            );
        }
    }
    // Omni robot on a line along +x with a fixed heading: wheel i rolls u_ix·L.
    let omni = robot("seed000-0.1mm.toml");
    let traj = build("seed000-line").unwrap();
    let stream = generate(&omni, None, traj.as_ref(), &opts()).unwrap();
    for (i, enc) in omni.encoders.iter().enumerate() {
        let rolled = enc.wheel.ux * trajectory::SEED000_LENGTH_M;
        assert_count(
            net(&stream, i as u16),
            rolled,
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
    let expected = 3.0 * lever * PI / omni.encoders[0].metres_per_count;
    assert!(
        (total as f64 - expected).abs() <= 3.0,
        "sum of counts {total}, expected {expected}"
    );
}

#[test]
fn every_catalogue_trajectory_generates_for_every_robot_it_suits() {
    // Counts against the rolled distance integrated here independently (Gauss–Legendre on
    // 1 ms pieces of the rolling speed), time order, and the last truth row.
    for robot_file in ["seed000-0.8mm.toml", "seed001.toml"] {
        let r = robot(robot_file);
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
                    rolled,
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
    let stream = generate(&r, None, &traj, &opts()).unwrap();
    let step = r.encoders[0].metres_per_count;
    let ticks = ticks_of(&stream, 0);
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
        let expected = (traj.x(t_ns as f64 * 1e-9) / step).floor() as i64;
        assert_eq!(count, expected, "at {t_ns} ns");
        checked += 1;
    }
    assert!(checked > 3900);
    // Both wheels of a differential robot see the same thing here.
    assert_eq!(ticks, ticks_of(&stream, 1));
}

#[test]
fn accelerating_wheel_ticks_at_the_closed_form_instants() {
    // x(t) = A·sin(wt): while it rises, edge m is crossed at asin(m·step/A)/w.
    let r = robot("seed001.toml");
    let traj = Shuttle {
        amplitude: 0.0123,
        freq: 1.7,
        duration: 0.1,
    };
    let stream = generate(&r, None, &traj, &opts()).unwrap();
    let step = r.encoders[0].metres_per_count;
    let w = TAU * traj.freq;
    let ticks = ticks_of(&stream, 0);
    assert_eq!(ticks.len() as i64, (traj.x(0.1) / step).floor() as i64);
    for (k, &(t_ns, s)) in ticks.iter().enumerate() {
        assert_eq!(s, 1);
        let exact_ns = ((k + 1) as f64 * step / traj.amplitude).asin() / w * 1e9;
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
    // inside one 1 ms integration interval, at the closed-form instants.
    let r = robot("seed001.toml");
    let step = r.encoders[0].metres_per_count;
    let traj = Shuttle {
        amplitude: 30.0 * step + 2e-9,
        freq: 1.7,
        duration: 0.16,
    };
    let stream = generate(&r, None, &traj, &opts()).unwrap();
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

// ---------------------------------------------------------------------------------------------
// The catalogue.

/// Path length: ∫ |(v_x, v_y)| dt.
fn path_length(traj: &dyn Trajectory) -> f64 {
    integral(traj, |v| v.vx.hypot(v.vy))
}

/// ∫ f(twist(t)) dt over the trajectory, 5-point Gauss–Legendre on 1 ms pieces between
/// breakpoints.
fn integral(traj: &dyn Trajectory, f: impl Fn(Twist) -> f64) -> f64 {
    const X: [f64; 5] = [
        -0.906_179_845_938_664,
        -0.538_469_310_105_683_1,
        0.0,
        0.538_469_310_105_683_1,
        0.906_179_845_938_664,
    ];
    const W: [f64; 5] = [
        0.236_926_885_056_189_1,
        0.478_628_670_499_366_5,
        0.568_888_888_888_888_9,
        0.478_628_670_499_366_5,
        0.236_926_885_056_189_1,
    ];
    let mut cuts = traj.breakpoints();
    cuts.push(0.0);
    cuts.push(traj.duration());
    cuts.sort_by(f64::total_cmp);
    let mut total = 0.0;
    for w in cuts.windows(2) {
        let n = ((w[1] - w[0]) / 1e-3).ceil().max(1.0) as usize;
        let h = (w[1] - w[0]) / n as f64;
        for j in 0..n {
            let m = w[0] + h * (j as f64 + 0.5);
            for (x, wt) in X.iter().zip(W) {
                total += 0.5 * h * wt * f(traj.twist(m + 0.5 * h * x));
            }
        }
    }
    total
}

fn twist_norm(a: Twist, b: Twist) -> f64 {
    (a.vx - b.vx)
        .abs()
        .max((a.vy - b.vy).abs())
        .max((a.omega - b.omega).abs())
}

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

// ---------------------------------------------------------------------------------------------
// Seed 004's swivel carriage.

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
    // 80 cm, the swivel reads 0 throughout (raw 0xFF: Gray, active-low).
    let r = robot("seed004.toml");
    let traj = build("seed000-line").unwrap();
    let stream = generate(&r, None, traj.as_ref(), &opts()).unwrap();
    for (i, enc) in r.encoders.iter().enumerate() {
        assert_count(
            net(&stream, i as u16),
            trajectory::SEED000_LENGTH_M,
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
