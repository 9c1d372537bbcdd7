#!/usr/bin/env python3
"""Where the release images spend their time on the chip model: each function's share of the
code bytes executed (every basic block the CPU runs, weighted by its size in bytes: Thumb-2
mixes 2- and 4-byte instructions, so this is a share of work, not an instruction count).

    python3 board-model/tools/profile.py [--ms 150] [--top 15] [--slave ELF] [--master ELF]
    python3 board-model/tools/profile.py --play TICKS [--top 15] [-- PLAY'S OPTIONS]
    python3 board-model/tools/profile.py --wall [--play TICKS | --ms 150]

Both boards run from reset for --ms of simulated time, as `scripts/board-model boot` runs
them (idle after boot: the SPI link's polls, the time driver, the executors); or, with
--play, through `scripts/board-model play-check --ticks TICKS` (boot, then host-bench's
`play` of that stream: both boards busy relaying it), from reset to play's end. A unicorn
block hook on every block makes the model about 3x slower than without it.

--wall instead splits the model's own wall time (no block hook): inside `emu_start`, split
into the Python register accesses, the Python traps (the BKPTs over WFE/SEV and the panic
entries) and the rest of it (unicorn, the native fast path, ctypes' way to Python and back and
ucfast's wrappers around the accesses); and outside it (the lock-step loop, events, exception
entries, the pty). `perf record` then `perf report --sort dso` splits that rest further.
"""

import argparse
import bisect
import collections
import os
import subprocess
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from unicorn import UC_HOOK_BLOCK  # noqa: E402

from f103.bench import Bench, IMAGES, main as bench_main  # noqa: E402
from f103.core import Chip  # noqa: E402
from f103.elf import InputError  # noqa: E402
from f103 import ucfast  # noqa: E402


def functions(path):
    """(start, size, demangled name) of every function in the ELF, by address."""
    out = subprocess.run(
        ["llvm-nm", "-C", "-S", "--defined-only", path], capture_output=True, text=True, check=True
    ).stdout
    funcs = []
    for line in out.splitlines():
        parts = line.split(" ", 3)
        if len(parts) == 4 and parts[2] in "tT":
            funcs.append((int(parts[0], 16) & ~1, int(parts[1], 16), parts[3]))
    return sorted(funcs)


def run_with(a, hook):
    """Both boards run as --play or --ms say, `hook(bench)` called on the bench first; the
    bench, or play-check's non-zero status."""
    benches = []

    def on_bench(bench):
        benches.append(bench)
        hook(bench)

    if a.play:
        argv = ["play-check", "--ticks", a.play, "--slave", image(a, "slave")]
        argv += ["--master", image(a, "master"), "--"] + a.play_args
        rc = bench_main(argv, on_bench=on_bench)
        if rc:
            return rc
    else:
        bench = Bench(image(a, "slave"), image(a, "master"))
        on_bench(bench)
        bench.run(int(a.ms * 1e-3 * Chip.TICK_HZ))
    return benches[0]


def image(a, name):
    return getattr(a, name) or os.path.join(IMAGES, f"firmware-{name}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ms", type=float, default=150.0, help="simulated time from reset")
    ap.add_argument("--top", type=int, default=15, help="functions listed per board")
    ap.add_argument("--slave", help="slave ELF")
    ap.add_argument("--master", help="master ELF")
    ap.add_argument("--play", metavar="TICKS", help="profile a play of this tick stream instead")
    ap.add_argument("--wall", action="store_true", help="split the model's wall time instead")
    ap.add_argument("play_args", nargs="*", help="more of play's options, after --")
    a = ap.parse_args()
    if a.wall:
        return wall_split(a)
    bytes_at = {}

    def hook(bench):
        for name, chip in bench.boards.items():
            seen = collections.Counter()
            bytes_at[name] = seen

            def on_block(_uc, addr, size, _ud, seen=seen):
                seen[addr] += size

            chip.uc.hook_add(UC_HOOK_BLOCK, on_block)

    bench = run_with(a, hook)
    if isinstance(bench, int):
        return bench
    what = f"from reset to the end of a play of {a.play}" if a.play else f"in {a.ms:g} simulated ms"
    for name, seen in bytes_at.items():
        funcs = functions(image(a, name))
        starts = [f[0] for f in funcs]
        per = collections.Counter()
        for addr, n in seen.items():
            i = bisect.bisect_right(starts, addr) - 1
            inside = i >= 0 and addr < funcs[i][0] + funcs[i][1]
            per[funcs[i][2] if inside else hex(addr)] += n
        total = sum(per.values())
        print(f"{name}: {total} code bytes executed {what}")
        for func, n in per.most_common(a.top):
            print(f"  {100 * n / total:5.1f} %  {func[:100]}")


def wall_split(a):
    """--wall: time inside `emu_start` and inside the Python callbacks, measured around each."""
    clock = time.perf_counter
    t = {"emu": 0.0, "slices": 0, "cb": 0.0, "calls": 0, "trap": 0.0, "traps": 0}
    mmio_map = ucfast.FastUc.mmio_map
    on_intr = Chip._on_intr

    def timed_intr(self, uc, intno, ud):
        t0 = clock()
        try:
            return on_intr(self, uc, intno, ud)
        finally:
            t["trap"] += clock() - t0
            t["traps"] += 1

    Chip._on_intr = timed_intr

    def timed_map(self, address, size, read, write, page=None):
        def r(off, size_):
            t0 = clock()
            try:
                return read(off, size_)
            finally:
                t["cb"] += clock() - t0
                t["calls"] += 1

        def w(off, size_, value):
            t0 = clock()
            try:
                write(off, size_, value)
            finally:
                t["cb"] += clock() - t0
                t["calls"] += 1

        return mmio_map(self, address, size, r, w, page)

    ucfast.FastUc.mmio_map = timed_map

    def hook(bench):
        for chip in bench.boards.values():
            start = chip.uc.emu_start

            def emu_start(begin, until, timeout=0, count=0, start=start):
                t0 = clock()
                try:
                    start(begin, until, timeout, count)
                finally:
                    t["emu"] += clock() - t0
                    t["slices"] += 1

            chip.uc.emu_start = emu_start

    t0 = clock()
    bench = run_with(a, hook)
    if isinstance(bench, int):
        return bench
    wall = clock() - t0
    sim_s = bench.now / Chip.TICK_HZ
    instr = sum(c.instructions for c in bench.boards.values())
    in_uc = t["emu"] - t["cb"] - t["trap"]
    per_call = 1e6 * t["cb"] / max(t["calls"], 1)
    print(
        f"{wall:.2f} s wall for {sim_s * 1e3:.0f} simulated ms from reset, "
        f"{instr / 1e6:.1f} M instructions on both boards"
    )
    print(f"  {t['emu']:6.2f} s  in emu_start ({t['slices']} slices), of which")
    print(f"  {t['cb']:12.2f} s  {t['calls']} Python register accesses, {per_call:.1f} us each")
    print(f"  {t['trap']:12.2f} s  {t['traps']} Python traps (WFE, SEV, panic entries)")
    print(
        f"  {in_uc:12.2f} s  unicorn, the native fast path, ctypes' crossings "
        f"({1e9 * in_uc / max(instr, 1):.0f} ns an instruction)"
    )
    print(f"  {wall - t['emu']:6.2f} s  outside: lock-step loop, events, exception entries, pty, start-up")
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main())
    except InputError as e:
        print(f"profile: error: {e}", file=sys.stderr)
        sys.exit(2)
