"""DMA1 controller, 7 channels (RM0008 §13.3 functional description, §13.4 registers).

Modelled: per channel CCR (EN, TCIE/HTIE/TEIE, DIR, CIRC, PINC, MINC, PSIZE, MSIZE, PL,
MEM2MEM), CNDTR (the remaining count while enabled, reloaded in circular mode), CPAR, CMAR;
ISR flags GIF/TCIF/HTIF/TEIF and IFCR; the request lines of Table 78 (a peripheral asserts
`dma_request(key)` while it needs a transfer; the channel moves one data item per request);
data width conversion by truncation / zero extension (Table 79, little-endian); a bus error
sets TEIF and disables the channel (§13.3.5). Transfers take no simulated time and
priorities between channels are not modelled (requests are served in channel order).
"""

from . import native
from .periph import Peripheral

SIZES = [1, 2, 4, 4]


class Channel:
    def __init__(self, n):
        self.n = n
        self.ccr = 0
        self.cndtr = 0
        self.cpar = 0
        self.cmar = 0
        self.remaining = 0
        self.p = 0
        self.m = 0
        self.total = 0


class Dma(Peripheral):
    name = "DMA1"
    IRQ_BASE = 11  # DMA1_Channel1 is IRQ 11 (Table 63)

    def __init__(self, chip, base):
        self.sources = {n: [] for n in range(1, 8)}
        self._busy = False
        self._again = False
        super().__init__(chip, base)

    def reset(self):
        self.ch = {n: Channel(n) for n in range(1, 8)}
        self.isr = 0
        self.transfers = 0
        self.active = []  # enabled channels, for kick()
        self._levels = [False] * 8
        self._publish()

    # --- the native fast path (native.py) ------------------------------------------------
    _page = None

    def attach_native(self, page):
        """CCRx read natively, as `_publish` last wrote them."""
        self._page = page
        for n in range(1, 8):
            page.read_kind[(0x08 + 20 * (n - 1)) >> 2] = native.MIRROR
        self._publish()

    def _publish(self):
        """After anything that changes a CCR."""
        pg = self._page
        if pg is not None:
            for n, c in self.ch.items():
                pg.regs[(0x08 + 20 * (n - 1)) >> 2] = c.ccr

    def connect(self, n, periph, key):
        self.sources[n].append((periph, key))

    # --- engine ----------------------------------------------------------------------------
    def kick(self):
        if self._busy:
            self._again = True
            return
        self._busy = True
        try:
            while True:
                self._again = False
                moved = False
                for c in self.active:
                    n = c.n
                    if c.remaining == 0:
                        continue
                    if c.ccr & (1 << 14):
                        while c.remaining and (c.ccr & 1):
                            self._transfer(c)
                        moved = True
                        continue
                    for periph, key in self.sources[n]:
                        if periph.dma_request(key):
                            self._transfer(c)
                            moved = True
                            break
                if not moved and not self._again:
                    break
        finally:
            self._busy = False

    def _transfer(self, c):
        chip = self.chip
        psize = SIZES[(c.ccr >> 8) & 3]
        msize = SIZES[(c.ccr >> 10) & 3]
        try:
            if c.ccr & (1 << 4):  # memory -> peripheral
                v = chip.bus_read(c.m, msize)
                chip.bus_write(c.p, psize, v & ((1 << (8 * psize)) - 1))
            else:
                v = chip.bus_read(c.p, psize)
                chip.bus_write(c.m, msize, v & ((1 << (8 * msize)) - 1))
        except Exception as e:  # bus error (§13.3.5)
            chip.log(f"DMA1 channel {c.n}: transfer error ({e}) at p={c.p:#x} m={c.m:#x}")
            self._flag(c.n, 8)
            c.ccr &= ~1
            self._publish()
            self.active = [ch for ch in self.ch.values() if ch.ccr & 1]
            self._irq()
            return
        self.transfers += 1
        if c.ccr & (1 << 6):
            c.p += psize
        if c.ccr & (1 << 7):
            c.m += msize
        c.remaining -= 1
        if c.remaining == c.total // 2:
            self._flag(c.n, 4)
            self._irq_ch(c.n)
        if c.remaining == 0:
            self._flag(c.n, 2)
            if c.ccr & (1 << 5):  # circular
                c.remaining = c.total
                c.p = c.cpar
                c.m = c.cmar
            self._irq_ch(c.n)

    def advance(self, c, k):
        """`k` items of a plain (non-circular, memory-incrementing, 8-bit) channel moved at
        once by a peripheral's burst: the same count, address, flags and interrupt line as
        `k` calls of `_transfer`."""
        if not k:
            return
        before = c.remaining
        c.remaining -= k
        c.m += k
        self.transfers += k
        half = c.total // 2
        if before > half >= c.remaining:
            self._flag(c.n, 4)
        if c.remaining == 0:
            self._flag(c.n, 2)
        self._irq_ch(c.n)

    def plain_channels(self, periph, dr):
        """(rx, tx): the enabled channels of `periph` that move bytes to or from its data
        register `dr` plainly (PSIZE = MSIZE = 8 bits, MINC, no PINC, no CIRC, no MEM2MEM),
        each None when there is none. A burst may move such bytes in one go."""
        rx = tx = None
        for c in self.active:
            if c.p != dr or (c.ccr & 0x4FE0) != 0x80:
                continue
            if any(p is periph for p, _ in self.sources[c.n]):
                if c.ccr & 0x10:
                    tx = c
                else:
                    rx = c
        return rx, tx

    def _flag(self, n, bits):
        self.isr |= (bits | 1) << (4 * (n - 1))

    def _irq(self):
        for n in range(1, 8):
            self._irq_ch(n)

    def _irq_ch(self, n):
        lvl = bool((self.isr >> (4 * (n - 1))) & self.ch[n].ccr & 0xE)
        if lvl != self._levels[n]:
            self._levels[n] = lvl
            self.irq(self.IRQ_BASE + n - 1, lvl)

    # --- registers -----------------------------------------------------------------------
    def read(self, off):
        if off == 0x00:
            return self.isr
        if off == 0x04:
            return 0
        n, r = divmod(off - 0x08, 20)
        n += 1
        if not 1 <= n <= 7:
            return 0
        c = self.ch[n]
        if r == 0:
            return c.ccr
        if r == 4:
            return c.remaining if c.ccr & 1 else c.cndtr
        if r == 8:
            return c.cpar
        if r == 12:
            return c.cmar
        return 0

    def write(self, off, value, mask):
        if off == 0x04:
            v = value & mask
            for n in range(1, 8):
                f = (v >> (4 * (n - 1))) & 0xF
                if f & 1:
                    f = 0xF  # CGIF clears all four
                self.isr &= ~(f << (4 * (n - 1)))
            self._irq()
            return
        if off == 0x00:
            return
        n, r = divmod(off - 0x08, 20)
        n += 1
        if not 1 <= n <= 7:
            return
        c = self.ch[n]
        if r == 0:
            was = c.ccr & 1
            c.ccr = self.merge(c.ccr, value, mask) & 0x7FFF
            if c.ccr & 1 and not was:
                c.total = c.remaining = c.cndtr
                c.p, c.m = c.cpar, c.cmar
            elif was and not c.ccr & 1:
                c.cndtr = c.remaining
            self._publish()
            self.active = [ch for ch in self.ch.values() if ch.ccr & 1]
            self._irq()
            self.kick()
        elif r == 4:
            if not c.ccr & 1:  # writable only while disabled (§13.4.4)
                c.cndtr = value & mask & 0xFFFF
        elif r == 8:
            if not c.ccr & 1:
                c.cpar = value & mask
        elif r == 12:
            if not c.ccr & 1:
                c.cmar = value & mask
