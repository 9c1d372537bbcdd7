"""One STM32F103C8: a Cortex-M3 on unicorn plus the peripheral models, on a 72 MHz time base.

Memory map (RM0008 §3.3, Table 3; PM0056 §2.2): flash 64 KiB at 0x08000000, aliased at 0
(BOOT0 = 0), read-only; SRAM 20 KiB at 0x20000000 (nothing is mapped above 0x20005000, so an
access there faults); system memory page 0x1FFFF000 (flash size register F_SIZE at 0x1FFFF7E0
= 64, unique ID at 0x1FFFF7E8, RM0008 §30.1/§30.2); peripherals 0x40000000..0x40023FFF; the
private peripheral bus 0xE0000000.. (nvic.Scs).

Time: `now` counts ticks of 1/72 MHz. The CPU executes one instruction per HCLK cycle times
`cpi` (default 1.0: one instruction = one cycle; the F103 at 72 MHz with 2 flash wait states
averages more, scripts/m3-bench suggests ~1.5), so at HSI (8 MHz, before the PLL) an
instruction takes 9 ticks. The CPU runs in slices (`emu_start(count=N)`) that end at the next
peripheral event or the caller's limit; peripheral registers read inside a slice see the time
at the slice's start (an error below one slice). Interrupts are taken at slice boundaries
(latency up to one slice) and at exception returns (tail-chaining).

Exceptions (ARMv7-M ARM B1.5): unicorn has no NVIC, so entry (8-word frame, 8-byte alignment
with xPSR bit 9 when CCR.STKALIGN, EXC_RETURN in LR, vector from VTOR) and return (a branch to
0xFFFFFFFx, which unicorn reports as interrupt 8: pop the frame, tail-chain) are done here;
IPSR is kept by the model (unicorn's own stays 0, so it keeps running as in thread mode:
MRS IPSR reads 0 — not modelled). Only the main stack is modelled (CONTROL.SPSEL=1 is
reported). Faults: an undefined instruction (UDF: the panic handler's) is a UsageFault, an
access to unmapped memory a BusFault; both escalate to HardFault (their SHCSR enables and
priorities are honoured); a fault at priority -1 is a lock-up. A HardFault handler that is an
endless loop (cortex-m-rt's DefaultHandler) stops the board.

WFE/SEV (B1.5.18): WFE is caught by a code hook at each WFE address of the image; with the
event register set it clears it and continues, otherwise the CPU sleeps until an interrupt can
be taken (time jumps to the next peripheral event). SEV sets the event register. WFI is not in
these images (and would be treated like WFE).
"""

import ctypes
import re
import struct
import subprocess

from unicorn import (Uc, UcError, UC_ARCH_ARM, UC_MODE_THUMB, UC_MODE_MCLASS, UC_PROT_READ,
                     UC_PROT_EXEC, UC_PROT_ALL, UC_HOOK_CODE, UC_HOOK_INTR, UC_HOOK_MEM_UNMAPPED,
                     UC_HOOK_MEM_PROT, UC_ERR_INSN_INVALID, UC_ERR_READ_UNMAPPED,
                     UC_ERR_WRITE_UNMAPPED, UC_ERR_FETCH_UNMAPPED, UC_ERR_READ_PROT,
                     UC_ERR_WRITE_PROT, UC_ERR_FETCH_PROT)
from unicorn.arm_const import (UC_CPU_ARM_CORTEX_M3, UC_ARM_REG_R0, UC_ARM_REG_R1,
                               UC_ARM_REG_R2, UC_ARM_REG_R3, UC_ARM_REG_R12, UC_ARM_REG_LR,
                               UC_ARM_REG_PC, UC_ARM_REG_SP, UC_ARM_REG_XPSR,
                               UC_ARM_REG_PRIMASK, UC_ARM_REG_BASEPRI, UC_ARM_REG_CONTROL)

from . import nvic as nv
from .crc import Crc
from .dma import Dma
from .exti import Exti
from .gpio import Afio, Gpio
from .periph import Reserved
from .rcc import Rcc, Flash, Pwr
from .spi import Spi
from .tim import Timer
from .usart import Usart

FLASH_BASE, FLASH_SIZE = 0x08000000, 64 * 1024
SRAM_BASE, SRAM_SIZE = 0x20000000, 20 * 1024
SYSMEM_BASE = 0x1FFFF000
PERIPH_BASE, PERIPH_SIZE = 0x40000000, 0x24000
PPB_BASE, PPB_SIZE = 0xE0000000, 0x100000
PAINT = 0xA5
REG_FRAME = [UC_ARM_REG_R0, UC_ARM_REG_R1, UC_ARM_REG_R2, UC_ARM_REG_R3, UC_ARM_REG_R12,
             UC_ARM_REG_LR]


class Chip:
    TICK_HZ = 72_000_000

    def __init__(self, name, elf, uid=b"", cpi=1.0, log=None):
        self.name = name
        self.elf = elf
        self.cpi = cpi
        self._log = log
        self.now = 0
        self.uid = (uid + bytes(12))[:12]
        self._unmodelled_seen = set()
        self.messages = []
        uc = self.uc = Uc(UC_ARCH_ARM, UC_MODE_THUMB | UC_MODE_MCLASS)
        uc.ctl_set_cpu_model(UC_CPU_ARM_CORTEX_M3)
        self.flash = ctypes.create_string_buffer(b"\xff" * FLASH_SIZE, FLASH_SIZE)
        for paddr, _vaddr, data, _memsz in elf.segments:
            if FLASH_BASE <= paddr < FLASH_BASE + FLASH_SIZE and data:
                if paddr + len(data) > FLASH_BASE + FLASH_SIZE:
                    raise ValueError("image larger than 64 KiB of flash")
                ctypes.memmove(ctypes.addressof(self.flash) + paddr - FLASH_BASE, data, len(data))
        ptr = ctypes.addressof(self.flash)
        uc.mem_map_ptr(0, FLASH_SIZE, UC_PROT_READ | UC_PROT_EXEC, ptr)
        uc.mem_map_ptr(FLASH_BASE, FLASH_SIZE, UC_PROT_READ | UC_PROT_EXEC, ptr)
        uc.mem_map(SRAM_BASE, SRAM_SIZE, UC_PROT_ALL)
        uc.mem_map(SYSMEM_BASE, 0x1000, UC_PROT_READ)
        sysmem = bytearray(b"\xff" * 0x1000)
        sysmem[0x7E0:0x7E2] = struct.pack("<H", 64)
        sysmem[0x7E8:0x7F4] = self.uid
        uc.mem_write(SYSMEM_BASE, bytes(sysmem))
        uc.mem_map(0xFFFFF000, 0x1000, UC_PROT_READ | UC_PROT_EXEC)
        uc.mem_write(0xFFFFF000, b"\xfe\xe7" * 0x800)
        uc.mmio_map(PERIPH_BASE, PERIPH_SIZE, self._pread, None, self._pwrite, None)
        uc.mmio_map(PPB_BASE, PPB_SIZE, self._sread, None, self._swrite, None)
        self._build_peripherals()
        uc.hook_add(UC_HOOK_INTR, self._on_intr)
        uc.hook_add(UC_HOOK_MEM_UNMAPPED | UC_HOOK_MEM_PROT, self._on_bad_access)
        self._hook_instructions()
        self.reset()

    # --- set-up --------------------------------------------------------------------------
    def _build_peripherals(self):
        self.ptab = {}
        self.timed = []

        def add(p, clock=None):
            p.clock = clock
            for page in range((p.base - PERIPH_BASE) >> 10, (p.base - PERIPH_BASE + p.size) >> 10):
                self.ptab[page] = p
            return p

        self.nvic = nv.Scs(self, PPB_BASE)
        self.rcc = add(Rcc(self, 0x40021000))
        self.flashif = add(Flash(self, 0x40022000))
        self.pwr = add(Pwr(self, 0x40007000), ("APB1", 28))
        self.exti = add(Exti(self, 0x40010400))
        self.afio = add(Afio(self, 0x40010000), ("APB2", 0))
        self.gpio = [add(Gpio(self, 0x40010800 + 0x400 * i, i), ("APB2", 2 + i)) for i in range(5)]
        self.dma = add(Dma(self, 0x40020000), ("AHB", 0))
        self.crc = add(Crc(self, 0x40023000), ("AHB", 6))
        self.tim1 = add(Timer(self, 0x40012C00, "TIM1", 2,
                              {"brk": 24, "up": 25, "trg": 26, "cc": 27}), ("APB2", 11))
        self.tim2 = add(Timer(self, 0x40000000, "TIM2", 1, {"up": 28}), ("APB1", 0))
        self.tim3 = add(Timer(self, 0x40000400, "TIM3", 1, {"up": 29}), ("APB1", 1))
        self.tim4 = add(Timer(self, 0x40000800, "TIM4", 1, {"up": 30}), ("APB1", 2))
        gpa = self.gpio[0]
        self.spi1 = add(Spi(self, 0x40013000, "SPI1", 2, 35, miso_pin=(gpa, 6)), ("APB2", 12))
        self.spi1.nss_pin = (gpa, 4)
        self.usart1 = add(Usart(self, 0x40013800, "USART1", 2, 37), ("APB2", 14))
        for base, name, clk in ((0x40002800, "RTC", None), (0x40002C00, "WWDG", ("APB1", 11)),
                                (0x40003000, "IWDG", None), (0x40003800, "SPI2", ("APB1", 14)),
                                (0x40004400, "USART2", ("APB1", 17)),
                                (0x40004800, "USART3", ("APB1", 18)),
                                (0x40005400, "I2C1", ("APB1", 21)), (0x40005800, "I2C2", ("APB1", 22)),
                                (0x40005C00, "USB", ("APB1", 23)), (0x40006400, "CAN", ("APB1", 25)),
                                (0x40006C00, "BKP", ("APB1", 27)),
                                (0x40012400, "ADC1", ("APB2", 9)), (0x40012800, "ADC2", ("APB2", 10))):
            add(Reserved(self, base, name), clk)
        # DMA1 request lines (RM0008 Table 78), the ones with a model
        self.dma.connect(2, self.spi1, "rx")
        self.dma.connect(3, self.spi1, "tx")
        self.dma.connect(4, self.usart1, "tx")
        self.dma.connect(5, self.usart1, "rx")
        self.timed = [self.tim1, self.tim2, self.tim3, self.tim4, self.usart1, self.spi1, self.nvic]
        self.resettable = {("APB2", 0): self.afio, ("APB2", 11): self.tim1,
                           ("APB2", 12): self.spi1, ("APB2", 14): self.usart1,
                           ("APB1", 0): self.tim2, ("APB1", 1): self.tim3, ("APB1", 2): self.tim4}
        for i in range(5):
            self.resettable[("APB2", 2 + i)] = self.gpio[i]

    def _hook_instructions(self):
        """Code hooks on single addresses: WFE/WFI/SEV, and the panic entry points."""
        self.wfe_addrs, self.sev_addrs = [], []
        dis = subprocess.run(["/usr/bin/llvm-objdump", "-d", "--no-show-raw-insn", self.elf.path],
                             capture_output=True, text=True).stdout
        for m in re.finditer(r"^\s*([0-9a-f]+):\s+(wfe|wfi|sev)(\.w)?\s*$", dis, re.M):
            a = int(m.group(1), 16)
            size = 4 if m.group(3) else 2
            if m.group(2) == "sev":
                self.sev_addrs.append(a)
                self.uc.hook_add(UC_HOOK_CODE, self._on_sev, size, a, a)
            else:
                self.wfe_addrs.append(a)
                self.uc.hook_add(UC_HOOK_CODE, self._on_wfe, size, a, a)
        self.panic_entries = {}
        for name, addr in self.elf.symbols.items():
            if ("rust_begin_unwind" in name or name == "_defmt_panic" or "panicking" in name
                    or "panic_already_borrowed" in name or "len_mismatch_fail" in name
                    or "slice_index_fail" in name or "slice_end_index" in name
                    or "slice_start_index" in name) and FLASH_BASE <= addr < FLASH_BASE + FLASH_SIZE:
                a = addr & ~1
                if a not in self.panic_entries:
                    self.panic_entries[a] = a
                    self.uc.hook_add(UC_HOOK_CODE, self._on_panic_entry, a, a, a)
        self.default_handler = (self.elf.sym("DefaultHandler") or 0) & ~1

    def reset(self):
        uc = self.uc
        uc.mem_write(SRAM_BASE, bytes([PAINT]) * SRAM_SIZE)    # power-on garbage / stack paint
        for p in set(self.ptab.values()):
            p.reset()
        self.nvic.reset()
        self.ipsr = 0
        self.event = False
        self.sleeping = False
        self.halted = None
        self.faults = []
        self.panics = []
        self.first_idle = None
        self.instructions = 0
        self.busy_ticks = 0
        self.sleeps = 0
        self.exceptions = 0
        self.sp_min = 0xFFFFFFFF
        self.pending_reset = None
        self._next_cache = None
        self._stop_reason = None
        sp0, pc0 = struct.unpack("<II", uc.mem_read(0, 8))
        self.sp_top = sp0
        uc.reg_write(UC_ARM_REG_SP, sp0)
        uc.reg_write(UC_ARM_REG_LR, 0xFFFFFFFF)
        uc.reg_write(UC_ARM_REG_PRIMASK, 0)
        uc.reg_write(UC_ARM_REG_CONTROL, 0)
        uc.reg_write(UC_ARM_REG_XPSR, 0x01000000)
        self.pc = pc0 & ~1
        self._clock_update()

    # --- clocks --------------------------------------------------------------------------
    def _clock_update(self):
        snap = self.rcc.snapshot()
        self.hclk = snap["hclk"]
        self.pclk = snap["pclk"]
        self.timclk = snap["timclk"]
        self.tpi = self.TICK_HZ / self.hclk * self.cpi      # ticks per instruction

    def clock_changed(self):
        for p in self.timed:
            p.sync(self.now)
        self._clock_update()
        self.reschedule()

    def ticks_per_hclk(self):
        return self.TICK_HZ // self.hclk

    def cycles(self):
        return int(self.now / (self.TICK_HZ / self.hclk))

    # --- logging -------------------------------------------------------------------------
    def log(self, msg):
        line = f"[{self.name} {self.now / self.TICK_HZ * 1e3:10.4f} ms] {msg}"
        self.messages.append(line)
        if self._log:
            self._log(line)

    def unmodelled(self, p, off, what):
        key = (p.name, off, what)
        if key not in self._unmodelled_seen:
            self._unmodelled_seen.add(key)
            self.log(f"unmodelled {what} of {p.name}+{off:#x} at pc {self.pc_now():#x}")

    def pc_now(self):
        return self.uc.reg_read(UC_ARM_REG_PC)

    # --- bus -------------------------------------------------------------------------------
    def clock_on(self, p):
        c = p.clock
        if c is None:
            return True
        r = self.rcc
        return ((r.ahbenr if c[0] == "AHB" else r.apb1enr if c[0] == "APB1" else r.apb2enr) >> c[1]) & 1

    def _pread(self, uc, off, size, _ud):
        p = self.ptab.get(off >> 10)
        shift = (off & 3) * 8
        if p is None:
            self.unmodelled(Reserved(self, PERIPH_BASE + (off & ~0x3FF), "reserved"), off & 0x3FF, "read")
            return 0
        if not self.clock_on(p):
            self.unmodelled(p, off & 0x3FF, "read (clock off)")
            return 0
        return (p.read((off - (p.base - PERIPH_BASE)) & ~3) >> shift) & ((1 << (8 * size)) - 1)

    def _pwrite(self, uc, off, size, value, _ud):
        p = self.ptab.get(off >> 10)
        if p is None:
            self.unmodelled(Reserved(self, PERIPH_BASE + (off & ~0x3FF), "reserved"), off & 0x3FF, "write")
            return
        if not self.clock_on(p):
            self.unmodelled(p, off & 0x3FF, "write (clock off)")
            return
        shift = (off & 3) * 8
        mask = ((1 << (8 * size)) - 1) << shift
        p.write((off - (p.base - PERIPH_BASE)) & ~3, (value << shift) & mask, mask)

    def _sread(self, uc, off, size, _ud):
        shift = (off & 3) * 8
        return (self.nvic.read(off & ~3) >> shift) & ((1 << (8 * size)) - 1)

    def _swrite(self, uc, off, size, value, _ud):
        shift = (off & 3) * 8
        mask = ((1 << (8 * size)) - 1) << shift
        self.nvic.write(off & ~3, (value << shift) & mask, mask)

    def bus_read(self, addr, size):
        """A bus master's read (DMA): memory or peripheral."""
        if PERIPH_BASE <= addr < PERIPH_BASE + PERIPH_SIZE:
            return self._pread(self.uc, addr - PERIPH_BASE, size, None)
        if not (SRAM_BASE <= addr < SRAM_BASE + SRAM_SIZE or FLASH_BASE <= addr < FLASH_BASE + FLASH_SIZE
                or addr < FLASH_SIZE):
            raise ValueError(f"bus error at {addr:#x}")
        return int.from_bytes(self.uc.mem_read(addr, size), "little")

    def bus_write(self, addr, size, value):
        if PERIPH_BASE <= addr < PERIPH_BASE + PERIPH_SIZE:
            self._pwrite(self.uc, addr - PERIPH_BASE, size, value, None)
            return
        if not SRAM_BASE <= addr < SRAM_BASE + SRAM_SIZE:
            raise ValueError(f"bus error at {addr:#x}")
        self.uc.mem_write(addr, value.to_bytes(size, "little"))

    def read32(self, addr):
        return struct.unpack("<I", self.uc.mem_read(addr, 4))[0]

    # --- scheduling ----------------------------------------------------------------------
    def reschedule(self):
        self._next_cache = None

    def irq_changed(self):
        pass

    def next_event(self):
        if self._next_cache is None:
            best = None
            for p in self.timed:
                t = p.next_event()
                if t is not None and (best is None or t < best):
                    best = t
            self._next_cache = (best,)
        return self._next_cache[0]

    def reset_peripheral(self, bus, bit):
        p = self.resettable.get((bus, bit))
        if p is not None:
            p.reset()
            self.reschedule()

    def request_reset(self, why):
        self.pending_reset = why

    # --- running -------------------------------------------------------------------------
    def run_until(self, t_end):
        uc = self.uc
        while self.now < t_end and self.halted is None:
            now = self.now
            nxt = self.next_event()
            if nxt is not None and nxt <= now:
                for p in self.timed:
                    p.sync(now)
                self.dma.kick()
                self.reschedule()
                nxt = self.next_event()
                if nxt is not None and nxt <= now:
                    nxt = now + 1
            self._service()
            if self.halted is not None:
                break
            limit = t_end if nxt is None or nxt > t_end else nxt
            if self.sleeping:
                self.now = limit
                continue
            n = int((limit - now) / self.tpi)
            if n < 1:
                n = 1
            self._stop_reason = None
            try:
                uc.emu_start(self.pc | 1, 0, count=n)
            except UcError as e:
                self._uc_fault(e)
            self.pc = uc.reg_read(UC_ARM_REG_PC)
            sp = uc.reg_read(UC_ARM_REG_SP)
            if sp < self.sp_min:
                self.sp_min = sp
            dt = n * self.tpi
            if self._stop_reason == "sleep":
                self.instructions += n // 2              # where in the slice it slept: unknown
                self.busy_ticks += dt / 2
            else:
                self.instructions += n
                self.busy_ticks += dt
            self.now = max(limit, int(now + dt)) if self._stop_reason is None else limit
            if self.pending_reset:
                self.log(f"system reset ({self.pending_reset})")
                self.reset()

    def _service(self):
        """At a slice boundary: take an interrupt that can be taken."""
        nv_ = self.nvic
        if nv_.pending and nv_.takeable(0, 0) is not None:
            uc = self.uc
            primask = uc.reg_read(UC_ARM_REG_PRIMASK)
            basepri = uc.reg_read(UC_ARM_REG_BASEPRI) if not primask else 0
            e = nv_.takeable(primask, basepri)
            if e is not None:
                if self.sleeping:
                    self.sleeping = False
                self._enter(e, self.pc)
                self.pc = uc.reg_read(UC_ARM_REG_PC) & ~1

    def wake_time(self, limit):
        """When this board next needs the CPU, if it sleeps now (else its own time)."""
        if not self.sleeping or self.halted is not None:
            return self.now if self.halted is None else limit
        if self.nvic.pending and self.nvic.takeable(0, 0) is not None:
            return self.now
        t = self.next_event()
        return limit if t is None or t > limit else max(t, self.now)

    # --- exceptions ----------------------------------------------------------------------
    def _enter(self, exc, ret_pc):
        """Exception entry (B1.5.6): push the frame, EXC_RETURN in LR, jump to the vector."""
        uc = self.uc
        vals = uc.reg_read_batch(REG_FRAME + [UC_ARM_REG_XPSR, UC_ARM_REG_SP, UC_ARM_REG_CONTROL])
        r0, r1, r2, r3, r12, lr, xpsr, sp, control = vals
        if control & 2:
            self.log("CONTROL.SPSEL=1 (process stack): not modelled")
        xpsr = (xpsr & ~0x1FF) | self.ipsr
        align = (sp >> 2) & 1 if self.nvic.ccr & 0x200 else 0
        frame = ((sp - 0x20) & ~(align << 2)) & 0xFFFFFFFF
        self.exceptions += 1
        if not (SRAM_BASE <= frame and frame + 0x20 <= SRAM_BASE + SRAM_SIZE):
            self._lockup(f"stacking for {nv.exc_name(exc)} at SP {frame:#x}: outside SRAM (MSP overflow)", ret_pc)
            return
        uc.mem_write(frame, struct.pack("<8I", r0, r1, r2, r3, r12, lr, ret_pc & ~1,
                                        (xpsr & ~(1 << 9)) | (align << 9)))
        exc_return = 0xFFFFFFF1 if self.ipsr else 0xFFFFFFF9
        vector = self.read32((self.nvic.vtor + 4 * exc) & 0xFFFFFFFF)
        self.ipsr = exc
        self.nvic.activate(exc)
        self.event = True                           # wake-up event (WFE returns)
        uc.reg_write_batch([(UC_ARM_REG_SP, frame), (UC_ARM_REG_LR, exc_return),
                            (UC_ARM_REG_XPSR, (xpsr & 0xF8000000) | 0x01000000),
                            (UC_ARM_REG_PC, vector | 1)])
        if sp < self.sp_min:
            self.sp_min = frame
        if exc == nv.HARDFAULT and (vector & ~1) == self.default_handler:
            self.halted = f"in HardFault handler ({self.elf.name_of(vector)}: an endless loop)"

    def _on_intr(self, uc, intno, _ud):
        if intno != 8:                              # not an exception return
            self._stop_reason = f"cpu exception {intno}"
            self._fault_pending = ("UsageFault", f"CPU exception {intno}")
            uc.emu_stop()
            return
        exc_return = uc.reg_read(UC_ARM_REG_PC) | 1
        sp = uc.reg_read(UC_ARM_REG_SP)
        ret = self.ipsr
        self.nvic.deactivate(ret)
        r0, r1, r2, r3, r12, lr, pc, psr = struct.unpack("<8I", uc.mem_read(sp, 0x20))
        sp_new = sp + 0x20 + (4 if (psr >> 9) & 1 and self.nvic.ccr & 0x200 else 0)
        self.ipsr = psr & 0x1FF
        if bool(exc_return & 8) != (self.ipsr == 0):
            self.log(f"exception return {exc_return:#x} with stacked IPSR {self.ipsr}: INVPC")
        uc.reg_write_batch([(UC_ARM_REG_R0, r0), (UC_ARM_REG_R1, r1), (UC_ARM_REG_R2, r2),
                            (UC_ARM_REG_R3, r3), (UC_ARM_REG_R12, r12), (UC_ARM_REG_LR, lr),
                            (UC_ARM_REG_SP, sp_new),
                            (UC_ARM_REG_XPSR, (psr & ~0x3FF) | 0x01000000)])
        # tail-chain (B1.5.12): another exception that can be taken now
        if self.nvic.pending:
            primask, basepri = uc.reg_read_batch([UC_ARM_REG_PRIMASK, UC_ARM_REG_BASEPRI])
            e = self.nvic.takeable(primask, basepri)
            if e is not None:
                self._enter(e, pc)
                if self.halted:
                    uc.emu_stop()
                return
        uc.reg_write(UC_ARM_REG_PC, pc | 1)

    def _on_wfe(self, uc, addr, size, _ud):
        if self.event:
            self.event = False
            uc.reg_write(UC_ARM_REG_PC, (addr + size) | 1)
            return
        if self.first_idle is None:
            self.first_idle = self.now
        self.sleeping = True
        self.sleeps += 1
        self._stop_reason = "sleep"
        uc.reg_write(UC_ARM_REG_PC, (addr + size) | 1)
        uc.emu_stop()

    def _on_sev(self, uc, addr, size, _ud):
        self.event = True
        uc.reg_write(UC_ARM_REG_PC, (addr + size) | 1)

    def _on_panic_entry(self, uc, addr, _size, name):
        lr, sp = uc.reg_read_batch([UC_ARM_REG_LR, UC_ARM_REG_SP])
        if len(self.panics) < 8:
            self.panics.append({"entry": " / ".join(self.elf.aliases.get(name, [hex(name)])), "caller": (lr & ~1) - 4, "sp": sp, "t": self.now})
            if sp < self.sp_min:
                self.sp_min = sp

    def _on_bad_access(self, uc, access, addr, size, value, _ud):
        self._bad_access = (access, addr, size)
        return False

    _bad_access = None
    _fault_pending = None

    def _uc_fault(self, e):
        pc = self.uc.reg_read(UC_ARM_REG_PC) & ~1
        sp = self.uc.reg_read(UC_ARM_REG_SP)
        if sp < self.sp_min:
            self.sp_min = sp
        if e.errno == UC_ERR_INSN_INVALID:
            kind, cfsr_bit, exc = "UsageFault (undefined instruction)", 1 << 16, nv.USAGEFAULT
            ins = struct.unpack("<H", self.uc.mem_read(pc, 2))[0]
            if ins & 0xFF00 == 0xDE00:
                kind = f"UsageFault (UDF #{ins & 0xFF})"
        elif e.errno in (UC_ERR_READ_UNMAPPED, UC_ERR_WRITE_UNMAPPED, UC_ERR_READ_PROT,
                         UC_ERR_WRITE_PROT):
            acc = self._bad_access
            where = f" at {acc[1]:#010x}" if acc else ""
            kind, cfsr_bit, exc = f"BusFault (precise data access{where})", 1 << 9, nv.BUSFAULT
            if acc:
                self.nvic.bfar = acc[1]
                cfsr_bit |= 1 << 15
        elif e.errno in (UC_ERR_FETCH_UNMAPPED, UC_ERR_FETCH_PROT):
            kind, cfsr_bit, exc = "BusFault (instruction fetch)", 1 << 8, nv.BUSFAULT
        elif self._fault_pending:
            kind, cfsr_bit, exc = self._fault_pending[1], 0, nv.USAGEFAULT
        else:
            kind, cfsr_bit, exc = f"unicorn error: {e}", 0, nv.HARDFAULT
        self._bad_access = None
        self._fault_pending = None
        self.nvic.cfsr |= cfsr_bit
        self._stop_reason = "fault"
        rec = {"kind": kind, "pc": pc, "t": self.now, "sp": sp, "symbol": self.elf.name_of(pc)}
        self.faults.append(rec)
        self.log(f"{kind} at pc {pc:#x} <{rec['symbol']}>, sp {sp:#x}")
        # escalation (B1.5.5): the configurable fault if enabled and its priority is higher
        primask, basepri = self.uc.reg_read_batch([UC_ARM_REG_PRIMASK, UC_ARM_REG_BASEPRI])
        exec_prio = self.nvic.execution_priority(0, 0)
        enabled_bit = {nv.MEMMANAGE: 16, nv.BUSFAULT: 17, nv.USAGEFAULT: 18}.get(exc)
        if exc != nv.HARDFAULT and enabled_bit is not None and (self.nvic.shcsr >> enabled_bit) & 1 \
                and self.nvic.group(self.nvic.priority(exc)) < exec_prio:
            target = exc
        else:
            target = nv.HARDFAULT
            self.nvic.hfsr |= 1 << 30           # FORCED
        if self.nvic.execution_priority(0, 0) <= -1:
            self._lockup(f"{kind} inside HardFault/NMI", pc)
            return
        self._enter(target, pc)
        self.pc = self.uc.reg_read(UC_ARM_REG_PC) & ~1

    def _lockup(self, why, pc):
        self.halted = f"lock-up: {why}"
        self.faults.append({"kind": "lock-up", "pc": pc, "t": self.now, "sp": self.uc.reg_read(UC_ARM_REG_SP),
                            "symbol": self.elf.name_of(pc)})
        self.log(self.halted)

    # --- reports -------------------------------------------------------------------------
    def stack_report(self):
        """(used, room, overflowed) from the paint between _stack_end and the initial SP."""
        lo = self.elf.sym("_stack_end", SRAM_BASE)
        hi = self.sp_top
        data = bytes(self.uc.mem_read(lo, hi - lo))
        i = 0
        while i < len(data) and data[i] == PAINT:
            i += 1
        used = len(data) - i
        return used, hi - lo, i == 0

    def default_handler_lines(self):
        out = []
        for n in sorted(set(self.nvic.ever_enabled)):
            v = self.read32(self.nvic.vtor + 4 * (16 + n)) & ~1
            if v == self.default_handler:
                out.append((n, nv.IRQ_NAMES[n], self.nvic.enabled[n]))
        return out
