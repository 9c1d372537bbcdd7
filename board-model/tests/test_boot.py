"""Both release images from reset: they must reach idle without a fault or a panic.

Uses the images in target/thumbv7m-none-eabi/release (build them first:
`cargo build -p firmware-slave -p firmware-master --release --target thumbv7m-none-eabi`);
skipped when they are missing. BOARD_MODEL_SLAVE / BOARD_MODEL_MASTER name other images."""

import json
import os
import subprocess
import sys
import unittest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
MODEL_DIR = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

from support import BOARD_MODEL, MASTER, SLAVE, needs_images, needs_slave  # noqa: E402

from f103.bench import Bench  # noqa: E402
from f103.core import Chip  # noqa: E402


@needs_images
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
        self.assertGreater(m.spi1.bytes, 128 * 10)  # a frame every 2 ms


@needs_images
class TestClock(unittest.TestCase):
    def test_a_boards_time_never_goes_back(self):
        """Through boot (the switch to the PLL inside a slice: 9 ticks an instruction, then 1)
        and a slave reset, every time a board is given is at or after the one before."""
        back = []

        def get(chip):
            return chip.__dict__.get("_now_checked", 0)

        def put(chip, t):
            if t < get(chip):
                back.append((chip.name, get(chip), t))
            chip.__dict__["_now_checked"] = t

        Chip.now = property(get, put)
        try:
            bench = Bench(SLAVE, MASTER)
            bench.reset_at("slave", 0.01, 5)
            bench.run(int(0.03 * Chip.TICK_HZ))
        finally:
            del Chip.now
        self.assertEqual(back, [])


class TestBadInputs(unittest.TestCase):
    def test_a_missing_image_a_wrong_file_or_a_missing_tool_is_said_in_one_line(self):
        for args, said in (
            (["--slave", "/nonexistent/firmware-slave"], "No such file or directory"),
            (["--slave", os.path.abspath(__file__)], "not a little-endian ELF32 file"),
        ):
            run = subprocess.run(
                [sys.executable, BOARD_MODEL, "boot", *args], capture_output=True, text=True
            )
            self.assertEqual(run.returncode, 2, run.stderr)
            self.assertIn(said, run.stderr)
            self.assertNotIn("Traceback", run.stderr)
        from f103.elf import InputError, need_tool

        with self.assertRaisesRegex(InputError, "apt install llvm"):
            need_tool("llvm-no-such-tool")


# Both boards from reset, the slave's wheels turning: what the native fast path must not change.
SAME_RUN = """
import hashlib, json, sys
sys.path.insert(0, sys.argv[1])
from f103 import edges, native
from f103.bench import Bench
from f103.core import Chip
bench = Bench(sys.argv[2], sys.argv[3])
rows, hold = edges.drive_spec("PA0,PA1,0.004,600,40000")
edges.EdgeDriver(bench.boards["slave"], rows, hold)
bench.run(int(0.03 * Chip.TICK_HZ))
out = {"native": native.library() is not None}
for name, c in bench.boards.items():
    ram = hashlib.sha256(bytes(c.uc.mem_read(0x20000000, 0x5000))).hexdigest()
    out[name] = [c.instructions, c.exceptions, c.sleeps, c.spi1.bytes, c.tim2.cnt, ram,
                 c.now, sorted(c.nvic.pending), c.faults, c.panics, c.messages]
print(json.dumps(out))
"""


@needs_images
class TestNativeFastPath(unittest.TestCase):
    def test_python_alone_and_the_fast_path_agree_to_the_instruction(self):
        """The same 30 ms (boot, the SPI link, 600 encoder counts on the slave) with the
        native fast path and without: the same instructions, exceptions, sleeps, SPI bytes,
        encoder count, every byte of both boards' RAM, their clocks, pending interrupts,
        faults, panics and log."""
        runs = {}
        for flag in ("0", "1"):
            out = subprocess.run(
                [sys.executable, "-c", SAME_RUN, MODEL_DIR, SLAVE, MASTER],
                env={**os.environ, "BOARD_MODEL_NATIVE": flag},
                capture_output=True,
                text=True,
                check=True,
            ).stdout
            runs[flag] = json.loads(out)
        self.assertFalse(runs["0"].pop("native"))
        self.assertTrue(runs["1"].pop("native"), "the fast path did not load (is cc there?)")
        self.assertEqual(runs["0"], runs["1"])
        self.assertEqual(runs["1"]["slave"][4], 600)  # TIM2 counted every edge


@needs_slave
class TestPanicTrap(unittest.TestCase):
    def test_a_panic_is_recorded_and_halts_the_board(self):
        """The panic entries are BKPT traps patched into the flash image (core.Chip._trap):
        a call lands in `panics` and the original code then runs to the HardFault loop."""
        from unicorn.arm_const import UC_ARM_REG_LR

        bench = Bench(SLAVE, MASTER, boards=("slave",))
        bench.run(int(0.005 * Chip.TICK_HZ))
        c = bench.boards["slave"]
        c.sleeping = False
        c.pc = next(iter(c.panic_entries))  # as if a panic were called from 0x08000200
        c.uc.reg_write(UC_ARM_REG_LR, 0x08000201)
        bench.run(int(0.002 * Chip.TICK_HZ))
        self.assertEqual(len(c.panics), 1)
        self.assertEqual(c.panics[0]["caller"], 0x08000200 - 4)
        self.assertIn("HardFault", c.halted or "")


if __name__ == "__main__":
    unittest.main()
