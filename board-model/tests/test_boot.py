"""Both release images from reset: they must reach idle without a fault or a panic.

Uses the images in target/thumbv7m-none-eabi/release (build them first:
`cargo build -p firmware-slave -p firmware-master --release --target thumbv7m-none-eabi`);
skipped when they are missing. BOARD_MODEL_SLAVE / BOARD_MODEL_MASTER name other images."""

import os
import sys
import unittest

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from f103.bench import IMAGES, Bench  # noqa: E402
from f103.core import Chip  # noqa: E402

SLAVE = os.environ.get("BOARD_MODEL_SLAVE", os.path.join(IMAGES, "firmware-slave"))
MASTER = os.environ.get("BOARD_MODEL_MASTER", os.path.join(IMAGES, "firmware-master"))


@unittest.skipUnless(os.path.exists(SLAVE) and os.path.exists(MASTER), "images not built")
class TestBoot(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.bench = Bench(SLAVE, MASTER)
        cls.bench.run(int(0.05 * Chip.TICK_HZ))

    def check(self, name):
        c = self.bench.boards[name]
        self.assertEqual(c.faults, [], f"{name}: faults")
        self.assertEqual(c.panics, [], f"{name}: panics")
        self.assertIsNone(c.halted)
        self.assertIsNotNone(c.first_idle, f"{name} never reached the executor's WFE")
        used, room, over = c.stack_report()
        self.assertFalse(over, f"{name}: stack overflow")
        self.assertLess(used, room)

    def test_slave(self):
        self.check("slave")

    def test_master(self):
        self.check("master")

    def test_spi_frames_flow(self):
        m = self.bench.boards["master"]
        self.assertGreater(m.spi1.bytes, 128 * 10)     # a frame every 2 ms


if __name__ == "__main__":
    unittest.main()
