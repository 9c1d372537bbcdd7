"""CRC calculation unit (RM0008 §4): CRC-32, polynomial 0x04C11DB7, 32-bit words fed MSB
first, no reflection, no final XOR; DR resets to 0xFFFFFFFF (CR.RESET); IDR is a free 8-bit
register. Byte and halfword writes to DR are taken as a full word (as the hardware does: DR is
a 32-bit register and the calculation always uses the whole word).

Both images run their CRC-32 on the unit, a word per DR write (tens of thousands a second
while the boards talk), so a word is computed with four table look-ups ("slicing by 4":
TABLES[k][b] is byte b followed by k zero bytes) instead of 32 shift steps."""

from . import native
from .periph import Peripheral

POLY = 0x04C11DB7


def crc32_word(crc, word):
    """The definition: 32 steps of the shift register (the reference for the tables)."""
    crc ^= word & 0xFFFFFFFF
    for _ in range(32):
        crc = ((crc << 1) ^ POLY) & 0xFFFFFFFF if crc & 0x80000000 else (crc << 1) & 0xFFFFFFFF
    return crc


def _tables():
    t0 = []  # one byte through 8 steps ...
    for b in range(256):
        c = b << 24
        for _ in range(8):
            c = ((c << 1) ^ POLY) & 0xFFFFFFFF if c & 0x80000000 else (c << 1) & 0xFFFFFFFF
        t0.append(c)
    tables = [t0]
    for _ in range(3):  # ... then 8 more zero bits each
        prev = tables[-1]
        tables.append([((prev[b] << 8) & 0xFFFFFFFF) ^ t0[prev[b] >> 24] for b in range(256)])
    return tables


_T0, _T1, _T2, _T3 = _tables()


def crc32_word_fast(crc, word):
    x = (crc ^ word) & 0xFFFFFFFF
    return _T3[x >> 24] ^ _T2[(x >> 16) & 0xFF] ^ _T1[(x >> 8) & 0xFF] ^ _T0[x & 0xFF]


class Crc(Peripheral):
    """DR and IDR live in `regs`: a list, or the native fast path's registers (which then
    computes the word writes to DR itself)."""

    name = "CRC"
    regs = None

    def reset(self):
        if self.regs is None:
            self.regs = [0, 0]
        self.dr = 0xFFFFFFFF
        self.idr = 0

    def attach_native(self, page):
        page.regs[0], page.regs[1] = self.dr, self.idr
        self.regs = page.regs
        page.read_kind[0] = page.read_kind[1] = native.MIRROR
        page.write_kind[0] = native.CRC_DR
        page.write_kind[2] = native.CRC_CR

    dr = property(lambda self: self.regs[0], lambda self, v: self.regs.__setitem__(0, v))
    idr = property(lambda self: self.regs[1], lambda self, v: self.regs.__setitem__(1, v))

    def read(self, off):
        if off == 0x00:
            return self.dr
        if off == 0x04:
            return self.idr
        return 0

    def write(self, off, value, mask):
        if off == 0x00:
            self.dr = crc32_word_fast(self.dr, value & mask)
        elif off == 0x04:
            self.idr = value & 0xFF
        elif off == 0x08 and value & 1:
            self.dr = 0xFFFFFFFF
