//! Each encoder's rolled distance, summed interval by interval, and its edge crossings found by
//! root finding.

use super::cheb::SpeedSeries;
use super::edges::EdgeMap;
use super::interp::{Interp, SAMPLES};
use super::{to_ns, TIME_TOL_S};
use crate::formats::robot::Robot;
use crate::formats::tickstream::Event;
use robot_math::wheel::Wheel;

/// A running sum with Neumaier compensation.
#[derive(Clone, Copy, Debug, Default)]
struct Sum {
    hi: f64,
    lo: f64,
}

impl Sum {
    fn add(&mut self, x: f64) {
        let t = self.hi + x;
        if self.hi.abs() >= x.abs() {
            self.lo += (self.hi - t) + x;
        } else {
            self.lo += (x - t) + self.hi;
        }
        self.hi = t;
    }
    fn value(&self) -> f64 {
        self.hi + self.lo
    }
    /// `self − e`, without losing the compensation.
    fn minus(&self, e: f64) -> f64 {
        (self.hi - e) + self.lo
    }
}

/// One encoder's rolling speed over one interval, and the pieces of it between reversals
/// (on each the wheel rolls one way): nothing here depends on where the encoder powered on.
pub(super) struct WheelMotion {
    series: SpeedSeries,
    pieces: Vec<(f64, f64)>,
}

impl WheelMotion {
    /// Every encoder wheel of `wheels` over the interval of `frame` (the twist of the wheels'
    /// frame).
    pub(super) fn of(wheels: &[Wheel], frame: &Interp) -> Vec<WheelMotion> {
        let (t0, t1) = (frame.t[0], frame.t[SAMPLES - 1]);
        wheels
            .iter()
            .map(|wheel| {
                let row = wheel.row();
                let speeds = frame
                    .v
                    .map(|v| row[0] * v[0] + row[1] * v[1] + row[2] * v[2]);
                let series = SpeedSeries::new(&frame.t, &speeds);
                let rate = |t: f64| series.speed(t);
                // Reversals: where the sign of the speed changes between non-zero samples.
                let mut splits = Vec::new();
                let mut last: Option<usize> = None;
                for k in 0..SAMPLES {
                    if speeds[k] == 0.0 {
                        continue;
                    }
                    if let Some(l) = last {
                        if (speeds[l] > 0.0) != (speeds[k] > 0.0) {
                            splits.push(bisect_sign(
                                &rate,
                                frame.t[l],
                                frame.t[k],
                                speeds[l] > 0.0,
                            ));
                        }
                    }
                    last = Some(k);
                }
                let mut pieces = Vec::new();
                let mut a = t0;
                for b in splits.into_iter().chain(std::iter::once(t1)) {
                    if b > a {
                        pieces.push((a, b));
                        a = b;
                    }
                }
                WheelMotion { series, pieces }
            })
            .collect()
    }
}

pub(super) struct Ticker {
    steps: Vec<f64>,
    /// Where each encoder stood at power-on, metres of its wheel's travel from its edge 0's
    /// ideal place (phase × step with ideal edges).
    offsets: Vec<f64>,
    /// Offset plus distance the wheel rolled so far: the count is the edge map's count there
    /// (`floor(rolled / step)` with ideal edges).
    rolled: Vec<Sum>,
    /// Where each encoder's edges are.
    pub(super) edges: Vec<EdgeMap>,
    /// Each encoder's last time stamp (its capture latency must not reorder them).
    last_stamp: Vec<u64>,
    pub(super) events: Vec<Event>,
}

impl Ticker {
    /// `phases`: each encoder's power-on phase, in `[0, 1)` of the count it starts in;
    /// `edges`: where each puts its edges.
    pub(super) fn new(robot: &Robot, phases: &[f64], edges: Vec<EdgeMap>) -> Ticker {
        let steps: Vec<f64> = robot.encoders.iter().map(|e| e.metres_per_count).collect();
        let offsets: Vec<f64> = steps
            .iter()
            .zip(phases)
            .zip(&edges)
            .map(|((&step, &phase), map)| {
                if !map.is_ideal() {
                    let (e0, e1) = (map.edge(0), map.edge(1));
                    return (e0 + phase * (e1 - e0)) * step;
                }
                // φ·step rounds up to the step itself for φ within an ulp of 1: stay inside
                // count 0, so that counts start at 0 whatever the phase.
                let mut offset = phase * step;
                while (offset / step).floor() >= 1.0 {
                    offset = offset.next_down();
                }
                offset
            })
            .collect();
        let last_stamp = vec![0; steps.len()];
        Ticker {
            rolled: offsets.iter().map(|&hi| Sum { hi, lo: 0.0 }).collect(),
            offsets,
            steps,
            edges,
            last_stamp,
            events: Vec::new(),
        }
    }

    /// Per encoder: the distance rolled since power-on (metres) and the count now.
    pub(super) fn totals(&self) -> Vec<(f64, i64)> {
        self.rolled
            .iter()
            .zip(&self.offsets)
            .zip(&self.steps)
            .zip(&self.edges)
            .map(|(((r, &offset), &step), map)| (r.minus(offset), map.count_at(r.value() / step)))
            .collect()
    }

    /// Advances every encoder over one interval, its wheels' motion already worked out
    /// ([`WheelMotion::of`], shared by every power-on phase of the same trajectory).
    pub(super) fn interval(&mut self, motion: &[WheelMotion]) {
        for (i, m) in motion.iter().enumerate() {
            for &(a, b) in &m.pieces {
                self.piece(i, &m.series, a, b);
            }
        }
    }

    /// Encoder `i` rolls monotonically over `[a, b]`: emit its edge crossings.
    fn piece(&mut self, i: usize, series: &SpeedSeries, a: f64, b: f64) {
        let scale = self.edges[i].scale;
        let rolled_at_a = series.rolled(a);
        let ds = (series.rolled(b) - rolled_at_a) * scale;
        let step = self.steps[i];
        let start = self.rolled[i];
        let mut end = start;
        end.add(ds);
        let map = &self.edges[i];
        let c0 = map.count_at(start.value() / step);
        let c1 = map.count_at(end.value() / step);
        self.rolled[i] = end;
        if c0 == c1 {
            return;
        }
        let up = c1 > c0;
        let dir = if up { 1.0 } else { -1.0 };
        let edges: Box<dyn Iterator<Item = i64>> = if up {
            Box::new(c0 + 1..=c1)
        } else {
            Box::new((c1 + 1..=c0).rev())
        };
        // g(t) = dir·(s(t) − edge): negative before the crossing, ≥ 0 after it. At `a` it is
        // dir·base; at the previous crossing minus the gap between the two edges; at `b`
        // dir·(base + ds).
        let mut lo = a;
        for m in edges {
            let edge = self.edges[i].edge(m) * step;
            let base = start.minus(edge);
            let g = |t: f64| dir * (base + (series.rolled(t) - rolled_at_a) * scale);
            let g_lo = if lo == a {
                dir * base
            } else {
                let previous = if up { m - 1 } else { m + 1 };
                -(self.edges[i].edge(m) - self.edges[i].edge(previous)).abs() * step
            };
            let g_hi = dir * (base + ds);
            let t = find_crossing(
                &g,
                &|t| dir * scale * series.speed(t),
                (lo, g_lo),
                (b, g_hi),
            );
            // Stamped late by the capture latency, never before the last stamp.
            let t_ns = (to_ns(t) + self.edges[i].latency_ns()).max(self.last_stamp[i]);
            self.last_stamp[i] = t_ns;
            self.events.push(Event::Tick {
                t_ns,
                encoder: i as u16,
                step: if up { 1 } else { -1 },
            });
            lo = t;
        }
    }
}

/// The instant in `[lo, hi]` where the non-decreasing `g` reaches 0, given `g` at both ends
/// (if `g(lo) ≥ 0` already, `lo`; if `g(hi) < 0`, `hi`). Newton's method with derivative `dg`,
/// safeguarded by bisection: every iterate stays inside the shrinking bracket. Where `g` is
/// exactly 0 on a whole interval (a wheel standing still on an edge) any instant of it may be
/// returned: the wheel is on the edge at each.
fn find_crossing(
    g: &dyn Fn(f64) -> f64,
    dg: &dyn Fn(f64) -> f64,
    (lo, g_lo): (f64, f64),
    (hi, g_hi): (f64, f64),
) -> f64 {
    let (mut lo, mut hi) = (lo, hi);
    if g_lo >= 0.0 {
        return lo;
    }
    if g_hi < 0.0 {
        // Rounding put the edge past the end of the piece: it is crossed at its very end.
        return hi;
    }
    // Start from the secant guess.
    let mut t = lo + (hi - lo) * (-g_lo / (g_hi - g_lo));
    for _ in 0..200 {
        if !(t > lo && t < hi) {
            t = 0.5 * (lo + hi);
        }
        let gt = g(t);
        if gt == 0.0 {
            return t;
        }
        if gt > 0.0 {
            hi = t;
        } else {
            lo = t;
        }
        if hi - lo <= TIME_TOL_S {
            break;
        }
        let d = dg(t);
        let next = if d > 0.0 { t - gt / d } else { f64::NAN };
        // Converged: the step is below the tolerance. Checked before the bracket, since a step
        // that small can land on the bracket's end (g's rounding), and bisecting from there
        // would take some 30 more halvings to get where Newton already is.
        if (next - t).abs() <= TIME_TOL_S {
            return next.clamp(lo, hi);
        }
        t = if next > lo && next < hi {
            next
        } else {
            0.5 * (lo + hi)
        };
    }
    hi
}

/// Where `rate` changes sign in `[a, b]` (positive at `a` iff `positive_at_a`), by bisection.
fn bisect_sign(rate: &dyn Fn(f64) -> f64, a: f64, b: f64, positive_at_a: bool) -> f64 {
    let (mut lo, mut hi) = (a, b);
    while hi - lo > TIME_TOL_S {
        let mid = 0.5 * (lo + hi);
        if mid <= lo || mid >= hi {
            break;
        }
        let r = rate(mid);
        if r != 0.0 && (r > 0.0) == positive_at_a {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crossing_of_a_line_is_exact() {
        // g(t) = 0.3·t − 0.1: root 1/3.
        let t = find_crossing(&|t| 0.3 * t - 0.1, &|_| 0.3, (0.0, -0.1), (1.0, 0.2));
        assert!((t - 1.0 / 3.0).abs() < 1e-12, "{t}");
        // Non-linear: g = t³ − 0.2 on [0, 1].
        let t = find_crossing(
            &|t| t * t * t - 0.2,
            &|t| 3.0 * t * t,
            (0.0, -0.2),
            (1.0, 0.8),
        );
        assert!((t - 0.2f64.cbrt()).abs() < 1e-12, "{t}");
    }

    #[test]
    fn a_root_hit_exactly_takes_one_evaluation() {
        // The secant lands on the root of a line: g(t) = 0 there, and Newton's step is zero.
        // The finder used to see the step land on its bracket's end and bisect some 40 times.
        let calls = std::cell::Cell::new(0);
        let g = |t: f64| {
            calls.set(calls.get() + 1);
            t - 0.5
        };
        let t = find_crossing(&g, &|_| 1.0, (0.0, -0.5), (1.0, 0.5));
        assert_eq!((t, calls.get()), (0.5, 1));
    }

    #[test]
    fn compensated_sum_does_not_drift() {
        let mut s = Sum::default();
        for _ in 0..100_000 {
            s.add(0.0004);
        }
        assert!((s.value() - 40.0).abs() < 1e-13, "{}", s.value());
    }
}
