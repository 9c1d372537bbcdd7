//! Is every encoder wired as the robot file says? Before any fit, each encoder's counts are
//! set against the rolling the truth's motion gives each wheel on the nominal geometry: a
//! wheel that counts backwards, or two whose cables are swapped, get a verdict, not a fit
//! that bends the geometry to explain them (the first complaint of odometry users).

use anyhow::{bail, Result};
use robot_math::se2::wrap_angle;

use crate::formats::robot::Robot;
use crate::formats::tickstream::Event;

/// `agree[i][j]`: the cosine between encoder i's count changes (as travel) and the travel the
/// truth's motion gives wheel j, over the run's truth intervals. None without a track of
/// truth (ten rows at least) or for encoders on a carriage (the truth is the body's).
pub fn agreement(robot: &Robot, events: &[Event]) -> Option<Vec<Vec<f64>>> {
    if robot.carriage.is_some() {
        return None;
    }
    let truth: Vec<(u64, robot_math::Pose2)> = events.iter().filter_map(Event::truth).collect();
    if truth.len() < 10 {
        return None;
    }
    let n = robot.encoders.len();
    let rows: Vec<[f64; 3]> = robot.encoders.iter().map(|e| e.wheel.row()).collect();
    let mut counted = vec![0.0f64; n];
    let mut dot = vec![vec![0.0f64; n]; n];
    let (mut act2, mut pred2) = (vec![0.0f64; n], vec![0.0f64; n]);
    let ticks = events.iter().filter_map(|e| match *e {
        Event::Tick {
            t_ns,
            encoder,
            step,
        } if (encoder as usize) < n => Some((t_ns, encoder as usize, step)),
        _ => None,
    });
    let mut ticks = ticks.peekable();
    for w in truth.windows(2) {
        let ((ta, a), (tb, b)) = (w[0], w[1]);
        counted.iter_mut().for_each(|c| *c = 0.0);
        while let Some(&(t, j, step)) = ticks.peek() {
            if t > tb {
                break;
            }
            if t > ta {
                counted[j] += step as f64 * robot.encoders[j].metres_per_count;
            }
            ticks.next();
        }
        // The body's displacement, in its frame at the interval's start.
        let (s, c) = a.theta.sin_cos();
        let (dx, dy) = (b.x - a.x, b.y - a.y);
        let d = [
            c * dx + s * dy,
            -s * dx + c * dy,
            wrap_angle(b.theta - a.theta),
        ];
        let pred: Vec<f64> = (rows.iter())
            .map(|r| r[0] * d[0] + r[1] * d[1] + r[2] * d[2])
            .collect();
        for i in 0..n {
            act2[i] += counted[i] * counted[i];
            pred2[i] += pred[i] * pred[i];
            for j in 0..n {
                dot[i][j] += counted[i] * pred[j];
            }
        }
    }
    Some(
        (0..n)
            .map(|i| {
                (0..n)
                    .map(|j| {
                        let norm = (act2[i] * pred2[j]).sqrt();
                        if norm > 0.0 {
                            dot[i][j] / norm
                        } else {
                            0.0
                        }
                    })
                    .collect()
            })
            .collect(),
    )
}

/// A verdict on the wiring from one run's agreement, or `Ok`.
pub fn check(robot: &Robot, run: &str, agree: &[Vec<f64>]) -> Result<()> {
    let name = |i: usize| &robot.encoders[i].name;
    for (i, row) in agree.iter().enumerate() {
        let own = row[i];
        // Another wheel's rolling explains its counts far better than its own: the cables.
        if let Some((j, &v)) = (row.iter().enumerate())
            .filter(|&(j, _)| j != i)
            .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
        {
            if v.abs() > 0.9 && v.abs() > own.abs() + 0.1 {
                bail!(
                    "{run}: encoders {} and {} look swapped: {} counts what {} should roll \
                     (agreement {v:+.2}, with its own wheel {own:+.2}); check which input each \
                     is on; no fit is made",
                    name(i),
                    name(j),
                    name(i),
                    name(j)
                );
            }
        }
        if own < -0.5 {
            bail!(
                "{run}: encoder {} counts backwards: its counts go against the motion the truth \
                 shows (agreement {own:+.2}). It is wired or signed the wrong way (swap its A \
                 and B lines, or turn its direction_deg by 180 in the robot file); no fit is made",
                name(i)
            );
        }
    }
    Ok(())
}
