"""Peripheral models against RM0008's behaviour, on a stub chip (no CPU)."""

import os
import sys
import unittest

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from f103 import nvic as nv  # noqa: E402
from f103.crc import Crc, crc32_word  # noqa: E402
from f103.rcc import Rcc  # noqa: E402
from f103.tim import Timer  # noqa: E402
from f103.usart import Usart  # noqa: E402

W = 0xFFFFFFFF


class StubDma:
    def kick(self):
        pass


class StubChip:
    TICK_HZ = 72_000_000

    def __init__(self):
        self.now = 0
        self.pclk = {1: 36_000_000, 2: 72_000_000}
        self.timclk = {1: 72_000_000, 2: 72_000_000}
        self.hclk = 72_000_000
        self.nvic = nv.Scs(self, 0xE0000000)
        self.dma = StubDma()
        self.changed = 0

    def reschedule(self):
        pass

    def clock_changed(self):
        self.changed += 1

    def irq_changed(self):
        pass

    def unmodelled(self, *a):
        pass

    def log(self, m):
        pass

    def cycles(self):
        return self.now

    def ticks_per_hclk(self):
        return 1


class TestCrc(unittest.TestCase):
    # RM0008 §4: CRC-32 (Ethernet polynomial), word-wise, initial 0xFFFFFFFF, no reflection
    def test_known_value(self):
        c = Crc(StubChip(), 0x40023000)
        c.write(0x00, 0x12345678, W)
        self.assertEqual(c.read(0x00), 0xDF8A8A2B)  # the usual STM32 CRC check value
        self.assertEqual(c.read(0x00), crc32_word(0xFFFFFFFF, 0x12345678))

    def test_reset_and_idr(self):
        c = Crc(StubChip(), 0x40023000)
        c.write(0x00, 1, W)
        c.write(0x04, 0x1AB, W)
        c.write(0x08, 1, W)
        self.assertEqual(c.read(0x00), 0xFFFFFFFF)
        self.assertEqual(c.read(0x04), 0xAB)


class TestRcc(unittest.TestCase):
    # RM0008 §7.3.1/7.3.2: ready flags, switch only onto a ready clock, 72 MHz from HSE x9
    def test_pll_72mhz(self):
        chip = StubChip()
        r = Rcc(chip, 0x40021000)
        self.assertEqual(r.sysclk_hz(), 8_000_000)
        r.write(0x04, 2, W)  # SW=PLL while the PLL is off: ignored
        self.assertEqual((r.read(0x04) >> 2) & 3, 0)
        r.write(0x00, r.read(0x00) | (1 << 16), W)
        self.assertTrue(r.read(0x00) & (1 << 17))  # HSERDY
        r.write(0x04, (7 << 18) | (1 << 16) | (4 << 8), W)  # PLL x9 from HSE, APB1 /2
        r.write(0x00, r.read(0x00) | (1 << 24), W)
        self.assertTrue(r.read(0x00) & (1 << 25))  # PLLRDY
        r.write(0x04, r.read(0x04) | 2, W)
        self.assertEqual((r.read(0x04) >> 2) & 3, 2)
        self.assertEqual(r.sysclk_hz(), 72_000_000)
        self.assertEqual(r.pclk_hz(1), 36_000_000)
        self.assertEqual(r.timer_hz(1), 72_000_000)  # x2 when APB1 is divided


class TestTimer(unittest.TestCase):
    # RM0008 §15.3: PSC preloaded (takes effect at UG), overflow sets UIF, CNT==CCR sets CCxIF
    def test_counting_and_flags(self):
        chip = StubChip()
        t = Timer(chip, 0x40000800, "TIM4", 1, {"up": 30})
        t.write(0x28, 71, W)  # 1 MHz
        t.write(0x2C, 0xFFFF, W)
        t.write(0x00, 4, W)  # URS
        t.write(0x14, 1, W)  # UG: no UIF while URS=1
        t.write(0x00, 0, W)
        self.assertEqual(t.read(0x10) & 1, 0)
        t.write(0x34, 0x8000, W)
        t.write(0x0C, 3, W)  # UIE, CC1IE
        t.write(0x00, 1, W)
        chip.now = 72 * 1000
        self.assertEqual(t.read(0x24), 1000)
        self.assertEqual(t.next_event(), 72 * 0x8000)
        chip.now = 72 * 0x8000
        self.assertTrue(t.read(0x10) & 2)  # CC1IF at CNT == 0x8000
        self.assertIn(16 + 30, chip.nvic.pending)
        t.write(0x10, ~2 & 0xFFFF, W)  # rc_w0
        self.assertFalse(t.read(0x10) & 2)
        chip.now = 72 * 0x10000
        self.assertTrue(t.read(0x10) & 1)  # UIF at the overflow
        self.assertEqual(t.read(0x24), 0)

    def test_encoder_x4(self):
        # §15.3.12, Table 83: SMS=3 counts every edge of TI1 and TI2, direction from the other
        chip = StubChip()
        t = Timer(chip, 0x40000000, "TIM2", 1, {"up": 28})
        t.write(0x08, 3, W)
        t.write(0x00, 1, W)
        a = b = 0
        for _ in range(4):  # A leads B: one full cycle = 4 counts up
            a ^= 1
            t.encoder_edge(0, a)
            b ^= 1
            t.encoder_edge(1, b)
        self.assertEqual(t.read(0x24), 8)
        for _ in range(2):  # reverse: B leads A
            b ^= 1
            t.encoder_edge(1, b)
            a ^= 1
            t.encoder_edge(0, a)
        self.assertEqual(t.read(0x24), 4)


class TestNvic(unittest.TestCase):
    # ARMv7-M B1.5.4: lower value wins; only the group priority preempts; PRIMASK masks >= 0
    def test_priorities(self):
        chip = StubChip()
        n = chip.nvic
        n.write(0xE100, (1 << 30) | (1 << 6), W)  # enable TIM4, EXTI0
        n.write(0xE400 + 28, 0x20 << 16, W)  # IPR[30] = 0x20
        n.write(0xE404, 0x10 << 16, W)  # IPR[6] = 0x10
        n.set_line(30, True)
        n.set_line(6, True)
        self.assertEqual(n.takeable(0), 16 + 6)  # EXTI0 (0x10) before TIM4 (0x20)
        self.assertIsNone(n.takeable(1))  # PRIMASK
        n.activate(16 + 6)
        self.assertIsNone(n.takeable(0))  # 0x20 does not preempt 0x10
        n.set_line(6, False)
        n.deactivate(16 + 6)
        self.assertEqual(n.takeable(0), 16 + 30)

    def test_level_repends_on_return(self):
        n = StubChip().nvic
        n.write(0xE100, 1 << 30, W)
        n.set_line(30, True)
        n.activate(16 + 30)
        n.deactivate(16 + 30)  # line still high: pending again
        self.assertIn(16 + 30, n.pending)

    def test_second_word_of_each_bank(self):
        # PM0056 §4.3: ISER/ICER/ISPR/ICPR are banks of words, a word per 32 lines; the F103's
        # lines 32..42 (SPI1 35, USART1 37, EXTI15_10 40) live in each bank's second word.
        # The model once took the byte offset for the word's index and dropped every write to a
        # second word: USART1's interrupt never fired.
        n = StubChip().nvic
        n.write(0xE104, 1 << (37 - 32), W)  # ISER1: USART1
        self.assertTrue(n.enabled[37])
        self.assertEqual(n.read(0xE104), 1 << 5)
        self.assertEqual(n.read(0xE184), 1 << 5)  # ICER reads the enables too
        n.write(0xE204, 1 << (40 - 32), W)  # ISPR1: EXTI15_10 pending
        self.assertIn(16 + 40, n.pending)
        self.assertEqual(n.read(0xE204), 1 << 8)
        n.write(0xE284, 1 << (40 - 32), W)  # ICPR1
        self.assertNotIn(16 + 40, n.pending)
        n.write(0xE184, 1 << (37 - 32), W)  # ICER1
        self.assertFalse(n.enabled[37])
        self.assertEqual(n.read(0xE100), 0)
        n.activate(16 + 37)  # IABR1: USART1 active (the bank after ICPR, read-only)
        self.assertEqual(n.read(0xE304), 1 << 5)


class TestUsart(unittest.TestCase):
    # RM0008 §27.3: a byte takes 10 bit times at 8N1; TXE at once, TC after the frame
    def test_frame_time(self):
        chip = StubChip()
        u = Usart(chip, 0x40013800, "USART1", 2, 37)
        out = []
        u.tx_sink = out.append
        u.write(0x08, 625, W)  # 72 MHz / 115200
        u.write(0x0C, (1 << 13) | (1 << 3) | (1 << 2), W)
        u.write(0x04, 0x55, W)
        self.assertTrue(u.read(0x00) & 0x80)  # TXE: moved to the shift register
        self.assertEqual(u.next_event(), 6250)  # 86.8 us
        chip.now = 6249
        u.sync(chip.now)
        self.assertEqual(out, [])
        chip.now = 6250
        u.sync(chip.now)
        self.assertEqual(out, [0x55])
        self.assertTrue(u.read(0x00) & 0x40)  # TC

    def test_receive_idle(self):
        chip = StubChip()
        u = Usart(chip, 0x40013800, "USART1", 2, 37)
        u.write(0x08, 625, W)
        u.write(0x0C, (1 << 13) | (1 << 2), W)
        u.receive(b"ab")
        chip.now = 6250
        u.sync(chip.now)
        self.assertTrue(u.read(0x00) & 0x20)
        self.assertEqual(u.read(0x04), ord("a"))
        chip.now = 12500
        u.sync(chip.now)
        self.assertEqual(u.read(0x04), ord("b"))
        chip.now = 18750
        u.sync(chip.now)
        self.assertTrue(u.read(0x00) & 0x10)  # IDLE after one idle frame
        u.read(0x04)
        self.assertFalse(u.read(0x00) & 0x10)  # cleared by SR read then DR read



class TestInstructionClock(unittest.TestCase):
    # ucfast.counter_offset: unicorn's own count of a counted run, read inside a slice.
    def test_an_access_sees_its_instructions_time(self):
        from unicorn import Uc, UC_ARCH_ARM, UC_MODE_THUMB, UC_MODE_MCLASS
        from unicorn.arm_const import UC_ARM_REG_R2, UC_CPU_ARM_CORTEX_M3

        from f103.ucfast import FastUc, counter_offset

        self.assertIsNotNone(counter_offset(), "unicorn 2.1.4's counter not found")
        uc = Uc(UC_ARCH_ARM, UC_MODE_THUMB | UC_MODE_MCLASS)
        uc.ctl_set_cpu_model(UC_CPU_ARM_CORTEX_M3)
        uc.mem_map(0x08000000, 0x1000)
        # movs r0,#1 ; movs r0,#2 ; ldr r3,[r2] ; movs r0,#3 ; str r3,[r2] ; b .
        uc.mem_write(0x08000000, bytes.fromhex("0120" "0220" "1368" "0320" "1360" "fee7"))

        class Clock:
            now = 0

        clock, seen = Clock(), []
        fast = FastUc(uc, clock=clock)
        fast.mmio_map(
            0x40000000,
            0x400,
            lambda off, size: seen.append(("read", clock.now)) or 0,
            lambda off, size, value: seen.append(("write", clock.now)),
        )
        uc.reg_write(UC_ARM_REG_R2, 0x40000000)
        fast.set_slice(1000, 9.0)  # at HSI: 9 ticks an instruction
        uc.emu_start(0x08000001, 0, count=8)
        # the load is the third instruction, the store the fifth
        self.assertEqual(seen, [("read", 1000 + 2 * 9), ("write", 1000 + 4 * 9)])
        # a run stopped by its limit reads one more than it ran
        self.assertEqual(fast.counter.value, 9)

    def test_a_lowered_limit_ends_the_run_after_the_access(self):
        # what Chip.irq_changed does when a register write raises an interrupt to take
        from unicorn import Uc, UC_ARCH_ARM, UC_MODE_THUMB, UC_MODE_MCLASS
        from unicorn.arm_const import UC_ARM_REG_PC, UC_ARM_REG_R0, UC_ARM_REG_R2
        from unicorn.arm_const import UC_CPU_ARM_CORTEX_M3

        from f103.ucfast import FastUc

        uc = Uc(UC_ARCH_ARM, UC_MODE_THUMB | UC_MODE_MCLASS)
        uc.ctl_set_cpu_model(UC_CPU_ARM_CORTEX_M3)
        uc.mem_map(0x08000000, 0x1000)
        # movs r0,#1 ; str r3,[r2] ; movs r0,#2 ; movs r0,#3 ; b .
        uc.mem_write(0x08000000, bytes.fromhex("0120" "1360" "0220" "0320" "fee7"))
        fast, writes = FastUc(uc), []

        def write(off, size, value):
            writes.append(off)
            fast.limit.value = fast.counter.value

        fast.mmio_map(0x40000000, 0x400, lambda off, size: 0, write)
        uc.reg_write(UC_ARM_REG_R2, 0x40000000)
        uc.emu_start(0x08000001, 0, count=100)
        self.assertEqual(writes, [0])  # the store ran once, not again
        self.assertEqual(uc.reg_read(UC_ARM_REG_PC), 0x08000004)  # stopped after it
        self.assertEqual(uc.reg_read(UC_ARM_REG_R0), 1)
        self.assertEqual(fast.counter.value - 1, 2)  # two instructions ran


class TestNativeTimer(unittest.TestCase):
    # native.py: a timer's CNT read without Python, except at or past its next enabled event
    def test_cnt_reads_go_to_python_once_an_enabled_event_is_due(self):
        from unicorn import Uc, UC_ARCH_ARM, UC_MODE_THUMB, UC_MODE_MCLASS
        from unicorn.arm_const import UC_ARM_REG_R2, UC_ARM_REG_R3, UC_CPU_ARM_CORTEX_M3

        from f103 import native
        from f103.ucfast import FastUc

        self.assertIsNotNone(native.library(), "the native fast path did not load (cc?)")
        uc = Uc(UC_ARCH_ARM, UC_MODE_THUMB | UC_MODE_MCLASS)
        uc.ctl_set_cpu_model(UC_CPU_ARM_CORTEX_M3)
        uc.mem_map(0x08000000, 0x1000)
        # ldr r3, [r2, #0x24] twelve times (TIM4's CNT); b .
        uc.mem_write(0x08000000, bytes.fromhex("536a") * 12 + bytes.fromhex("fee7"))
        chip = StubChip()
        t = Timer(chip, 0x40000800, "TIM4", 1, {"up": 30})
        t.write(0x34, 50, W)  # CCR1
        t.write(0x0C, 2, W)  # CC1IE
        t.write(0x00, 1, W)  # CEN at tick 0, a count a tick (PSC 0, 72 MHz)
        page, by_python = native.Page(), []
        t.attach_native(page)
        fast = FastUc(uc, clock=chip)

        def read(off, size):
            by_python.append((off, chip.now))
            return t.read(off)

        fast.mmio_map(0x40000800, 0x400, read, lambda off, size, v: t.write(off, v, W), page)
        page.gate_on = 1
        uc.reg_write(UC_ARM_REG_R2, 0x40000800)
        fast.set_slice(0, 9.0)  # instruction k at tick 9 (k - 1)
        uc.emu_start(0x08000001, 0, count=12)
        # reads 1..6 (ticks 0..45) natively; the 7th, at tick 54, past CC1 at 50, by Python,
        # whose sync raises CC1IF; then natively again (the next match is a wrap away)
        self.assertEqual(by_python, [(0x24, 54)])
        self.assertIn(16 + 30, chip.nvic.pending)
        self.assertEqual(uc.reg_read(UC_ARM_REG_R3), 99)  # the 12th read, at tick 99


if __name__ == "__main__":
    unittest.main()
