"""A system reset of the slave board (its NRST pin held low, reset.py) under the real images.

On the model alone: the slave starts again from its vector table and comes back to idle with
no fault, its SRAM as it was (the stack's paint, so the high-water mark covers both runs),
RCC_CSR telling a pin reset after a power-on one. Then through `serve`, as `host-bench play`
sees it on a board: a play during which the slave resets stops with play's "slave reset"
error and a non-zero exit (the master tells the slave's restarted clock, status SLAVE_RESET),
and the next play on the same boards runs whole, bit-exact. Needs the release images and
target/debug/host-bench, as test_play."""

import os
import re
import signal
import subprocess
import sys
import tempfile
import unittest

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))
sys.path.insert(0, HERE)

from f103.bench import Bench  # noqa: E402
from f103.core import Chip  # noqa: E402
from f103.reset import PINRSTF, PORRSTF, SFTRSTF  # noqa: E402
from support import (  # noqa: E402
    HOST_BENCH,
    MASTER,
    SLAVE,
    board_model,
    circle_stream,
    needs_host_bench,
    needs_images,
)

MS = Chip.TICK_HZ // 1000


@needs_images
class TestSlaveReset(unittest.TestCase):
    def test_back_to_idle_with_sram_kept(self):
        bench = Bench(SLAVE, MASTER)
        bench.reset_at("slave", 0.030, hold_ms=5.0)
        bench.run(25 * MS)
        s = bench.boards["slave"]
        # a byte deep in the stack's room, below anything the image uses: SRAM, not a register
        marker = s.elf.sym("_stack_end") + 8
        s.uc.mem_write(marker, b"\x5a")
        used_before = s.stack_report()[0]
        bench.run(10 * MS)  # through the reset at 30 ms, held low to 35 ms
        self.assertEqual(len(s.resets), 1)
        self.assertEqual(s.resets[0]["t"], 30 * MS)
        self.assertIsNone(s.resets[0]["idle"], "ran while NRST was held low")
        bench.run(20 * MS)
        idle = s.resets[0]["idle"]
        self.assertIsNotNone(idle, "the slave did not come back to idle after its reset")
        self.assertGreater(idle, 35 * MS)
        self.assertEqual((s.faults, s.panics, s.halted), ([], [], None))
        self.assertEqual(bytes(s.uc.mem_read(marker, 1)), b"\x5a")
        self.assertGreaterEqual(s.stack_report()[0], used_before)
        self.assertEqual(s.rcc.csr & (PINRSTF | PORRSTF | SFTRSTF), PINRSTF | PORRSTF)
        m = bench.boards["master"]
        self.assertEqual((m.faults, m.panics, m.resets), ([], [], []))


@needs_images
@needs_host_bench
class TestPlayThroughSlaveReset(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.dir = tempfile.TemporaryDirectory()
        # 0.5 laps, 5.2 s played: the play is still streaming at the slave's reset at 1 s of
        # simulated time, however soon after the model's start it began (0.15 laps no longer
        # were, once play checked one pose in 50 and the SPI stream ran at 4.5 MHz)
        cls.ticks = circle_stream(cls.dir.name, laps=0.5)

    @classmethod
    def tearDownClass(cls):
        cls.dir.cleanup()

    def play(self, port, clock):
        return subprocess.run(
            [HOST_BENCH, "play", "--port", port, "--clock", clock, "--ticks", self.ticks],
            capture_output=True,
            text=True,
            timeout=90,
        )

    def test_play_stops_then_plays_again(self):
        # the reset at 1 s of simulated time, in the middle of the first play
        serve = subprocess.Popen(
            [
                *board_model("serve"),
                "--reset-slave-at",
                "1.0",
            ],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        try:
            port = serve.stdout.readline().strip().removeprefix("port: ")
            clock = serve.stdout.readline().strip().removeprefix("clock: ")
            first = self.play(port, clock)
            second = self.play(port, clock)
        finally:
            serve.send_signal(signal.SIGTERM)
            _, err = serve.communicate(timeout=30)
        out1 = first.stdout + first.stderr
        self.assertNotEqual(first.returncode, 0, out1)
        self.assertRegex(out1, r"the slave reset after \d+ of \d+ updates", out1)
        out2 = second.stdout + second.stderr
        self.assertEqual(second.returncode, 0, out2 + err)
        self.assertRegex(out2, r"(\d+) of \1 updates bit-exact, 0 mismatches", out2)
        # the model's report: the slave's reset, idle again after it, nothing faulted
        self.assertEqual(serve.returncode, 0, err)
        self.assertTrue(
            re.search(r"slave system reset at 1000\.0000 ms \(NRST pin.*idle again at", err), err
        )
        self.assertNotIn("FAULT", err)
        self.assertNotIn("PANIC", err)


if __name__ == "__main__":
    unittest.main()
