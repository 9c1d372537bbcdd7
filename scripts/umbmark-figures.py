#!/usr/bin/env python3
"""UMBmark's figures over seeds, as docs/calibration.md ("Figures") quotes them: a robot whose
geometry is off its robot file (the right wheel 1 % larger than the left, E_d = 1.01, and the
wheels 3 % further apart, E_b = 1.03), its squares driven both ways, the end poses measured
with a person's tape-measure noise, `host-bench calibrate --method umbmark`, and the squares
driven again with the corrected robot file. Standard library only; it runs host-bench.

Three robots:
    seed002  seed 002's chassis, emulated closed loop (`emulate --true-robot`): the master
             steers it round the square by the slave's odometry, as UMBmark prescribes. The
             true robot is robots/seed002-as-built.toml.
    seed001  seed 001's differential drive (no controller of ours drives it: `generate` writes
             the true squares of the robot as built, which the odometry follows). Its as-built
             file is written here from robots/seed001.toml.
    seed004  seed 004's measuring wheels on their trailing swivel carriage (robots/
             seed004-as-built.toml), generated true squares as seed001's, each started with
             the carriage swung a random angle (up to 90 degrees either way) from straight
             behind, as the last motion would leave it.

For the generated robots, `calibrate --method fit` is also made on the same squares and
measured end poses, and the squares replayed on its corrected file: "after the fit".

The measured end poses get uniform noise of +-1 mm in x and y and +-0.2 deg in heading, drawn
from the noise seed; the "after" figure is the true E_max,syst of the squares driven (or
replayed) with the corrected file, measured without noise.

Usage: python3 scripts/umbmark-figures.py [--host-bench PATH] [--seeds 5] [--noise-seeds 5]
                                          [--goal X] [--jobs N]
With --goal, exits 1 unless every calibration cut E_max,syst at least X times. The host-bench
runs go --jobs at a time (default: one per core); each is deterministic, so the figures do not
depend on it.
"""

import argparse
import concurrent.futures
import json
import os
import random
import re
import statistics
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
NOISE_M = 0.001
NOISE_DEG = 0.2


def run(hb, *args, out=None):
    res = subprocess.run([hb, *args], capture_output=True, text=True)
    if res.returncode != 0:
        sys.exit(f"host-bench {' '.join(args)} failed:\n{res.stderr}")
    if out:
        with open(out, "w") as f:
            f.write(res.stdout)
    return res.stdout


def noisy(rng, x, y, th):
    return (
        x + rng.uniform(-NOISE_M, NOISE_M),
        y + rng.uniform(-NOISE_M, NOISE_M),
        th + rng.uniform(-NOISE_DEG, NOISE_DEG) * 3.141592653589793 / 180.0,
    )


def calibrate(hb, robot, runs, out=None, measured=None):
    args = ["calibrate", "--robot", robot, "--json", "--runs", *runs]
    if out:
        args += ["--out", out]
    if measured:
        args += ["--measured", measured]
    return json.loads(run(hb, *args))


def seed002(hb, tmp, seeds, pool):
    """The squares driven before calibration, then a function of the noise seed that measures
    them, calibrates and drives them again: (UMBmark's result, E_max,syst after, None)."""
    nominal = os.path.join(ROOT, "robots/seed002.toml")
    truly = os.path.join(ROOT, "robots/seed002-as-built.toml")
    scen = lambda way: os.path.join(ROOT, f"scenarios/umbmark-{way}.toml")
    drive = lambda way, robot, out: run(
        hb, "emulate", "--scenario", scen(way), "--true-robot", truly, "--sweep", str(seeds),
        "--json", *(["--robot", robot] if robot else []), out=out)
    before = {way: os.path.join(tmp, f"002-{way}.json") for way in ("cw", "ccw")}
    list(pool.map(lambda way: drive(way, None, before[way]), before))

    def chain(ns):
        rng = random.Random(ns)
        runs = []
        for way in ("cw", "ccw"):
            with open(before[way]) as f:
                sweep = json.load(f)
            for r in sweep["runs"]:
                x, y = r["final_position_m"]
                x, y, th = noisy(rng, x, y, r["final_heading_rad"])
                r["final_position_m"], r["final_heading_rad"] = [x, y], th
            path = os.path.join(tmp, f"002-{way}-noisy-{ns}.json")
            with open(path, "w") as f:
                json.dump(sweep, f)
            runs.append(path)
        fitted = os.path.join(tmp, f"002-fitted-{ns}.toml")
        c = calibrate(hb, nominal, runs, out=fitted)
        again = []
        for way in ("cw", "ccw"):
            path = os.path.join(tmp, f"002-{way}-after-{ns}.json")
            drive(way, fitted, path)
            again.append(path)
        a = calibrate(hb, fitted, again)
        return (c["umbmark"], a["umbmark"]["e_max_syst_m"], None)

    return chain


def as_built_seed001(tmp):
    """seed001.toml with the right wheel 1 % larger than the left and a 3 % wider track."""
    with open(os.path.join(ROOT, "robots/seed001.toml")) as f:
        text = f.read()
    text = text.replace('name = "seed001"', 'name = "seed001-as-built"')
    k = 0.0004
    left, right = k * 2 / 2.01, k * 2 * 1.01 / 2.01
    parts = text.split("[[encoders]]")
    assert len(parts) == 3
    parts[1] = parts[1].replace("y_m = 0.15", "y_m = 0.1545").replace(
        "metres_per_count = 0.0004", f"metres_per_count = {left!r}")
    parts[2] = parts[2].replace("y_m = -0.15", "y_m = -0.1545").replace(
        "metres_per_count = 0.0004", f"metres_per_count = {right!r}", 1)
    path = os.path.join(tmp, "seed001-as-built.toml")
    with open(path, "w") as f:
        f.write("[[encoders]]".join(parts))
    return path


def last_truth(path):
    last = None
    with open(path) as f:
        for line in f:
            if ",truth," in line:
                last = line
    t, _, _, _, x, y, th = last.strip().split(",")
    return float(x), float(y), float(th)


def generated(hb, tmp, tag, nominal, truly, seeds, swivel, pool):
    """The true squares written, then a function of the noise seed that measures their end
    poses, calibrates both ways and replays them on each corrected file: (UMBmark's result,
    E_max,syst after it, E_max,syst after the fit)."""
    jobs = []
    for way in ("cw", "ccw"):
        for s in range(seeds):
            path = os.path.join(tmp, f"{tag}-{way}-{s}.csv")
            extra = []
            if swivel:
                deg = random.Random(f"{tag}-{way}-{s}").uniform(-90.0, 90.0)
                extra = ["--start-swivel-deg", repr(deg)]
            jobs.append((path, ["generate", "--robot", truly, "--trajectory", f"umbmark-{way}",
                                "--seed", str(s), *extra, "--out", path]))
    list(pool.map(lambda job: run(hb, *job[1]), jobs))
    streams = [path for path, _ in jobs]

    def chain(ns):
        rng = random.Random(1000 + ns)
        measured = os.path.join(tmp, f"{tag}-measured-{ns}.csv")
        with open(measured, "w") as f:
            f.write("run,x_m,y_m,heading_deg\n")
            for s in streams:
                x, y, th = noisy(rng, *last_truth(s))
                f.write(f"{s},{x!r},{y!r},{th * 180 / 3.141592653589793!r}\n")
        fitted = os.path.join(tmp, f"{tag}-fitted-{ns}.toml")
        c = calibrate(hb, nominal, streams, out=fitted, measured=measured)
        # The same true squares replayed on the corrected file, their true end poses.
        a = calibrate(hb, fitted, streams)
        by_fit = os.path.join(tmp, f"{tag}-fit-{ns}.toml")
        run(hb, "calibrate", "--method", "fit", "--robot", nominal, "--runs", *streams,
            "--measured", measured, "--out", by_fit)
        f = calibrate(hb, by_fit, streams)
        return (c["umbmark"], a["umbmark"]["e_max_syst_m"], f["umbmark"]["e_max_syst_m"])

    return chain


def report(name, rows, goal):
    before = [u["e_max_syst_m"] for u, _, _ in rows]
    after = [a for _, a, _ in rows]
    ratio = [b / a for b, a in zip(before, after)]
    ed = [u["e_d"] for u, _, _ in rows]
    eb = [u["e_b"] for u, _, _ in rows]
    mm = lambda v: f"{min(v) * 1e3:.2f} / {statistics.median(v) * 1e3:.2f} / {max(v) * 1e3:.2f}"
    print(f"{name}: E_max,syst before {mm(before)} mm, after UMBmark {mm(after)} mm (min / median "
          f"/ max over {len(rows)} noise seeds); {min(ratio):.0f}x to {max(ratio):.0f}x less; "
          f"E_d {min(ed):.5f} to {max(ed):.5f}, E_b {min(eb):.5f} to {max(eb):.5f} (true: 1.01, 1.03)")
    ok = True
    if goal and min(ratio) < goal:
        print(f"error: {name}: E_max,syst cut only {min(ratio):.1f}x, the goal is {goal}x",
              file=sys.stderr)
        ok = False
    by_fit = [f for _, _, f in rows if f is not None]
    if by_fit:
        fit_ratio = [b / f for b, f in zip(before, by_fit)]
        print(f"    after the fit {mm(by_fit)} mm; {min(fit_ratio):.0f}x to {max(fit_ratio):.0f}x less")
        if goal and min(fit_ratio) < goal:
            print(f"error: {name}: the fit cut E_max,syst only {min(fit_ratio):.1f}x, the goal is "
                  f"{goal}x", file=sys.stderr)
            ok = False
    return ok


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--host-bench", default=os.path.join(ROOT, "target/debug/host-bench"))
    ap.add_argument("--seeds", type=int, default=5, help="squares each way (power-on seeds)")
    ap.add_argument("--noise-seeds", type=int, default=5, help="draws of the measuring noise")
    ap.add_argument("--goal", type=float, default=0, help="least cut of E_max,syst, or exit 1")
    ap.add_argument("--jobs", type=int, default=len(os.sched_getaffinity(0)),
                    help="host-bench runs at a time (default: one per core)")
    a = ap.parse_args()
    robots = [
        (f"seed002 (emulated, steered by its odometry, {a.seeds} squares each way)",
         lambda tmp, pool: seed002(a.host_bench, tmp, a.seeds, pool)),
        (f"seed001 (generated true squares, {a.seeds} each way)",
         lambda tmp, pool: generated(a.host_bench, tmp, "001",
                                     os.path.join(ROOT, "robots/seed001.toml"),
                                     as_built_seed001(tmp), a.seeds, False, pool)),
        (f"seed004 (its carriage's measuring wheels, generated true squares, {a.seeds} each way)",
         lambda tmp, pool: generated(a.host_bench, tmp, "004",
                                     os.path.join(ROOT, "robots/seed004.toml"),
                                     os.path.join(ROOT, "robots/seed004-as-built.toml"),
                                     a.seeds, True, pool)),
    ]
    with tempfile.TemporaryDirectory() as tmp, \
            concurrent.futures.ThreadPoolExecutor(max(1, a.jobs)) as pool:
        # Each robot's runs before calibration, then every (robot, noise seed) chain at once:
        # the chains are independent, so the pool stays full to the end.
        try:
            chains = [prepare(tmp, pool) for _, prepare in robots]
            rows = [[pool.submit(chain, ns) for ns in range(a.noise_seeds)] for chain in chains]
            ok = True
            for (name, _), futures in zip(robots, rows):
                ok &= report(name, [f.result() for f in futures], a.goal)
        except BaseException:
            # A failed run, or Ctrl-C: the runs not started yet are not started.
            pool.shutdown(wait=False, cancel_futures=True)
            raise
    sys.exit(0 if ok else 1)

if __name__ == "__main__":
    main()
