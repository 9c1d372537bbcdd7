//! One method's figures over every power-on seed of a case: median, p95 and max.

use serde::Serialize;

use crate::eval::replay::Score;

/// A figure across seeds.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Spread {
    pub median: f64,
    pub p95: f64,
    pub max: f64,
}

impl Spread {
    /// Nearest-rank median and 95th percentile, and the maximum, of `values` (not empty).
    pub fn of(values: impl IntoIterator<Item = f64>) -> Spread {
        let mut v: Vec<f64> = values.into_iter().collect();
        v.sort_by(f64::total_cmp);
        if v.is_empty() {
            return Spread::default();
        }
        let rank = |q: f64| v[((q * v.len() as f64).ceil() as usize).clamp(1, v.len()) - 1];
        Spread {
            median: rank(0.5),
            p95: rank(0.95),
            max: v[v.len() - 1],
        }
    }
}

/// A method on a case in one mode, over every seed.
#[derive(Clone, Debug, Serialize)]
pub struct MethodSpread {
    pub name: String,
    pub final_error_m: Spread,
    /// Each run's median error over its truth rows (the error while moving), across seeds.
    pub median_error_m: Spread,
    pub max_error_m: Spread,
    /// Each run's median error while moving (relative pose error over 0.5 m of path once every
    /// wheel is placed: [`super::moving`]), across seeds; `None` if a seed has none.
    pub moving_median_error_m: Option<Spread>,
    pub final_heading_error_rad: Spread,
    /// Every seed's run, in seed order (the first one's track feeds `--out`).
    #[serde(skip)]
    pub runs: Vec<Score>,
}

impl MethodSpread {
    /// The spread of `runs` (one per seed, not empty) and of their errors while moving.
    pub fn of(runs: Vec<Score>, moving: Vec<Option<f64>>) -> MethodSpread {
        let f = |g: fn(&Score) -> f64| Spread::of(runs.iter().map(g));
        MethodSpread {
            name: runs.first().map(|s| s.name.clone()).unwrap_or_default(),
            final_error_m: f(|s| s.final_error_m),
            median_error_m: f(|s| s.median_error_m),
            max_error_m: f(|s| s.max_error_m),
            moving_median_error_m: moving
                .into_iter()
                .collect::<Option<Vec<f64>>>()
                .filter(|m| !m.is_empty())
                .map(Spread::of),
            final_heading_error_rad: f(|s| s.final_heading_error_rad.abs()),
            runs,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Spread;

    #[test]
    fn nearest_rank_percentiles() {
        let s = Spread::of((1..=20).map(f64::from));
        assert_eq!((s.median, s.p95, s.max), (10.0, 19.0, 20.0));
        let one = Spread::of([3.0]);
        assert_eq!((one.median, one.p95, one.max), (3.0, 3.0, 3.0));
        let eight = Spread::of([8.0, 1.0, 7.0, 2.0, 6.0, 3.0, 5.0, 4.0]);
        assert_eq!((eight.median, eight.p95, eight.max), (4.0, 8.0, 8.0));
    }
}
