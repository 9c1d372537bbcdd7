"""The two boards of omnibench in lock-step on one 72 MHz clock, and the commands of
scripts/board-model."""

import argparse
import os
import signal
import subprocess
import sys
import time

from .core import Chip
from . import edges
from .elf import Elf
from .pty_link import PtyLink, run_paced

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
IMAGES = os.path.join(ROOT, "target", "thumbv7m-none-eabi", "release")


class Bench:
    def __init__(
        self,
        slave_elf=None,
        master_elf=None,
        slice_us=10.0,
        cpi=1.0,
        log=None,
        boards=("slave", "master"),
    ):
        self.boards = {}
        paths = {
            "slave": slave_elf or os.path.join(IMAGES, "firmware-slave"),
            "master": master_elf or os.path.join(IMAGES, "firmware-master"),
        }
        for i, name in enumerate(boards):
            self.boards[name] = Chip(
                name, Elf(paths[name]), uid=bytes([0x30 + i]) * 12, cpi=cpi, log=log
            )
        self.slice = int(slice_us * Chip.TICK_HZ / 1e6)
        self.now = 0
        self.scheduled_resets = []  # (tick, board, hold ticks), in order
        if "slave" in self.boards and "master" in self.boards:
            self.wire()
        self.rest_encoders()

    def rest_encoders(self):
        """The encoders on timer inputs are wired from power-on and stand still, both lines
        high (what the pull-ups give with open-collector outputs released): the slave's
        measuring wheels on PA0/PA1 (TIM2) and PA8/PA9 (TIM1), the master's motor 2 encoder on
        PA8/PA9 (TIM1), docs/pinmap.md. Left floating, the model reads an input as 0 and the
        pull-ups the firmware turns on after starting the timers in encoder mode would make a
        rising edge on each line: two counts of motion that no wheel made. `--drive` starts
        from these levels."""
        rest = {"slave": (0, 1, 8, 9), "master": (8, 9)}
        for name, chip in self.boards.items():
            for pin in rest[name]:
                chip.gpio[0].drive(pin, 1)

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

    def reset_at(self, board, secs, hold_ms):
        """A system reset of `board` by its NRST pin, `secs` of simulated time after power-on,
        the pin held low `hold_ms` (reset.py)."""
        tick = int(round(secs * Chip.TICK_HZ))
        self.scheduled_resets.append((tick, board, int(hold_ms * 1e-3 * Chip.TICK_HZ)))
        self.scheduled_resets.sort()

    def run(self, ticks, stop_on_halt=True):
        end = self.now + ticks
        while self.now < end:
            # a slice ends at a scheduled reset, so that it lands on its tick
            stop = min(end, self.scheduled_resets[0][0]) if self.scheduled_resets else end
            t = min(stop, self.now + self.slice)
            # every board asleep: jump to the first wake-up (lock-step resumes from there)
            w = min(b.wake_time(stop) for b in self.boards.values())
            if w > t:
                t = w
            for b in self.boards.values():
                b.run_until(t)
            self.now = t
            self._fire_resets()
            if stop_on_halt and all(b.halted for b in self.boards.values()):
                break

    def _fire_resets(self):
        while self.scheduled_resets and self.scheduled_resets[0][0] <= self.now:
            _, name, hold = self.scheduled_resets.pop(0)
            self.boards[name].system_reset("NRST pin", hold)


def fmt_fault(chip, f):
    where = chip.elf.where(f["pc"])
    s = f"{f['kind']} at {f['t'] / Chip.TICK_HZ * 1e3:.4f} ms, pc {f['pc']:#010x} <{f['symbol']}>, sp {f['sp']:#010x}"
    if where:
        s += "\n        " + "\n        inlined in ".join(where[:4])
    return s


def load_line(chip):
    sim_s = chip.now / Chip.TICK_HZ
    load = chip.busy_ticks / max(1, chip.now)
    return (
        f"{chip.instructions / max(sim_s, 1e-9) / 1e6:.2f} M instructions per simulated s "
        f"({100 * load:.1f} % busy at CPI {chip.cpi}); {chip.exceptions} exceptions, "
        f"{chip.sleeps} sleeps"
    )


def speed_line(sim_ticks, wall):
    ms = sim_ticks / Chip.TICK_HZ * 1e3
    return (
        f"{ms:.1f} simulated ms in {wall:.2f} s wall = {ms / wall:.1f} simulated ms per "
        f"wall s ({ms / 1e3 / wall:.3f}x real time)"
    )


def ms(ticks):
    return f"{ticks / Chip.TICK_HZ * 1e3:.4f} ms"


def reset_lines(chip):
    """(text, idle again) for each system reset of `chip`: when, from what, and whether the
    image came back to its executor's WFE after it."""
    out = []
    for r in chip.resets:
        idle = r["idle"]
        again = f"idle again at {ms(idle)}" if idle is not None else "NOT idle again"
        out.append(
            (f"at {ms(r['t'])} ({r['source']}, held {ms(r['hold'])}), {again}", idle is not None)
        )
    return out


def stack_line(chip):
    """(ok, the stack's high-water mark since power-on, as `boot` prints it)."""
    used, room, over = chip.stack_report()
    deepest = chip.sp_top - chip.sp_min if chip.sp_min <= chip.sp_top else 0
    if over:
        lo = chip.elf.sym("_stack_end")
        return False, (
            f"OVERFLOW: all {room} B of room between _stack_end {lo:#x} and {chip.sp_top:#x} "
            f"overwritten; deepest SP seen {chip.sp_min:#x} = {deepest} B deep "
            f"({deepest - room} B into the statics)"
        )
    return True, (
        f"used {used} B of {room} B room ({100 * used / room:.0f} %), {room - used} B free "
        f"(deepest SP sampled {deepest} B)"
    )


def report(chip, sim_ticks, wall):
    ok = True
    lines = [f"== {chip.name}: {os.path.relpath(chip.elf.path, ROOT)}"]
    idle = chip.first_idle
    lines.append(
        f"  reached idle      {'yes, at %.4f ms (executor in WFE)' % (idle / Chip.TICK_HZ * 1e3) if idle is not None else 'no'}"
    )
    if idle is None:
        ok = False
    for text, again in reset_lines(chip):
        lines.append(f"  system reset      {text}")
        ok &= again
    if chip.panics:
        p = chip.panics[0]
        where = chip.elf.where(p["caller"])
        lines.append(
            f"  PANIC             at {p['t'] / Chip.TICK_HZ * 1e3:.4f} ms: {chip.elf.name_of(p['caller'])} called {p['entry']}, sp {p['sp']:#010x} ({0x20005000 - p['sp']} B below the stack top)"
        )
        for w in where[:5]:
            lines.append(f"                    at {w}")
        ok = False
    for f in chip.faults:
        lines.append("  FAULT             " + fmt_fault(chip, f))
        ok = False
    if chip.halted:
        lines.append(f"  stopped           {chip.halted}")
    stack_ok, text = stack_line(chip)
    lines.append(f"  stack             {text}")
    ok &= stack_ok
    dh = chip.default_handler_lines()
    # A line left enabled on DefaultHandler fails the board. One enabled only during
    # `embassy_stm32::init`, and masked before anything could set its pending bit (its EXTI
    # line or DMA channel not configured yet), is listed as a note.
    left = [(n, name) for n, name, en in dh if en]
    if left:
        ok = False
        for n, name in left:
            lines.append(
                f"  DEFAULT HANDLER   IRQ {n} {name} enabled with vector DefaultHandler (an endless loop)"
            )
    masked = [f"{n} {name}" for n, name, en in dh if not en]
    if masked:
        lines.append(
            "  masked at init    "
            + ", ".join(masked)
            + " (on DefaultHandler: enabled by embassy's init, masked by the board)"
        )
    if not dh:
        lines.append(
            "  NVIC lines        "
            + (
                ", ".join(
                    f"{n} {__import__('f103.nvic', fromlist=['x']).IRQ_NAMES[n]}"
                    for n in sorted(chip.nvic.ever_enabled)
                )
                or "none"
            )
            + " enabled; none on DefaultHandler"
        )
    lines.append(f"  load              {load_line(chip)}")
    for m in chip.messages[:12]:
        lines.append("  log " + m)
    if len(chip.messages) > 12:
        lines.append(f"  log ... {len(chip.messages) - 12} more")
    return ok, "\n".join(lines)


def cmd_boot(args):
    bench = _bench_for(args, boards=args.boards)
    _schedule_resets(bench, args)
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
    print(f"== speed: {speed_line(sim, wall)}, slice {args.slice_us} us")
    print("== result:", "OK" if all_ok else "FAILED")
    return 0 if all_ok else 1


def _bench_for(args, boards=("slave", "master")):
    bench = Bench(
        args.slave,
        args.master,
        slice_us=args.slice_us,
        cpi=args.cpi,
        log=(lambda m: print(m, file=sys.stderr)) if args.verbose else None,
        boards=boards,
    )
    if args.on_bench is not None:
        args.on_bench(bench)
    return bench


def _stop_flag():
    """A list that SIGINT and SIGTERM append to. Only a flag: an exception raised by a signal
    handler inside one of unicorn's callbacks would be lost by ctypes (and a background job
    ignores SIGINT, so `kill PID` must end a serve too)."""
    stop = []
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.append(1))
    return stop


def _tell_halts(bench):
    for b in bench.boards.values():
        if b.halted and not getattr(b, "_halt_told", False):
            b._halt_told = True
            print(report(b, bench.now, 0)[1], file=sys.stderr, flush=True)
        elif not b.halted:
            b._halt_told = False  # running again after a reset: a new halt is told too


def _summary(bench, sim_ticks, wall, link=None):
    master = bench.boards["master"]
    print(
        f"board model: {sim_ticks / Chip.TICK_HZ:.3f} s simulated in {wall:.3f} s; USART1 "
        f"{master.usart1.bytes_out} bytes out, {master.usart1.bytes_in} in"
        + (
            f", at {link.usart_baud()} baud at the end, {link.garbled} bytes garbled"
            if link
            else ""
        )
        + "; SPI1 "
        f"{master.spi1.bytes} bytes; " + speed_line(sim_ticks, wall),
        file=sys.stderr,
    )
    for b in bench.boards.values():
        print(f"board model: {b.name} {load_line(b)}", file=sys.stderr)


def _boards_end(bench, wall):
    """Per board, after `serve` or `play-check`: its stack high-water mark since power-on and
    its system resets, one line each; a board that faulted, panicked, stopped, overflowed its
    stack or did not come back to idle after a reset gets `boot`'s whole report. False if any
    did."""
    all_ok = True
    for b in bench.boards.values():
        ok, text = stack_line(b)
        print(f"board model: {b.name} stack {text}", file=sys.stderr)
        for text, again in reset_lines(b):
            print(f"board model: {b.name} system reset {text}", file=sys.stderr)
            ok &= again
        if not ok or b.halted or b.faults or b.panics:
            print(report(b, bench.now, wall)[1], file=sys.stderr)
            all_ok = False
    return all_ok


def _schedule_resets(bench, args):
    for secs in args.reset_slave_at or ():
        if "slave" not in bench.boards:
            sys.exit("board-model: --reset-slave-at without the slave board")
        bench.reset_at("slave", secs, args.reset_hold_ms)


def _add_reset_args(p):
    p.add_argument(
        "--reset-slave-at",
        type=float,
        action="append",
        metavar="SECS",
        help="system reset of the slave by its NRST pin, SECS of simulated time after "
        "power-on (repeatable); SRAM kept (board-model/README.md)",
    )
    p.add_argument(
        "--reset-hold-ms",
        type=float,
        default=5.0,
        help="how long NRST is held low; the slave then runs from its vector table "
        "(default 5 ms, as virtual-board's --fault-slave-reset-at)",
    )


def cmd_serve(args):
    """The master's USART1 on a pseudo-terminal, as `host-bench virtual-board` serves its
    emulated boards: the first line is `port: /dev/pts/N`, and the second `clock: FILE`, the
    model's simulated time for the host to time its waits by (`host-bench play --clock FILE`)."""
    boards = ("master",) if args.no_slave else ("slave", "master")
    bench = _bench_for(args, boards)
    drivers = _drive(bench, args)
    _schedule_resets(bench, args)
    link = PtyLink(bench.boards["master"].usart1, args.max_baud)
    print(f"port: {link.port}", flush=True)
    print(f"clock: {link.clock.path}", flush=True)
    print(
        f"board model serving ({'+'.join(boards)}, USART1 at the baud the firmware sets); "
        "Ctrl-C ends it",
        file=sys.stderr,
        flush=True,
    )
    stop = _stop_flag()
    end = int(args.ms * 1e-3 * Chip.TICK_HZ) if args.ms else None
    try:
        wall = run_paced(
            bench,
            link,
            int(args.step_ms * 1e-3 * Chip.TICK_HZ),
            lambda: stop or (end is not None and bench.now >= end),
            lambda: _tell_halts(bench),
        )
        _summary(bench, bench.now, wall, link)
    finally:
        link.close()  # the pty, and the clock file with its folder
    ok = _boards_end(bench, wall)
    for d in drivers:
        s = bench.boards["slave"]
        print(
            f"board model: edges applied {d.applied} of {len(d.rows)}; slave TIM2 CNT "
            f"{s.tim2.cnt}, TIM1 CNT {s.tim1.cnt}, EXTI edges {s.exti.edges}",
            file=sys.stderr,
        )
    return 0 if ok else 1


def _drive(bench, args):
    """The slave's encoder pins from `--drive` specs and `--edges` files (edges.py)."""
    if not (args.drive or args.edges) or "slave" not in bench.boards:
        return []
    slave = bench.boards["slave"]
    rows, hold = [], {}
    for spec in args.drive or ():
        r, h = edges.drive_spec(spec)
        rows += r
        hold.update(h)
    for path in args.edges or ():
        rows += edges.load(path)
    return [edges.EdgeDriver(slave, rows, hold)]


def cmd_play_check(args):
    """Boot both boards, serve USART1 on a pty and run `host-bench play` against it; exit with
    play's status. The model's speed is measured over the play alone."""
    bench = _bench_for(args)
    _schedule_resets(bench, args)
    link = PtyLink(bench.boards["master"].usart1, args.max_baud)
    bench.run(int(args.boot_ms * 1e-3 * Chip.TICK_HZ))  # boot before the host knocks
    cmd = [
        args.host_bench,
        "play",
        "--port",
        link.port,
        "--ticks",
        args.ticks,
        "--sensor",
        args.sensor,
        # The model runs at a fraction of real time: play times its waits for the boards (its
        # resends, its stall check, its pace on the line) by the model's clock, not the wall's.
        "--clock",
        link.clock.path,
    ]
    if args.patience > 1:
        cmd += ["--patience", str(args.patience)]
    cmd += args.play_args
    print("board model: " + " ".join(cmd), file=sys.stderr, flush=True)
    host = subprocess.Popen(cmd)
    stop = _stop_flag()
    start = bench.now
    wall = run_paced(
        bench,
        link,
        int(args.step_ms * 1e-3 * Chip.TICK_HZ),
        lambda: stop or host.poll() is not None,
        lambda: _tell_halts(bench),
    )
    if host.poll() is None:
        host.terminate()
    rc = host.wait()
    link.close()
    _summary(bench, bench.now - start, wall, link)
    if not _boards_end(bench, wall):
        rc = rc or 1
    return rc


def main(argv=None, on_bench=None):
    """scripts/board-model's commands; `on_bench(bench)`, if given, is called on the bench a
    command builds before it runs (tools/profile.py hooks the CPUs there)."""
    ap = argparse.ArgumentParser(prog="board-model", description=__doc__)
    sub = ap.add_subparsers(dest="cmd", required=True)
    b = sub.add_parser("boot", help="run both images from reset and report")
    b.add_argument("--ms", type=float, default=100.0, help="simulated time (default 100 ms)")
    b.add_argument(
        "--slave", help="slave ELF (default target/thumbv7m-none-eabi/release/firmware-slave)"
    )
    b.add_argument("--master", help="master ELF")
    b.add_argument("--boards", nargs="+", default=["slave", "master"], choices=["slave", "master"])
    b.add_argument("--slice-us", type=float, default=10.0, help="lock-step slice (default 10 us)")
    b.add_argument("--cpi", type=float, default=1.0, help="cycles per instruction (default 1)")
    b.add_argument("-v", "--verbose", action="store_true", help="log as it runs")
    _add_reset_args(b)
    b.set_defaults(fn=cmd_boot)
    sv = sub.add_parser("serve", help="the master's USART1 on a pseudo-terminal, in real time")
    sv.add_argument("--slave", help="slave ELF")
    sv.add_argument("--master", help="master ELF")
    sv.add_argument("--no-slave", action="store_true", help="the master alone")
    sv.add_argument("--ms", type=float, default=0, help="stop after this much simulated time")
    sv.add_argument(
        "--max-baud",
        type=int,
        help="the fastest rate the USB-serial adapter carries (a faster switch garbles)",
    )
    sv.add_argument("--slice-us", type=float, default=10.0)
    sv.add_argument("--step-ms", type=float, default=2.0, help="pty polling period, simulated")
    sv.add_argument("--cpi", type=float, default=1.0)
    sv.add_argument("-v", "--verbose", action="store_true")
    sv.add_argument(
        "--drive",
        action="append",
        metavar="A,B,START_S,COUNTS,RATE_HZ[,rev]",
        help="quadrature edges on the slave's pins A, B (e.g. PA0,PA1,0.5,400,2000)",
    )
    sv.add_argument(
        "--edges",
        action="append",
        metavar="FILE",
        help="timed edges for the slave's pins, CSV t_us,pin,level",
    )
    _add_reset_args(sv)
    sv.set_defaults(fn=cmd_serve)
    pc = sub.add_parser(
        "play-check", help="serve, and run `host-bench play` against it; its exit status"
    )
    pc.add_argument("--ticks", required=True, help="tick stream (docs/tick-stream.md)")
    pc.add_argument(
        "--max-baud",
        type=int,
        help="the fastest rate the USB-serial adapter carries (a faster switch garbles)",
    )
    pc.add_argument("--sensor", default="timestamps", choices=["timestamps", "counts"])
    pc.add_argument("--host-bench", default=os.path.join(ROOT, "target", "debug", "host-bench"))
    pc.add_argument("--slave", help="slave ELF")
    pc.add_argument("--master", help="master ELF")
    pc.add_argument("--boot-ms", type=float, default=20.0, help="run this long before play starts")
    pc.add_argument("--slice-us", type=float, default=10.0)
    pc.add_argument("--step-ms", type=float, default=2.0)
    pc.add_argument("--cpi", type=float, default=1.0)
    pc.add_argument("-v", "--verbose", action="store_true")
    pc.add_argument(
        "--patience",
        type=int,
        default=1,
        help="play's --patience: how many times longer it waits for the boards, on top of "
        "its clock being the model's (default 1)",
    )
    pc.add_argument("play_args", nargs="*", help="more of play's options, after --")
    _add_reset_args(pc)
    pc.set_defaults(fn=cmd_play_check)
    args = ap.parse_args(argv)
    args.on_bench = on_bench
    return args.fn(args)
