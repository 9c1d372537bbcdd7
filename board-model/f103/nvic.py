"""Private peripheral bus of the Cortex-M3 (0xE0000000..0xE00FFFFF): NVIC, SCB, SysTick, DWT
(CYCCNT), DEMCR, and the STM32's DBGMCU.

Sources: RM0008 §10.1 (the F103's 43 maskable interrupt lines, 16 priority levels: the upper
4 bits of each priority byte are implemented), PM0056 (STM32F10xxx Cortex-M3 programming
manual) §4.3 NVIC, §4.4 SCB, §4.5 SysTick, and the ARMv7-M ARM B1.5 (exception model:
priorities, grouping by AIRCR.PRIGROUP, preemption, pending/active state, level-sensitive
lines re-pending on return) and C1.8 (DWT CYCCNT, DEMCR.TRCENA).
"""

from .periph import Peripheral

NUM_IRQ = 43  # RM0008 Table 63 (medium density)
PRIO_MASK = 0xF0  # 4 priority bits implemented (RM0008 §10.1.1)

RESET, NMI, HARDFAULT, MEMMANAGE, BUSFAULT, USAGEFAULT = 1, 2, 3, 4, 5, 6
SVCALL, DEBUGMON, PENDSV, SYSTICK = 11, 12, 14, 15
EXC_NAMES = {
    1: "Reset",
    2: "NMI",
    3: "HardFault",
    4: "MemManage",
    5: "BusFault",
    6: "UsageFault",
    11: "SVCall",
    12: "DebugMonitor",
    14: "PendSV",
    15: "SysTick",
}
IRQ_NAMES = [
    "WWDG",
    "PVD",
    "TAMPER",
    "RTC",
    "FLASH",
    "RCC",
    "EXTI0",
    "EXTI1",
    "EXTI2",
    "EXTI3",
    "EXTI4",
    "DMA1_CHANNEL1",
    "DMA1_CHANNEL2",
    "DMA1_CHANNEL3",
    "DMA1_CHANNEL4",
    "DMA1_CHANNEL5",
    "DMA1_CHANNEL6",
    "DMA1_CHANNEL7",
    "ADC1_2",
    "USB_HP_CAN1_TX",
    "USB_LP_CAN1_RX0",
    "CAN1_RX1",
    "CAN1_SCE",
    "EXTI9_5",
    "TIM1_BRK",
    "TIM1_UP",
    "TIM1_TRG_COM",
    "TIM1_CC",
    "TIM2",
    "TIM3",
    "TIM4",
    "I2C1_EV",
    "I2C1_ER",
    "I2C2_EV",
    "I2C2_ER",
    "SPI1",
    "SPI2",
    "USART1",
    "USART2",
    "USART3",
    "EXTI15_10",
    "RTCALARM",
    "USBWAKEUP",
]


def exc_name(exc):
    return EXC_NAMES.get(exc) or (IRQ_NAMES[exc - 16] if 16 <= exc < 16 + NUM_IRQ else f"exc{exc}")


class Scs(Peripheral):
    """Everything at 0xE0000000.. that the firmware touches. Exception state lives here; the
    mechanics of entry and return (stacking) are in core.Chip."""

    name = "PPB"
    size = 0x100000

    def reset(self):
        self.enabled = [False] * NUM_IRQ
        self.ipr = [0] * NUM_IRQ
        self.shpr = [0] * 16  # by exception number 4..15
        self.pending = set()  # exception numbers
        self.active = []  # exception numbers, in order of activation
        self.lines = [False] * NUM_IRQ
        self.ever_enabled = set()
        self.vtor = 0
        self.prigroup = 0
        self.scr = 0
        self.ccr = 0x200  # STKALIGN=1 (PM0056 §4.4.8 reset value)
        self.shcsr = 0
        self.cfsr = 0
        self.hfsr = 0
        self.bfar = 0
        self.demcr = 0
        self.dwt_ctrl = 0x40000000  # NUMCOMP etc. not modelled
        self.cyccnt_base = 0  # CYCCNT = cycles - base while enabled
        self.cyccnt_frozen = 0
        self.systick_csr = 0
        self.systick_rvr = 0
        self.systick_cvr = 0
        self.systick_at = 0
        self.dbgmcu_cr = 0

    # --- priorities (ARMv7-M B1.5.4) -------------------------------------------------------
    def priority(self, exc):
        if exc == RESET:
            return -3
        if exc == NMI:
            return -2
        if exc == HARDFAULT:
            return -1
        if exc >= 16:
            return self.ipr[exc - 16]
        return self.shpr[exc]

    def group(self, prio):
        if prio < 0:
            return prio
        return prio & ~((2 << self.prigroup) - 1) & 0xFF

    def exc_enabled(self, exc):
        if exc >= 16:
            return self.enabled[exc - 16]
        return True

    def execution_priority(self, primask, basepri=0, faultmask=0):
        p = 256
        for e in self.active:
            p = min(p, self.group(self.priority(e)))
        if basepri & PRIO_MASK:
            p = min(p, self.group(basepri & PRIO_MASK))
        if primask & 1:
            p = min(p, 0)
        if faultmask & 1:
            p = min(p, -1)
        return p

    def pending_exception(self):
        """Highest-priority pending and enabled exception, or None."""
        best = None
        for e in self.pending:
            if not self.exc_enabled(e):
                continue
            key = (self.priority(e), e)
            if best is None or key < best[0]:
                best = (key, e)
        return None if best is None else best[1]

    def takeable(self, primask, basepri=0):
        e = self.pending_exception()
        if e is None:
            return None
        if self.group(self.priority(e)) < self.execution_priority(primask, basepri):
            return e
        return None

    # --- lines from the peripherals --------------------------------------------------------
    def set_line(self, irq, level):
        old = self.lines[irq]
        self.lines[irq] = level
        if level and not old:
            self.pending.add(16 + irq)
            self.chip.irq_changed()

    def pend(self, exc):
        self.pending.add(exc)
        self.chip.irq_changed()

    def activate(self, exc):
        self.pending.discard(exc)
        self.active.append(exc)

    def deactivate(self, exc):
        if exc in self.active:
            self.active.remove(exc)
        if exc >= 16 and self.lines[exc - 16]:
            self.pending.add(exc)  # level still asserted: pends again (B1.5.2)

    def vectactive(self):
        return self.active[-1] if self.active else 0

    # --- SysTick (PM0056 §4.5), counted in HCLK or HCLK/8 --------------------------------
    def _systick_clock_div(self):
        return self.chip.ticks_per_hclk() * (1 if self.systick_csr & 4 else 8)

    def _systick_sync(self, now):
        if not (self.systick_csr & 1):
            self.systick_at = now
            return
        div = self._systick_clock_div()
        n = (now - self.systick_at) // div
        if n <= 0:
            return
        self.systick_at += n * div
        reload = self.systick_rvr & 0xFFFFFF
        cvr = self.systick_cvr
        if n < cvr or cvr == 0 and reload == 0:
            self.systick_cvr = cvr - n if cvr else cvr
            return
        # counts down to 0 (wrap: reload on the clock after 0)
        n -= cvr
        self.systick_csr |= 1 << 16
        if self.systick_csr & 2:
            self.pend(SYSTICK)
        period = reload + 1
        if reload:
            wraps, rem = divmod(n, period)
            if wraps:
                self.systick_csr |= 1 << 16
                if self.systick_csr & 2:
                    self.pend(SYSTICK)
            self.systick_cvr = (reload - rem + 1) % period if rem else 0
        else:
            self.systick_cvr = 0

    def next_event(self):
        if (self.systick_csr & 3) == 3 and self.systick_rvr:
            div = self._systick_clock_div()
            c = self.systick_cvr or (self.systick_rvr & 0xFFFFFF) + 1
            return self.systick_at + c * div
        return None

    def sync(self, now):
        self._systick_sync(now)

    # --- registers -------------------------------------------------------------------------
    def read(self, off):
        c = self.chip
        if off == 0x1000:
            return self.dwt_ctrl
        if off == 0x1004:  # DWT_CYCCNT
            if self.dwt_ctrl & 1:
                return (c.cycles() - self.cyccnt_base) & 0xFFFFFFFF
            return self.cyccnt_frozen
        if 0x1008 <= off < 0x1100:
            return 0
        if off == 0xE004:  # ICTR: 64 lines
            return 1
        if off == 0xE010:
            self._systick_sync(c.now)
            v = self.systick_csr
            self.systick_csr &= ~(1 << 16)  # COUNTFLAG clears on read
            return v
        if off == 0xE014:
            return self.systick_rvr
        if off == 0xE018:
            self._systick_sync(c.now)
            return self.systick_cvr
        if off == 0xE01C:
            return 9000  # TENMS at 9 MHz (HCLK/8)
        if 0xE100 <= off < 0xE300:
            # ISER, ICER, ISPR, ICPR: 0x80 apart, a word per 32 lines
            group, idx = divmod(off - 0xE100, 0x80)
            idx //= 4
            if idx >= 8:
                return 0
            v = 0
            for b in range(32):
                n = idx * 32 + b
                if n >= NUM_IRQ:
                    break
                if group == 0 or group == 1:
                    bit = self.enabled[n]
                else:
                    bit = (16 + n) in self.pending
                v |= bit << b
            return v
        if 0xE300 <= off < 0xE320:  # IABR
            v = 0
            for b in range(32):
                n = (off - 0xE300) * 8 + b
                if n < NUM_IRQ and (16 + n) in self.active:
                    v |= 1 << b
            return v
        if 0xE400 <= off < 0xE400 + 4 * 11:
            n = off - 0xE400
            return sum(self.ipr[n + i] << (8 * i) for i in range(4) if n + i < NUM_IRQ)
        if off == 0xED00:
            return 0x411FC231  # CPUID: Cortex-M3 r1p1 (PM0056 §4.4.1)
        if off == 0xED04:
            return self._icsr()
        if off == 0xED08:
            return self.vtor
        if off == 0xED0C:
            return 0xFA050000 | (self.prigroup << 8)
        if off == 0xED10:
            return self.scr
        if off == 0xED14:
            return self.ccr
        if 0xED18 <= off < 0xED24:
            n = off - 0xED18 + 4
            return sum(self.shpr[n + i] << (8 * i) for i in range(4))
        if off == 0xED24:
            return self._shcsr()
        if off == 0xED28:
            return self.cfsr
        if off == 0xED2C:
            return self.hfsr
        if off == 0xED38:
            return self.bfar
        if off == 0xEDFC:
            return self.demcr
        if off == 0x42000:  # DBGMCU_IDCODE (0xE0042000)
            return 0x20036410  # medium density, rev X
        if off == 0x42004:
            return self.dbgmcu_cr
        c.unmodelled(self, off, "read")
        return 0

    def _icsr(self):
        v = self.vectactive()
        if len(self.active) <= 1:
            v |= 1 << 11  # RETTOBASE
        p = self.pending_exception()
        if p is not None:
            v |= p << 12
        if any(e >= 16 for e in self.pending):
            v |= 1 << 22
        if PENDSV in self.pending:
            v |= 1 << 28
        if SYSTICK in self.pending:
            v |= 1 << 26
        return v

    def _shcsr(self):
        v = self.shcsr & (7 << 16)
        for e, bit in (
            (MEMMANAGE, 0),
            (BUSFAULT, 1),
            (USAGEFAULT, 3),
            (SVCALL, 7),
            (DEBUGMON, 8),
            (PENDSV, 10),
            (SYSTICK, 11),
        ):
            if e in self.active:
                v |= 1 << bit
        return v

    def write(self, off, value, mask):
        c = self.chip
        if off == 0x1000:
            was = self.dwt_ctrl & 1
            self.dwt_ctrl = self.merge(self.dwt_ctrl, value, mask)
            if (self.dwt_ctrl & 1) and not was:
                self.cyccnt_base = c.cycles() - self.cyccnt_frozen
            elif was and not (self.dwt_ctrl & 1):
                self.cyccnt_frozen = (c.cycles() - self.cyccnt_base) & 0xFFFFFFFF
            return
        if off == 0x1004:
            v = self.merge(self.read(0x1004), value, mask)
            self.cyccnt_frozen = v
            self.cyccnt_base = c.cycles() - v
            return
        if off == 0xE010:
            self._systick_sync(c.now)
            self.systick_csr = (self.systick_csr & (1 << 16)) | (value & 7)
            self.systick_at = c.now
            c.reschedule()
            return
        if off == 0xE014:
            self.systick_rvr = value & 0xFFFFFF
            return
        if off == 0xE018:
            self.systick_cvr = 0  # any write clears (PM0056 §4.5.3)
            self.systick_csr &= ~(1 << 16)
            self.systick_at = c.now
            return
        if 0xE100 <= off < 0xE300:
            # ISER, ICER, ISPR, ICPR: 0x80 apart, a word per 32 lines
            group, idx = divmod(off - 0xE100, 0x80)
            idx //= 4
            if idx >= 8:
                return
            value &= mask
            for b in range(32):
                if not (value >> b) & 1:
                    continue
                n = idx * 32 + b
                if n >= NUM_IRQ:
                    break
                if group == 0:
                    self.enabled[n] = True
                    self.ever_enabled.add(n)
                elif group == 1:
                    self.enabled[n] = False
                elif group == 2:
                    self.pending.add(16 + n)
                elif group == 3:
                    self.pending.discard(16 + n)
                    if self.lines[n] and (16 + n) not in self.active:
                        self.pending.add(16 + n)
            c.irq_changed()
            return
        if 0xE400 <= off < 0xE400 + 4 * 11:
            n = off - 0xE400
            for i in range(4):
                if (mask >> (8 * i)) & 0xFF and n + i < NUM_IRQ:
                    self.ipr[n + i] = (value >> (8 * i)) & PRIO_MASK
            c.irq_changed()
            return
        if off == 0xED04:
            if value & (1 << 28):
                self.pending.add(PENDSV)
            if value & (1 << 27):
                self.pending.discard(PENDSV)
            if value & (1 << 26):
                self.pending.add(SYSTICK)
            if value & (1 << 25):
                self.pending.discard(SYSTICK)
            if value & (1 << 31):
                self.pending.add(NMI)
            c.irq_changed()
            return
        if off == 0xED08:
            self.vtor = value & 0x3FFFFF80
            return
        if off == 0xED0C:
            if (value >> 16) == 0x05FA:
                self.prigroup = (value >> 8) & 7
                if value & 4:
                    c.request_reset("SYSRESETREQ")
            return
        if off == 0xED10:
            self.scr = value & 0x16
            return
        if off == 0xED14:
            self.ccr = self.merge(self.ccr, value, mask) & 0x31B
            return
        if 0xED18 <= off < 0xED24:
            n = off - 0xED18 + 4
            for i in range(4):
                if (mask >> (8 * i)) & 0xFF:
                    self.shpr[n + i] = (value >> (8 * i)) & PRIO_MASK
            c.irq_changed()
            return
        if off == 0xED24:
            self.shcsr = self.merge(self.shcsr, value, mask) & (7 << 16)
            return
        if off == 0xED28:
            self.cfsr &= ~(value & mask)  # write 1 to clear
            return
        if off == 0xED2C:
            self.hfsr &= ~(value & mask)
            return
        if off == 0xEDFC:
            self.demcr = self.merge(self.demcr, value, mask)
            return
        if off == 0xEF00:  # STIR
            n = value & 0x1FF
            if n < NUM_IRQ:
                self.pending.add(16 + n)
                c.irq_changed()
            return
        if off == 0x42004:
            self.dbgmcu_cr = self.merge(self.dbgmcu_cr, value, mask)
            return
        c.unmodelled(self, off, "write")
