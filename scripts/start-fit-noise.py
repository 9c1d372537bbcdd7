#!/usr/bin/env python3
"""How far a wheel's start inside its count is misplaced when its first ticks are not where
the fit takes them: the start fit's sensitivity to uneven edges (docs/odometry.md, "Learning
the edges", what it does not do yet).

A wheel powered on at rest, a random fraction φ into its count, starts at power-on as
s(t) = J·t³ (a jerk-limited start, counts) or s(t) = A·t² (constant acceleration). Its edges
are at k + (each kind's offset) + (its line's placement, uniform within ±`--line` counts, one
line per four counts, the lines falling anywhere against the count at power-on). The fit
knows each kind's offset (as after `exact` has learned them) but not the lines'. It fits a
polynomial of degree 3 through four of the first ticks (as `robot-math/src/ticks/start.rs`
does: the first four, or once learned the 1st, 2nd, 5th and 9th) or by least squares over
more, takes the latest zero of its speed before the first tick (or power-on), and reads the
start there. Printed: the error
|fitted − φ| in counts, median / 90th percentile / max over the trials. Standard library only,
in f64: it measures the method, not the integer arithmetic.

Usage: python3 scripts/start-fit-noise.py [--trials 200] [--line 0.0167] [--seed 1]
"""

import argparse
import random

# Each kind's offset, counts (one HEDS-9040 typical draw: the generator's seed 4, encoder 0).
KINDS = [-0.0137, 0.0171, 0.0260, -0.0295]


def solve(a, b):
    """Gaussian elimination with partial pivoting, a: n×n, b: n."""
    n = len(b)
    m = [row[:] + [b[i]] for i, row in enumerate(a)]
    for c in range(n):
        p = max(range(c, n), key=lambda r: abs(m[r][c]))
        m[c], m[p] = m[p], m[c]
        for r in range(c + 1, n):
            f = m[r][c] / m[c][c]
            for k in range(c, n + 1):
                m[r][k] -= f * m[c][k]
    x = [0.0] * n
    for r in reversed(range(n)):
        x[r] = (m[r][n] - sum(m[r][k] * x[k] for k in range(r + 1, n))) / m[r][r]
    return x


def cubic_fit(xs, ys):
    """Least squares (exact through 4 points) u(x) = c0 + c1 x + c2 x² + c3 x³."""
    a = [[sum(x ** (i + j) for x in xs) for j in range(4)] for i in range(4)]
    b = [sum(y * x**i for x, y in zip(xs, ys)) for i in range(4)]
    return solve(a, b)


def latest_speed_zero(c, lo):
    """The latest x in (lo, 0) where c1 + 2 c2 x + 3 c3 x² = 0, else lo."""
    a, b, cc = 3 * c[3], 2 * c[2], c[1]
    roots = []
    if abs(a) < 1e-15:
        if abs(b) > 1e-15:
            roots = [-cc / b]
    else:
        d = b * b - 4 * a * cc
        if d >= 0:
            roots = [(-b + s * d**0.5) / (2 * a) for s in (1, -1)]
    inside = [r for r in roots if lo < r < 0]
    return max(inside) if inside else lo


def trial(rng, ticks, line, profile):
    """One start: the error of the fit through (or, past four, by least squares over) the
    ticks numbered `ticks` (1: the first)."""
    n = max(ticks)
    # Where the code wheel's lines fall against the count at power-on: the quadrature state
    # then (0..3). The wheel stands inside its count, between its edges' places.
    phi = 0.05 + 0.9 * rng.random()
    q0 = rng.randrange(4)
    lines = [(rng.random() - 0.5) * 2 * line for _ in range(n // 4 + 3)]
    times = []
    for m in range(1, n + 1):
        travel = m + KINDS[(m + q0) % 4] + lines[(m + q0) // 4] - phi
        t = (travel / 1552.0) ** (1 / 3) if profile == "jerk" else (travel / 300.0) ** 0.5
        times.append(round(t * 1e9) * 1e-9)
    times = [times[m - 1] for m in ticks]
    t1, span = times[0], times[-1] - times[0]
    xs = [(t - t1) / span for t in times]
    ys = [m + KINDS[(m + q0) % 4] for m in ticks]
    c = cubic_fit(xs, ys)
    x = latest_speed_zero(c, -t1 / span)
    return abs(c[0] + c[1] * x + c[2] * x * x + c[3] * x**3 - phi)


# What robot-math fits: through the first four ticks, then (once learned, nine ticks one way)
# through the first, second, fifth and ninth; and least squares over more, for comparison.
FITS = [
    ([1, 2, 3, 4], "through the first four (the first fit)"),
    ([1, 2, 5, 9], "through the 1st, 2nd, 5th and 9th (the fit again)"),
    (list(range(1, 9)), "least squares, the first 8"),
    (list(range(1, 13)), "least squares, the first 12"),
    (list(range(1, 17)), "least squares, the first 16"),
]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--trials", type=int, default=400)
    ap.add_argument("--line", type=float, default=0.0167)
    ap.add_argument("--seed", type=int, default=1)
    a = ap.parse_args()
    print(f"start error, counts: median / p90 / max over {a.trials} starts; lines within ±{a.line}")
    for profile in ("jerk", "accel"):
        for ticks, what in FITS:
            rng = random.Random(a.seed)
            e = sorted(trial(rng, ticks, a.line, profile) for _ in range(a.trials))
            med, p90 = e[len(e) // 2], e[int(0.9 * (len(e) - 1))]
            name = "s = J t^3" if profile == "jerk" else "s = A t^2"
            print(f"{name}  {what:52}: {med:.3f} / {p90:.3f} / {e[-1]:.3f}")


if __name__ == "__main__":
    main()
