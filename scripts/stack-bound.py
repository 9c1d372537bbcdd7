#!/usr/bin/env python3
"""Static worst-case stack bound of a Cortex-M3 (thumbv7m) release ELF, checked against its room.

Disassembles the linked image (llvm-objdump), splits it into functions at symbols (`$t`/`$d` are
mapping symbols, not functions: `$d` is a literal pool or a jump table), walks each function's
control flow tracking the sp offset (push/pop, stmdb/ldm sp!, `[sp, #-4]!`, sub/add sp by an
immediate or by a register holding a constant, sp restored from r7), and adds up frames along
the call graph from Reset (thread mode) and from every vector-table handler:

  bound = deepest path from Reset + sum over distinct handlers of (handler depth + 36 B)

36 B = the 8-word exception frame + 4 B of alignment padding (no FPU on the M3). Priorities are
set at run time, and the firmware says them (`--priority HANDLER=LEVEL`, what its board code
sets; unlisted handlers are at 0, the NVIC's reset value, where embassy-stm32 leaves its DMA
and time-driver interrupts): a handler preempts only handlers of a lower priority (a larger
number; PRIGROUP is left at its reset value, so every priority bit is a preemption bit), so
each priority level nests at most once, with its deepest handler. DefaultHandler (cortex-m-rt:
it never returns) counts once however many vectors point at it. A priority set in the board
code and not given here makes the bound unsound: keep the two together.

Conservative (over-approximating) choices:
  * the frame at a call is the largest sp offset reaching it over all paths; conditional (IT)
    sp decrements are taken, conditional increments ignored;
  * a branch into the middle of another function counts that whole function (and walks the
    code from there at the function's largest offset); code falling off a function's end runs
    into the next symbol (memcpy -> memcpy8); panic paths count like any other.
Indirect calls (`blx rN`, `bx rN`, writes to pc), resolved in this order:
  1. rN holds a constant (literal pool, movw/movt, mov #imm) in the same basic block or, for the
     callee-saved r4-r11, at every definition in the function: a direct call (-Oz's idiom);
  2. DWARF says the call is inlined `core::task::Waker::{clone,wake,wake_by_ref,drop}`: that slot
     of every RawWakerVTable (four function pointers at an address the code uses);
  3. otherwise every *address-taken* function: its address|1 is a word in .rodata or .data, or
     a literal-pool/movw-movt constant that escapes (is stored, passed or returned, not only
     called). Vector entries are not address-taken (only the hardware calls them).
  ASSUMPTION (embassy's design): a task's poll function (`TaskStorage<F>::poll`) is only stored
  in its task header's `poll_fn` and only called by the executor, so only a call site inlined
  from EXECUTOR reaches the task polls (and every address-taken function).
  ASSUMPTION (bluepill/src/panic.rs): the panic handler logs only on its first entry, so a panic
  while logging re-enters it once, as a leaf; that cycle is reported and bounded.
Unknown, and the image fails: any other recursion (the cycle is named), an sp write that is not
a constant (or sp growing around a loop), an indirect call with nothing address-taken to bound it.
Room: `_stack_start - _stack_end` (stack above the statics: cortex-m-rt's layout), or
`_stack_start - 0x20000000` when the stack sits below the statics (flip-link).

Usage: python3 scripts/stack-bound.py [--budget-fraction 0.5] [--json] ELF [ELF ...]
       python3 scripts/stack-bound.py --self-test    (synthetic images that must be flagged)
"""

import argparse
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from stack_bound.image import Image, load_elf  # noqa: E402
from stack_bound.graph import analyse  # noqa: E402


def summary(r):
    b = lambda v: "unknown" if v is None else f"{v}"
    pct = f"{100 * r['bound'] / r['room']:.1f} %" if r["bound"] is not None else "?"
    print(
        f"{r['name']:<24} stack bound {b(r['bound'])} B (thread {b(r['thread'])} + interrupts "
        f"{b(r['interrupts'])}) of {r['room']} B room ({pct}), budget {r['budget']} B: "
        f"{'ok' if r['ok'] else 'OVER' if r['bound'] is not None else 'UNKNOWN'}"
    )


def report(r):
    b = lambda v: "unknown" if v is None else f"{v}"
    summary(r)
    print(f"  layout: {r['layout']}")
    print(
        "  deepest thread chain (frame: sp offset at the call; address of the largest push/sub sp; call):"
    )
    for c in r["chain"]:
        print(
            f"    {c['frame']:6d} B  {c['sub_sp_at']:>10} {c['call_at'] or '':>10}  {c['function']}"
        )
    print("  interrupt handlers (+ 36 B exception frame; the deepest of each priority nests once):")
    for h in r["handlers"]:
        print(f"    {b(h['depth']):>6} B  {h['function']}")
    print("  unresolved indirect call sites (the rest load a constant: direct calls):")
    for i in r["indirect"]:
        d = i["deepest"]
        print(
            f"    {i['at']:>10} {i['kind']:<4} in {i['function']}: {i['bound']} ({i['targets']}), "
            f"deepest {d[0]} B {d[1]}"
            if d
            else f"    {i['at']} in {i['function']}: nothing"
        )
    print(f"  indirect call sites that load a constant ({len(r['direct'])}, direct calls):")
    groups = {}
    for i in r["direct"]:
        groups.setdefault((i["function"], ", ".join(i["targets"])), []).append(i["at"])
    for (fn, ts), at in groups.items():
        print(f"    {len(at)}x in {fn} -> {ts} ({' '.join(at)})")
    for c in r["reentries"]:
        print(f"  bounded recursion: {c}")
    for c in r["cycles"]:
        print(f"  RECURSION: {c}")
    for p in r["problems"]:
        print(f"  UNKNOWN: {p}")


SELF_TEST = """
08000100 <Reset>:
 8000100:      \tpush\t{r7, lr}
 8000102:      \tbl\t0x8000110 <main>
 8000106:      \tpop\t{r7, pc}
08000110 <main>:
 8000110:      \tpush\t{r4, lr}
 8000112:      \tsub.w\tsp, sp, #4096
 8000116:      \tldr\tr4, [pc, #8]           @ 0x8000120 <$d>
 8000118:      \tblx\tr4
 800011a:      \tadd.w\tsp, sp, #4096
 800011e:      \tpop\t{r4, pc}
08000120 <$d>:
 8000120:\t31 01 00 08\t.word\t0x08000131
08000130 <leaf>:
 8000130:      \tsub\tsp, #8
 8000132:      \tadd\tsp, #8
 8000134:      \tbx\tlr
08000140 <DefaultHandler>:
 8000140:      \tb\t0x8000140 <DefaultHandler>
08000150 <rec_a>:
 8000150:      \tpush\t{r7, lr}
 8000152:      \tbl\t0x8000160 <rec_b>
 8000156:      \tpop\t{r7, pc}
08000160 <rec_b>:
 8000160:      \tb.w\t0x8000150 <rec_a>
08000170 <alloca>:
 8000170:      \tpush\t{r7, lr}
 8000172:      \tsub\tsp, r0
 8000174:      \tpop\t{r7, pc}
"""


def self_test():
    words = {0x8000120: 0x08000131}
    vec = [0x20002000, 0x08000101, 0x08000141, 0x08000141]
    over = analyse(Image("synthetic-4k", SELF_TEST, words.get, vec, 8192, "test", []), 0.5)
    report(over)
    rec = analyse(
        Image("synthetic-rec", SELF_TEST, words.get, [0, 0x08000101, 0x08000151], 8192, "test", []),
        0.5,
    )
    report(rec)
    dyn = analyse(
        Image("synthetic-alloca", SELF_TEST, words.get, [0, 0x08000171], 8192, "test", []), 0.5
    )
    report(dyn)
    ok = (
        over["bound"] == 8 + 4096 + 8 + 8 + 36
        and not over["ok"]
        and rec["bound"] is None
        and not rec["ok"]
        and any("rec_a -> rec_b -> rec_a" in c for c in rec["cycles"])
        and dyn["bound"] is None
        and any("sp set to an unknown value" in p for p in dyn["problems"])
    )
    print(
        "self-test: "
        + (
            "the 4 KiB frame is over budget, the recursion and the unknown sub sp are caught"
            if ok
            else "FAILED"
        )
    )
    return 0 if ok else 1


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--budget-fraction", type=float, default=0.5)
    ap.add_argument("--json", action="store_true")
    ap.add_argument(
        "--summary", action="store_true", help="print each image's one-line summary only"
    )
    ap.add_argument("--self-test", action="store_true")
    ap.add_argument(
        "--priority",
        metavar="HANDLER=LEVEL",
        action="append",
        default=[],
        help="the NVIC priority the firmware gives HANDLER (repeatable; unlisted: 0)",
    )
    ap.add_argument("elf", nargs="*")
    args = ap.parse_args()
    if args.self_test:
        return self_test()
    if not args.elf:
        ap.error("no ELF given")
    priorities = {}
    for spec in args.priority:
        name, _, level = spec.partition("=")
        if not level.isdigit():
            ap.error(f"--priority {spec!r}: expected HANDLER=LEVEL")
        priorities[name] = int(level)
    status = 0
    for path in args.elf:
        r = analyse(load_elf(path), args.budget_fraction, priorities)
        if args.json:
            print(json.dumps(r))
        elif args.summary:
            summary(r)
        else:
            report(r)
        status |= not r["ok"]
    return status


if __name__ == "__main__":
    sys.exit(main())
