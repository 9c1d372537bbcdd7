#!/usr/bin/env python3
"""Write a tick stream for a differential robot driving circles, independently of omnibench's
Rust code (standard library only), as a user would from their own tools.

The robot drives at constant speed v on a circle of radius R, turning left. Each wheel then
rolls at a constant speed, so every tick instant is known in closed form:
    wheel speed   v_i = v -/+ w * track / 2     (left, right; w = v / R)
    k-th tick     t_k = k * step / v_i
and so is the pose:  x = R sin(w t),  y = R (1 - cos(w t)),  theta = w t.

Usage: python3 scripts/circle-stream.py --out DIR [--radius 0.5] [--speed 0.3] [--track 0.3]
                                         [--step 0.0004] [--laps 2] [--truth-period 0.05]
Writes DIR/robot.toml and DIR/circle.csv.
"""
import argparse
import csv
import math
import os


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", required=True)
    ap.add_argument("--radius", type=float, default=0.5)
    ap.add_argument("--speed", type=float, default=0.3)
    ap.add_argument("--track", type=float, default=0.3)
    ap.add_argument("--step", type=float, default=0.0004)
    ap.add_argument("--laps", type=float, default=2.0)
    ap.add_argument("--truth-period", type=float, default=0.05)
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)

    with open(os.path.join(a.out, "robot.toml"), "w") as f:
        f.write('format = "omnibench robot v1"\nname = "circle-diff-drive"\n')
        f.write('description = "differential drive written by scripts/circle-stream.py"\n')
        for name, y in (("left", a.track / 2), ("right", -a.track / 2)):
            f.write(f'\n[[encoders]]\nname = "{name}"\nx_m = 0.0\ny_m = {y!r}\n'
                    f'direction_deg = 0.0\nmetres_per_count = {a.step!r}\n')

    w = a.speed / a.radius
    duration = a.laps * 2 * math.pi / w
    rows = []
    for enc, v in ((0, a.speed - w * a.track / 2), (1, a.speed + w * a.track / 2)):
        ticks = int(v * duration / a.step)
        rows += [(round(k * a.step / v * 1e9), "tick", enc, 1, "", "", "") for k in range(1, ticks + 1)]
    n_truth = int(duration / a.truth_period)
    for i in range(n_truth + 1):
        t = i * a.truth_period
        rows.append((round(t * 1e9), "truth", "", "",
                     repr(a.radius * math.sin(w * t)), repr(a.radius * (1 - math.cos(w * t))), repr(w * t)))
    rows.sort(key=lambda r: (r[0], r[1] == "truth"))  # ticks before the truth at the same instant
    with open(os.path.join(a.out, "circle.csv"), "w", newline="") as f:
        f.write("# omnibench tick stream v1\n# robot: robot.toml\n")
        f.write(f"# circle R={a.radius} m v={a.speed} m/s track={a.track} m step={a.step} m laps={a.laps}\n")
        out = csv.writer(f)
        out.writerow(["t_ns", "kind", "id", "value", "x_m", "y_m", "theta_rad"])
        out.writerows(rows)


if __name__ == "__main__":
    main()
