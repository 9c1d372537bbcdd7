"""How one Chip takes exceptions, faults and sleeps, the parts of a Cortex-M3 that unicorn does
not model (mixed into core.Chip).

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
import struct

from unicorn import (
    UC_ERR_FETCH_PROT,
    UC_ERR_FETCH_UNMAPPED,
    UC_ERR_INSN_INVALID,
    UC_ERR_READ_PROT,
    UC_ERR_READ_UNMAPPED,
    UC_ERR_WRITE_PROT,
    UC_ERR_WRITE_UNMAPPED,
)
from unicorn.arm_const import (
    UC_ARM_REG_BASEPRI,
    UC_ARM_REG_CONTROL,
    UC_ARM_REG_LR,
    UC_ARM_REG_PC,
    UC_ARM_REG_PRIMASK,
    UC_ARM_REG_R0,
    UC_ARM_REG_R1,
    UC_ARM_REG_R2,
    UC_ARM_REG_R3,
    UC_ARM_REG_R12,
    UC_ARM_REG_SP,
    UC_ARM_REG_XPSR,
)

from . import nvic as nv
from .memmap import FLASH_BASE, FLASH_SIZE, SRAM_BASE, SRAM_SIZE

REG_FRAME = (
    UC_ARM_REG_R0,
    UC_ARM_REG_R1,
    UC_ARM_REG_R2,
    UC_ARM_REG_R3,
    UC_ARM_REG_R12,
    UC_ARM_REG_LR,
)
REGS_ENTRY = REG_FRAME + (UC_ARM_REG_XPSR, UC_ARM_REG_SP, UC_ARM_REG_CONTROL)
REGS_ENTERED = (UC_ARM_REG_SP, UC_ARM_REG_LR, UC_ARM_REG_XPSR, UC_ARM_REG_PC)
REGS_RETURN = REG_FRAME + (UC_ARM_REG_SP, UC_ARM_REG_XPSR)
REGS_PC_SP = (UC_ARM_REG_PC, UC_ARM_REG_SP)
REGS_MASKS = (UC_ARM_REG_PRIMASK, UC_ARM_REG_BASEPRI)


class ExceptionModel:
    # --- exceptions ----------------------------------------------------------------------
    def _enter(self, exc, ret_pc):
        """Exception entry (B1.5.6): push the frame, EXC_RETURN in LR, jump to the vector."""
        fast = self.fast
        r0, r1, r2, r3, r12, lr, xpsr, sp, control = fast.regs(REGS_ENTRY)
        if control & 2:
            self.log("CONTROL.SPSEL=1 (process stack): not modelled")
        xpsr = (xpsr & ~0x1FF) | self.ipsr
        align = (sp >> 2) & 1 if self.nvic.ccr & 0x200 else 0
        frame = ((sp - 0x20) & ~(align << 2)) & 0xFFFFFFFF
        self.exceptions += 1
        if not (SRAM_BASE <= frame and frame + 0x20 <= SRAM_BASE + SRAM_SIZE):
            self._lockup(
                f"stacking for {nv.exc_name(exc)} at SP {frame:#x}: outside SRAM (MSP overflow)",
                ret_pc,
            )
            return
        fast.write(
            frame,
            struct.pack(
                "<8I", r0, r1, r2, r3, r12, lr, ret_pc & ~1, (xpsr & ~(1 << 9)) | (align << 9)
            ),
        )
        exc_return = 0xFFFFFFF1 if self.ipsr else 0xFFFFFFF9
        vector = self.read32((self.nvic.vtor + 4 * exc) & 0xFFFFFFFF)
        self.ipsr = exc
        self.nvic.activate(exc)
        self.event = True  # wake-up event (WFE returns)
        fast.set_regs(
            REGS_ENTERED, (frame, exc_return, (xpsr & 0xF8000000) | 0x01000000, vector | 1)
        )
        if sp < self.sp_min:
            self.sp_min = frame
        if exc == nv.HARDFAULT and (vector & ~1) == self.default_handler:
            self.halted = f"in HardFault handler ({self.elf.name_of(vector)}: an endless loop)"

    def _trap(self, addr, size, handler):
        """BKPT #0xB0 (0xBEB0) over the instruction at `addr` (a 32-bit one: then a NOP)."""
        off = addr & (FLASH_SIZE - 1)
        patch = b"\xb0\xbe" + (b"\x00\xbf" if size == 4 else b"")
        self.traps[addr] = (handler, size, self.flash.raw[off : off + 2])
        ctypes.memmove(ctypes.addressof(self.flash) + off, patch, len(patch))

    def _untrap(self, addr):
        """The original first halfword back (the CPU then runs the original instruction)."""
        off = addr & (FLASH_SIZE - 1)
        ctypes.memmove(ctypes.addressof(self.flash) + off, self.traps.pop(addr)[2], 2)
        self.uc.ctl_remove_cache(addr, addr + 4)
        self.uc.ctl_remove_cache(addr - FLASH_BASE, addr - FLASH_BASE + 4)

    def _on_intr(self, uc, intno, _ud):
        fast = self.fast
        if fast.clock is not None:  # the time of this instruction (ucfast.counter_offset)
            self.now = fast.instruction_time()
        if intno == 7:  # BKPT: one of the model's traps?
            addr = self.fast.reg(UC_ARM_REG_PC) & ~1
            if addr < FLASH_SIZE:
                addr |= FLASH_BASE  # the flash's alias at 0
            trap = self.traps.get(addr)
            if trap is not None:
                trap[0](uc, addr, trap[1])
                return
        if intno != 8:  # not an exception return
            self._stop_reason = f"cpu exception {intno}"
            self._fault_pending = ("UsageFault", f"CPU exception {intno}")
            uc.emu_stop()
            return
        exc_return, sp = fast.regs(REGS_PC_SP)
        exc_return |= 1
        ret = self.ipsr
        self.nvic.deactivate(ret)
        r0, r1, r2, r3, r12, lr, pc, psr = struct.unpack("<8I", fast.read(sp, 0x20))
        sp_new = sp + 0x20 + (4 if (psr >> 9) & 1 and self.nvic.ccr & 0x200 else 0)
        self.ipsr = psr & 0x1FF
        if bool(exc_return & 8) != (self.ipsr == 0):
            self.log(f"exception return {exc_return:#x} with stacked IPSR {self.ipsr}: INVPC")
        fast.set_regs(REGS_RETURN, (r0, r1, r2, r3, r12, lr, sp_new, (psr & ~0x3FF) | 0x01000000))
        # tail-chain (B1.5.12): another exception that can be taken now
        if self.nvic.pending:
            primask, basepri = fast.regs(REGS_MASKS)
            e = self.nvic.takeable(primask, basepri)
            if e is not None:
                self._enter(e, pc)
                if self.halted:
                    uc.emu_stop()
                return
        fast.set_reg(UC_ARM_REG_PC, pc | 1)

    def _on_wfe(self, uc, addr, size):
        if self.event:
            self.event = False
            uc.reg_write(UC_ARM_REG_PC, (addr + size) | 1)
            return
        self.idle_reached()
        self.sleeping = True
        self.sleeps += 1
        self._stop_reason = "sleep"
        uc.reg_write(UC_ARM_REG_PC, (addr + size) | 1)
        uc.emu_stop()

    def _on_sev(self, uc, addr, size):
        self.event = True
        uc.reg_write(UC_ARM_REG_PC, (addr + size) | 1)

    def _on_panic_entry(self, uc, addr, _size):
        """Recorded, then the entry's own instruction restored and run (a panic ends in the
        HardFault handler's loop, so each entry is recorded once at most)."""
        name = self.panic_entries[addr]
        self._untrap(addr)
        uc.reg_write(UC_ARM_REG_PC, addr | 1)
        lr, sp = uc.reg_read_batch([UC_ARM_REG_LR, UC_ARM_REG_SP])
        if len(self.panics) < 8:
            self.panics.append(
                {
                    "entry": " / ".join(self.elf.aliases.get(name, [hex(name)])),
                    "caller": (lr & ~1) - 4,
                    "sp": sp,
                    "t": self.now,
                }
            )
            if sp < self.sp_min:
                self.sp_min = sp

    def _on_bad_access(self, uc, access, addr, size, value, _ud):
        self._bad_access = (access, addr, size)
        return False

    _bad_access = None
    _fault_pending = None

    def _uc_fault(self, e):
        if self.fast.clock is not None and self._in_slice:
            self.now = self.fast.instruction_time()  # the faulting instruction's
        pc = self.uc.reg_read(UC_ARM_REG_PC) & ~1
        sp = self.uc.reg_read(UC_ARM_REG_SP)
        if sp < self.sp_min:
            self.sp_min = sp
        if e.errno == UC_ERR_INSN_INVALID:
            kind, cfsr_bit, exc = "UsageFault (undefined instruction)", 1 << 16, nv.USAGEFAULT
            ins = struct.unpack("<H", self.uc.mem_read(pc, 2))[0]
            if ins & 0xFF00 == 0xDE00:
                kind = f"UsageFault (UDF #{ins & 0xFF})"
        elif e.errno in (
            UC_ERR_READ_UNMAPPED,
            UC_ERR_WRITE_UNMAPPED,
            UC_ERR_READ_PROT,
            UC_ERR_WRITE_PROT,
        ):
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
        if (
            exc != nv.HARDFAULT
            and enabled_bit is not None
            and (self.nvic.shcsr >> enabled_bit) & 1
            and self.nvic.group(self.nvic.priority(exc)) < exec_prio
        ):
            target = exc
        else:
            target = nv.HARDFAULT
            self.nvic.hfsr |= 1 << 30  # FORCED
        if self.nvic.execution_priority(0, 0) <= -1:
            self._lockup(f"{kind} inside HardFault/NMI", pc)
            return
        self._enter(target, pc)
        self.pc = self.uc.reg_read(UC_ARM_REG_PC) & ~1

    def _lockup(self, why, pc):
        self.halted = f"lock-up: {why}"
        self.faults.append(
            {
                "kind": "lock-up",
                "pc": pc,
                "t": self.now,
                "sp": self.uc.reg_read(UC_ARM_REG_SP),
                "symbol": self.elf.name_of(pc),
            }
        )
        self.log(self.halted)
