"""Power-on reset and system reset of one chip: what each sets back, what each keeps (mixed into
core.Chip).

Power-on reset (RM0008 §7.1.3): every register to its reset value and SRAM undefined, which
the model paints 0xA5 so that the stack check can tell the deepest byte ever written.

System reset (RM0008 §7.1.2): "sets all registers to their reset values except the reset flags
in the clock controller CSR register and the registers in the Backup domain". Its sources are
the NRST pin held low, the window and independent watchdogs, software (ARMv7-M B3.2.6,
AIRCR.SYSRESETREQ) and low-power management. SRAM is not a register and is not cleared: it
keeps what the firmware left there (the firmware's own start-up code then zeroes .bss and
copies .data, as after any reset). Modelled:
* the core as after reset (ARMv7-M B1.5.5 "Reset behavior", TakeReset): SP and PC from the vector table, LR
  0xFFFFFFFF, xPSR Thumb, PRIMASK/FAULTMASK/BASEPRI/CONTROL 0, thread mode, no exception active, the
  event register clear; R0..R12 keep their values (UNKNOWN after a reset);
* the SCB/NVIC/SysTick/DWT and every peripheral model at its reset value;
* RCC_CSR: the reset flags (bits 31..26) kept, and the source's own set: PINRSTF for the NRST
  pin; SFTRSTF for SYSRESETREQ, with PINRSTF as well, because an internal reset source drives
  NRST low through the reset pulse generator (RM0008 Figure 4) — the model's reading of the
  figure, not checked on a board;
* NRST held low for `hold` ticks: the CPU does not run and the peripherals stay at their
  reset values; then the core starts from the vector table. SYSRESETREQ's own pulse (at least
  20 us, Figure 4) is not modelled: that reset starts on the next instruction;
* what drives the chip's pins from outside (the other board, the encoders) is not the chip's
  and stays (gpio.Gpio keeps `ext`); the model's counters, the fault and panic records and the
  stack high-water mark cover the whole run, across resets.
Not modelled: the backup domain (BKP, RTC: not modelled at all), the watchdogs and low-power
sources, and debug (DHCSR, which a system reset does not reset either).
"""

import struct

from unicorn.arm_const import (
    UC_ARM_REG_BASEPRI,
    UC_ARM_REG_CONTROL,
    UC_ARM_REG_FAULTMASK,
    UC_ARM_REG_LR,
    UC_ARM_REG_PRIMASK,
    UC_ARM_REG_SP,
    UC_ARM_REG_XPSR,
)

from .memmap import SRAM_BASE, SRAM_SIZE

PAINT = 0xA5

# RCC_CSR reset flags (RM0008 §7.3.10)
PINRSTF = 1 << 26
PORRSTF = 1 << 27
SFTRSTF = 1 << 28
RESET_FLAGS = 0xFC000000
SOURCE_FLAGS = {"NRST pin": PINRSTF, "SYSRESETREQ": SFTRSTF | PINRSTF}


class ResetModel:
    def power_on(self):
        """Power-on reset: SRAM painted, the model's records cleared, registers at reset."""
        self.uc.mem_write(SRAM_BASE, bytes([PAINT]) * SRAM_SIZE)  # garbage / stack paint
        self.faults = []
        self.panics = []
        self.resets = []  # system resets: {"t", "source", "hold", "idle"}
        self.first_idle = None
        self.instructions = 0
        self.busy_ticks = 0
        self.sleeps = 0
        self.exceptions = 0
        self.sp_min = 0xFFFFFFFF
        self._registers_at_reset()  # RCC_CSR: PORRSTF and PINRSTF, rcc.Rcc.reset

    def system_reset(self, source, hold=0):
        """A system reset from `source` ("NRST pin" or "SYSRESETREQ"), NRST held low for
        `hold` ticks; SRAM and the model's records stay."""
        flags = self.rcc.csr & RESET_FLAGS
        self.log(f"system reset ({source}), held {hold / self.TICK_HZ * 1e3:.3f} ms")
        self._registers_at_reset()
        self.rcc.csr = (self.rcc.csr & ~RESET_FLAGS) | flags | SOURCE_FLAGS[source]
        self.held_until = self.now + hold if hold > 0 else None
        self.resets.append({"t": self.now, "source": source, "hold": hold, "idle": None})

    def _registers_at_reset(self):
        """Core, SCB/NVIC and peripherals at their reset values (SRAM untouched)."""
        for p in set(self.ptab.values()):
            p.reset()
        self.nvic.reset()
        self.ipsr = 0
        self.event = False
        self.sleeping = False
        self.halted = None
        self.held_until = None
        self.pending_reset = None
        self._next_cache = None
        self._stop_reason = None
        uc = self.uc
        sp0, pc0 = struct.unpack("<II", uc.mem_read(0, 8))
        self.sp_top = sp0
        uc.reg_write(UC_ARM_REG_SP, sp0)
        uc.reg_write(UC_ARM_REG_LR, 0xFFFFFFFF)
        uc.reg_write(UC_ARM_REG_PRIMASK, 0)
        uc.reg_write(UC_ARM_REG_BASEPRI, 0)
        uc.reg_write(UC_ARM_REG_FAULTMASK, 0)
        uc.reg_write(UC_ARM_REG_CONTROL, 0)
        uc.reg_write(UC_ARM_REG_XPSR, 0x01000000)
        self.pc = pc0 & ~1
        self._clock_update()

    def idle_reached(self):
        """The executor's WFE: the first since power-on, and the first since the last reset."""
        if self.first_idle is None:
            self.first_idle = self.now
        if self.resets and self.resets[-1]["idle"] is None:
            self.resets[-1]["idle"] = self.now
