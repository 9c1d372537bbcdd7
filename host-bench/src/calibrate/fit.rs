//! `--method fit`: every measuring encoder's lateral position, rolling direction and travel
//! per count, by nonlinear least squares (Levenberg–Marquardt on nalgebra) over the runs' end
//! poses, for any layout the robot format allows: body-fixed encoders, or seed 004's two
//! wheels on a trailing swivel carriage (their spacing and each one's travel per count; see
//! [`Model`] for how the carriage's start is handled). UMBmark's two factors on a carriage are
//! refined here too ([`umbmark_on_carriage`]).
//!
//! A run is its encoders' count changes in short bins (a bin ends after 10 ms or 64 counts on
//! any encoder) from its start pose to its measured end. For a trial geometry each bin's
//! distances go through the robot's own wheel solver (`robot_math::wheelset`: two wheels on an
//! axle, three exactly, more by least squares) to a body displacement, integrated as an arc;
//! the residual is the end pose against the measured one, in units of the measuring noise
//! (`sigma_m`, `sigma_rad`). A wheel's position along its own rolling direction changes none of
//! its readings, so only its position across it (its lever arm) is fitted.
//!
//! On a carriage the bins dead-reckon the carriage's axle midpoint, not the body: it starts
//! `trail` behind the pivot (the body's reference point) along the carriage's heading, which
//! is the body's plus the swivel as read at the start; the body ends at the axle plus `trail`
//! along the carriage's end heading, facing that heading less the swivel read at the end.

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
    /// A carriage's swivel as its absolute encoder read it at the start and at the end,
    /// radians; none for body-fixed encoders.
    pub swivel: Option<(f64, f64)>,
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
    /// Half the distance between a swivel carriage's two wheels, as a change from nominal,
    /// metres: both move, mirrored, as the robot format keeps them symmetric about the axle
    /// midpoint (the carriage frame's origin).
    Spacing,
    /// UMBmark's E_d, a carriage's right wheel's diameter over its left's, their mean kept.
    DiameterRatio,
    /// UMBmark's E_b, a carriage's true wheel spacing over the nominal.
    SpacingRatio,
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
///
/// With a swivel carriage the encoders are the carriage's, and each run's carriage heading at
/// the start is the body's plus the swivel as its absolute encoder read it, which is off by up
/// to half a code (0.7° for seed 004's 8 bits): a rotation of the whole run that a geometry
/// must not be bent to explain. So each run has that offset as a parameter of its own (a
/// nuisance, not reported), after the encoders' ones.
struct Model<'a> {
    nominal: &'a [EncoderGeometry],
    free: Vec<(usize, Param)>,
    /// The carriage's trail (pivot to axle midpoint), metres.
    trail: Option<f64>,
    /// The end heading's noise: the measuring noise and, with a carriage, the end swivel
    /// reading's quantisation (a code's width over √12).
    heading_sigma: f64,
}

impl<'a> Model<'a> {
    fn new(
        robot: &Robot,
        nominal: &'a [EncoderGeometry],
        free: Vec<(usize, Param)>,
        runs: &[BinnedRun],
        noise: Noise,
    ) -> Result<Self> {
        let trail = robot.carriage.map(|c| c.trail_m);
        let mut heading_sigma = noise.sigma_rad;
        if trail.is_some() {
            let layout = robot.odometry_layout()?;
            let step = layout.carriage_geometry().map_or(0.0, |c| c.abs_step());
            heading_sigma = heading_sigma.hypot(step / 12f64.sqrt());
            if let Some(r) = runs.iter().find(|r| r.swivel.is_none()) {
                bail!(
                    "{}: robot {} has a swivel carriage, and the run has no reading of its \
                     swivel",
                    r.name,
                    robot.name
                );
            }
        }
        Ok(Model {
            nominal,
            free,
            trail,
            heading_sigma,
        })
    }

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
                Param::Spacing => {
                    g[0].y_m = self.nominal[0].y_m + p[k];
                    g[1].y_m = -g[0].y_m;
                }
                Param::DiameterRatio => {
                    g[0].metres_per_count = self.nominal[0].metres_per_count * 2.0 / (p[k] + 1.0);
                    g[1].metres_per_count =
                        self.nominal[1].metres_per_count * 2.0 * p[k] / (p[k] + 1.0);
                }
                Param::SpacingRatio => {
                    g[0].y_m = self.nominal[0].y_m * p[k];
                    g[1].y_m = -g[0].y_m;
                }
            }
        }
        g
    }

    /// The nominal geometry, and no offsets, for `runs` runs.
    fn start(&self, runs: usize) -> DVector<f64> {
        let encoders = self.free.iter().map(|&(j, what)| match what {
            Param::Lever | Param::Spacing => 0.0,
            Param::DiameterRatio | Param::SpacingRatio => 1.0,
            Param::Direction => self.nominal[j].direction_deg.to_radians(),
            Param::Scale => self.nominal[j].metres_per_count,
        });
        let offsets = std::iter::repeat_n(0.0, self.offsets(runs));
        DVector::from_iterator(
            self.free.len() + self.offsets(runs),
            encoders.chain(offsets),
        )
    }

    /// How many nuisance parameters `runs` runs bring.
    fn offsets(&self, runs: usize) -> usize {
        if self.trail.is_some() {
            runs
        } else {
            0
        }
    }

    /// How many parameters a fit of `runs` runs has, and how many numbers they give.
    fn unknowns_and_numbers(&self, runs: usize) -> (usize, usize) {
        (self.free.len() + self.offsets(runs), 3 * runs)
    }

    /// Each parameter's step for the numeric Jacobian and its scale for conditioning.
    fn scale(&self, k: usize) -> f64 {
        match self.free.get(k) {
            Some(&(_, Param::Lever | Param::Direction | Param::Spacing)) => 0.01,
            Some(&(_, Param::DiameterRatio | Param::SpacingRatio)) => 0.01,
            Some(&(j, Param::Scale)) => self.nominal[j].metres_per_count * 0.01,
            // A run's carriage heading offset, radians.
            None => 0.01,
        }
    }

    /// Where `run` (the `i`th) ends with parameters `p`.
    fn end(
        &self,
        g: &[EncoderGeometry],
        p: &DVector<f64>,
        i: usize,
        run: &BinnedRun,
    ) -> Option<Pose2> {
        let Some(trail) = self.trail else {
            return dead_reckon(g, run.start, &run.bins);
        };
        let (at_start, at_end) = run.swivel?;
        let phi = run.start.theta + at_start + p[self.free.len() + i];
        let (s, c) = phi.sin_cos();
        let axle = Pose2::new(run.start.x - trail * c, run.start.y - trail * s, phi);
        let axle = dead_reckon(g, axle, &run.bins)?;
        let (s, c) = axle.theta.sin_cos();
        Some(Pose2::new(
            axle.x + trail * c,
            axle.y + trail * s,
            axle.theta - at_end,
        ))
    }
}

/// Where `bins` of counts take the encoders' frame from `start`, on geometry `g`.
fn dead_reckon(g: &[EncoderGeometry], start: Pose2, bins: &[i32]) -> Option<Pose2> {
    let wheels: Vec<Wheel> = (g.iter())
        .map(|e| Wheel::at(e.x_m, e.y_m, e.direction_deg.to_radians()))
        .collect();
    let solver = WheelSolver::new(&wheels).ok()?;
    let n = g.len();
    let k: Vec<f64> = g.iter().map(|e| e.metres_per_count).collect();
    let mut d = vec![0.0; n];
    let mut pose = start;
    for bin in bins.chunks_exact(n) {
        for j in 0..n {
            d[j] = bin[j] as f64 * k[j];
        }
        let t = solver.solve(&d);
        pose = pose.compose_increment(t.vx, t.vy, t.omega);
    }
    Some(pose)
}

fn residuals(
    model: &Model,
    p: &DVector<f64>,
    runs: &[BinnedRun],
    noise: Noise,
) -> Option<DVector<f64>> {
    let g = model.geometry(p);
    let mut r = Vec::with_capacity(3 * runs.len());
    for (i, run) in runs.iter().enumerate() {
        r.extend(run_residuals(model, &g, p, i, run, noise)?);
    }
    Some(DVector::from_vec(r))
}

/// The `i`th run's three residuals.
fn run_residuals(
    model: &Model,
    g: &[EncoderGeometry],
    p: &DVector<f64>,
    i: usize,
    run: &BinnedRun,
    noise: Noise,
) -> Option<[f64; 3]> {
    let end = model.end(g, p, i, run)?;
    let m = run.measured_end;
    Some([
        (end.x - m.x) / noise.sigma_m,
        (end.y - m.y) / noise.sigma_m,
        wrap_angle(end.theta - m.theta) / model.heading_sigma,
    ])
}

/// Fit `robot`'s encoders to `runs`.
pub fn fit(
    robot: &Robot,
    nominal: &[EncoderGeometry],
    runs: &[BinnedRun],
    noise: Noise,
) -> Result<Fit> {
    let n = nominal.len();
    let axle = n == 2;
    // Two wheels on an axle stay parallel: their lever arms and travel per count are fitted,
    // not their direction (turning both is a turn of the body's frame, which no end pose
    // shows). With three or more, everything across each wheel.
    // A carriage's two wheels stay symmetric about its origin (the robot format's rule): one
    // spacing for both.
    let trail = robot.carriage.map(|c| c.trail_m);
    let mut free = Vec::new();
    if trail.is_some() {
        free.push((0, Param::Spacing));
    }
    for j in 0..n {
        if trail.is_none() {
            free.push((j, Param::Lever));
        }
        if !axle {
            free.push((j, Param::Direction));
        }
        free.push((j, Param::Scale));
    }
    let model = Model::new(robot, nominal, free, runs, noise)?;
    let (unknowns, m) = model.unknowns_and_numbers(runs.len());
    if m < unknowns {
        let least = (1..)
            .find(|&n| {
                let (u, m) = model.unknowns_and_numbers(n);
                m >= u
            })
            .expect("every run gives more numbers than it brings parameters");
        bail!(
            "{} runs give {} numbers (x, y, heading at each end) for {} parameters{}: at least \
             {least} runs are needed",
            runs.len(),
            m,
            unknowns,
            if trail.is_some() {
                " (each run's carriage heading at the start among them)"
            } else {
                ""
            }
        );
    }
    let wall = std::time::Instant::now();
    let start = model.start(runs.len());
    let r0 = residuals(&model, &start, runs, noise)
        .ok_or_else(|| anyhow::anyhow!("the nominal geometry cannot be solved"))?;
    let rms_before = (r0.norm_squared() / m as f64).sqrt();
    let (p, r, iterations) = levenberg_marquardt(&model, runs, noise, start)?;
    let fit_seconds = wall.elapsed().as_secs_f64();
    // Repeatability: the fit again with each run left out in turn, from the nominal.
    let mut spread: Vec<(f64, f64)> = vec![(f64::MAX, f64::MIN); p.len()];
    let mut subsets = 0;
    let (spare_unknowns, spare_numbers) = model.unknowns_and_numbers(runs.len().saturating_sub(1));
    if spare_numbers >= spare_unknowns && runs.len() > 1 {
        for k in 0..runs.len() {
            let rest: Vec<BinnedRun> = (runs.iter().enumerate())
                .filter(|&(i, _)| i != k)
                .map(|(_, r)| r.clone())
                .collect();
            let start = model.start(rest.len());
            if let Ok((q, _, _)) = levenberg_marquardt(&model, &rest, noise, start) {
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
        .map(|&(e, what)| format!("{} {}", encoder_name(robot, e, what), param_name(what)))
        .chain(
            (0..model.offsets(runs.len()))
                .map(|i| format!("{} carriage heading at the start", runs[i].name)),
        )
        .collect();
    let mut unresolved = Vec::new();
    if let Some(vt) = &svd.v_t {
        for (i, &s) in sv.iter().enumerate() {
            if s < 1e-6 * max {
                let row = vt.row(i);
                // A run's carriage heading alone is a nuisance the runs need not pin down:
                // only what moves the geometry is worth a test motion.
                if (0..model.free.len()).all(|k| row[k].abs() <= 0.2) {
                    continue;
                }
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
    // The nominal geometry's values (no runs: no offsets).
    let nominal_values = model.start(0);
    let mut params = Vec::new();
    for (k, &(e, what)) in model.free.iter().enumerate() {
        let before = nominal_values[k];
        let sigma = cov
            .as_ref()
            .map_or(f64::NAN, |c| (c[(k, k)] * s2).sqrt() * model.scale(k));
        params.push(Fitted {
            encoder: encoder_name(robot, e, what),
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
    let advice = advise(&unresolved, axle, n);
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

/// UMBmark's two factors for a swivel carriage's wheels, `(E_d, E_b)`, refined on the runs'
/// own counts: the carriage does not turn in place at a corner but swings round behind the
/// body, so the square of [`super::umbmark::square_error`] is not its path. Least squares
/// over the end poses, as the fit (each run's carriage heading at the start a nuisance), from
/// the nominal; UMBmark's first-order values are reported beside them.
pub fn umbmark_on_carriage(
    robot: &Robot,
    nominal: &[EncoderGeometry],
    runs: &[BinnedRun],
    noise: Noise,
) -> Result<(f64, f64)> {
    let free = vec![(0, Param::DiameterRatio), (0, Param::SpacingRatio)];
    let model = Model::new(robot, nominal, free, runs, noise)?;
    let (p, _, _) = levenberg_marquardt(&model, runs, noise, model.start(runs.len()))?;
    Ok((p[0], p[1]))
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
    let g = model.geometry(p);
    for k in 0..p.len() {
        let h = model.scale(k) * 1e-4;
        let mut q = p.clone();
        q[k] += h;
        if let Some(i) = k.checked_sub(model.free.len()) {
            // A run's own carriage offset moves that run alone.
            let r = run_residuals(model, &g, &q, i, &runs[i], noise)?;
            for (row, v) in r.iter().enumerate() {
                j[(3 * i + row, k)] = (v - r0[3 * i + row]) / h;
            }
        } else {
            let r = residuals(model, &q, runs, noise)?;
            j.set_column(k, &((r - r0) / h));
        }
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
    let cost = |p: &DVector<f64>| residuals(model, p, runs, noise);
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

/// The encoder a parameter belongs to: a carriage's spacing belongs to both.
fn encoder_name(robot: &Robot, e: usize, what: Param) -> String {
    match what {
        Param::Spacing | Param::DiameterRatio | Param::SpacingRatio => {
            format!("{}+{}", robot.encoders[0].name, robot.encoders[1].name)
        }
        _ => robot.encoders[e].name.clone(),
    }
}

fn param_name(p: Param) -> &'static str {
    match p {
        Param::Lever => "lever arm",
        Param::Spacing => "half spacing",
        Param::DiameterRatio => "diameter ratio E_d",
        Param::SpacingRatio => "spacing ratio E_b",
        Param::Direction => "direction",
        Param::Scale => "travel per count",
    }
}

/// Which test motion excites what the runs left unresolved.
fn advise(unresolved: &[Vec<(String, f64)>], axle: bool, encoders: usize) -> Vec<String> {
    let mut advice = Vec::new();
    // More than three wheels: the odometry solves their counts by least squares, and on counts
    // that agree (no slip) only its 3 x 3 restriction to the counts a motion can give matters:
    // 9 combinations of the 3n numbers. The other 3(n - 3) no motion shows.
    if encoders > 3 && unresolved.len() <= 3 * (encoders - 3) {
        advice.push(format!(
            "no motion: with {encoders} wheels the end poses fix 9 combinations of their {} \
             numbers, those the odometry uses (any geometry that gives the same odometry fits as \
             well); the runs held out (--check) say whether the fitted file holds",
            3 * encoders
        ));
        return advice;
    }
    for parts in unresolved {
        let has = |what: &str| parts.iter().any(|(n, _)| n.ends_with(what));
        if has("lever arm") || has("half spacing") {
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
