//! `--method fit`: every measuring encoder's lateral position, rolling direction and travel
//! per count, by nonlinear least squares (Levenberg–Marquardt on nalgebra) over the runs' end
//! poses, for any layout of body-fixed encoders the robot format allows.
//!
//! A run is its encoders' count changes in short bins (a bin ends after 10 ms or 16 counts on
//! any encoder) from its start pose to its measured end. For a trial geometry each bin's
//! distances go through the robot's own wheel solver (`robot_math::wheelset`: two wheels on an
//! axle, three exactly, more by least squares) to a body displacement, integrated as an arc;
//! the residual is the end pose against the measured one, in units of the measuring noise
//! (`sigma_m`, `sigma_rad`). A wheel's position along its own rolling direction changes none of
//! its readings, so only its position across it (its lever arm) is fitted.

use anyhow::{bail, Result};
use nalgebra::{DMatrix, DVector};
use robot_math::se2::wrap_angle;
use robot_math::wheel::Wheel;
use robot_math::wheelset::WheelSolver;
use robot_math::Pose2;
use serde::Serialize;

use crate::formats::robot::{EncoderGeometry, Robot};

/// One run as the fit reads it.
#[derive(Clone, Debug)]
pub struct BinnedRun {
    pub name: String,
    pub start: Pose2,
    pub measured_end: Pose2,
    /// Count changes, `n` a bin.
    pub bins: Vec<i32>,
}

/// What can be fitted of one encoder, and how.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Param {
    /// Position across the rolling direction (to its left), metres.
    Lever,
    /// Rolling direction, radians.
    Direction,
    /// Travel per count, metres.
    Scale,
}

/// The measuring noise the residuals are scaled by.
#[derive(Clone, Copy, Debug)]
pub struct Noise {
    pub sigma_m: f64,
    pub sigma_rad: f64,
}

/// A fitted parameter: which encoder, which number, before and after, and its σ.
#[derive(Clone, Debug, Serialize)]
pub struct Fitted {
    pub encoder: String,
    pub param: Param,
    pub before: f64,
    pub after: f64,
    pub sigma: f64,
    /// Its least and largest value over the fits with one run left out (none when no run
    /// can be spared).
    pub repeat_min: Option<f64>,
    pub repeat_max: Option<f64>,
}

/// The fit's result.
#[derive(Clone, Debug, Serialize)]
pub struct Fit {
    pub params: Vec<Fitted>,
    pub after: Vec<EncoderGeometry>,
    /// Largest over smallest singular value of the scaled Jacobian.
    pub condition: f64,
    /// Combinations of parameters the runs cannot tell apart: each a list of (parameter,
    /// weight) with the weights of a null direction.
    pub unresolved: Vec<Vec<(String, f64)>>,
    /// What motion would resolve them.
    pub advice: Vec<String>,
    /// Root-mean-square normalised residual before and after.
    pub rms_before: f64,
    pub rms_after: f64,
    pub iterations: usize,
    /// Fits made with one run left out, for each parameter's `repeat_min`/`repeat_max`.
    pub subsets: usize,
    /// Wall-clock seconds the fit took (the runs read and binned before), and the subsets'.
    pub fit_seconds: f64,
    pub subsets_seconds: f64,
}

/// The model: which parameters are free, and the nominal geometry they move.
struct Model<'a> {
    nominal: &'a [EncoderGeometry],
    free: Vec<(usize, Param)>,
}

impl Model<'_> {
    fn geometry(&self, p: &DVector<f64>) -> Vec<EncoderGeometry> {
        let mut g = self.nominal.to_vec();
        for (k, &(j, what)) in self.free.iter().enumerate() {
            let n = self.nominal[j];
            let (s, c) = n.direction_deg.to_radians().sin_cos();
            match what {
                // Across the nominal rolling direction, to its left.
                Param::Lever => {
                    g[j].x_m = n.x_m - s * p[k];
                    g[j].y_m = n.y_m + c * p[k];
                }
                Param::Direction => g[j].direction_deg = p[k].to_degrees(),
                Param::Scale => g[j].metres_per_count = p[k],
            }
        }
        g
    }

    fn start(&self) -> DVector<f64> {
        DVector::from_iterator(
            self.free.len(),
            self.free.iter().map(|&(j, what)| match what {
                Param::Lever => 0.0,
                Param::Direction => self.nominal[j].direction_deg.to_radians(),
                Param::Scale => self.nominal[j].metres_per_count,
            }),
        )
    }

    /// Each parameter's step for the numeric Jacobian and its scale for conditioning.
    fn scale(&self, k: usize) -> f64 {
        match self.free[k].1 {
            Param::Lever => 0.01,
            Param::Direction => 0.01,
            Param::Scale => self.nominal[self.free[k].0].metres_per_count * 0.01,
        }
    }
}

/// Where `run` ends on geometry `g`.
fn dead_reckon(g: &[EncoderGeometry], run: &BinnedRun) -> Option<Pose2> {
    let wheels: Vec<Wheel> = (g.iter())
        .map(|e| Wheel::at(e.x_m, e.y_m, e.direction_deg.to_radians()))
        .collect();
    let solver = WheelSolver::new(&wheels).ok()?;
    let n = g.len();
    let k: Vec<f64> = g.iter().map(|e| e.metres_per_count).collect();
    let mut d = vec![0.0; n];
    let mut pose = run.start;
    for bin in run.bins.chunks_exact(n) {
        for j in 0..n {
            d[j] = bin[j] as f64 * k[j];
        }
        let t = solver.solve(&d);
        pose = pose.compose_increment(t.vx, t.vy, t.omega);
    }
    Some(pose)
}

fn residuals(g: &[EncoderGeometry], runs: &[BinnedRun], noise: Noise) -> Option<DVector<f64>> {
    let mut r = Vec::with_capacity(3 * runs.len());
    for run in runs {
        let end = dead_reckon(g, run)?;
        let m = run.measured_end;
        r.push((end.x - m.x) / noise.sigma_m);
        r.push((end.y - m.y) / noise.sigma_m);
        r.push(wrap_angle(end.theta - m.theta) / noise.sigma_rad);
    }
    Some(DVector::from_vec(r))
}

/// Fit `robot`'s encoders to `runs`.
pub fn fit(
    robot: &Robot,
    nominal: &[EncoderGeometry],
    runs: &[BinnedRun],
    noise: Noise,
) -> Result<Fit> {
    if robot.carriage.is_some() {
        bail!(
            "robot {}: its encoders are on a swivel carriage; the fit takes body-fixed encoders \
             only so far (docs/calibration.md)",
            robot.name
        );
    }
    let n = nominal.len();
    let axle = n == 2;
    // Two wheels on an axle stay parallel: their lever arms and travel per count are fitted,
    // not their direction (turning both is a turn of the body's frame, which no end pose
    // shows). With three or more, everything across each wheel.
    let mut free = Vec::new();
    for j in 0..n {
        free.push((j, Param::Lever));
        if !axle {
            free.push((j, Param::Direction));
        }
        free.push((j, Param::Scale));
    }
    let model = Model { nominal, free };
    let m = 3 * runs.len();
    if m < model.free.len() {
        bail!(
            "{} runs give {} numbers (x, y, heading at each end) for {} parameters: at least {} \
             runs are needed",
            runs.len(),
            m,
            model.free.len(),
            model.free.len().div_ceil(3)
        );
    }
    let wall = std::time::Instant::now();
    let start = model.start();
    let r0 = residuals(&model.geometry(&start), runs, noise)
        .ok_or_else(|| anyhow::anyhow!("the nominal geometry cannot be solved"))?;
    let rms_before = (r0.norm_squared() / m as f64).sqrt();
    let (p, r, iterations) = levenberg_marquardt(&model, runs, noise, start.clone())?;
    let fit_seconds = wall.elapsed().as_secs_f64();
    // Repeatability: the fit again with each run left out in turn, from the nominal.
    let mut spread: Vec<(f64, f64)> = vec![(f64::MAX, f64::MIN); p.len()];
    let mut subsets = 0;
    if 3 * (runs.len() - 1) >= model.free.len() && runs.len() > 1 {
        for k in 0..runs.len() {
            let rest: Vec<BinnedRun> = (runs.iter().enumerate())
                .filter(|&(i, _)| i != k)
                .map(|(_, r)| r.clone())
                .collect();
            if let Ok((q, _, _)) = levenberg_marquardt(&model, &rest, noise, start.clone()) {
                subsets += 1;
                for (s, v) in spread.iter_mut().zip(q.iter()) {
                    *s = (s.0.min(*v), s.1.max(*v));
                }
            }
        }
    }
    let jacobian = |p: &DVector<f64>, r0: &DVector<f64>| jacobian(&model, runs, noise, p, r0);
    let j =
        jacobian(&p, &r).ok_or_else(|| anyhow::anyhow!("the fitted geometry cannot be solved"))?;
    // Conditioning on parameters in their own scales, so units do not decide it.
    let scaled = DMatrix::from_fn(m, p.len(), |i, k| j[(i, k)] * model.scale(k));
    let svd = scaled.clone().svd(false, true);
    let sv = &svd.singular_values;
    let (max, min) = (sv.max(), sv.min());
    let condition = if min > 0.0 { max / min } else { f64::INFINITY };
    let names: Vec<String> = (model.free.iter())
        .map(|&(e, what)| format!("{} {}", robot.encoders[e].name, param_name(what)))
        .collect();
    let mut unresolved = Vec::new();
    if let Some(vt) = &svd.v_t {
        for (i, &s) in sv.iter().enumerate() {
            if s < 1e-6 * max {
                let row = vt.row(i);
                let mut parts: Vec<(String, f64)> = (0..row.len())
                    .filter(|&k| row[k].abs() > 0.2)
                    .map(|k| (names[k].clone(), row[k]))
                    .collect();
                parts.sort_by(|a, b| b.1.abs().total_cmp(&a.1.abs()));
                unresolved.push(parts);
            }
        }
    }
    // σ from the scaled normal equations, with the residuals' own spread when it is larger
    // than the noise assumed.
    let dof = (m - p.len()).max(1) as f64;
    let s2 = (r.norm_squared() / dof).max(1.0);
    let cov = (scaled.transpose() * &scaled)
        .pseudo_inverse(1e-12 * max * max)
        .ok();
    let after = model.geometry(&p);
    let mut params = Vec::new();
    for (k, &(e, what)) in model.free.iter().enumerate() {
        let before = match what {
            Param::Lever => 0.0,
            Param::Direction => nominal[e].direction_deg.to_radians(),
            Param::Scale => nominal[e].metres_per_count,
        };
        let sigma = cov
            .as_ref()
            .map_or(f64::NAN, |c| (c[(k, k)] * s2).sqrt() * model.scale(k));
        params.push(Fitted {
            encoder: robot.encoders[e].name.clone(),
            param: what,
            before,
            after: p[k],
            sigma,
            repeat_min: (subsets > 0).then_some(spread[k].0),
            repeat_max: (subsets > 0).then_some(spread[k].1),
        });
    }
    for f in &params {
        if f.param == Param::Scale && f.after <= 0.0 {
            bail!(
                "encoder {} counts backwards: the runs fit only with its travel per count \
                 negative ({:.6e} m). It is wired or signed the wrong way (swap its A and B \
                 lines, or turn its direction_deg by 180 in the robot file); no fit is made",
                f.encoder,
                f.after
            );
        }
    }
    let advice = advise(&unresolved, axle);
    Ok(Fit {
        params,
        after,
        condition,
        unresolved,
        advice,
        rms_before,
        rms_after: (r.norm_squared() / m as f64).sqrt(),
        iterations,
        subsets,
        fit_seconds,
        subsets_seconds: wall.elapsed().as_secs_f64() - fit_seconds,
    })
}

/// The numeric Jacobian of the residuals at `p` (whose residuals are `r0`).
fn jacobian(
    model: &Model,
    runs: &[BinnedRun],
    noise: Noise,
    p: &DVector<f64>,
    r0: &DVector<f64>,
) -> Option<DMatrix<f64>> {
    let mut j = DMatrix::zeros(r0.len(), p.len());
    for k in 0..p.len() {
        let h = model.scale(k) * 1e-4;
        let mut q = p.clone();
        q[k] += h;
        let r = residuals(&model.geometry(&q), runs, noise)?;
        j.set_column(k, &((r - r0) / h));
    }
    Some(j)
}

/// Levenberg–Marquardt from `start`: the parameters, their residuals, the iterations.
fn levenberg_marquardt(
    model: &Model,
    runs: &[BinnedRun],
    noise: Noise,
    start: DVector<f64>,
) -> Result<(DVector<f64>, DVector<f64>, usize)> {
    let cost = |p: &DVector<f64>| residuals(&model.geometry(p), runs, noise);
    let mut p = start;
    let mut r = cost(&p).ok_or_else(|| anyhow::anyhow!("the nominal geometry cannot be solved"))?;
    let mut lambda = 1e-3;
    let mut iterations = 0;
    for it in 0..100 {
        iterations = it + 1;
        let Some(j) = jacobian(model, runs, noise, &p, &r) else {
            bail!("the geometry left the solvable during the fit")
        };
        let jtj = j.transpose() * &j;
        let g = j.transpose() * &r;
        let mut improved = false;
        while lambda < 1e12 {
            let mut a = jtj.clone();
            for k in 0..a.nrows() {
                a[(k, k)] += lambda * jtj[(k, k)].max(1e-12);
            }
            let Some(step) = a.lu().solve(&(-&g)) else {
                lambda *= 10.0;
                continue;
            };
            let q = &p + &step;
            match cost(&q) {
                Some(rq) if rq.norm_squared() < r.norm_squared() => {
                    let small =
                        (0..step.len()).all(|k| step[k].abs() < 1e-10 * model.scale(k) * 100.0);
                    p = q;
                    r = rq;
                    lambda = (lambda / 10.0).max(1e-12);
                    improved = !small;
                    break;
                }
                _ => lambda *= 10.0,
            }
        }
        if !improved {
            break;
        }
    }
    Ok((p, r, iterations))
}

fn param_name(p: Param) -> &'static str {
    match p {
        Param::Lever => "lever arm",
        Param::Direction => "direction",
        Param::Scale => "travel per count",
    }
}

/// Which test motion excites what the runs left unresolved.
fn advise(unresolved: &[Vec<(String, f64)>], axle: bool) -> Vec<String> {
    let mut advice = Vec::new();
    for parts in unresolved {
        let has = |what: &str| parts.iter().any(|(n, _)| n.ends_with(what));
        if has("lever arm") {
            advice.push(
                "spin in place, both ways: a spin turns every wheel by its lever arm alone"
                    .to_string(),
            );
        }
        if has("direction") {
            advice.push(if axle {
                "a square the other way round".to_string()
            } else {
                "a sideways run and a diagonal one: they roll each wheel by its direction"
                    .to_string()
            });
        }
        if has("travel per count") {
            advice.push(
                "a straight run of a measured length: it scales every wheel's travel at once"
                    .to_string(),
            );
        }
    }
    advice.dedup();
    advice
}
