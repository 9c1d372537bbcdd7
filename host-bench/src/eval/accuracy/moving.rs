//! The error while moving: the relative pose error over a fixed length of path, from the
//! instant every wheel is placed on.
//!
//! Where a wheel stands inside its count at power-on is not in its ticks when it starts from
//! rest (docs/odometry.md, "Where a wheel starts inside its count"): a start error ε_j per wheel
//! is a constant offset of its position from then on. Wheel increments after that are exact, so
//! an exact integrator carries the start error as one rigid transform of the whole later path
//! (`estimate(t) = estimate(t_p) ∘ truth(t_p)⁻¹ ∘ truth(t)`), which the absolute errors report
//! and the start bound covers. What a method adds while moving is what it gets wrong between
//! two instants: from each truth row `i` after the wheels are placed, the motion to the first
//! row `j` at least [`SEGMENT_M`] of path later, estimate against truth, each seen from its own
//! pose at `i` (the relative pose error of the TUM RGB-D and KITTI odometry benchmarks; a rigid
//! offset cancels in it, drift does not). Every method is measured the same way on the same
//! rows.

use crate::eval::replay::Score;
use crate::formats::tickstream::{Event, TickStream};
use robot_math::se2::Pose2;
use robot_math::ticks::PLACING_TICKS;

/// The instant (s) by which every encoder that ticks at least [`PLACING_TICKS`] times has
/// done so (the tracker's fit has placed each of them by then); `None` if none does.
pub fn placed_after_s(stream: &TickStream) -> Option<f64> {
    let mut ticks: Vec<(usize, u64)> = Vec::new();
    for e in &stream.events {
        if let Event::Tick { t_ns, encoder, .. } = *e {
            let i = encoder as usize;
            if ticks.len() <= i {
                ticks.resize(i + 1, (0, 0));
            }
            let (n, at) = &mut ticks[i];
            if *n < PLACING_TICKS {
                *n += 1;
                *at = t_ns;
            }
        }
    }
    ticks
        .iter()
        .filter(|(n, _)| *n == PLACING_TICKS)
        .map(|&(_, t)| t)
        .max()
        .map(|t| t as f64 * 1e-9)
}

/// `a⁻¹ ∘ b`: `b` seen from `a`.
fn relative(a: Pose2, b: Pose2) -> Pose2 {
    let (s, c) = a.theta.sin_cos();
    let (dx, dy) = (b.x - a.x, b.y - a.y);
    Pose2::new(c * dx + s * dy, -s * dx + c * dy, b.theta - a.theta)
}

/// Path length over which the relative pose error is taken, metres (the shortest seed paths
/// are 0.8 m long).
pub const SEGMENT_M: f64 = 0.5;

/// The median, over the truth rows `i` at or after `t_ref_s` that have a row `j` at least
/// `segment_m` of true path later, of the distance between the estimate's and the truth's
/// position at `j`, each seen from its own pose at `i`. `None` if no row has one.
pub fn median_moving_error(score: &Score, t_ref_s: f64, segment_m: f64) -> Option<f64> {
    let track = &score.track;
    let mut along = Vec::with_capacity(track.len());
    let mut s = 0.0;
    for (k, row) in track.iter().enumerate() {
        if k > 0 {
            s += track[k - 1].2.distance_to(row.2);
        }
        along.push(s);
    }
    let mut errors = Vec::new();
    let mut j = 0;
    for (i, &(t, e0, t0)) in track.iter().enumerate() {
        if t < t_ref_s {
            continue;
        }
        j = j.max(i);
        while j < track.len() && along[j] - along[i] < segment_m {
            j += 1;
        }
        let Some(&(_, e, tr)) = track.get(j) else {
            break;
        };
        errors.push(relative(e0, e).distance_to(relative(t0, tr)));
    }
    errors.sort_by(f64::total_cmp);
    errors.get(errors.len() / 2).copied()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn score(track: Vec<(f64, Pose2, Pose2)>) -> Score {
        Score {
            name: "x".into(),
            final_error_m: 0.0,
            max_error_m: 0.0,
            final_heading_error_rad: 0.0,
            path_length_m: 0.0,
            median_error_m: 0.0,
            truth_rows: track.len(),
            track,
        }
    }

    #[test]
    fn a_rigidly_moved_path_has_no_error_while_moving_and_a_drifting_one_has() {
        // The truth runs along +x; the estimate is the same path turned by 0.01 rad and shifted
        // by 1 mm at the reference instant (what a start error does to an exact integrator).
        let off = Pose2::new(0.001, -0.002, 0.01);
        let compose = |a: Pose2, b: Pose2| {
            let (s, c) = a.theta.sin_cos();
            Pose2::new(
                a.x + c * b.x - s * b.y,
                a.y + s * b.x + c * b.y,
                a.theta + b.theta,
            )
        };
        let truth = |t: f64| Pose2::new(0.5 * t, 0.1 * t * t, 0.2 * t);
        let rigid: Vec<_> = (0..50)
            .map(|k| {
                let t = k as f64 * 0.1;
                (t, compose(off, truth(t)), truth(t))
            })
            .collect();
        let e = median_moving_error(&score(rigid.clone()), 1.0, 0.5).unwrap();
        assert!(e < 1e-12, "{e}");
        // Absolute errors are large: the 0.01 rad tilt times up to 2.5 m.
        assert!(rigid[40].1.distance_to(rigid[40].2) > 0.01);
        // A path that drifts keeps its drift: 0.1 mm/s over the ~1 s a 0.5 m segment takes
        // here, seen from a heading within 0.8 rad of the drift's.
        let bent: Vec<_> = rigid
            .iter()
            .map(|&(t, e, tr)| (t, Pose2::new(e.x + 1e-4 * t, e.y, e.theta), tr))
            .collect();
        let e = median_moving_error(&score(bent), 1.0, 0.5).unwrap();
        assert!(e > 0.3e-4 && e < 1.5e-4, "{e}");
        // No row with 0.5 m of path after it past 4.9 s.
        assert_eq!(median_moving_error(&score(rigid), 4.9, 0.5), None);
    }

    #[test]
    fn placed_after_the_last_wheel_s_fourth_tick() {
        let tick = |t_ns, encoder| Event::Tick {
            t_ns,
            encoder,
            step: 1,
        };
        let mut events: Vec<Event> = (1..=6).map(|k| tick(k * 10, 0)).collect();
        events.extend((1..=4).map(|k| tick(k * 100, 1)));
        events.push(tick(5, 2)); // ticks once only: never placed, not waited for
        let stream = TickStream {
            robot: None,
            comments: vec![],
            events,
        };
        assert_eq!(placed_after_s(&stream), Some(400.0 * 1e-9));
    }
}
