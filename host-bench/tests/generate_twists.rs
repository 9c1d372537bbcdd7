//! The tick generator on our constant-twist trajectories: the twist jumps at every joint, so
//! each wheel rolls at a constant speed on each piece and its tick instants have a closed
//! form, which the generator must meet to the nanosecond across every abrupt change.

mod common;

use common::*;
use host_bench::sim::generate::{check_drive, generate, PowerOnPhase};
use host_bench::sim::trajectory::{build, named, Trajectory};

/// The exact ticks of a wheel that starts at `offset` (metres into count 0) and rolls at a
/// constant speed on each piece `(start, end, speed)`: (time in s, ±1).
fn closed_form_ticks(pieces: &[(f64, f64, f64)], offset: f64, step: f64) -> Vec<(f64, i8)> {
    let mut out = Vec::new();
    let mut pos = offset;
    for &(a, b, v) in pieces {
        let end = pos + v * (b - a);
        if v > 0.0 {
            // Edge m is reached from below.
            let mut m = (pos / step).floor() + 1.0;
            while m * step <= end {
                out.push((a + (m * step - pos) / v, 1));
                m += 1.0;
            }
        } else if v < 0.0 {
            // The count drops when the position falls below edge m.
            let mut m = (pos / step).floor();
            while m * step > end {
                out.push((a + (pos - m * step) / -v, -1));
                m -= 1.0;
            }
        }
        pos = end;
    }
    out
}

#[test]
fn ticks_across_abrupt_twist_changes_are_at_the_closed_form_instants() {
    let cases = [
        ("seed001.toml", "twist-arcs"),
        ("seed001.toml", "twist-s-spin-reverse"),
        ("seed001.toml", "rest-then-arcs"),
        ("diff-wide.toml", "twist-s-spin-reverse"),
        ("seed000-0.4mm.toml", "twist-sideways-spin"),
        ("skewed3.toml", "twist-sideways-spin"),
        ("omni4-ls.toml", "twist-sideways-spin"),
        ("omni4-ls.toml", "rest-then-arcs"),
    ];
    for (file, name) in cases {
        let r = robot(file);
        assert!(
            check_drive(&r, named(name).unwrap().drive).is_ok(),
            "{file} {name}"
        );
        let traj = build(name).unwrap();
        // Random phases only: from an edge, our round speeds and durations put many wheels
        // exactly on an edge at a joint (0.28 m/s for 1.5 s is 1050 counts of 0.4 mm), where
        // which side rounding lands on is arbitrary.
        for seed in [3, 4] {
            let phase = PowerOnPhase::Random { seed };
            let o = host_bench::sim::generate::GenerateOptions { phase, ..opts() };
            let stream = generate(&r, None, traj.as_ref(), &o).unwrap();
            let off = offsets(&r, &o);
            for (i, enc) in r.encoders.iter().enumerate() {
                let what = format!("{file} {name} {phase} encoder {i}");
                let pieces = constant_pieces(traj.as_ref(), |tw| enc.wheel.rolling_speed(tw));
                let expected = closed_form_ticks(&pieces, off[i], enc.metres_per_count);
                let got = ticks_of(&stream, i as u16);
                assert_eq!(got.len(), expected.len(), "{what}");
                assert!(got.len() > 100, "{what}: {} ticks", got.len());
                for (k, (&(t_ns, s), &(t, es))) in got.iter().zip(&expected).enumerate() {
                    assert_eq!(s, es, "{what}, tick {k}");
                    assert!(
                        (t_ns as f64 - t * 1e9).abs() <= 0.51,
                        "{what}, tick {k}: {t_ns} ns, exact {} ns",
                        t * 1e9
                    );
                }
            }
        }
    }
}

/// The pieces between breakpoints and the wheel's speed on each, checking that the speed is
/// the same at both ends of the piece (constant twist) as in its middle.
fn constant_pieces(
    traj: &dyn Trajectory,
    speed: impl Fn(robot_math::se2::Twist) -> f64,
) -> Vec<(f64, f64, f64)> {
    cuts(traj)
        .windows(2)
        .map(|w| {
            let v = speed(traj.twist(0.5 * (w[0] + w[1])));
            let (first, last) = (speed(traj.twist(w[0])), speed(traj.twist_before(w[1])));
            assert!(
                (first - v).abs() < 1e-15 && (last - v).abs() < 1e-15,
                "not a constant twist on [{}, {}]: {first} {v} {last}",
                w[0],
                w[1]
            );
            (w[0], w[1], v)
        })
        .collect()
}
