"""Timers TIM1 (advanced, RM0008 §14) and TIM2..TIM4 (general purpose, §15), as counters.

Modelled: the up-counter (CR1.CEN, DIR=0, edge-aligned) clocked from the timer clock of its
APB (RCC: x2 when the APB prescaler is not 1, §7.2) through PSC; PSC and (with ARPE) ARR and
(with OCxPE) CCRx are preloaded and take effect on an update event (§15.3.1); the update event
on overflow or EGR.UG (UIF unless UDIS; UG sets no UIF while URS=1, §15.4.1/§15.4.5); compare
matches CNT == CCRx set CCxIF (§15.3.8, output compare; the pin outputs are not modelled);
EGR.CCxG; SR is rc_w0; DIER interrupt enables; the NVIC lines (TIM1: UP/CC/TRG_COM/BRK split,
TIM2..4 one line each, RM0008 Table 63).
Encoder interface mode (SMCR.SMS = 1/2/3, §15.3.12): the counter counts the edges of TI1/TI2
from the pins (`encoder_edge`, fed by the GPIO levels), up or down by the quadrature rule of
Table 83; the input filter (ICxF) is not modelled (edges count at once).
Not modelled: down and centre-aligned counting, one-pulse mode, input capture, PWM pin
levels, slave modes other than encoder, master/slave triggers, DMA requests from timers,
repetition counter and break (TIM1).
"""

from . import native
from .periph import Peripheral

M16 = 0xFFFF


class Timer(Peripheral):
    def __init__(self, chip, base, name, apb, irqs):
        self.name = name
        self.apb = apb
        self.irqs = irqs  # dict: "up", "cc", "trg", "brk" -> IRQ number
        self.enc_pins = None  # (gpio, pin1, gpio, pin2) for encoder mode
        # TI1/TI2 follow the pins' levels (Chip._route_timer_inputs), not the registers: an
        # RCC reset of the timer does not change what is on its input pins
        self.ti = [0, 0]
        super().__init__(chip, base)

    def reset(self):
        self.cr1 = self.cr2 = self.smcr = self.dier = self.sr = 0
        self.ccmr = [0, 0]
        self.ccer = 0
        self.cnt = 0
        self.psc = self.psc_active = 0
        self.arr = self.arr_active = M16
        self.ccr = [0, 0, 0, 0]
        self.ccr_active = [0, 0, 0, 0]
        self.rcr = self.bdtr = self.dcr = 0
        self.anchor = self.chip.now if hasattr(self.chip, "now") else 0
        self._irq()
        self._publish()

    # --- the native fast path (native.py) ------------------------------------------------
    _page = None

    def attach_native(self, page):
        """CNT and DIER read natively: CNT from what `_publish` tells it, DIER as published."""
        self._page = page
        page.is_timer = 1
        page.read_kind[0x24 >> 2] = native.TIM_CNT
        page.read_kind[0x0C >> 2] = native.MIRROR
        self._publish()

    def _publish(self):
        """Tell the fast path the counter's state (and what `next_event` needs): after anything
        that changes it."""
        pg = self._page
        if pg is None:
            return
        pg.regs[0x0C >> 2] = self.dier
        pg.tim_cr1, pg.tim_smcr, pg.tim_cnt, pg.tim_anchor = self.cr1, self.smcr, self.cnt, self.anchor
        pg.tim_psc, pg.tim_psc_active = self.psc, self.psc_active
        pg.tim_arr, pg.tim_arr_active = self.arr, self.arr_active
        pg.tim_ccr_active[:] = self.ccr_active
        timclk = getattr(self.chip, "timclk", None)
        pg.tim_div = self.chip.TICK_HZ // timclk[self.apb] if timclk else 0

    # --- clocking --------------------------------------------------------------------------
    def ticks_per_count(self):
        div = self.chip.TICK_HZ // self.chip.timclk[self.apb]
        return div * (self.psc_active + 1)

    def running(self):
        return (self.cr1 & 1) and not self.encoder_mode()

    def encoder_mode(self):
        return (self.smcr & 7) in (1, 2, 3)

    def _update_event(self, set_flag=True):
        self.psc_active = self.psc
        self.arr_active = self.arr
        for i in range(4):
            self.ccr_active[i] = self.ccr[i]
        if set_flag and not (self.cr1 & 2):
            self.sr |= 1

    def _preload_pending(self):
        return (
            self.psc != self.psc_active
            or self.arr != self.arr_active
            or self.ccr != self.ccr_active
        )

    def _advance(self, n):
        """Count n times from the current state (up-counting, CNT <= ARR)."""
        while n > 0:
            mod = self.arr_active + 1
            cnt = self.cnt
            to_ovf = (self.arr_active - cnt) % 0x10000 + 1
            step = to_ovf if (self._preload_pending() and n >= to_ovf) else n
            for i in range(4):
                c = self.ccr_active[i]
                if c <= self.arr_active:
                    d = (c - cnt) % mod or mod
                    if d <= step:
                        self.sr |= 2 << i
            if step >= to_ovf:
                self.overflows += 1 + (step - to_ovf) // mod
                self.cnt = (step - to_ovf) % mod
                if not (self.cr1 & 2):  # UDIS
                    self._update_event()
                if self.cr1 & 8:  # one-pulse mode: stop at the update
                    self.cr1 &= ~1
                    self.cnt = 0
                    return
            else:
                self.cnt = cnt + step
            n -= step

    overflows = 0

    _synced_at = -1

    def sync(self, now):
        # A second sync at the same tick changes nothing (the counter moved to `now` already,
        # a write since then re-anchored it at `now`), and registers read within one CPU slice
        # all see the slice's start: most calls are such repeats.
        if now == self._synced_at:
            return
        self._synced_at = now
        if not self.running():
            self.anchor = now
            return
        per = self.ticks_per_count()
        n = (now - self.anchor) // per
        if n <= 0:
            return
        sr, overflows = self.sr, self.overflows
        while n > 0:
            # the prescaler may change at the first update: count up to it, then re-read
            to_ovf = (self.arr_active - self.cnt) % 0x10000 + 1
            if self.psc != self.psc_active and n >= to_ovf:
                self._advance(to_ovf)
                self.anchor += to_ovf * per
                per = self.ticks_per_count()
                n = (now - self.anchor) // per
            else:
                self._advance(n)
                self.anchor += n * per
                n = 0
        pg = self._page
        if pg is not None:
            if self.overflows != overflows:  # an update: preloads, one-pulse mode's stop
                self._publish()
            else:  # the count moved, nothing else
                pg.tim_cnt, pg.tim_anchor = self.cnt, self.anchor
        if self.sr != sr:
            self._irq()
            self.chip.reschedule()

    def next_event(self):
        if not self.running():
            return None
        en = self.dier & self._enabled_flags()
        if not en:
            return None
        per = self.ticks_per_count()
        mod = self.arr_active + 1
        best = None
        if en & 1:
            best = (self.arr_active - self.cnt) % 0x10000 + 1
        for i in range(4):
            if en & (2 << i):
                c = self.ccr_active[i]
                if c <= self.arr_active:
                    d = (c - self.cnt) % mod
                    if d == 0:
                        d = mod
                    best = d if best is None else min(best, d)
        if best is None:
            return None
        return self.anchor + best * per

    def _enabled_flags(self):
        return 0x1F

    def _irq(self):
        s = self.sr & self.dier
        if (
            "up" in self.irqs
            and "cc" in self.irqs
            and len(self.irqs) > 1
            and self.irqs["up"] != self.irqs["cc"]
        ):
            self.irq(self.irqs["up"], bool(s & 1))
            self.irq(self.irqs["cc"], bool(s & 0x1E))
            if "trg" in self.irqs:
                self.irq(self.irqs["trg"], bool(s & 0x60))
            if "brk" in self.irqs:
                self.irq(self.irqs["brk"], bool(s & 0x80))
        else:
            self.irq(self.irqs["up"], bool(s & 0xFF))

    # --- encoder interface (§15.3.12) ----------------------------------------------------
    def encoder_edge(self, ch, level):
        """TI1 (ch=0) or TI2 (ch=1) changed level."""
        self.ti[ch] = level
        if not (self.cr1 & 1) or not self.encoder_mode():
            return
        sms = self.smcr & 7
        if (sms == 1 and ch == 1) or (sms == 2 and ch == 0):
            return  # mode 1: TI1 edges only; 2: TI2 only
        # polarity (CCxP inverts TIx)
        t1 = self.ti[0] ^ ((self.ccer >> 1) & 1)
        t2 = self.ti[1] ^ ((self.ccer >> 5) & 1)
        rising = level ^ ((self.ccer >> (1 + 4 * ch)) & 1)
        # Table 83: counting on TI1 edges: direction from TI2's level; on TI2: from TI1's
        if ch == 0:
            up = (not rising) if t2 else rising
        else:
            up = rising if t1 else (not rising)
        if up:
            if self.cnt == self.arr_active:
                self.cnt = 0
                self._update_event()
            else:
                self.cnt = (self.cnt + 1) & M16
        else:
            if self.cnt == 0:
                self.cnt = self.arr_active
                self._update_event()
            else:
                self.cnt -= 1
        self.cr1 = (self.cr1 & ~0x10) | (0 if up else 0x10)
        for i in range(4):
            if self.cnt == self.ccr_active[i] and i >= 2:
                self.sr |= 2 << i
        self._publish()
        self._irq()

    # --- registers -----------------------------------------------------------------------
    def read(self, off):
        self.sync(self.chip.now)
        if off == 0x00:
            return self.cr1
        if off == 0x04:
            return self.cr2
        if off == 0x08:
            return self.smcr
        if off == 0x0C:
            return self.dier
        if off == 0x10:
            return self.sr
        if off == 0x18:
            return self.ccmr[0]
        if off == 0x1C:
            return self.ccmr[1]
        if off == 0x20:
            return self.ccer
        if off == 0x24:
            return self.cnt
        if off == 0x28:
            return self.psc
        if off == 0x2C:
            return self.arr
        if off == 0x30:
            return self.rcr
        if 0x34 <= off <= 0x40:
            return self.ccr[(off - 0x34) >> 2]
        if off == 0x44:
            return self.bdtr
        if off == 0x48:
            return self.dcr
        return 0

    def write(self, off, value, mask):
        now = self.chip.now
        self.sync(now)
        v = value & mask & 0xFFFF
        if off == 0x00:
            was = self.running()
            self.cr1 = self.merge(self.cr1, value, mask) & 0x3FF
            if self.running() and not was:
                self.anchor = now
        elif off == 0x04:
            self.cr2 = self.merge(self.cr2, value, mask) & 0xFFFF
        elif off == 0x08:
            was = self.running()
            self.smcr = self.merge(self.smcr, value, mask) & 0xFFFF
            if self.running() and not was:
                self.anchor = now
        elif off == 0x0C:
            self.dier = self.merge(self.dier, value, mask) & 0x7FFF
        elif off == 0x10:
            self.sr &= (value | ~mask) & 0xFFFF  # rc_w0
        elif off == 0x14:
            if v & 1:  # UG
                self.cnt = 0
                self.anchor = now
                self._update_event(set_flag=not (self.cr1 & 4))
            for i in range(4):
                if v & (2 << i):
                    self.sr |= 2 << i
            if v & 0x40:
                self.sr |= 0x40
            if v & 0x80:
                self.sr |= 0x80
        elif off in (0x18, 0x1C):
            i = (off - 0x18) >> 2
            self.ccmr[i] = self.merge(self.ccmr[i], value, mask) & 0xFFFF
        elif off == 0x20:
            self.ccer = self.merge(self.ccer, value, mask) & 0xFFFF
        elif off == 0x24:
            self.cnt = v
        elif off == 0x28:
            self.psc = v
        elif off == 0x2C:
            self.arr = v
            if not (self.cr1 & 0x80):
                self.arr_active = v
        elif off == 0x30:
            self.rcr = v & 0xFF
        elif 0x34 <= off <= 0x40:
            i = (off - 0x34) >> 2
            self.ccr[i] = v
            ocpe = (self.ccmr[i >> 1] >> (3 + 8 * (i & 1))) & 1
            if not ocpe:
                self.ccr_active[i] = v
        elif off == 0x44:
            self.bdtr = v
        elif off == 0x48:
            self.dcr = v
        self._publish()
        self._irq()
        self.chip.reschedule()
