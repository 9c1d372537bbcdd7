//! Borenstein and Feng's UMBmark (IEEE Transactions on Robotics and Automation 12(6), 1996):
//! the systematic odometry errors of two parallel measuring wheels from squares driven
//! clockwise and counter-clockwise, and the two factors that correct them: `E_d`, the ratio
//! of the right wheel's diameter to the left's, and `E_b`, the true wheel base over the
//! nominal.
//!
//! Each run gives its return position error, true end minus odometry's end, in the frame the
//! run started in (x ahead, y to the left). To first order a wheel-base error turns every
//! corner by `a` too little (clockwise) or too much (counter-clockwise), and unequal wheels
//! curve every leg of side `L` by `β`; the four legs then leave
//!
//! ```text
//! clockwise:          x = 2L(a - β),  y =  2L(a - β)
//! counter-clockwise:  x = 2L(a + β),  y = -2L(a + β)
//! ```
//!
//! UMBmark solves for `α = -a` and `β` from the centroids' x; the y give the same two
//! numbers, and both are averaged here. Then `E_b = 90° / (90° - α)` and, with the radius
//! the curved leg implies, `R = (L/2) / sin(β/2)`, `E_d = (R + b/2) / (R - b/2)`.
//!
//! Those formulas are first order: at E_d = 1.01 on a 4 m square and a 0.3 m base each leg
//! curves by 7.6°, and they miss E_d by 4·10⁻⁴ and E_b by 3·10⁻³, which leave about a
//! twentieth of the error. So
//! the two factors are then refined on the square itself ([`square_error`]: each leg an arc,
//! each turn in place a turn, as the odometry counted them), by Gauss–Newton from UMBmark's
//! values until the modelled centroids are the measured ones. Both are reported; the
//! correction uses the refined pair.

use anyhow::{bail, Result};
use serde::Serialize;

/// Which way round a square went.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Direction {
    Clockwise,
    CounterClockwise,
}

/// One square run: which way, its side, and its return position error (true end minus
/// odometry's, in the start frame), metres.
#[derive(Clone, Debug, Serialize)]
pub struct SquareRun {
    pub name: String,
    pub direction: Direction,
    pub side_m: f64,
    pub error_m: (f64, f64),
    /// Whether the robot was steered by its odometry round the square (UMBmark's way: the
    /// odometry ends where it started, the robot does not), or drove a true square that the
    /// odometry followed (a generated stream: the robot ends where it started). The first
    /// order is the same; the refinement models each as it was.
    pub driven_by_odometry: bool,
}

/// UMBmark's figures and corrections.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct Umbmark {
    pub side_m: f64,
    /// Centre of gravity of each direction's return errors, metres.
    pub centroid_cw_m: (f64, f64),
    pub centroid_ccw_m: (f64, f64),
    /// UMBmark's measure of systematic error: the larger centroid's distance from the origin.
    pub e_max_syst_m: f64,
    /// The orientation error a wheel-base error adds at each corner (UMBmark's α) and the
    /// heading a leg curves by (β), radians.
    pub alpha_rad: f64,
    pub beta_rad: f64,
    /// Right wheel's diameter over the left's, and true wheel base over nominal: refined on
    /// the square ([`square_error`]), and as UMBmark's first-order formulas give them.
    pub e_d: f64,
    pub e_b: f64,
    pub e_d_first_order: f64,
    pub e_b_first_order: f64,
    /// Runs each way.
    pub runs_cw: usize,
    pub runs_ccw: usize,
}

/// UMBmark over `runs` (at least one each way), for a wheel base `wheel_base_m`.
pub fn umbmark(runs: &[SquareRun], wheel_base_m: f64) -> Result<Umbmark> {
    let centroid = |d: Direction| {
        let of: Vec<&SquareRun> = runs.iter().filter(|r| r.direction == d).collect();
        let n = of.len() as f64;
        let c = of
            .iter()
            .fold((0.0, 0.0), |(x, y), r| (x + r.error_m.0, y + r.error_m.1));
        (of.len(), (c.0 / n, c.1 / n))
    };
    let (runs_cw, cw) = centroid(Direction::Clockwise);
    let (runs_ccw, ccw) = centroid(Direction::CounterClockwise);
    if runs_cw == 0 || runs_ccw == 0 {
        bail!(
            "UMBmark needs squares both ways: {runs_cw} clockwise and {runs_ccw} \
             counter-clockwise given"
        );
    }
    let side_m = runs.iter().map(|r| r.side_m).sum::<f64>() / runs.len() as f64;
    if side_m.is_nan() || side_m <= 10.0 * wheel_base_m.abs() {
        bail!(
            "the squares' side ({side_m:.3} m) must be many wheel bases ({wheel_base_m:.3} m) \
             long: UMBmark's first-order model is of long legs and turns in place"
        );
    }
    let four_l = 4.0 * side_m;
    // α = -a, from x and from y; β likewise.
    let alpha = ((cw.0 + ccw.0) / -four_l + (cw.1 - ccw.1) / -four_l) / 2.0;
    let beta = ((cw.0 - ccw.0) / -four_l + (cw.1 + ccw.1) / -four_l) / 2.0;
    let quarter = std::f64::consts::FRAC_PI_2;
    let e_b = quarter / (quarter - alpha);
    // (R + b/2)/(R - b/2) with R = (L/2)/sin(β/2), written without dividing by sin(β/2),
    // so a straight leg (β = 0) gives 1.
    let s = wheel_base_m * (beta / 2.0).sin() / side_m;
    let e_d_first_order = (1.0 + s) / (1.0 - s);
    let (e_d, e_b) = refine(runs, wheel_base_m, (e_d_first_order, e_b));
    let e_b_first_order = quarter / (quarter - alpha);
    let radius = |c: (f64, f64)| c.0.hypot(c.1);
    Ok(Umbmark {
        side_m,
        centroid_cw_m: cw,
        centroid_ccw_m: ccw,
        e_max_syst_m: radius(cw).max(radius(ccw)),
        alpha_rad: alpha,
        beta_rad: beta,
        e_d,
        e_b,
        e_d_first_order,
        e_b_first_order,
        runs_cw,
        runs_ccw,
    })
}

/// Where a robot ends, in its start frame, whose wheels count a square of side `side`
/// `dir` on a wheel base `base` (forward along each leg, turning in place at each corner),
/// when each count is really `cl` (left) and `cr` (right) times the travel counted and the
/// wheels turn the robot on `base · scale`. Each leg and each turn is one arc of constant
/// curvature, exactly.
fn square_end(side: f64, base: f64, cl: f64, cr: f64, scale: f64, dir: Direction) -> (f64, f64) {
    let (mut x, mut y, mut th) = (0.0f64, 0.0f64, 0.0f64);
    let mut arc = |dl: f64, dr: f64| {
        let (tl, tr) = (dl * cl, dr * cr);
        let ds = (tl + tr) / 2.0;
        let dth = (tr - tl) / (base * scale);
        // ds·sinc(dθ/2) along the mean heading: exact for an arc.
        let half = dth / 2.0;
        let chord = if half.abs() < 1e-9 {
            ds
        } else {
            ds * half.sin() / half
        };
        x += chord * (th + half).cos();
        y += chord * (th + half).sin();
        th += dth;
    };
    let turn = match dir {
        Direction::Clockwise => -1.0,
        Direction::CounterClockwise => 1.0,
    };
    let spin = turn * std::f64::consts::FRAC_PI_2 * base / 2.0;
    for _ in 0..4 {
        arc(side, side);
        arc(-spin, spin);
    }
    (x, y)
}

/// The return error (true end minus odometry's, start frame, metres) of a square run of side
/// `side` `dir` when the right wheel's diameter is `e_d` times the left's (their mean as the
/// odometry takes it) and the wheel base `e_b` times the odometry's `base`: steered by the
/// odometry (it counts the square; the robot ends off), or driving a true square (the
/// odometry ends off).
pub fn square_error(
    side: f64,
    base: f64,
    e_d: f64,
    e_b: f64,
    dir: Direction,
    driven_by_odometry: bool,
) -> (f64, f64) {
    let (cl, cr) = (2.0 / (e_d + 1.0), 2.0 * e_d / (e_d + 1.0));
    if driven_by_odometry {
        square_end(side, base, cl, cr, e_b, dir)
    } else {
        // The true square's counts, as the odometry turns them into a path.
        let (x, y) = square_end(side, base * e_b, 1.0 / cl, 1.0 / cr, 1.0 / e_b, dir);
        (-x, -y)
    }
}

/// `(E_d, E_b)` that make [`square_error`] each run's measured error, by Gauss–Newton from
/// `start` (least squares over every run's two coordinates).
fn refine(runs: &[SquareRun], base: f64, start: (f64, f64)) -> (f64, f64) {
    let residual = |p: (f64, f64)| -> Vec<f64> {
        (runs.iter())
            .flat_map(|r| {
                let m = square_error(r.side_m, base, p.0, p.1, r.direction, r.driven_by_odometry);
                [m.0 - r.error_m.0, m.1 - r.error_m.1]
            })
            .collect()
    };
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
    let mut p = start;
    for _ in 0..30 {
        let r = residual(p);
        let h = 1e-7;
        let (rd, rb) = (residual((p.0 + h, p.1)), residual((p.0, p.1 + h)));
        let jd: Vec<f64> = rd.iter().zip(&r).map(|(a, b)| (a - b) / h).collect();
        let jb: Vec<f64> = rb.iter().zip(&r).map(|(a, b)| (a - b) / h).collect();
        let (a11, a12, a22) = (dot(&jd, &jd), dot(&jd, &jb), dot(&jb, &jb));
        let (g1, g2) = (dot(&jd, &r), dot(&jb, &r));
        let det = a11 * a22 - a12 * a12;
        if det.is_nan() || det == 0.0 {
            break;
        }
        let step = ((a22 * g1 - a12 * g2) / det, (a11 * g2 - a12 * g1) / det);
        p = (p.0 - step.0, p.1 - step.1);
        if step.0.abs() < 1e-13 && step.1.abs() < 1e-13 {
            break;
        }
    }
    // A divergent step (no runs that say anything) falls back to the first-order values.
    if p.0.is_finite() && p.1.is_finite() && p.0 > 0.5 && p.0 < 2.0 && p.1 > 0.5 && p.1 < 2.0 {
        p
    } else {
        start
    }
}

/// The corrected left and right travel per count and wheel base, as UMBmark sets them:
/// the diameters' ratio becomes `E_d` with their mean kept, the base is `E_b` times.
pub fn corrected(u: &Umbmark, left_m: f64, right_m: f64, base_m: f64) -> (f64, f64, f64) {
    let left = left_m * 2.0 / (u.e_d + 1.0);
    let right = right_m * 2.0 / (1.0 / u.e_d + 1.0);
    (left, right, base_m * u.e_b)
}

#[cfg(test)]
mod tests {
    use super::*;
    use robot_math::se2::wrap_angle;

    /// A square of side `l` in small steps, by a differential drive whose right wheel is
    /// `e_d` times the left's and whose wheel base is `e_b` times the odometry's `b`:
    /// `steered`, the odometry counts the square and the robot ends off (UMBmark's way);
    /// else the robot drives a true square and the odometry, counting it with the nominal
    /// numbers, ends off. The return error, true end minus odometry's.
    fn small_steps(
        l: f64,
        b: f64,
        e_d: f64,
        e_b: f64,
        dir: Direction,
        steered: bool,
    ) -> (f64, f64) {
        let (cl, cr) = (2.0 / (e_d + 1.0), 2.0 * e_d / (e_d + 1.0));
        // What the moving path's wheels roll per unit of the square's, and its base.
        let (kl, kr, base) = if steered {
            (cl, cr, b * e_b)
        } else {
            (1.0 / cl, 1.0 / cr, b)
        };
        let (mut x, mut y, mut th) = (0.0f64, 0.0f64, 0.0f64);
        let mut step = |dl: f64, dr: f64| {
            let (tl, tr) = (dl * kl, dr * kr);
            let ds = (tl + tr) / 2.0;
            let dth = (tr - tl) / base;
            x += ds * (th + dth / 2.0).cos();
            y += ds * (th + dth / 2.0).sin();
            th = wrap_angle(th + dth);
        };
        let n = 20_000;
        let turn = match dir {
            Direction::Clockwise => -1.0,
            Direction::CounterClockwise => 1.0,
        };
        // A quarter turn in place of the square's own wheels (the odometry's, or the true).
        let arc = turn * std::f64::consts::FRAC_PI_2 * if steered { b } else { b * e_b } / 2.0;
        for _ in 0..4 {
            for _ in 0..n {
                step(l / n as f64, l / n as f64);
            }
            for _ in 0..n {
                step(-arc / n as f64, arc / n as f64);
            }
        }
        if steered {
            (x, y)
        } else {
            (-x, -y)
        }
    }

    /// The formulas recover what the simulated drive had (in 80 000 small steps, not the
    /// refinement's arcs): E_d within 10^-3 and E_b within 5·10^-3 at first order at a 1 % diameter and 3 %
    /// wheel-base error, within 10^-7 refined, and E_max,syst the larger centroid.
    #[test]
    fn recovers_the_diameter_ratio_and_the_wheel_base() {
        let (l, b) = (4.0, 0.3);
        for (e_d, e_b) in [(1.01, 1.03), (0.995, 0.98), (1.0, 1.0), (1.002, 1.0)] {
            let runs: Vec<SquareRun> = [Direction::Clockwise, Direction::CounterClockwise]
                .into_iter()
                .map(|d| SquareRun {
                    name: format!("{d:?}"),
                    direction: d,
                    side_m: l,
                    error_m: small_steps(l, b, e_d, e_b, d, true),
                    driven_by_odometry: true,
                })
                .collect();
            let u = umbmark(&runs, b).unwrap();
            // First order: close, not exact (7.6° a leg at E_d = 1.01).
            assert!((u.e_d_first_order - e_d).abs() < 1e-3, "{u:?}");
            assert!((u.e_b_first_order - e_b).abs() < 5e-3, "{u:?}");
            // Refined on the square: to the small steps' own accuracy.
            assert!((u.e_d - e_d).abs() < 1e-7, "E_d {} for {e_d}", u.e_d);
            assert!((u.e_b - e_b).abs() < 1e-7, "E_b {} for {e_b}", u.e_b);
            let r = |e: (f64, f64)| e.0.hypot(e.1);
            assert_eq!(u.e_max_syst_m, r(runs[0].error_m).max(r(runs[1].error_m)));
        }
    }

    /// The other way round: the robot drives a true square (a generated stream), and the
    /// odometry ends off.
    #[test]
    fn recovers_them_from_true_squares_too() {
        let (l, b, e_d, e_b) = (4.0, 0.3, 1.01, 1.03);
        let runs: Vec<SquareRun> = [Direction::Clockwise, Direction::CounterClockwise]
            .into_iter()
            .map(|d| SquareRun {
                name: format!("{d:?}"),
                direction: d,
                side_m: l,
                error_m: small_steps(l, b, e_d, e_b, d, false),
                driven_by_odometry: false,
            })
            .collect();
        let u = umbmark(&runs, b).unwrap();
        // First order it is rougher this way round (E_b 1.021 for 1.03): the odometry's own
        // corners are the ones off, and its legs start from them.
        assert!((u.e_d_first_order - e_d).abs() < 2e-3, "{u:?}");
        assert!((u.e_b_first_order - e_b).abs() < 1.5e-2, "{u:?}");
        assert!((u.e_d - e_d).abs() < 1e-7, "E_d {} for {e_d}", u.e_d);
        assert!((u.e_b - e_b).abs() < 1e-7, "E_b {} for {e_b}", u.e_b);
    }

    #[test]
    fn one_direction_alone_is_refused() {
        let run = SquareRun {
            name: "a".into(),
            direction: Direction::Clockwise,
            side_m: 4.0,
            error_m: (0.01, 0.0),
            driven_by_odometry: true,
        };
        assert!(umbmark(&[run], 0.3).is_err());
    }
}
