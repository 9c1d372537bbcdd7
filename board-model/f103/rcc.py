"""RCC: reset and clock control (RM0008 §7.2 clocks, §7.3 registers, connectivity line
excluded).

Modelled: HSI (8 MHz, on at reset), HSE (8 MHz crystal, HSEON -> HSERDY), the PLL (source
HSI/2 or HSE[/2], x2..x16, PLLON -> PLLRDY, refuses to start while its inputs are not ready),
the system clock switch (SW -> SWS, only onto a ready source), AHB/APB1/APB2 prescalers (the
timers' x2 when an APB prescaler is not 1, §7.2), the peripheral clock enables (a peripheral
whose clock is off reads 0 and ignores writes: core.Chip checks `clock_on`) and the APBx
reset registers (a 0->1 write resets the peripheral model).
Oscillator start-up times are not modelled: a source is ready on the access after it was
switched on.
"""

from .periph import Peripheral

HSI_HZ = 8_000_000
HSE_HZ = 8_000_000

AHB = {"DMA1": 0, "SRAM": 2, "FLITF": 4, "CRC": 6}
APB2 = {
    "AFIO": 0,
    "GPIOA": 2,
    "GPIOB": 3,
    "GPIOC": 4,
    "GPIOD": 5,
    "GPIOE": 6,
    "ADC1": 9,
    "ADC2": 10,
    "TIM1": 11,
    "SPI1": 12,
    "USART1": 14,
}
APB1 = {
    "TIM2": 0,
    "TIM3": 1,
    "TIM4": 2,
    "WWDG": 11,
    "SPI2": 14,
    "USART2": 17,
    "USART3": 18,
    "I2C1": 21,
    "I2C2": 22,
    "USB": 23,
    "CAN": 25,
    "BKP": 27,
    "PWR": 28,
}
AHB_DIV = [1, 1, 1, 1, 1, 1, 1, 1, 2, 4, 8, 16, 64, 128, 256, 512]
APB_DIV = [1, 1, 1, 1, 2, 4, 8, 16]


class Rcc(Peripheral):
    name = "RCC"

    def reset(self):
        self.cr = 0x83  # HSION, HSIRDY, HSITRIM=16
        self.cfgr = 0
        self.cir = 0
        self.apb2rstr = 0
        self.apb1rstr = 0
        self.ahbenr = 0x14  # SRAMEN, FLITFEN
        self.apb2enr = 0
        self.apb1enr = 0
        self.bdcr = 0
        self.csr = 0x0C000000  # PINRSTF, PORRSTF

    # --- clock tree --------------------------------------------------------------------------
    def pll_hz(self):
        mul = min(((self.cfgr >> 18) & 0xF) + 2, 16)
        if self.cfgr & (1 << 16):
            src = HSE_HZ // (2 if self.cfgr & (1 << 17) else 1)
        else:
            src = HSI_HZ // 2
        return src * mul

    def sysclk_hz(self):
        sws = (self.cfgr >> 2) & 3
        return {0: HSI_HZ, 1: HSE_HZ, 2: self.pll_hz()}.get(sws, HSI_HZ)

    def hclk_hz(self):
        return self.sysclk_hz() // AHB_DIV[(self.cfgr >> 4) & 0xF]

    def pclk_hz(self, apb):
        pre = (self.cfgr >> (8 if apb == 1 else 11)) & 7
        return self.hclk_hz() // APB_DIV[pre]

    def timer_hz(self, apb):
        pre = (self.cfgr >> (8 if apb == 1 else 11)) & 7
        p = self.pclk_hz(apb)
        return p if APB_DIV[pre] == 1 else 2 * p

    def enabled(self, bus, bit):
        reg = {"AHB": self.ahbenr, "APB1": self.apb1enr, "APB2": self.apb2enr}[bus]
        return (reg >> bit) & 1

    def snapshot(self):
        """The clock tree as numbers, cached by the chip (recomputed on every RCC write)."""
        return {
            "hclk": self.hclk_hz(),
            "pclk": {1: self.pclk_hz(1), 2: self.pclk_hz(2)},
            "timclk": {1: self.timer_hz(1), 2: self.timer_hz(2)},
        }

    # --- registers -----------------------------------------------------------------------
    def read(self, off):
        return {
            0x00: self.cr,
            0x04: self.cfgr,
            0x08: self.cir,
            0x0C: self.apb2rstr,
            0x10: self.apb1rstr,
            0x14: self.ahbenr,
            0x18: self.apb2enr,
            0x1C: self.apb1enr,
            0x20: self.bdcr,
            0x24: self.csr,
        }.get(off, 0)

    def write(self, off, value, mask):
        c = self.chip
        if off == 0x00:
            v = self.merge(self.cr, value, mask)
            rw = (1 << 0) | (0x1F << 3) | (1 << 16) | (1 << 18) | (1 << 19) | (1 << 24)
            cr = (self.cr & ~rw) | (v & rw)
            # ready flags follow their enables (start-up time not modelled)
            cr = (cr & ~(1 << 1)) | ((cr & 1) << 1)
            hse_ok = bool(cr & (1 << 16))
            cr = (cr & ~(1 << 17)) | (hse_ok << 17)
            pll_src_ok = hse_ok if self.cfgr & (1 << 16) else bool(cr & 1)
            cr = (cr & ~(1 << 25)) | ((bool(cr & (1 << 24)) and pll_src_ok) << 25)
            # the clock in use cannot be switched off (§7.3.1)
            sws = (self.cfgr >> 2) & 3
            if sws == 0:
                cr |= 3
            elif sws == 1:
                cr |= 3 << 16
            elif sws == 2:
                cr |= 3 << 24
            self.cr = cr
        elif off == 0x04:
            v = self.merge(self.cfgr, value, mask)
            sws = (self.cfgr >> 2) & 3
            sw = v & 3
            ready = {0: self.cr & 2, 1: self.cr & (1 << 17), 2: self.cr & (1 << 25)}.get(sw, 0)
            if ready:
                sws = sw
            # the PLL configuration may change only while the PLL is off (§7.3.2)
            if self.cr & (1 << 24):
                v = (v & ~(0x3F << 16)) | (self.cfgr & (0x3F << 16))
            self.cfgr = (v & ~0xC) | (sws << 2)
            c.clock_changed()
        elif off == 0x08:
            self.cir = self.merge(self.cir, value, mask) & 0x1F00
        elif off in (0x0C, 0x10):
            old = self.apb2rstr if off == 0x0C else self.apb1rstr
            v = self.merge(old, value, mask)
            if off == 0x0C:
                self.apb2rstr = v
            else:
                self.apb1rstr = v
            bus = "APB2" if off == 0x0C else "APB1"
            rising = v & ~old
            for b in range(32):
                if (rising >> b) & 1:
                    c.reset_peripheral(bus, b)
        elif off == 0x14:
            self.ahbenr = self.merge(self.ahbenr, value, mask)
        elif off == 0x18:
            self.apb2enr = self.merge(self.apb2enr, value, mask)
        elif off == 0x1C:
            self.apb1enr = self.merge(self.apb1enr, value, mask)
        elif off == 0x20:
            v = self.merge(self.bdcr, value, mask)
            v = (v & ~2) | ((v & 1) << 1)  # LSERDY follows LSEON
            self.bdcr = v
        elif off == 0x24:
            v = self.merge(self.csr, value, mask)
            v = (v & ~2) | ((v & 1) << 1)  # LSIRDY follows LSION
            if v & (1 << 24):  # RMVF clears the reset flags
                v &= 0x00FFFFFF
            self.csr = v & ~(1 << 24)
        if off in (0x14, 0x18, 0x1C):  # a clock enable: the native fast path answers while on
            c.gates_changed()
        c.reschedule()


class Flash(Peripheral):
    """Flash memory interface (RM0008 §3.3.3 and PM0075): ACR (LATENCY, HLFCYA, PRFTBE, PRFTBS
    follows PRFTBE), the other registers read their reset values. Programming and erasing are
    not modelled; wait states do not slow the model's CPU (see core.py, CPI)."""

    name = "FLASH"

    def reset(self):
        self.acr = 0x30

    def read(self, off):
        return {0x00: self.acr, 0x0C: 0, 0x10: 0x80, 0x1C: 0x03FFFFFC, 0x20: 0xFFFFFFFF}.get(off, 0)

    def write(self, off, value, mask):
        if off == 0x00:
            v = self.merge(self.acr, value, mask) & 0x1F
            self.acr = v | ((v & 0x10) << 1)
        else:
            self.chip.unmodelled(self, off, "write")


class Pwr(Peripheral):
    """Power control (RM0008 §5.4): CR (DBP and the low-power bits are stored; CWUF/CSBF clear
    the CSR flags), CSR (EWUP stored; no wake-up or standby flags: no low-power modes are
    modelled; PVDO reads 0, i.e. VDD above the PVD threshold)."""

    name = "PWR"

    def reset(self):
        self.cr = 0
        self.csr = 0

    def read(self, off):
        return {0x00: self.cr, 0x04: self.csr}.get(off, 0)

    def write(self, off, value, mask):
        if off == 0x00:
            v = self.merge(self.cr, value, mask) & 0x1FF
            if v & 4:
                self.csr &= ~1
            if v & 8:
                self.csr &= ~2
            self.cr = v & ~0xC
        elif off == 0x04:
            self.csr = (self.csr & ~0x100) | (value & mask & 0x100)
