"""What the image tests share: where the images and host-bench are, when a test may skip for
their lack, and a stream of the independent writer's to play.

CI says where the images (BOARD_MODEL_SLAVE, BOARD_MODEL_MASTER) and host-bench (HOST_BENCH)
are; then a missing file fails the tests instead of skipping them. Elsewhere they default to
the workspace's target/ and the tests skip, saying what to build."""

import os
import subprocess
import sys
import unittest

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from f103.bench import IMAGES, ROOT  # noqa: E402

SLAVE = os.environ.get("BOARD_MODEL_SLAVE", os.path.join(IMAGES, "firmware-slave"))
MASTER = os.environ.get("BOARD_MODEL_MASTER", os.path.join(IMAGES, "firmware-master"))
HOST_BENCH = os.environ.get("HOST_BENCH", os.path.join(ROOT, "target", "debug", "host-bench"))
BOARD_MODEL = os.path.join(ROOT, "scripts", "board-model")

needs_slave = unittest.skipUnless(
    os.path.exists(SLAVE) or "BOARD_MODEL_SLAVE" in os.environ,
    "the slave image is not built (cargo build --release --target thumbv7m-none-eabi)",
)
needs_images = unittest.skipUnless(
    os.path.exists(SLAVE) and os.path.exists(MASTER) or "BOARD_MODEL_SLAVE" in os.environ,
    "the images are not built (cargo build --release --target thumbv7m-none-eabi)",
)
needs_host_bench = unittest.skipUnless(
    os.path.exists(HOST_BENCH) or "HOST_BENCH" in os.environ,
    f"{HOST_BENCH} missing: `cargo build -p host-bench` first",
)


def board_model(command):
    """scripts/board-model's `command` (boot, serve, play-check) on the images under test, as
    an argument list to extend."""
    return [sys.executable, BOARD_MODEL, command, "--slave", SLAVE, "--master", MASTER]


def circle_stream(out_dir, laps=0.05):
    """scripts/circle-stream.py's circle, `laps` of it (0.05: 0.52 s, 784 ticks); its file's
    path."""
    writer = os.path.join(ROOT, "scripts", "circle-stream.py")
    subprocess.run([sys.executable, writer, "--out", out_dir, "--laps", str(laps)], check=True)
    return os.path.join(out_dir, "circle.csv")
