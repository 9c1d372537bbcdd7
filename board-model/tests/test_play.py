"""`host-bench play` through the real images on the model: every pose update the slave reports
must be bit-exact with the host's, in both sensor modes (time-stamped ticks, counts).

The stream is written by scripts/circle-stream.py (an independent writer, not host-bench's
generator): a differential drive on a circle, half a second of it. Needs the release images
(as test_boot) and target/debug/host-bench (`cargo build -p host-bench`; CI builds it first);
skipped when either is missing. The model runs slower than real time and play's host side
has wall-clock timeouts: each play takes about 15 s here."""

import os
import subprocess
import sys
import tempfile
import unittest

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))

from f103.bench import IMAGES, ROOT  # noqa: E402

SLAVE = os.environ.get("BOARD_MODEL_SLAVE", os.path.join(IMAGES, "firmware-slave"))
MASTER = os.environ.get("BOARD_MODEL_MASTER", os.path.join(IMAGES, "firmware-master"))
HOST_BENCH = os.environ.get("HOST_BENCH", os.path.join(ROOT, "target", "debug", "host-bench"))


@unittest.skipUnless(
    os.path.exists(SLAVE) and os.path.exists(MASTER) or "BOARD_MODEL_SLAVE" in os.environ,
    "images not built",
)
# Skipped only where nobody said which host-bench to use: CI sets HOST_BENCH, and then a
# missing binary fails the test instead of skipping it.
@unittest.skipUnless(
    os.path.exists(HOST_BENCH) or "HOST_BENCH" in os.environ,
    f"{HOST_BENCH} missing: `cargo build -p host-bench` first",
)
class TestPlay(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.dir = tempfile.TemporaryDirectory()
        subprocess.run(
            [
                sys.executable,
                os.path.join(ROOT, "scripts", "circle-stream.py"),
                "--out",
                cls.dir.name,
                "--laps",
                "0.05",
            ],
            check=True,
        )
        cls.ticks = os.path.join(cls.dir.name, "circle.csv")

    @classmethod
    def tearDownClass(cls):
        cls.dir.cleanup()

    def play(self, sensor):
        r = subprocess.run(
            [
                sys.executable,
                os.path.join(ROOT, "scripts", "board-model"),
                "play-check",
                "--ticks",
                self.ticks,
                "--sensor",
                sensor,
                "--slave",
                SLAVE,
                "--master",
                MASTER,
                "--host-bench",
                HOST_BENCH,
            ],
            capture_output=True,
            text=True,
            timeout=120,
        )
        out = r.stdout + r.stderr
        self.assertEqual(r.returncode, 0, out)
        line = next((l for l in r.stdout.splitlines() if l.startswith("board vs host")), "")
        self.assertRegex(line, r"(\d+) of \1 updates bit-exact, 0 mismatches", out)
        return out

    def test_timestamps(self):
        self.play("timestamps")

    def test_counts(self):
        self.play("counts")


if __name__ == "__main__":
    unittest.main()
