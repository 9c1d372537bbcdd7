"""The two boards of omnibench in lock-step on one 72 MHz clock, and the commands of
scripts/board-model."""

import argparse
import os
import sys
import time

from .core import Chip
from .elf import Elf

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
IMAGES = os.path.join(ROOT, "target", "thumbv7m-none-eabi", "release")


class Bench:
    def __init__(self, slave_elf=None, master_elf=None, slice_us=10.0, cpi=1.0, log=None,
                 boards=("slave", "master")):
        self.boards = {}
        paths = {"slave": slave_elf or os.path.join(IMAGES, "firmware-slave"),
                 "master": master_elf or os.path.join(IMAGES, "firmware-master")}
        for i, name in enumerate(boards):
            self.boards[name] = Chip(name, Elf(paths[name]), uid=bytes([0x30 + i]) * 12, cpi=cpi,
                                     log=log)
        self.slice = int(slice_us * Chip.TICK_HZ / 1e6)
        self.now = 0
        if "slave" in self.boards and "master" in self.boards:
            self.wire()

    def wire(self):
        """The four SPI wires (docs/pinmap.md, "Between the boards"): the master's SPI1 clocks
        bytes through the slave's SPI1 (MOSI, MISO, SCK as byte exchanges); the master's PA4
        (chip select, a GPIO output) drives the slave's PA4 (hardware NSS and EXTI4).
        The effects reach the slave at the master's time (up to one slice before the slave's
        own clock gets there)."""
        m, s = self.boards["master"], self.boards["slave"]
        m.spi1.peer = s.spi1
        s.gpio[0].drive(4, m.gpio[0].level(4))
        m.gpio[0].listen(4, lambda lvl: s.gpio[0].drive(4, lvl))

    def run(self, ticks, stop_on_halt=True):
        end = self.now + ticks
        while self.now < end:
            t = min(end, self.now + self.slice)
            # every board asleep: jump to the first wake-up (lock-step resumes from there)
            w = min(b.wake_time(end) for b in self.boards.values())
            if w > t:
                t = w
            for b in self.boards.values():
                b.run_until(t)
            self.now = t
            if stop_on_halt and all(b.halted for b in self.boards.values()):
                break


def fmt_fault(chip, f):
    where = chip.elf.where(f["pc"])
    s = f"{f['kind']} at {f['t'] / Chip.TICK_HZ * 1e3:.4f} ms, pc {f['pc']:#010x} <{f['symbol']}>, sp {f['sp']:#010x}"
    if where:
        s += "\n        " + "\n        inlined in ".join(where[:4])
    return s


def report(chip, sim_ticks, wall):
    ok = True
    ms = sim_ticks / Chip.TICK_HZ * 1e3
    lines = [f"== {chip.name}: {os.path.relpath(chip.elf.path, ROOT)}"]
    idle = chip.first_idle
    lines.append(f"  reached idle      {'yes, at %.4f ms (executor in WFE)' % (idle / Chip.TICK_HZ * 1e3) if idle is not None else 'no'}")
    if idle is None:
        ok = False
    if chip.panics:
        p = chip.panics[0]
        where = chip.elf.where(p["caller"])
        lines.append(f"  PANIC             at {p['t'] / Chip.TICK_HZ * 1e3:.4f} ms: {chip.elf.name_of(p['caller'])} called {p['entry']}, sp {p['sp']:#010x} ({0x20005000 - p['sp']} B below the stack top)")
        for w in where[:5]:
            lines.append(f"                    at {w}")
        ok = False
    for f in chip.faults:
        lines.append("  FAULT             " + fmt_fault(chip, f))
        ok = False
    if chip.halted:
        lines.append(f"  stopped           {chip.halted}")
    used, room, over = chip.stack_report()
    lo = chip.elf.sym("_stack_end")
    deepest = chip.sp_top - chip.sp_min if chip.sp_min else 0
    if over:
        lines.append(f"  stack             OVERFLOW: all {room} B of room between _stack_end {lo:#x} and {chip.sp_top:#x} overwritten; deepest SP seen {chip.sp_min:#x} = {deepest} B deep ({deepest - room} B into the statics)")
        ok = False
    else:
        lines.append(f"  stack             used {used} B of {room} B room ({100 * used / room:.0f} %), {room - used} B free (deepest SP sampled {deepest} B)")
    dh = chip.default_handler_lines()
    # A line left enabled on DefaultHandler fails the board. One enabled only during
    # `embassy_stm32::init`, and masked before anything could set its pending bit (its EXTI
    # line or DMA channel not configured yet), is listed as a note.
    left = [(n, name) for n, name, en in dh if en]
    if left:
        ok = False
        for n, name in left:
            lines.append(f"  DEFAULT HANDLER   IRQ {n} {name} enabled with vector DefaultHandler (an endless loop)")
    masked = [f"{n} {name}" for n, name, en in dh if not en]
    if masked:
        lines.append("  masked at init    " + ", ".join(masked) + " (on DefaultHandler: enabled by embassy's init, masked by the board)")
    if not dh:
        lines.append("  NVIC lines        " + (", ".join(f"{n} {__import__('f103.nvic', fromlist=['x']).IRQ_NAMES[n]}" for n in sorted(chip.nvic.ever_enabled)) or "none") + " enabled; none on DefaultHandler")
    sim_s = sim_ticks / Chip.TICK_HZ
    load = chip.busy_ticks / max(1, chip.now)
    lines.append(f"  load              {chip.instructions / max(sim_s, 1e-9) / 1e6:.2f} M instructions per simulated s ({100 * load:.1f} % busy at CPI {chip.cpi}); {chip.exceptions} exceptions, {chip.sleeps} sleeps")
    for m in chip.messages[:12]:
        lines.append("  log " + m)
    if len(chip.messages) > 12:
        lines.append(f"  log ... {len(chip.messages) - 12} more")
    return ok, "\n".join(lines)


def cmd_boot(args):
    bench = Bench(args.slave, args.master, slice_us=args.slice_us, cpi=args.cpi,
                  log=(lambda m: print(m, file=sys.stderr)) if args.verbose else None,
                  boards=args.boards)
    ticks = int(args.ms * 1e-3 * Chip.TICK_HZ)
    t0 = time.perf_counter()
    bench.run(ticks, stop_on_halt=True)
    wall = time.perf_counter() - t0
    sim = bench.now
    all_ok = True
    for chip in bench.boards.values():
        ok, text = report(chip, sim, wall)
        all_ok &= ok
        print(text)
    print(f"== speed: {sim / Chip.TICK_HZ * 1e3:.1f} simulated ms in {wall:.2f} s wall = "
          f"{sim / Chip.TICK_HZ * 1e3 / wall:.1f} simulated ms per wall s "
          f"({sim / Chip.TICK_HZ / wall:.3f}x real time), slice {args.slice_us} us")
    print("== result:", "OK" if all_ok else "FAILED")
    return 0 if all_ok else 1


def cmd_serve(args):
    """The master's USART1 on a pseudo-terminal, in real time (imitates `host-bench
    virtual-board`: the first line is `port: /dev/pts/N`)."""
    import select
    import tty
    boards = ("master",) if args.no_slave else ("slave", "master")
    bench = Bench(args.slave, args.master, slice_us=args.slice_us, cpi=args.cpi,
                  log=(lambda m: print(m, file=sys.stderr)) if args.verbose else None,
                  boards=boards)
    master = bench.boards["master"]
    pty_m, pty_s = os.openpty()
    tty.setraw(pty_s)
    tty.setraw(pty_m)
    os.set_blocking(pty_m, False)
    print(f"port: {os.ttyname(pty_s)}", flush=True)
    print(f"board model serving ({'+'.join(boards)}, USART1 at the baud the firmware sets); "
          "Ctrl-C ends it", file=sys.stderr, flush=True)
    out = bytearray()
    master.usart1.tx_sink = out.append
    step = int(args.step_ms * 1e-3 * Chip.TICK_HZ)
    t0 = time.perf_counter()
    end = int(args.ms * 1e-3 * Chip.TICK_HZ) if args.ms else None
    lag_reported = 0
    try:
        while end is None or bench.now < end:
            # input from the host: what arrived in the pty since the last step
            try:
                r, _, _ = select.select([pty_m], [], [], 0)
                if r:
                    data = os.read(pty_m, 4096)
                    if data:
                        master.usart1.receive(data)
            except (BlockingIOError, OSError):
                pass
            bench.run(step, stop_on_halt=False)
            if out:
                try:
                    n = os.write(pty_m, bytes(out))
                    del out[:n]
                except (BlockingIOError, OSError):
                    if len(out) > 1 << 16:
                        del out[:len(out) - (1 << 16)]       # a host that does not read
            # pace to the wall clock
            ahead = bench.now / Chip.TICK_HZ - (time.perf_counter() - t0)
            if ahead > 0:
                time.sleep(ahead)
            elif ahead < -1.0 and time.perf_counter() - lag_reported > 10:
                lag_reported = time.perf_counter()
                print(f"board model: {-ahead:.1f} s behind real time", file=sys.stderr, flush=True)
            for b in bench.boards.values():
                if b.halted and not getattr(b, "_halt_told", False):
                    b._halt_told = True
                    ok, text = report(b, bench.now, 0)
                    print(text, file=sys.stderr, flush=True)
    except KeyboardInterrupt:
        pass
    wall = time.perf_counter() - t0
    print(f"board model: {bench.now / Chip.TICK_HZ:.3f} s simulated in {wall:.3f} s; USART1 "
          f"{master.usart1.bytes_out} bytes out, {master.usart1.bytes_in} in; SPI1 "
          f"{master.spi1.bytes} bytes", file=sys.stderr)
    return 0


def main(argv=None):
    ap = argparse.ArgumentParser(prog="board-model", description=__doc__)
    sub = ap.add_subparsers(dest="cmd", required=True)
    b = sub.add_parser("boot", help="run both images from reset and report")
    b.add_argument("--ms", type=float, default=100.0, help="simulated time (default 100 ms)")
    b.add_argument("--slave", help="slave ELF (default target/thumbv7m-none-eabi/release/firmware-slave)")
    b.add_argument("--master", help="master ELF")
    b.add_argument("--boards", nargs="+", default=["slave", "master"], choices=["slave", "master"])
    b.add_argument("--slice-us", type=float, default=10.0, help="lock-step slice (default 10 us)")
    b.add_argument("--cpi", type=float, default=1.0, help="cycles per instruction (default 1)")
    b.add_argument("-v", "--verbose", action="store_true", help="log as it runs")
    b.set_defaults(fn=cmd_boot)
    sv = sub.add_parser("serve", help="the master's USART1 on a pseudo-terminal, in real time")
    sv.add_argument("--slave", help="slave ELF")
    sv.add_argument("--master", help="master ELF")
    sv.add_argument("--no-slave", action="store_true", help="the master alone")
    sv.add_argument("--ms", type=float, default=0, help="stop after this much simulated time")
    sv.add_argument("--slice-us", type=float, default=10.0)
    sv.add_argument("--step-ms", type=float, default=2.0, help="pty polling period, simulated")
    sv.add_argument("--cpi", type=float, default=1.0)
    sv.add_argument("-v", "--verbose", action="store_true")
    sv.set_defaults(fn=cmd_serve)
    args = ap.parse_args(argv)
    return args.fn(args)
