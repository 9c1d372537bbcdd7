#!/usr/bin/env python3
"""How fast unicorn itself runs Cortex-M3 code, as the model drives it (`emu_start(count=N)`
slices of 2000 instructions, SRAM mapped as the model maps it), and without the counting: a
loop of two NOPs, of two word loads from SRAM, of two word stores to SRAM, each with its
counter and branch.

    python3 board-model/tools/unicorn-speed.py

What it shows (2026-11-29, the 2-core machine):
* counting costs most of plain code's time: with `count=N` unicorn calls a helper before every
  instruction (the model needs the count: each register access is timed by it, and a slice
  ends after a given instruction), 6 to 8 ns an instruction, against a fraction of a
  nanosecond for the translated code alone;
* unicorn 2.1.4 sends every store through its slow path (a look-up of the mapping and the
  code-page check on each): about 35 ns a store, counted or not.
The images store a lot (frames, copies, the stack), so on them unicorn averages several times
the plain figure (tools/profile.py --wall).
"""

import time

from unicorn import Uc, UC_ARCH_ARM, UC_MODE_THUMB, UC_MODE_MCLASS, UC_PROT_ALL, UC_PROT_READ
from unicorn import UC_PROT_EXEC
from unicorn.arm_const import UC_ARM_REG_PC, UC_ARM_REG_R0, UC_ARM_REG_R2, UC_CPU_ARM_CORTEX_M3

LOOPS = 2_000_000


def run(body, count=2000):
    """M instructions per second for `LOOPS` rounds of `body` (Thumb, hex) + adds, subs, bne,
    in runs of `count` instructions (0: not counted, to the loop's end)."""
    uc = Uc(UC_ARCH_ARM, UC_MODE_THUMB | UC_MODE_MCLASS)
    uc.ctl_set_cpu_model(UC_CPU_ARM_CORTEX_M3)
    uc.mem_map(0x08000000, 0x1000, UC_PROT_READ | UC_PROT_EXEC)
    uc.mem_map(0x20000000, 0x5000, UC_PROT_ALL)
    code = bytes.fromhex(body + "0131" + "0138")  # adds r1, #1 ; subs r0, #1
    back = -(len(code) + 4) // 2
    code += (0xD100 | (back & 0xFF)).to_bytes(2, "little")  # bne to the start
    end = 0x08000000 + len(code)
    code += bytes.fromhex("fee7")  # b .
    uc.mem_write(0x08000000, code)
    uc.reg_write(UC_ARM_REG_R0, LOOPS)
    uc.reg_write(UC_ARM_REG_R2, 0x20000000)
    per_loop = (len(code) - 2) // 2
    t0 = time.perf_counter()
    pc = 0x08000000
    while pc != end:
        uc.emu_start(pc | 1, end, count=count)
        pc = uc.reg_read(UC_ARM_REG_PC)
    return LOOPS * per_loop / (time.perf_counter() - t0) / 1e6


def main():
    print("  counted (the model's slices)       not counted")
    for what, body in (
        ("nop; nop", "00bf00bf"),
        ("ldr r1, [r2]; ldr r1, [r2, #4]", "11685168"),
        ("str r1, [r2]; str r1, [r2, #4]", "11605160"),
    ):
        rates = [run(body, count) for count in (2000, 0)]
        cells = "  ".join(f"{r:6.0f} M/s ({1e3 / r:5.1f} ns each)" for r in rates)
        print(f"{cells}  {what}; adds; subs; bne")


if __name__ == "__main__":
    main()
