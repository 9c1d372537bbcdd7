"""CRC calculation unit (RM0008 §4): CRC-32, polynomial 0x04C11DB7, 32-bit words fed MSB
first, no reflection, no final XOR; DR resets to 0xFFFFFFFF (CR.RESET); IDR is a free 8-bit
register. Byte and halfword writes to DR are taken as a full word (as the hardware does: DR is
a 32-bit register and the calculation always uses the whole word)."""

from .periph import Peripheral

POLY = 0x04C11DB7


def crc32_word(crc, word):
    crc ^= word & 0xFFFFFFFF
    for _ in range(32):
        crc = ((crc << 1) ^ POLY) & 0xFFFFFFFF if crc & 0x80000000 else (crc << 1) & 0xFFFFFFFF
    return crc


# table-driven version of the same (8 bits at a time)
_TABLE = []
for _i in range(256):
    _c = _i << 24
    for _ in range(8):
        _c = ((_c << 1) ^ POLY) & 0xFFFFFFFF if _c & 0x80000000 else (_c << 1) & 0xFFFFFFFF
    _TABLE.append(_c)


def crc32_word_fast(crc, word):
    crc ^= word & 0xFFFFFFFF
    for _ in range(4):
        crc = ((crc << 8) & 0xFFFFFFFF) ^ _TABLE[crc >> 24]
    return crc


class Crc(Peripheral):
    name = "CRC"

    def reset(self):
        self.dr = 0xFFFFFFFF
        self.idr = 0

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
