//! 5-point Gauss–Legendre quadrature (arc lengths here, wheel travel in the tick generator).

const GL5_X: [f64; 5] = [
    -0.906_179_845_938_664,
    -0.538_469_310_105_683_1,
    0.0,
    0.538_469_310_105_683_1,
    0.906_179_845_938_664,
];
const GL5_W: [f64; 5] = [
    0.236_926_885_056_189_1,
    0.478_628_670_499_366_5,
    0.568_888_888_888_888_9,
    0.478_628_670_499_366_5,
    0.236_926_885_056_189_1,
];

/// The 5-point Gauss–Legendre nodes on `[a, b]`.
pub(crate) fn gl5_nodes(a: f64, b: f64) -> [f64; 5] {
    let (m, h) = (0.5 * (a + b), 0.5 * (b - a));
    GL5_X.map(|x| m + h * x)
}

/// `∫_a^b f` from the values of `f` at [`gl5_nodes`]`(a, b)` (exact for polynomials of degree 9).
pub(crate) fn gl5_sum(a: f64, b: f64, values: &[f64; 5]) -> f64 {
    let mut sum = 0.0;
    for (w, v) in GL5_W.iter().zip(values) {
        sum += w * v;
    }
    0.5 * (b - a) * sum
}

/// `∫_a^b f`, 5-point Gauss–Legendre.
pub(crate) fn gl5(a: f64, b: f64, mut f: impl FnMut(f64) -> f64) -> f64 {
    let values = gl5_nodes(a, b).map(&mut f);
    gl5_sum(a, b, &values)
}
