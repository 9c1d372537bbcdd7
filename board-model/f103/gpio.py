"""GPIO ports and AFIO (RM0008 §9.1 functional description, §9.2 GPIO registers, §9.4 AFIO
registers).

A pin's level: an output (MODE != 00) drives its ODR bit (general purpose) or its peripheral's
output (alternate function: `set_af_level`, idle high until a peripheral drives it); open-drain
outputs driving 1 read the external level, or 1 (an external pull-up assumed). An input reads
the external level when something drives it (`drive`, None = released), else its pull (CNF=10:
ODR selects up or down), else a floating input reads 0 (not defined on the chip; the model
picks 0). Analog inputs read 0 in IDR. Level changes go to EXTI through AFIO_EXTICRx and to
any listener (`listen(pin, fn)`: the wires to the other board).
LCKR is stored but does not lock.
"""

from .periph import Peripheral


class Gpio(Peripheral):
    def __init__(self, chip, base, port):
        self.port = port  # 0 = A, 1 = B, ...
        self.name = "GPIO" + "ABCDEFG"[port]
        self.listeners = {}
        # What drives the pins from outside (the other board, the encoders) is not the
        # port's: a reset of the port or of the chip leaves it (reset.py)
        self.ext = [None] * 16
        super().__init__(chip, base)

    def reset(self):
        self.cr = [0x44444444, 0x44444444]
        self.odr = 0
        self.lckr = 0
        self.af = [1] * 16
        if hasattr(self, "levels"):
            self._update()  # outputs let go: the wires to the other board see it
        else:
            self.levels = self._compute()  # at construction: nothing listens yet

    def listen(self, pin, fn):
        self.listeners.setdefault(pin, []).append(fn)

    def cfg(self, pin):
        return (self.cr[pin >> 3] >> ((pin & 7) * 4)) & 0xF

    def is_output(self, pin):
        return (self.cfg(pin) & 3) != 0

    def _level(self, pin):
        c = self.cfg(pin)
        mode, cnf = c & 3, c >> 2
        if mode:
            drive = self.af[pin] if cnf & 2 else (self.odr >> pin) & 1
            if cnf & 1 and drive:  # open drain released
                e = self.ext[pin]
                return 1 if e is None else e
            return drive
        if cnf == 0:
            return 0  # analog
        if self.ext[pin] is not None:
            return self.ext[pin]
        if cnf == 2:
            return (self.odr >> pin) & 1  # pull-up / pull-down
        return 0  # floating

    def _compute(self):
        v = 0
        for p in range(16):
            v |= self._level(p) << p
        return v

    def _update(self):
        new = self._compute()
        old = self.levels
        self.levels = new
        changed = old ^ new
        if changed:
            exti = self.chip.exti
            for p in range(16):
                if (changed >> p) & 1:
                    lvl = (new >> p) & 1
                    if self.chip.afio.exti_port(p) == self.port:
                        exti.edge(p, lvl)
                    for fn in self.listeners.get(p, ()):
                        fn(lvl)

    # external world ---------------------------------------------------------------------
    def drive(self, pin, level):
        """Drive a pin from outside (None: release)."""
        self.ext[pin] = level
        self._update()

    def set_af_level(self, pin, level):
        if self.af[pin] != level:
            self.af[pin] = level
            self._update()

    def level(self, pin):
        return (self.levels >> pin) & 1

    def read(self, off):
        if off == 0x00:
            return self.cr[0]
        if off == 0x04:
            return self.cr[1]
        if off == 0x08:
            return self.levels
        if off == 0x0C:
            return self.odr
        if off == 0x18:
            return self.lckr
        return 0

    def write(self, off, value, mask):
        if off in (0x00, 0x04):
            i = off >> 2
            self.cr[i] = self.merge(self.cr[i], value, mask)
        elif off == 0x0C:
            self.odr = self.merge(self.odr, value, mask) & 0xFFFF
        elif off == 0x10:
            v = value & mask
            self.odr = (self.odr & ~(v >> 16)) | (v & 0xFFFF)  # set wins over reset
        elif off == 0x14:
            self.odr &= ~(value & mask & 0xFFFF)
        elif off == 0x18:
            self.lckr = value & 0x1FFFF
        else:
            return
        self._update()


class Afio(Peripheral):
    name = "AFIO"

    def reset(self):
        self.evcr = 0
        self.mapr = 0
        self.exticr = [0, 0, 0, 0]
        self.mapr2 = 0

    def exti_port(self, line):
        return (self.exticr[line >> 2] >> ((line & 3) * 4)) & 0xF

    def read(self, off):
        if off == 0x00:
            return self.evcr
        if off == 0x04:
            return self.mapr & ~(7 << 24)  # SWJ_CFG is write-only
        if 0x08 <= off <= 0x14:
            return self.exticr[(off - 8) >> 2]
        if off == 0x1C:
            return self.mapr2
        return 0

    def write(self, off, value, mask):
        if off == 0x00:
            self.evcr = self.merge(self.evcr, value, mask) & 0xFF
        elif off == 0x04:
            self.mapr = self.merge(self.mapr, value, mask)
        elif 0x08 <= off <= 0x14:
            i = (off - 8) >> 2
            self.exticr[i] = self.merge(self.exticr[i], value, mask) & 0xFFFF
        elif off == 0x1C:
            self.mapr2 = self.merge(self.mapr2, value, mask)
