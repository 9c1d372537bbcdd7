//! One wheel's rolling speed over an interval as a Chebyshev series, and its exact integral.
//!
//! The interval's interpolant (`interp`, degree 10 through the Chebyshev–Lobatto points) is the
//! same polynomial in Chebyshev form, which integrates term by term: the distance rolled from the
//! interval's start to any instant is one Clenshaw sum of degree 11, where quadrature needed five
//! evaluations of the barycentric formula for all four twist components. The root finder calls it
//! at every Newton step of every tick, so this is most of `generate`'s (and `accuracy`'s) time.

use super::interp::SAMPLES;

const N: usize = SAMPLES - 1;

/// A speed polynomial on `[t0, t1]` and its antiderivative, both in Chebyshev form in
/// `x = (t − mid) / half` (well conditioned on `[−1, 1]`, unlike powers of `t`).
pub(super) struct SpeedSeries {
    mid: f64,
    half: f64,
    /// Speed: `Σ_{k=0..N} a_k T_k(x)`.
    a: [f64; N + 1],
    /// Distance rolled since `t0`: `half · Σ_{k=0..N+1} b_k T_k(x)`, zero at `x = −1`.
    b: [f64; N + 2],
}

impl SpeedSeries {
    /// From the speed at the interval's sample points `t` (increasing, Chebyshev–Lobatto:
    /// `t_j = mid − half·cos(πj/N)`, so `x_j = −cos(πj/N)`).
    pub(super) fn new(t: &[f64; SAMPLES], speed: &[f64; SAMPLES]) -> SpeedSeries {
        let (t0, t1) = (t[0], t[N]);
        let (mid, half) = (0.5 * (t0 + t1), 0.5 * (t1 - t0));
        // Discrete cosine transform on the Lobatto points (first and last terms halved):
        // x_j = cos(π(N − j)/N), so T_k(x_j) = cos(πk(N − j)/N) = (−1)^k cos(πkj/N).
        let cos = cosines();
        let mut a = [0.0; N + 1];
        for (k, ak) in a.iter_mut().enumerate() {
            let mut s = 0.0;
            for (j, &f) in speed.iter().enumerate() {
                let w = if j == 0 || j == N { 0.5 } else { 1.0 };
                s += w * f * cos[(k * j) % (2 * N)];
            }
            let sign = if k % 2 == 0 { 1.0 } else { -1.0 };
            let scale = if k == 0 || k == N { 1.0 } else { 2.0 };
            *ak = sign * scale * s / N as f64;
        }
        // ∫T_0 = T_1, ∫T_1 = T_2/4, ∫T_k = T_{k+1}/(2(k+1)) − T_{k−1}/(2(k−1)): collected by
        // the index of the result, b_k = (c_{k−1} − c_{k+1}) / (2k) with c_0 = 2·a_0.
        let c = |k: usize| match k {
            0 => 2.0 * a[0],
            k if k <= N => a[k],
            _ => 0.0,
        };
        let mut b = [0.0; N + 2];
        for (k, bk) in b.iter_mut().enumerate().skip(1) {
            *bk = (c(k - 1) - c(k + 1)) / (2 * k) as f64;
        }
        // The constant makes the distance zero at the interval's start (T_k(−1) = (−1)^k).
        b[0] = -b
            .iter()
            .enumerate()
            .skip(1)
            .map(|(k, &bk)| if k % 2 == 0 { bk } else { -bk })
            .sum::<f64>();
        SpeedSeries { mid, half, a, b }
    }

    fn x(&self, t: f64) -> f64 {
        ((t - self.mid) / self.half).clamp(-1.0, 1.0)
    }

    /// The speed at `t`.
    pub(super) fn speed(&self, t: f64) -> f64 {
        clenshaw(&self.a, self.x(t))
    }

    /// The distance rolled from the interval's start to `t`.
    pub(super) fn rolled(&self, t: f64) -> f64 {
        self.half * clenshaw(&self.b, self.x(t))
    }
}

/// `cos(πm/N)` for `m` in `0..2N` (the transform's only angles), computed once.
fn cosines() -> &'static [f64; 2 * N] {
    static COS: std::sync::OnceLock<[f64; 2 * N]> = std::sync::OnceLock::new();
    COS.get_or_init(|| std::array::from_fn(|m| (std::f64::consts::PI * m as f64 / N as f64).cos()))
}

/// `Σ c_k T_k(x)`.
fn clenshaw(c: &[f64], x: f64) -> f64 {
    let (mut b1, mut b2) = (0.0, 0.0);
    for &ck in c.iter().skip(1).rev() {
        let b0 = 2.0 * x * b1 - b2 + ck;
        b2 = b1;
        b1 = b0;
    }
    x * b1 - b2 + c[0]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lobatto(t0: f64, t1: f64) -> [f64; SAMPLES] {
        let (m, r) = (0.5 * (t0 + t1), 0.5 * (t1 - t0));
        std::array::from_fn(|j| m - r * (std::f64::consts::PI * j as f64 / N as f64).cos())
    }

    #[test]
    fn a_polynomial_speed_and_its_integral_are_exact() {
        // speed = 3t² − 2t + 0.5 on [1, 1.001]: distance t³ − t² + 0.5t from 1.
        let t = lobatto(1.0, 1.001);
        let v = t.map(|t| 3.0 * t * t - 2.0 * t + 0.5);
        let s = SpeedSeries::new(&t, &v);
        let dist = |t: f64| t * t * t - t * t + 0.5 * t - 0.5;
        for u in [1.0, 1.0002, 1.0005, 1.000_913, 1.001] {
            assert!(
                (s.speed(u) - (3.0 * u * u - 2.0 * u + 0.5)).abs() < 1e-12,
                "{u}"
            );
            assert!((s.rolled(u) - dist(u)).abs() < 1e-16, "{u}");
        }
    }

    #[test]
    fn a_smooth_speed_integrates_to_rounding() {
        // speed = cos(40 t) on a 1 ms interval: degree 10 interpolates it to rounding (1e-16 m
        // on 0.8 mm: 10 pm over a 100 s stream even if every interval erred the same way).
        let t = lobatto(0.25, 0.251);
        let s = SpeedSeries::new(&t, &t.map(|t| (40.0 * t).cos()));
        for u in [0.25f64, 0.2503, 0.2507, 0.251] {
            let exact = ((40.0 * u).sin() - (40.0 * 0.25f64).sin()) / 40.0;
            assert!(
                (s.rolled(u) - exact).abs() < 1e-16,
                "{u}: {:e}",
                s.rolled(u) - exact
            );
        }
    }
}
