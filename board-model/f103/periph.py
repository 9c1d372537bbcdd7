"""Base class of the memory-mapped peripheral models.

A model sees word-aligned register offsets. `read(off)` returns the 32-bit register;
`write(off, value, mask)` gets the bits the access wrote (mask: 0xFF/0xFFFF/0xFFFFFFFF shifted
to the byte lane; APB registers of the F103 are accessed as halfwords or words, RM0008 §3.1).
Time is the chip's clock in ticks of 1/72 MHz (`chip.now`); a model that makes events in time
returns the next one from `next_event()` and brings itself up to date in `sync(now)`.
"""


class Peripheral:
    name = "?"
    size = 0x400

    def __init__(self, chip, base):
        self.chip = chip
        self.base = base
        self.reset()

    # register interface -------------------------------------------------------------------
    def reset(self):
        pass

    def read(self, off):
        self.chip.unmodelled(self, off, "read")
        return 0

    def write(self, off, value, mask):
        self.chip.unmodelled(self, off, "write")

    # time interface ---------------------------------------------------------------------
    def next_event(self):
        """Absolute tick of the next self-timed event, or None."""
        return None

    def sync(self, now):
        """Advance internal state to `now` (raise flags, move bytes)."""

    # helpers ----------------------------------------------------------------------------
    def irq(self, line, level):
        self.chip.nvic.set_line(line, level)

    @staticmethod
    def merge(old, value, mask):
        return (old & ~mask) | (value & mask)


class Streaming(Peripheral):
    """A peripheral whose bytes move by DMA while it catches up (SPI, USART): its `_sync` reads
    and writes memory through the DMA, and a DMA access syncs the peripheral again. The guard
    makes that inner call a no-op; the outer loop goes on from where it is."""

    _in_sync = False

    def sync(self, now):
        if self._in_sync:
            return
        self._in_sync = True
        try:
            self._sync(now)
        finally:
            self._in_sync = False

    def _sync(self, now):
        """Advance to `now`; see `Peripheral.sync`."""


class Reserved(Peripheral):
    """A block that exists in the memory map but is not modelled: reads 0, writes ignored,
    every first access to a register is logged."""

    def __init__(self, chip, base, name, size=0x400):
        self.name = name
        self.size = size
        super().__init__(chip, base)
