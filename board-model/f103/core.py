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
peripheral event or the caller's limit. A peripheral register read or written inside a slice
sees the time of the instruction doing it (`ucfast.counter_offset`: unicorn's own instruction
counter; without it, the time at the slice's start). Interrupts are taken at slice boundaries
(latency up to one slice; one that a register access raises ends the slice after it,
`irq_changed`) and at exception returns (tail-chaining).

Exceptions, faults, WFE/SEV and the panic hooks: exceptions.py.
"""

import ctypes
import re
import struct
import subprocess

from unicorn import (
    Uc,
    UcError,
    UC_ARCH_ARM,
    UC_MODE_THUMB,
    UC_MODE_MCLASS,
    UC_PROT_READ,
    UC_PROT_EXEC,
    UC_PROT_ALL,
    UC_HOOK_INTR,
    UC_HOOK_MEM_UNMAPPED,
    UC_HOOK_MEM_PROT,
)
from unicorn.arm_const import (
    UC_CPU_ARM_CORTEX_M3,
    UC_ARM_REG_PC,
)

from . import native
from . import nvic as nv
from .crc import Crc, crc32_word_fast
from .dma import Dma
from .elf import need_tool
from .exceptions import ExceptionModel, REGS_MASKS, REGS_PC_SP
from .exti import Exti
from .gpio import Afio, Gpio
from .memmap import (
    FLASH_BASE,
    FLASH_SIZE,
    SRAM_BASE,
    SRAM_SIZE,
    SYSMEM_BASE,
    PERIPH_BASE,
    PERIPH_SIZE,
    PPB_BASE,
    PPB_SIZE,
)
from .periph import Reserved
from .rcc import Rcc, Flash, Pwr
from .reset import PAINT, ResetModel
from .spi import Spi
from .tim import Timer
from .ucfast import FastUc
from .usart import Usart

SIZE_MASK = {1: 0xFF, 2: 0xFFFF, 4: 0xFFFFFFFF}


class Chip(ExceptionModel, ResetModel):
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
        self._in_slice = False
        self.fast = FastUc(uc, clock=self)
        self._build_peripherals()
        self._map_bus()
        uc.hook_add(UC_HOOK_INTR, self._on_intr)
        uc.hook_add(UC_HOOK_MEM_UNMAPPED | UC_HOOK_MEM_PROT, self._on_bad_access)
        self._hook_instructions()
        self.power_on()

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
        self.tim1 = add(
            Timer(self, 0x40012C00, "TIM1", 2, {"brk": 24, "up": 25, "trg": 26, "cc": 27}),
            ("APB2", 11),
        )
        self.tim2 = add(Timer(self, 0x40000000, "TIM2", 1, {"up": 28}), ("APB1", 0))
        self.tim3 = add(Timer(self, 0x40000400, "TIM3", 1, {"up": 29}), ("APB1", 1))
        self.tim4 = add(Timer(self, 0x40000800, "TIM4", 1, {"up": 30}), ("APB1", 2))
        gpa = self.gpio[0]
        self.spi1 = add(Spi(self, 0x40013000, "SPI1", 2, 35, miso_pin=(gpa, 6)), ("APB2", 12))
        self.spi1.nss_pin = (gpa, 4)
        self.usart1 = add(Usart(self, 0x40013800, "USART1", 2, 37), ("APB2", 14))
        for base, name, clk in (
            (0x40002800, "RTC", None),
            (0x40002C00, "WWDG", ("APB1", 11)),
            (0x40003000, "IWDG", None),
            (0x40003800, "SPI2", ("APB1", 14)),
            (0x40004400, "USART2", ("APB1", 17)),
            (0x40004800, "USART3", ("APB1", 18)),
            (0x40005400, "I2C1", ("APB1", 21)),
            (0x40005800, "I2C2", ("APB1", 22)),
            (0x40005C00, "USB", ("APB1", 23)),
            (0x40006400, "CAN", ("APB1", 25)),
            (0x40006C00, "BKP", ("APB1", 27)),
            (0x40012400, "ADC1", ("APB2", 9)),
            (0x40012800, "ADC2", ("APB2", 10)),
        ):
            add(Reserved(self, base, name), clk)
        # DMA1 request lines (RM0008 Table 78), the ones with a model
        self.dma.connect(2, self.spi1, "rx")
        self.dma.connect(3, self.spi1, "tx")
        self.dma.connect(4, self.usart1, "tx")
        self.dma.connect(5, self.usart1, "rx")
        self.timed = [self.tim1, self.tim2, self.tim3, self.tim4, self.usart1, self.spi1, self.nvic]
        self._route_timer_inputs()
        self.resettable = {
            ("APB2", 0): self.afio,
            ("APB2", 11): self.tim1,
            ("APB2", 12): self.spi1,
            ("APB2", 14): self.usart1,
            ("APB1", 0): self.tim2,
            ("APB1", 1): self.tim3,
            ("APB1", 2): self.tim4,
        }
        for i in range(5):
            self.resettable[("APB2", 2 + i)] = self.gpio[i]

    def _route_timer_inputs(self):
        """Pin levels to the encoder inputs TI1/TI2 of TIM2 (PA0/PA1) and TIM1 (PA8/PA9): the
        mapping of AFIO_MAPR's TIM2_REMAP 00 or 10 and TIM1_REMAP 00 or 01 (RM0008 §9.3.7,
        Tables 43 and 44); with another remap these pins are not the timers' inputs."""
        gpa, afio = self.gpio[0], self.afio

        def route(timer, ch, remap_shift, remaps):
            def edge(level):
                if (afio.mapr >> remap_shift) & 3 in remaps:
                    timer.encoder_edge(ch, level)

            return edge

        gpa.listen(0, route(self.tim2, 0, 8, (0, 2)))
        gpa.listen(1, route(self.tim2, 1, 8, (0, 2)))
        gpa.listen(8, route(self.tim1, 0, 6, (0, 1)))
        gpa.listen(9, route(self.tim1, 1, 6, (0, 1)))

    def _map_bus(self):
        """Each modelled peripheral on an MMIO range of its own, with callbacks bound to it (no
        look-up per access: the images make hundreds of thousands a second); the reserved pages
        between them, and the private peripheral bus, on the generic handlers."""
        self.native_pages = []  # (peripheral, its native.Page)
        for p in {id(p): p for p in self.ptab.values()}.values():
            page = None
            if self.fast.native is not None and hasattr(p, "attach_native"):
                page = native.Page()
                p.attach_native(page)
                self.native_pages.append((p, page))
            self.fast.mmio_map(p.base, p.size, self._reader(p), self._writer(p), page)
        npages = PERIPH_SIZE >> 10
        page = 0
        while page < npages:
            if page in self.ptab:
                page += 1
                continue
            start = page
            while page < npages and page not in self.ptab:
                page += 1
            off0 = start << 10
            self.fast.mmio_map(
                PERIPH_BASE + off0,
                (page - start) << 10,
                lambda off, size, o=off0: self._pread(None, o + off, size, None),
                lambda off, size, v, o=off0: self._pwrite(None, o + off, size, v, None),
            )
        self.fast.mmio_map(PPB_BASE, PPB_SIZE, self._sread, self._swrite)

    def _enable(self, p):
        """(RCC enable register's attribute name, bit) of `p`'s clock, or (None, 0)."""
        if p.clock is None:
            return None, 0
        return {"AHB": "ahbenr", "APB1": "apb1enr", "APB2": "apb2enr"}[p.clock[0]], p.clock[1]

    def _reader(self, p):
        read, name, rcc = p.read, p.name, self.rcc
        enr, bit = self._enable(p)

        def on_read(off, size):
            if enr and not (getattr(rcc, enr) >> bit) & 1:
                self.unmodelled(p, off & 0x3FF, "read (clock off)")
                return 0
            return (read(off & ~3) >> ((off & 3) * 8)) & SIZE_MASK[size]

        on_read.__name__ = f"read_{name}"  # for profiles
        return on_read

    def _writer(self, p):
        if p is self.crc:
            return self._crc_writer()
        return self._generic_writer(p)

    def _generic_writer(self, p):
        write, name, rcc = p.write, p.name, self.rcc
        enr, bit = self._enable(p)

        def on_write(off, size, value):
            if enr and not (getattr(rcc, enr) >> bit) & 1:
                self.unmodelled(p, off & 0x3FF, "write (clock off)")
                return
            shift = (off & 3) * 8
            mask = SIZE_MASK[size] << shift
            write(off & ~3, (value << shift) & mask, mask)

        on_write.__name__ = f"write_{name}"
        return on_write

    def _crc_writer(self):
        """The CRC unit's writes: a word to DR (the images' CRC-32 loop, a write per word)
        straight to the calculation; anything else through `Crc.write`."""
        crc, rcc, word = self.crc, self.rcc, crc32_word_fast
        generic = self._generic_writer(crc)

        def on_write_crc(off, size, value):
            if off == 0 and size == 4 and rcc.ahbenr & 0x40:
                crc.dr = word(crc.dr, value)
            else:
                generic(off, size, value)

        return on_write_crc

    def _hook_instructions(self):
        """Traps at single addresses: WFE/WFI/SEV, and the panic entry points.

        Not unicorn code hooks: with `emu_start(count=N)` every instruction runs unicorn's
        code-hook helper, which walks every code hook's range, so each single-address hook
        slowed every instruction (7 of them: about 5x). Instead the instruction in the flash
        image is replaced by a BKPT (unicorn reports it as interrupt 7, PC on it) that the
        model handles in `_on_intr`; the firmware never reads its own code (nothing in it
        checksums the flash), so the patch is not visible to it."""
        self.wfe_addrs, self.sev_addrs = [], []
        self.traps = {}  # address -> (handler, size of the original instruction)
        dis = subprocess.run(
            [need_tool("llvm-objdump"), "-d", "--no-show-raw-insn", self.elf.path],
            capture_output=True,
            text=True,
            check=True,
        ).stdout
        for m in re.finditer(r"^\s*([0-9a-f]+):\s+(wfe|wfi|sev)(\.w)?\s*$", dis, re.M):
            a = int(m.group(1), 16)
            size = 4 if m.group(3) else 2
            if m.group(2) == "sev":
                self.sev_addrs.append(a)
                self._trap(a, size, self._on_sev)
            else:
                self.wfe_addrs.append(a)
                self._trap(a, size, self._on_wfe)
        self.panic_entries = {}
        for name, addr in self.elf.symbols.items():
            if (
                "rust_begin_unwind" in name
                or name == "_defmt_panic"
                or "panicking" in name
                or "panic_already_borrowed" in name
                or "len_mismatch_fail" in name
                or "slice_index_fail" in name
                or "slice_end_index" in name
                or "slice_start_index" in name
            ) and FLASH_BASE <= addr < FLASH_BASE + FLASH_SIZE:
                a = addr & ~1
                if a not in self.panic_entries:
                    self.panic_entries[a] = a
                    self._trap(a, 2, self._on_panic_entry)
        self.default_handler = (self.elf.sym("DefaultHandler") or 0) & ~1

    # --- clocks --------------------------------------------------------------------------
    def _clock_update(self):
        snap = self.rcc.snapshot()
        self.hclk = snap["hclk"]
        self.pclk = snap["pclk"]
        self.timclk = snap["timclk"]
        self.tpi = self.TICK_HZ / self.hclk * self.cpi  # ticks per instruction
        self.gates_changed()
        for p in (self.tim1, self.tim2, self.tim3, self.tim4):
            p._publish()  # its clock's divider

    def gates_changed(self):
        """An RCC clock enable changed: the native fast path answers only while one is on."""
        for p, page in getattr(self, "native_pages", ()):
            page.gate_on = 1 if self.clock_on(p) else 0

    def clock_changed(self):
        for p in self.timed:
            p.sync(self.now)
        self._clock_update()
        self.reschedule()
        if self._in_slice and self.fast.limit is not None:
            # The slice's instructions were timed at the old rate: end it after this one, so
            # the next runs at the new rate (run_until accounts for it at the old).
            self.fast.limit.value = self.fast.counter.value

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
        return (
            (r.ahbenr if c[0] == "AHB" else r.apb1enr if c[0] == "APB1" else r.apb2enr) >> c[1]
        ) & 1

    def _pread(self, uc, off, size, _ud):
        p = self.ptab.get(off >> 10)
        shift = (off & 3) * 8
        if p is None:
            self.unmodelled(
                Reserved(self, PERIPH_BASE + (off & ~0x3FF), "reserved"), off & 0x3FF, "read"
            )
            return 0
        if not self.clock_on(p):
            self.unmodelled(p, off & 0x3FF, "read (clock off)")
            return 0
        return (p.read((off - (p.base - PERIPH_BASE)) & ~3) >> shift) & ((1 << (8 * size)) - 1)

    def _pwrite(self, uc, off, size, value, _ud):
        p = self.ptab.get(off >> 10)
        if p is None:
            self.unmodelled(
                Reserved(self, PERIPH_BASE + (off & ~0x3FF), "reserved"), off & 0x3FF, "write"
            )
            return
        if not self.clock_on(p):
            self.unmodelled(p, off & 0x3FF, "write (clock off)")
            return
        shift = (off & 3) * 8
        mask = ((1 << (8 * size)) - 1) << shift
        p.write((off - (p.base - PERIPH_BASE)) & ~3, (value << shift) & mask, mask)

    def _sread(self, off, size):
        shift = (off & 3) * 8
        return (self.nvic.read(off & ~3) >> shift) & ((1 << (8 * size)) - 1)

    def _swrite(self, off, size, value):
        shift = (off & 3) * 8
        mask = ((1 << (8 * size)) - 1) << shift
        self.nvic.write(off & ~3, (value << shift) & mask, mask)

    def bus_read(self, addr, size):
        """A bus master's read (DMA): memory or peripheral."""
        if PERIPH_BASE <= addr < PERIPH_BASE + PERIPH_SIZE:
            return self._pread(self.uc, addr - PERIPH_BASE, size, None)
        if not (
            SRAM_BASE <= addr < SRAM_BASE + SRAM_SIZE
            or FLASH_BASE <= addr < FLASH_BASE + FLASH_SIZE
            or addr < FLASH_SIZE
        ):
            raise ValueError(f"bus error at {addr:#x}")
        return int.from_bytes(self.fast.read(addr, size), "little")

    def bus_write(self, addr, size, value):
        if PERIPH_BASE <= addr < PERIPH_BASE + PERIPH_SIZE:
            self._pwrite(self.uc, addr - PERIPH_BASE, size, value, None)
            return
        if not SRAM_BASE <= addr < SRAM_BASE + SRAM_SIZE:
            raise ValueError(f"bus error at {addr:#x}")
        self.fast.write(addr, value.to_bytes(size, "little"))

    def read32(self, addr):
        return struct.unpack("<I", self.fast.read(addr, 4))[0]

    # --- scheduling ----------------------------------------------------------------------
    def reschedule(self):
        self._next_cache = None

    def irq_changed(self):
        """An interrupt was pended. Inside a slice (a register access made it: a write that
        completed a DMA transfer, set a pending bit, ...), one the CPU can take now ends the
        slice after the running instruction, so it is taken at its instruction, not at the
        slice's end. (One pended while masked still waits for the slice's end: the CPU
        unmasks without a register access.)"""
        fast = self.fast
        if self._in_slice and fast.limit is not None and self._takeable_now() is not None:
            fast.limit.value = fast.counter.value

    def _takeable_now(self):
        """The exception the CPU takes at its next instruction, with PRIMASK and BASEPRI as they
        are, or None. (Most of the time nothing is pending, or nothing would be taken even
        unmasked: then the core's registers are not read.)"""
        nv_ = self.nvic
        if not nv_.pending or nv_.takeable(0, 0) is None:
            return None
        primask, basepri = self.fast.regs(REGS_MASKS)
        return nv_.takeable(primask, basepri)

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
            if self.held_until is not None:  # NRST low: nothing runs (reset.py)
                if self.now < self.held_until:
                    self.now = min(t_end, self.held_until)
                    continue
                self.held_until = None
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
            fast = self.fast
            # The slice's rate: a clock switch inside it changes self.tpi (and ends it).
            tpi = self.tpi
            fast.set_slice(now, tpi)
            self._in_slice = True
            try:
                uc.emu_start(self.pc | 1, 0, count=n)
            except UcError as e:
                self._uc_fault(e)
            finally:
                self._in_slice = False
            self.pc, sp = fast.regs(REGS_PC_SP)
            if sp < self.sp_min:
                self.sp_min = sp
            if self._stop_reason is None and fast.counter is not None:
                # Its limit ended it (a run reads one past its last instruction): n, or fewer
                # when something cut it (irq_changed, clock_changed).
                ran = max(0, min(fast.counter.value - 1, n))
                if ran < n:
                    n, limit = ran, int(now + ran * tpi)
            dt = n * tpi
            if self._stop_reason is None:
                self.instructions += n
                self.busy_ticks += dt
            elif fast.counter is not None:
                # Stopped early (a sleep, a trap): the counter says how many ran, the one
                # that stopped it included (a run stopped by its limit reads n + 1).
                ran = min(fast.counter.value, n)
                self.instructions += ran
                self.busy_ticks += ran * tpi
            else:
                self.instructions += n // 2  # where in the slice it stopped: unknown
                self.busy_ticks += dt / 2
            self.now = max(limit, int(now + dt)) if self._stop_reason is None else limit
            if self.pending_reset:
                self.system_reset(self.pending_reset)

    def _service(self):
        """At a slice boundary: take an interrupt that can be taken."""
        e = self._takeable_now()
        if e is not None:
            self.sleeping = False
            self._enter(e, self.pc)
            self.pc = self.fast.reg(UC_ARM_REG_PC) & ~1

    def wake_time(self, limit):
        """When this board next needs the CPU, if it sleeps now (else its own time)."""
        if self.held_until is not None and self.halted is None:
            return min(limit, max(self.held_until, self.now))
        if not self.sleeping or self.halted is not None:
            return self.now if self.halted is None else limit
        if self.nvic.pending and self.nvic.takeable(0, 0) is not None:
            return self.now
        t = self.next_event()
        return limit if t is None or t > limit else max(t, self.now)

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
