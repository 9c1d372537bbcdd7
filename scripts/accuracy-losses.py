#!/usr/bin/env python3
"""Which baseline `exact` loses to, case by case: `host-bench accuracy --json` for each edge
setting, the tick-time-stamp cases, `exact`'s maximum error on its worst seed against each
baseline's worst seed (as `accuracy`'s summary counts "at or below the best baseline").

Prints, per edge setting, how many cases `exact` is at or below all three baselines, and at or
below `arc` and `timing` alone, then each case lost with the baseline that beat it and by how
much. `lut` takes its heading in whole degrees (its sine table's step): on a path whose true
heading stays on whole degrees it is exact in heading by construction, which no method that
measures the heading finely can be.

Usage: python3 scripts/accuracy-losses.py [--host-bench PATH] [--edges ideal,typical,...]
Standard library only; it runs host-bench.
"""

import argparse
import json
import os
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
EDGES = "ideal,typical-cycle,max-cycle,typical,max"


def losses(hb, edges):
    res = subprocess.run([hb, "accuracy", "--edges", edges, "--json"], capture_output=True,
                         text=True)
    if res.returncode != 0:
        sys.exit(f"host-bench accuracy --edges {edges} failed:\n{res.stderr}")
    rows = []
    for case in json.loads(res.stdout)["cases"]:
        if case.get("mode") != "timestamps":
            continue
        worst = {a["name"]: a["max_error_m"]["max"] for a in case["algorithms"]}
        exact = worst.pop("exact")
        rows.append((f"{case['case']} on {case['robot']}", exact, worst))
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--host-bench", default=os.path.join(ROOT, "target/debug/host-bench"))
    ap.add_argument("--edges", default=EDGES, help=f"edge settings, comma-separated ({EDGES})")
    a = ap.parse_args()
    for edges in a.edges.split(","):
        rows = losses(a.host_bench, edges)
        at_all = sum(exact <= min(worst.values()) for _, exact, worst in rows)
        at_two = sum(exact <= min(worst[m] for m in ("arc", "timing")) for _, exact, worst in rows)
        print(f"{edges}: exact at or below the best of arc, lut and timing on {at_all} of "
              f"{len(rows)} cases; at or below the better of arc and timing on {at_two}")
        for case, exact, worst in rows:
            best = min(worst, key=worst.get)
            if exact > worst[best]:
                print(f"    {case:40} exact {exact * 1e3:8.3f} mm, {best:6} {worst[best] * 1e3:8.3f} "
                      f"mm ({exact / worst[best]:.2f}x)")


if __name__ == "__main__":
    main()
