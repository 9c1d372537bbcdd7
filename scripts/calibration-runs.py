#!/usr/bin/env python3
"""Write calibration runs of a robot that is not as its robot file says, independently of
omnibench's Rust code (standard library only): the robot file read with tomllib, each
encoder's travel per count off by up to 2 %, its rolling direction by up to 1 degree and its
lever arm (its position across the rolling direction) by up to 2 mm, and tick streams of
closed-form motion (pieces of constant body twist: spins both ways, sideways and diagonal
runs, arcs) with every encoder powered on at a random point inside its count. Truth rows every
10 ms, the last the end pose.

Usage: python3 scripts/calibration-runs.py --robot robots/skewed3.toml --out DIR
                                           [--runs 10] [--check 5] [--seed N]
Writes DIR/true.toml (the robot as it is), DIR/fit-K.csv (runs to fit) and DIR/check-K.csv
(runs held out), and prints the true numbers, for
    host-bench calibrate --method fit --robot robots/skewed3.toml --runs DIR/fit-*.csv
                         --check DIR/check-*.csv

       python3 scripts/calibration-runs.py --report [--seeds 5] [--host-bench PATH]
For robots/skewed3.toml and robots/seed000-0.1mm.toml (three omni wheels), seeds 0..N-1: the
runs written, `calibrate --method fit --json`, and the fitted numbers against the true ones:
the largest error in travel per count, direction and lever arm, the held-out runs' end error
cut (their errors summed), the fit's time; spreads over the seeds. Exits 1 if a goal is missed (0.05 %, 0.05 deg,
0.5 mm, 95 %).
"""

import argparse
import csv
import math
import os
import json
import random
import subprocess
import sys
import tomllib


def pose_after(pose, twist, t):
    """A pose moved by a constant body twist for t seconds (closed form)."""
    x, y, th = pose
    vx, vy, w = twist
    if abs(w) < 1e-12:
        c, s = math.cos(th), math.sin(th)
        return (x + (c * vx - s * vy) * t, y + (s * vx + c * vy) * t, th)
    s, c = math.sin(w * t), math.cos(w * t)
    dx = (vx * s - vy * (1 - c)) / w
    dy = (vx * (1 - c) + vy * s) / w
    ct, st = math.cos(th), math.sin(th)
    return (x + ct * dx - st * dy, y + st * dx + ct * dy, th + w * t)


def encoders_of(path):
    """(name, x, y, direction rad, metres per count) of each encoder, as the file says."""
    with open(path, "rb") as f:
        robot = tomllib.load(f)
    if "carriage" in robot:
        raise SystemExit(f"{path}: a carriage robot; this writer moves body-fixed encoders only")
    out = []
    for e in robot["encoders"]:
        if "metres_per_count" in e:
            k = e["metres_per_count"]
        else:
            k = math.pi * e["wheel_diameter_m"] / e["counts_per_rev"]
        out.append((e["name"], e["x_m"], e["y_m"], math.radians(e["direction_deg"]), k))
    return robot, out


def as_built(encoders, rng):
    """Each encoder off: travel per count by up to 2 %, direction by up to 1 degree, lever
    arm by up to 2 mm (along its direction it changes nothing: left as it is)."""
    out = []
    for name, x, y, d, k in encoders:
        lever = rng.uniform(-0.002, 0.002)
        out.append(
            (name, x - math.sin(d) * lever, y + math.cos(d) * lever,
             d + math.radians(rng.uniform(-1.0, 1.0)), k * (1 + rng.uniform(-0.02, 0.02)))
        )
    return out


def write_robot(path, robot, encoders):
    with open(path, "w") as f:
        f.write(f'format = "omnibench robot v1"\nname = "{robot["name"]}-as-built"\n')
        f.write('description = "written by scripts/calibration-runs.py: the robot as it is"\n')
        for name, x, y, d, k in encoders:
            f.write(
                f'\n[[encoders]]\nname = "{name}"\nx_m = {x!r}\ny_m = {y!r}\n'
                f"direction_deg = {math.degrees(d)!r}\nmetres_per_count = {k!r}\n"
            )


def motion(rng):
    """Pieces (seconds, vx, vy, w) that excite every wheel: a spin each way, a sideways and a
    diagonal run, and two arcs, in a random order and at random speeds."""
    pieces = [
        (rng.uniform(1.5, 3.0), 0.0, 0.0, rng.uniform(1.0, 2.0)),
        (rng.uniform(1.5, 3.0), 0.0, 0.0, -rng.uniform(1.0, 2.0)),
        (rng.uniform(1.0, 2.0), 0.0, rng.choice([-1, 1]) * rng.uniform(0.2, 0.4), 0.0),
        (rng.uniform(1.0, 2.0), rng.uniform(0.2, 0.4), rng.uniform(-0.3, 0.3), 0.0),
        (rng.uniform(1.0, 2.0), rng.uniform(0.1, 0.4), rng.uniform(-0.2, 0.2), rng.uniform(-1.0, 1.0)),
        (rng.uniform(1.0, 2.0), rng.uniform(-0.3, 0.3), rng.uniform(-0.3, 0.3), rng.uniform(-1.5, 1.5)),
    ]
    rng.shuffle(pieces)
    return pieces


def write_run(path, robot_file, encoders, pieces, rng):
    # Every encoder powers on somewhere inside its count.
    s = [rng.random() for _ in encoders]
    count = [0 for _ in encoders]
    rows, t, pose = [(0, "truth", "", "", "0.0", "0.0", "0.0")], 0.0, (0.0, 0.0, 0.0)
    for secs, vx, vy, w in pieces:
        for i, (_, x, y, d, k) in enumerate(encoders):
            ux, uy = math.cos(d), math.sin(d)
            v = (ux * (vx - w * y) + uy * (vy + w * x)) / k  # counts per second
            end = s[i] + v * secs
            if v > 0:
                while count[i] + 1 <= end:
                    count[i] += 1
                    rows.append((round((t + (count[i] - s[i]) / v) * 1e9), "tick", i, 1, "", "", ""))
            elif v < 0:
                while count[i] > end:
                    rows.append((round((t + (count[i] - s[i]) / v) * 1e9), "tick", i, -1, "", "", ""))
                    count[i] -= 1
            s[i] = end
        k0 = math.floor(t / 0.01) + 1
        while k0 * 0.01 <= t + secs + 1e-12:
            p = pose_after(pose, (vx, vy, w), k0 * 0.01 - t)
            rows.append((round(k0 * 0.01 * 1e9), "truth", "", "", repr(p[0]), repr(p[1]), repr(p[2])))
            k0 += 1
        pose = pose_after(pose, (vx, vy, w), secs)
        t += secs
    rows.sort(key=lambda r: (r[0], r[1] == "truth"))
    with open(path, "w", newline="") as f:
        f.write(f"# omnibench tick stream v1\n# robot: {robot_file}\n")
        f.write(f"# written by scripts/calibration-runs.py: {len(pieces)} pieces of constant twist\n")
        o = csv.writer(f)
        o.writerow(["t_ns", "kind", "id", "value", "x_m", "y_m", "theta_rad"])
        o.writerows(rows)


def write_all(robot_path, out, runs, check, seed):
    rng = random.Random(seed)
    robot, nominal = encoders_of(robot_path)
    truly = as_built(nominal, rng)
    write_robot(os.path.join(out, "true.toml"), robot, truly)
    paths = {"fit": [], "check": []}
    for kind, n in (("fit", runs), ("check", check)):
        for k in range(n):
            path = os.path.join(out, f"{kind}-{k}.csv")
            write_run(path, "true.toml", truly, motion(rng), rng)
            paths[kind].append(path)
    return nominal, truly, paths


def report(seeds, host_bench):
    import tempfile
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    ok = True
    for rel in ("robots/skewed3.toml", "robots/seed000-0.1mm.toml"):
        worst = {"scale": [], "dir": [], "lever": [], "cut": [], "least": [], "secs": []}
        for seed in range(seeds):
            with tempfile.TemporaryDirectory() as out:
                nominal, truly, paths = write_all(os.path.join(root, rel), out, 10, 5, seed)
                fitted = os.path.join(out, "fitted.toml")
                res = subprocess.run(
                    [host_bench, "calibrate", "--method", "fit", "--robot", os.path.join(root, rel),
                     "--json", "--out", fitted, "--runs", *paths["fit"], "--check", *paths["check"]],
                    capture_output=True, text=True)
                if res.returncode != 0:
                    raise SystemExit(f"calibrate failed on {rel} seed {seed}:\n{res.stderr}")
                v = json.loads(res.stdout)
                _, got = encoders_of(fitted)
                sc, di, le = 0.0, 0.0, 0.0
                for (_, x, y, d, k), (_, gx, gy, gd, gk), (_, _, _, d0, _) in zip(truly, got, nominal):
                    sc = max(sc, abs(gk / k - 1))
                    di = max(di, abs(math.degrees(math.remainder(gd - d, 2 * math.pi))))
                    lev = lambda px, py, dd: -px * math.sin(dd) + py * math.cos(dd)
                    le = max(le, abs(lev(gx, gy, d) - lev(x, y, d)))
                held = [r for r in v["runs"] if not r["fitted"]]
                # Over the held-out runs together, and the least of them alone (a run the
                # nominal robot already ends near is held back by the counts' quantisation).
                cut = 1 - sum(r["after_m"] for r in held) / sum(r["before_m"] for r in held)
                least = min(1 - r["after_m"] / r["before_m"] for r in held)
                for key, val in (("scale", sc), ("dir", di), ("lever", le), ("cut", cut),
                                 ("least", least), ("secs", v["fit_seconds"])):
                    worst[key].append(val)
        span = lambda vals, k, f: f"{min(vals) * k:{f}} to {max(vals) * k:{f}}"
        print(f"{rel}: over {seeds} seeds, 10 runs fitted, 5 held out each; worst encoder: travel "
              f"per count off {span(worst['scale'], 100, '.4f')} %, direction "
              f"{span(worst['dir'], 1, '.4f')} deg, lever arm {span(worst['lever'], 1e3, '.3f')} mm; "
              f"held-out end error cut by {span(worst['cut'], 100, '.1f')} % (the 5 together; "
              f"the least of them alone {span(worst['least'], 100, '.1f')} %); "
              f"fit {span(worst['secs'], 1, '.2f')} s")
        goals = (max(worst["scale"]) < 5e-4, max(worst["dir"]) < 0.05, max(worst["lever"]) < 5e-4,
                 min(worst["cut"]) >= 0.95)
        if not all(goals):
            print(f"error: {rel}: a goal is missed (travel, direction, lever, cut: {goals})",
                  file=sys.stderr)
            ok = False
    return ok


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--report", action="store_true")
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--host-bench", default=os.path.join(
        os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "target/debug/host-bench"))
    ap.add_argument("--robot")
    ap.add_argument("--out")
    ap.add_argument("--runs", type=int, default=10)
    ap.add_argument("--check", type=int, default=5)
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args()
    if a.report:
        sys.exit(0 if report(a.seeds, a.host_bench) else 1)
    if not (a.robot and a.out):
        ap.error("--robot and --out, or --report")
    os.makedirs(a.out, exist_ok=True)
    nominal, truly, _ = write_all(a.robot, a.out, a.runs, a.check, a.seed)
    print("encoder  lever arm mm   direction deg   travel per count um   (true; nominal in parentheses)")
    for (name, x, y, d, k), (_, x0, y0, d0, k0) in zip(truly, nominal):
        lever = -(x - x0) * math.sin(d0) + (y - y0) * math.cos(d0)
        print(f"{name:8} {lever * 1e3:+10.4f}   {math.degrees(d):12.4f} ({math.degrees(d0):.1f})   "
              f"{k * 1e6:12.5f} ({k0 * 1e6:.5f})")


if __name__ == "__main__":
    main()
