"""`host-bench record` through the real images on the model, the slave's encoder pins driven by
timed quadrature edges (f103/edges.py): the recorded stream must hold exactly the counts the
model's encoders made (TIM2 on PA0/PA1: +400; TIM1 on PA8/PA9, turning backwards: -200), in
time-stamped mode (every edge, from the slave's EXTI lines).

Needs the release images and target/debug/host-bench (skipped otherwise, as test_play)."""

import csv
import os
import re
import signal
import subprocess
import sys
import tempfile
import unittest

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

from support import (  # noqa: E402
    HOST_BENCH,
    MASTER,
    SLAVE,
    board_model,
    needs_host_bench,
    needs_images,
    needs_slave,
)

# from 0.5 s of simulated time: 400 counts forward on the left, 200 backwards on the right
# The edges start 1.5 s of simulated time after power-on: the recording must be under way by
# then (the host's start, hello and switch to reporting take a few hundred ms, while the model
# runs on). At 0.5 s, one clean CI run of five missed the first 36. The recording's 3 s are on
# the model's clock (`--clock`), so they cover the drive at whatever speed the model runs.
DRIVE = ["PA0,PA1,1.5,400,4000", "PA8,PA9,1.5,200,2000,rev"]


@needs_slave
class TestEncoderPins(unittest.TestCase):
    def test_timers_and_exti_count_every_edge(self):
        """The slave image alone: quadrature edges on PA0/PA1 and PA8/PA9 reach TIM2/TIM1 in
        encoder mode (x4) and EXTI lines 0/1/8/9 (both edges)."""
        from f103.bench import Bench
        from f103.core import Chip
        from f103.edges import EdgeDriver, drive_spec

        bench = Bench(SLAVE, MASTER, boards=("slave",))
        slave = bench.boards["slave"]
        rows, hold = [], {}
        for spec in ("PA0,PA1,0.02,100,20000", "PA8,PA9,0.02,60,10000,rev"):
            r, h = drive_spec(spec)
            rows += r
            hold.update(h)
        driver = EdgeDriver(slave, rows, hold)
        bench.run(int(0.03 * Chip.TICK_HZ))
        self.assertEqual(driver.applied, 160)
        self.assertEqual(slave.tim2.cnt, 100)
        self.assertEqual(slave.tim1.cnt, 0x10000 - 60)
        self.assertEqual(slave.exti.edges, 160)  # NSS (line 4) has no master here
        self.assertEqual(slave.faults, [])


@needs_images
@needs_host_bench
class TestRecord(unittest.TestCase):
    def test_recorded_counts_are_the_models(self):
        with tempfile.TemporaryDirectory() as d:
            cmd = board_model("serve")
            for spec in DRIVE:
                cmd += ["--drive", spec]
            err = open(os.path.join(d, "serve.err"), "w+")
            serve = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=err, text=True)
            try:
                port = serve.stdout.readline().split("port: ")[1].strip()
                clock = serve.stdout.readline().split("clock: ")[1].strip()
                out = os.path.join(d, "rec.csv")
                r = subprocess.run(
                    [
                        HOST_BENCH,
                        "record",
                        "--port",
                        port,
                        "--clock",
                        clock,
                        "--out",
                        out,
                        "--duration",
                        "3",
                    ],
                    capture_output=True,
                    text=True,
                    timeout=60,
                )
                self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
                recorded = tick_sums(out)
            finally:
                serve.send_signal(signal.SIGTERM)
                serve.wait(timeout=30)
                serve.stdout.close()
            err.seek(0)
            log = err.read()
            err.close()
        m = re.search(r"edges applied (\d+) of (\d+); slave TIM2 CNT (\d+), TIM1 CNT (\d+)", log)
        self.assertIsNotNone(m, log)
        self.assertEqual(
            m.group(1),
            m.group(2),
            f"the model did not reach the end of the drive within the recording "
            f"(too slow?):\n{log}",
        )
        tim2 = int(m.group(3))
        tim1 = int(m.group(4)) - 0x10000 if int(m.group(4)) > 0x8000 else int(m.group(4))
        self.assertEqual((tim2, tim1), (400, -200), log)
        self.assertEqual(recorded, {"0": tim2, "1": tim1})


def tick_sums(path):
    """Sum of the tick rows' values per encoder id of a tick stream (docs/tick-stream.md)."""
    sums = {}
    with open(path) as f:
        for row in csv.DictReader(line for line in f if not line.startswith("#")):
            if row["kind"] == "tick":
                sums[row["id"]] = sums.get(row["id"], 0) + int(row["value"])
    return sums


if __name__ == "__main__":
    unittest.main()
