"""EXTI: external interrupt/event controller (RM0008 §10.2, registers §10.3).

Lines 0..15 come from the GPIO pin selected by AFIO_EXTICRx; a selected edge (RTSR/FTSR) sets
the pending bit PR (whatever IMR says, as in the block diagram, figure 20); the NVIC line is
PR & IMR: lines 0..4 have their own vectors, 5..9 share EXTI9_5, 10..15 share EXTI15_10
(RM0008 Table 63). PR is cleared by writing 1; SWIER sets PR on a line enabled in IMR.
Event mode (EMR) has no effect in the model: the CPU does not use WFE events from EXTI here.
"""

from .periph import Peripheral

LINE_IRQ = [6, 7, 8, 9, 10] + [23] * 5 + [40] * 6 + [1, 41, 42]


class Exti(Peripheral):
    name = "EXTI"

    def reset(self):
        self.imr = 0
        self.emr = 0
        self.rtsr = 0
        self.ftsr = 0
        self.swier = 0
        self.pr = 0
        self.edges = 0  # statistics

    def edge(self, line, level):
        bit = 1 << line
        if (level and self.rtsr & bit) or (not level and self.ftsr & bit):
            self.pr |= bit
            self.edges += 1
            self._irq()

    def _irq(self):
        act = self.pr & self.imr
        for irq in sorted(set(LINE_IRQ)):
            lvl = any((act >> l) & 1 for l in range(19) if LINE_IRQ[l] == irq)
            self.irq(irq, lvl)

    def read(self, off):
        return {
            0x00: self.imr,
            0x04: self.emr,
            0x08: self.rtsr,
            0x0C: self.ftsr,
            0x10: self.swier,
            0x14: self.pr,
        }.get(off, 0)

    def write(self, off, value, mask):
        v = value & mask & 0x7FFFF
        if off == 0x00:
            self.imr = self.merge(self.imr, value, mask) & 0x7FFFF
        elif off == 0x04:
            self.emr = self.merge(self.emr, value, mask) & 0x7FFFF
        elif off == 0x08:
            self.rtsr = self.merge(self.rtsr, value, mask) & 0x7FFFF
        elif off == 0x0C:
            self.ftsr = self.merge(self.ftsr, value, mask) & 0x7FFFF
        elif off == 0x10:
            new = v & ~self.swier
            self.swier |= v
            self.pr |= new & self.imr
        elif off == 0x14:
            self.pr &= ~v
            self.swier &= ~v
        self._irq()
