#!/usr/bin/env python3
"""Write tick streams of a robot whose wheel is shaken across an edge at power-on, independently
of omnibench's Rust code (standard library only).

A differential drive (0.3 m track, 0.4 mm counts) stands still for 0.3 s after power-on, then
starts from rest along a straight line (0.25 m/s reached in 0.4 s, held 0.6 s). In the `shaken`
stream its left wheel stands 0.003 count below an edge and is shaken 0.006 count either way at
47 Hz while the robot stands (a motor holding it, a bump, a hand setting the robot down), so it
ticks over that edge and back; the right wheel stands still at a random place in its count. In
the `still` stream neither is shaken and the left wheel stands at a random place too. Edges are
ideal; each tick is found to the microsecond.

Usage: python3 scripts/shaken-start.py --out DIR [--seed N]
Writes DIR/robot.toml, DIR/shaken-N.csv and DIR/still-N.csv; replay them with
`host-bench replay --ticks DIR/shaken-N.csv`.
"""

import argparse
import math
import os
import random

STEP = 0.0004  # metres a count
REST, ACCEL, CRUISE, SPEED = 0.3, 0.4, 0.6, 0.25  # s, s, s, m/s
SHAKE, SHAKE_HZ = 0.006, 47.0  # counts, Hz
# The shake ends with a whole cycle before the start, where it passes through zero.
SHAKE_END = math.floor(REST * SHAKE_HZ) / SHAKE_HZ


def body(t):
    """Metres along the line at t."""
    if t < REST:
        return 0.0
    t -= REST
    a = SPEED / ACCEL
    if t < ACCEL:
        return 0.5 * a * t * t
    return 0.5 * a * ACCEL**2 + SPEED * (t - ACCEL)


def stream(shaken, seed):
    """The rows (t_ns, line) of one stream."""
    rng = random.Random(f"shaken-start/{seed}")
    places = [1.0 - 0.003 if shaken else rng.random(), rng.random()]
    end = REST + ACCEL + CRUISE

    def wheel(i, t):
        shake = SHAKE * math.sin(2 * math.pi * SHAKE_HZ * t) if shaken and i == 0 else 0.0
        return places[i] + (shake if t < SHAKE_END else 0.0) + body(t) / STEP

    rows = []
    for i in range(2):
        count, us = math.floor(wheel(i, 0.0)), 0
        while us < end * 1e6:
            us += 1
            k = math.floor(wheel(i, us * 1e-6))
            while k > count:
                count += 1
                rows.append((us * 1000, f"{us * 1000},tick,{i},1,,,"))
            while k < count:
                count -= 1
                rows.append((us * 1000, f"{us * 1000},tick,{i},-1,,,"))
    for j in range(round(end * 100) + 1):
        t_ns = j * 10_000_000
        rows.append((t_ns, f"{t_ns},truth,,,{body(j / 100):.9f},0.0,0.0"))
    rows.sort(key=lambda r: r[0])
    return rows


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", required=True)
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    with open(os.path.join(a.out, "robot.toml"), "w") as f:
        f.write('format = "omnibench robot v1"\nname = "shaken-start"\n')
        f.write('description = "written by scripts/shaken-start.py"\n')
        for name, y in (("left", 0.15), ("right", -0.15)):
            f.write(
                f'\n[[encoders]]\nname = "{name}"\nx_m = 0.0\ny_m = {y}\n'
                f"direction_deg = 0.0\nmetres_per_count = {STEP}\n"
            )
    for kind in ("shaken", "still"):
        path = os.path.join(a.out, f"{kind}-{a.seed}.csv")
        with open(path, "w") as f:
            f.write("# omnibench tick stream v1\n# robot: robot.toml\n")
            f.write(f"# scripts/shaken-start.py, {kind}, seed {a.seed}\n")
            f.write("t_ns,kind,id,value,x_m,y_m,theta_rad\n")
            for _, line in stream(kind == "shaken", a.seed):
                f.write(line + "\n")
        print(path)


if __name__ == "__main__":
    main()
