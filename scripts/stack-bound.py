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
import bisect
import json
import re
import struct
import subprocess
import sys
from pathlib import Path

EXC_FRAME = 36  # 8 stacked words + 4 B of alignment padding (no FPU on the M3)
RAM_START = 0x20000000
EXECUTOR = re.compile(r"^embassy_executor::(platform::.*::Executor::run|raw::(Sync)?Executor::poll)")
# bluepill/src/panic.rs: the panic handler logs only on its first entry (`PANICKED.swap`), so a
# panic while logging a panic re-enters it once, and that second entry calls nothing.
ONCE = re.compile(r"^(__rustc::)?rust_begin_unwind$")
WAKER = re.compile(r"^<core::task::wake::Waker( as [^>]*)?>::(wake|wake_by_ref|clone|drop)$")
TASK_POLL = re.compile(r"^embassy_executor::raw::TaskStorage<.*>::poll$")
COND = "eq|ne|cs|hs|cc|lo|mi|pl|vs|vc|hi|ls|ge|lt|gt|le"
BRANCH = re.compile(rf"^(b|b(?:{COND})|cbn?z)(\.[wn])?$")
CALL = re.compile(rf"^bl({COND})?(\.w)?$")
NO_WRITE = re.compile(rf"^(str|stm|push|cmp|cmn|tst|teq|b|bl|bx|blx|cbn?z|it[te]*|nop|dmb|dsb|isb|"
                      rf"msr|cps[ie][de]|wf[ei]|sev|udf|bkpt|svc|tb[bh]|clrex|trap|pld)(?:{COND})?(\.[wn])?$")
NAME_FIXES = [("$LT$", "<"), ("$GT$", ">"), ("$C$", ","), ("$RF$", "&"), ("$BP$", "*"), ("..", "::")]


def clean(name):
    name = re.sub(r"::h[0-9a-f]{16}$", "", name)
    for a, b in NAME_FIXES:
        name = name.replace(a, b)
    name = re.sub(r"\$u([0-9a-f]{2})\$", lambda m: chr(int(m.group(1), 16)), name)
    return name[1:] if name.startswith("_<") else name


def base(mnem):
    """Mnemonic without width suffix or condition: `addne.w` -> `add`, `popne` -> `pop`."""
    m = mnem.split(".")[0]
    s = re.sub(rf"({COND})$", "", m)
    return s if s in ("add", "sub", "addw", "subw", "pop", "push", "ldr", "str", "mov", "bx", "blx", "ldm",
                      "stm") else m


def regs(text):
    out = []
    for part in re.findall(r"\{([^}]*)\}", text)[0].split(","):
        a, _, b = part.strip().partition("-")
        out += [f"r{i}" for i in range(int(a[1:]), int(b[1:]) + 1)] if b and a[0] == "r" else [a]
    return out


def writes(mnem, ops):
    """Registers an instruction writes (besides pc/sp bookkeeping done elsewhere)."""
    b, out = base(mnem), set()
    if "!" in ops or re.search(r"\], #", ops):
        out.add(re.search(r"(\w+)", ops.split("[")[-1] if "[" in ops else ops).group(1))
    if b in ("pop", "ldm") or mnem.startswith("ldm"):
        return out | set(regs(ops))
    if b.startswith(("bl", "blx")):
        return out | {"r0", "r1", "r2", "r3", "r12", "lr"}
    first = [o.strip() for o in ops.split(",")]
    if mnem.startswith("strex"):
        return out | {first[0]}
    if NO_WRITE.match(mnem):
        return out
    if re.match(r"^(ldrd|umull|smull|umlal|smlal)", mnem):
        return out | {first[0], first[1]}
    return out | {first[0]} if first[0] else out


class Func:
    def __init__(self, name, start):
        self.name, self.start, self.insns, self.data, self.mid = name, start, [], [], set()


def parse(text):
    """Disassembly text -> {start: Func}; literal pools/jump tables kept as (addr, bytes)."""
    funcs, cur = {}, None
    for line in text.splitlines():
        m = re.match(r"^([0-9a-f]+) <(.+)>:$", line)
        if m:
            if not m.group(2).startswith("$"):
                cur = funcs.setdefault(int(m.group(1), 16), Func(clean(m.group(2)), int(m.group(1), 16)))
            continue
        parts = line.split("\t")
        if cur is None or len(parts) < 2 or not re.match(r"^\s*[0-9a-f]+:", parts[0]):
            continue
        addr = int(parts[0].split(":")[0], 16)
        if len(parts) >= 4 and parts[2].startswith("."):
            cur.data.append((addr, bytes.fromhex(parts[1].replace(" ", ""))))
        else:
            ops = parts[2] if len(parts) > 2 else ""
            ref = re.search(r"@ 0x([0-9a-f]+)", ops) or re.match(r"^(?:r\d+, )?0x([0-9a-f]+)", ops)
            ops = re.sub(r"\s*(@.*|<.*>)$", "", ops).strip()
            cur.insns.append((addr, parts[1].strip(), ops, int(ref.group(1), 16) if ref else None))
    return funcs


class Image:
    """What the analysis needs from an ELF: disassembly, memory words, vectors and stack room."""

    def __init__(self, name, text, words, vectors, room, layout, data_words, aliases=None, elf=None):
        self.name, self.words, self.vectors, self.room, self.layout = name, words, vectors, room, layout
        self.elf = elf
        self.aliases = aliases or {}  # address -> every symbol there (objdump labels only one)
        self.funcs = parse(text)
        self.starts = sorted(self.funcs)
        for f in self.funcs.values():
            for a, m, o, r in f.insns:  # branches into the middle of another function
                g = self.containing(r) if r and (BRANCH.match(m) or CALL.match(m)) else None
                if g is not None and g is not f and r != g.start:
                    g.mid.add(r)
        self.data_words = data_words  # .rodata and .data: literal pools are read by escapes()

    def containing(self, addr):
        k = bisect.bisect_right(self.starts, addr)
        return self.funcs[self.starts[k - 1]] if k else None

    def word(self, addr):
        return self.words(addr)

    def inline_frames(self, addrs):
        """address -> [innermost inlined function, ..., outermost] from the DWARF line tables."""
        if not self.elf or not addrs:
            return {}
        out, cur = {}, None
        run = subprocess.run(["llvm-addr2line", "-a", "-f", "-i", "-C", "-e", self.elf] + [hex(a) for a in addrs],
                             capture_output=True, text=True)
        for n, line in enumerate(run.stdout.splitlines()):
            if re.match(r"^0x[0-9a-f]+$", line):
                cur, parity = out.setdefault(int(line, 16), []), n + 1
            elif cur is not None and (n - parity) % 2 == 0 and line != "??":
                cur.append(clean(line))
        return out


def load_elf(path):
    blob = Path(path).read_bytes()
    shoff, = struct.unpack_from("<I", blob, 0x20)
    shentsize, shnum, shstrndx = struct.unpack_from("<HHH", blob, 0x2E)
    hdrs = [struct.unpack_from("<IIIIIIIIII", blob, shoff + i * shentsize) for i in range(shnum)]
    strtab = hdrs[shstrndx][4]
    secs = {}
    for h in hdrs:
        name = blob[strtab + h[0]:blob.index(b"\0", strtab + h[0])].decode()
        secs[name] = (h[3], blob[h[4]:h[4] + h[5]] if h[1] != 8 else b"")  # 8 = SHT_NOBITS

    def words(addr):
        for a, data in secs.values():
            if a and a <= addr and addr + 4 <= a + len(data):
                return struct.unpack_from("<I", data, addr - a)[0]
        return None
    data_words = [w for s in (".rodata", ".data") if s in secs
                  for w in struct.unpack_from(f"<{len(secs[s][1]) // 4}I", secs[s][1])]
    vt = secs[".vector_table"][1]
    vectors = list(struct.unpack_from(f"<{len(vt) // 4}I", vt))
    syms, aliases = {}, {}
    for line in subprocess.run(["llvm-nm", path], capture_output=True, text=True, check=True).stdout.splitlines():
        p = line.split()
        if len(p) == 3:
            syms[p[2]] = int(p[0], 16)
            aliases.setdefault(int(p[0], 16) & ~1, set()).add(p[2])
    start, end = syms["_stack_start"], syms.get("_stack_end", 0)
    statics = [a for s, (a, d) in secs.items() if s in (".data", ".bss", ".uninit") and a]
    if statics and start <= min(statics):
        room, layout = start - RAM_START, "flip-link (stack below the statics)"
    else:
        room, layout = start - end, "stack above the statics"
    text = subprocess.run(["llvm-objdump", "-d", "--demangle", "--no-show-raw-insn", path],
                          capture_output=True, text=True, check=True).stdout
    return Image(Path(path).name, text, words, vectors, room, layout, data_words, aliases, path)


def const_of(img, f, i, reg, depth=0):
    """The constant value(s) reg holds just before f.insns[i], or None if it may hold anything else."""
    targets = branch_targets(img, f)
    for j in range(i - 1, -1, -1):
        addr, mnem, ops, ref = f.insns[j]
        if reg in writes(mnem, ops):
            b, vals = mnem.split(".")[0], None
            b = b[:-2] if j in conds(f) else b
            if b == "ldr" and "[pc" in ops and ref is not None:
                vals = {img.word(ref)}
            elif b in ("mov", "movs", "movw") and re.match(rf"^{reg}, #(-?\d+)$", ops):
                vals = {int(ops.split("#")[1]) & 0xFFFFFFFF}
            elif b == "movt":
                lo = const_of(img, f, j, reg, depth + 1)
                vals = {(v & 0xFFFF) | int(ops.split("#")[1]) << 16 for v in lo} if lo else None
            elif b in ("mov", "movs") and re.match(rf"^{reg}, r\d+$", ops) and depth < 4:
                vals = const_of(img, f, j, ops.split(", ")[1], depth + 1)
            if vals and j in conds(f):  # a conditional write: or the value from before
                before = const_of(img, f, j, reg, depth + 1)
                vals = vals | before if before else None
            return None if vals is None or None in vals else vals
        if addr in targets:
            break
    if reg not in {f"r{n}" for n in range(4, 12)} or depth:
        return None
    # Callee-saved registers: a constant at every definition in the function (AAPCS: never an argument).
    defs = [j for j, (a, m, o, r) in enumerate(f.insns) if reg in writes(m, o) and not m.startswith(("pop", "ldm"))]
    vals = [const_of(img, f, j + 1, reg, 1) for j in defs]
    return set().union(*vals) if defs and all(vals) else None


def load_slot(img, f, k):
    """Offset k of the `ldr rN, [rM, #k]` that loaded the register f.insns[k] calls, or None."""
    reg = f.insns[k][2]
    for j in range(k - 1, -1, -1):
        addr, mnem, ops, ref = f.insns[j]
        if reg in writes(mnem, ops):
            m = re.match(rf"^ldr(\.w)? {reg}, \[r\d+(, #(\d+))?\]$", f"{mnem} {ops}")
            return int(m.group(3) or 0) if m else None
        if addr in branch_targets(img, f):
            return None
    return None


def branch_targets(img, f):
    if not hasattr(f, "targets"):
        f.targets = {ref for a, m, o, ref in f.insns if BRANCH.match(m) and ref}
        for a, m, o, ref in f.insns:
            if m.startswith("tb"):
                table, at = b"", a + 4
                for da, d in f.data:
                    if da == at:
                        table, at = table + d, at + len(d)
                step = 1 if m.startswith("tbb") else 2
                ents = [int.from_bytes(table[k:k + step], "little") for k in range(0, len(table) - step + 1, step)]
                f.targets |= {a + 4 + 2 * e for e in ents}
    return f.targets


def sp_effect(img, f, i, off, fp):
    """New sp offset (bytes below entry) after f.insns[i]; None = not statically known."""
    addr, mnem, ops, ref = f.insns[i]
    b = base(mnem)
    if b == "push" or (mnem.startswith("stmdb") and ops.startswith("sp!")):
        return off + 4 * len(regs(ops))
    if b == "pop" or (b == "ldm" and ops.startswith("sp!")):
        return off - 4 * len(regs(ops))
    m = re.search(r"\[sp, #(-?\d+)\]!|\[sp\], #(-?\d+)", ops)
    if m:
        return off - int(m.group(1) or m.group(2))
    if mnem.startswith("msr") and re.match(r"^(msp|psp)", ops):
        return None
    o = [x.strip() for x in ops.split(",")]
    if "sp" not in writes(mnem, ops):
        if b in ("add", "mov") and o[0] in ("r7", "r11") and o[1:2] == ["sp"]:
            fp[o[0]] = off - (int(o[2][1:]) if len(o) > 2 else 0)
        return off
    src = o[1:] if len(o) == 2 or o[1] != "sp" else o[2:]
    if b == "mov" and src[0] in fp:
        return fp[src[0]]
    if b == "sub" and len(o) == 3 and o[1] in fp and o[2].startswith("#"):
        return fp[o[1]] + int(o[2][1:])
    if b not in ("add", "sub", "subw", "addw") or len(src) != 1 or src[0] == "sp":
        return None
    vals = {int(src[0][1:])} if src[0].startswith("#") else const_of(img, f, i, src[0])
    if not vals:
        return None
    v = max(vals) if b.startswith("sub") else min(vals)
    return off + (v if b.startswith("sub") else -v)


def conds(f):
    """Indices of the instructions inside IT blocks (conditional), and the address -> index map."""
    if not hasattr(f, "cond"):
        f.cond, f.idx = set(), {a: k for k, (a, *_) in enumerate(f.insns)}
        for k, (a, m, o, r) in enumerate(f.insns):
            if re.match(r"^it[te]{0,3}$", m):
                f.cond |= set(range(k + 1, k + len(m)))
    return f.cond


def step(img, f, k):
    """Control flow of f.insns[k]: (exit kind or None, targets or None, successor indices)."""
    addr, mnem, ops, ref = f.insns[k]
    b, cond, exit_, targets, succ, flow = base(mnem), k in conds(f), None, None, [], True
    if CALL.match(mnem) and not BRANCH.match(mnem):
        exit_, targets = "call", [ref]
        flow = img.funcs.get(ref) is None or callee_returns(img, img.funcs[ref])
    elif b == "blx" or (b == "bx" and ops != "lr") or re.match(r"^pc, (?!\[sp|lr$)", ops):
        vals = const_of(img, f, k, ops) if re.match(r"^r\d+$", ops) else None
        exit_, targets = "icall" if b == "blx" else "ijump", [v & ~1 for v in vals] if vals else None
        flow = b == "blx" or cond
    elif BRANCH.match(mnem):
        if ref in f.idx:
            succ.append(f.idx[ref])
        else:
            exit_, targets = "tail", [ref]
        flow = mnem.split(".")[0] != "b" or cond
    elif mnem.startswith("tb"):
        succ += [f.idx[t] for t in branch_targets(img, f) if t in f.idx and t > addr]
        flow = False
    elif (b == "bx" and ops == "lr") or (b in ("pop", "ldm") and "pc" in ops) or ops.startswith("pc, ") \
            or mnem.startswith(("udf", "trap")):
        exit_, flow = "return", cond and not mnem.startswith("udf")
    if flow and k + 1 < len(f.insns):
        succ.append(k + 1)
    elif flow:
        exit_, targets = "falls into", [min((s for s in img.starts if s > f.start), default=addr + 4)]
    return exit_, targets, succ


def walk(img, f):
    """Max sp offset and call sites [(addr, offset, kind, targets or None)] of a function."""
    best, seen, visits, sites, fp, problems, work = 0, {}, {}, {}, {}, [], [(0, 0)] if f.insns else []
    while work:
        k, off = work.pop()
        if seen.get(k, -1) >= off:
            continue
        visits[k] = visits.get(k, 0) + 1
        if visits[k] > 8:
            problems.append(f"sp keeps growing around a loop at {f.insns[k][0]:#x}")
            break
        seen[k] = off
        new = sp_effect(img, f, k, off, fp)
        if new is None:
            problems.append("sp set to an unknown value at {:#x}: {} {}".format(*f.insns[k][:3]))
            continue
        new = max(new, off) if k in conds(f) else new  # a conditional sp increment may not happen
        best = max(best, new)
        exit_, targets, succ = step(img, f, k)
        if exit_ and exit_ != "return":
            sites[f.insns[k][0]] = (f.insns[k][0], new, exit_, targets)
        work += [(j, new) for j in succ]
        rest = [f.idx[e] for e in sorted(f.mid) if e in f.idx and f.idx[e] not in seen]
        if not work and rest:  # entered from another function's branch: walked from the max offset
            work = [(rest[0], best)]
    return best, list(sites.values()), problems


def escapes(img, f, k, reg):
    """Whether the constant f.insns[k] puts in reg is used other than by `blx reg` (stored, copied
    into a call's arguments, returned): then the function it points to is address-taken."""
    work, seen = [(k + 1, frozenset([reg]))], set()
    while work:
        j, live = work.pop()
        if not live or j >= len(f.insns) or (j, live) in seen:
            continue
        seen.add((j, live))
        addr, mnem, ops, ref = f.insns[j]
        exit_, targets, succ = step(img, f, j)
        used, first = set(re.findall(r"\b(r\d+|lr)\b", ops)), ops.split(",")[0].strip()
        if base(mnem) == "blx" and ops in live:
            used = set()
        elif re.match(r"^movs?(\.w)?$", mnem) and re.match(r"^r\d+, r\d+$", ops):
            live = live | {first} if ops.split(", ")[1] in live else live - {first}
            used = set()
        elif first in writes(mnem, ops) and (re.match(r"^(ldr|mov)", mnem) or ops.count(",") >= 2):
            used -= {first} if ops.count(first) == 1 else set()
        args = live & {"r0", "r1", "r2", "r3"}  # at a call, a return or a tail call: passed on
        if live & used or (exit_ and args and not (base(mnem) == "blx" and args == {ops})):
            return True
        live = live - writes(mnem, ops) if j not in conds(f) else live
        work += [(n, live) for n in succ]
    return False


def callee_returns(img, f):
    """Whether f can return (to the caller of whoever tail-called it): panics cannot."""
    if not hasattr(f, "returns"):
        f.returns = False  # a cycle of tail calls with no return instruction never returns
        conds(f)
        f.returns = not f.insns or any(
            (base(m) == "bx" or (base(m) in ("pop", "ldm") and "pc" in o) or o.startswith("pc"))
            or (BRANCH.match(m) and r not in f.idx
                and (img.containing(r) is None or callee_returns(img, img.containing(r))))
            for a, m, o, r in f.insns)
    return f.returns


class Analysis:
    def __init__(self, img):
        self.img, self.memo, self.stack, self.cycles, self.problems, self.indirect = img, {}, [], [], [], {}
        self.reentries, is_fn = set(), lambda w: w is not None and w & 1 and (w & ~1) in img.funcs
        self.frames = {s: walk(img, f) for s, f in img.funcs.items()}  # problems count where reached
        taken, refs = {w & ~1 for w in img.data_words if is_fn(w)}, set(img.data_words)
        for f in img.funcs.values():
            refs |= {int.from_bytes(d[i:i + 4], "little") for a, d in f.data for i in range(0, len(d) - 3, 4)}
            for k, (a, m, o, r) in enumerate(f.insns):
                reg = o.split(",")[0]
                if m.startswith("movt") or (m.startswith("ldr") and "[pc" in o):
                    vals = const_of(img, f, k + 1, reg) or set()
                    refs |= vals
                    fns = {v & ~1 for v in vals if is_fn(v)}
                    taken |= fns if fns and escapes(img, f, k, reg) else set()
        self.taken = sorted(taken)
        self.task_polls = {t for t in img.funcs if TASK_POLL.match(img.funcs[t].name)}
        # RawWakerVTable {clone, wake, wake_by_ref, drop}: four function pointers at an address the code uses.
        self.waker_tables = sorted(r for r in refs if all(is_fn(img.word(r + 4 * n)) for n in range(4)))
        sites = [s[0] for fr in self.frames.values() for s in fr[1] if s[3] is None]
        self.inline = img.inline_frames(sites)

    def resolve(self, f, site):
        addr, off, kind, targets = site
        if targets is not None:
            return [t if t in self.img.funcs else getattr(self.img.containing(t), "start", t) for t in targets]
        frames = self.inline.get(addr) or [f.name]
        if WAKER.match(frames[0]) and self.waker_tables:
            k = load_slot(self.img, f, f.idx[addr])
            slots = [k] if k in (0, 4, 8, 12) else [0, 4, 8, 12]
            cands = sorted({self.img.word(t + s) & ~1 for t in self.waker_tables for s in slots})
            rule = f"{frames[0]} (RawWakerVTable slot {'/'.join(str(s // 4) for s in slots)})"
        elif any(EXECUTOR.match(n) for n in frames):
            cands = sorted(set(self.taken) | self.task_polls)
            rule = f"{frames[0]}: every address-taken function, and every task poll"
        else:
            cands = [t for t in self.taken if t not in self.task_polls]
            rule = f"{frames[0]}: every address-taken function but the task polls"
        self.indirect[addr] = (f, addr, kind, rule, cands)
        if not cands:
            self.problems.append(f"{f.name}: indirect {kind} at {addr:#x} with no address-taken function")
        return cands

    def depth(self, start):
        """(depth in bytes, chain [(function, offset at the call, address)]) or (None, []) if unknown."""
        f = self.img.funcs.get(start)
        if f is None:
            self.problems.append(f"call to {start:#x}, which is no function")
            return None, []
        key = (start, any(ONCE.match(self.img.funcs[s].name) for s in self.stack))
        if key in self.memo:
            return self.memo[key]
        own, sites, probs = self.frames[start]
        if start in self.stack and ONCE.match(f.name):  # re-entered: straight to the fault
            self.reentries.add(f"{f.name} re-entered from {self.img.funcs[self.stack[-1]].name}: counted as a leaf")
            return own, [(f.name + " (re-entered)", own, self.frame_addr(f), None)]
        loop = self.stack[len(self.stack) - 1 - self.stack[::-1].index(start):] if start in self.stack else []
        if loop and not any(ONCE.match(self.img.funcs[s].name) for s in loop):
            self.cycles.append(" -> ".join([self.img.funcs[s].name for s in loop] + [f.name]))
            return None, []
        self.stack.append(start)
        self.problems += [f"{f.name}: {p}" for p in probs]
        result = (None, []) if probs else (own, [(f.name, own, self.frame_addr(f), None)])
        for site in sites:
            for t in self.resolve(f, site):
                d, chain = self.depth(t)
                if d is None:
                    result = (None, [])
                elif result[0] is not None and site[1] + d > result[0]:
                    result = (site[1] + d, [(f.name, site[1], self.frame_addr(f), site[0])] + chain)
        self.stack.pop()
        self.memo[key] = result
        return result

    def frame_addr(self, f):
        subs = [(a, m, o) for a, m, o, r in f.insns if base(m) in ("push", "sub", "subw") and o.startswith(("sp", "{"))]
        return max(subs, key=lambda s: int((re.findall(r"#(\d+)", s[2]) or ["0"])[-1]))[0] if subs else f.start


def analyse(img, fraction, priorities=None):
    """The image's bound. `priorities` maps handler names to their NVIC priority (the value
    the firmware sets; unlisted: 0, the NVIC's reset value): handlers of one priority cannot
    preempt each other, so each level adds its deepest handler once."""
    priorities = priorities or {}
    an = Analysis(img)
    reset = img.vectors[1] & ~1
    thread, chain = an.depth(reset)
    handlers, default = [], [v for v in img.vectors[2:] if "DefaultHandler" in img.aliases.get(v & ~1, ())
                             or getattr(img.funcs.get(v & ~1), "name", "") == "DefaultHandler"]
    for n, v in enumerate(img.vectors[2:]):
        if v and (v not in default or v not in img.vectors[2:n + 2]):
            name = "DefaultHandler" if v in default else getattr(img.funcs.get(v & ~1), "name", f"{v:#x}")
            # NMI and HardFault have fixed priorities above every configurable one.
            level = {2: -2, 3: -1}.get(n + 2, priorities.get(name, 0))
            handlers.append((f"{name} (vector {n + 2}, priority {level})", an.depth(v & ~1)[0], level))
    known = thread is not None and all(d is not None for _, d, _ in handlers) and not an.cycles and not an.problems
    deepest = {}
    for _, d, level in handlers:
        if known:
            deepest[level] = max(deepest.get(level, 0), d + EXC_FRAME)
    irq = sum(deepest.values()) if known else None
    bound = thread + irq if known else None
    budget = int(fraction * img.room)
    return dict(name=img.name, bound=bound, thread=thread, interrupts=irq, room=img.room, budget=budget,
                layout=img.layout, ok=known and bound <= budget,
                chain=[dict(function=n, frame=o, sub_sp_at=hex(a), call_at=c and hex(c)) for n, o, a, c in chain],
                handlers=[dict(function=n, depth=d, priority=lv) for n, d, lv in handlers],
                indirect=[dict(function=f.name, at=hex(a), kind=k, bound=rule, targets=len(c),
                               deepest=max(((an.memo.get((t, False), (0,))[0] or 0, img.funcs[t].name)
                                            for t in c), default=None))
                          for f, a, k, rule, c in sorted(an.indirect.values(), key=lambda i: i[1])],
                direct=[dict(function=img.funcs[s].name, at=hex(a),
                             targets=[img.funcs[t].name for t in ts if t in img.funcs])
                        for s in sorted({s for s, _ in an.memo}) for a, o, k, ts in an.frames[s][1]
                        if k[0] == "i" and ts],
                reentries=sorted(an.reentries),
                cycles=sorted(set(an.cycles)), problems=sorted(set(an.problems)))


def summary(r):
    b = lambda v: "unknown" if v is None else f"{v}"
    pct = f"{100 * r['bound'] / r['room']:.1f} %" if r["bound"] is not None else "?"
    print(f"{r['name']:<24} stack bound {b(r['bound'])} B (thread {b(r['thread'])} + interrupts "
          f"{b(r['interrupts'])}) of {r['room']} B room ({pct}), budget {r['budget']} B: "
          f"{'ok' if r['ok'] else 'OVER' if r['bound'] is not None else 'UNKNOWN'}")


def report(r):
    b = lambda v: "unknown" if v is None else f"{v}"
    summary(r)
    print(f"  layout: {r['layout']}")
    print("  deepest thread chain (frame: sp offset at the call; address of the largest push/sub sp; call):")
    for c in r["chain"]:
        print(f"    {c['frame']:6d} B  {c['sub_sp_at']:>10} {c['call_at'] or '':>10}  {c['function']}")
    print("  interrupt handlers (+ 36 B exception frame; the deepest of each priority nests once):")
    for h in r["handlers"]:
        print(f"    {b(h['depth']):>6} B  {h['function']}")
    print("  unresolved indirect call sites (the rest load a constant: direct calls):")
    for i in r["indirect"]:
        d = i["deepest"]
        print(f"    {i['at']:>10} {i['kind']:<4} in {i['function']}: {i['bound']} ({i['targets']}), "
              f"deepest {d[0]} B {d[1]}" if d else f"    {i['at']} in {i['function']}: nothing")
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
    rec = analyse(Image("synthetic-rec", SELF_TEST, words.get, [0, 0x08000101, 0x08000151], 8192, "test", []), 0.5)
    report(rec)
    dyn = analyse(Image("synthetic-alloca", SELF_TEST, words.get, [0, 0x08000171], 8192, "test", []), 0.5)
    report(dyn)
    ok = (over["bound"] == 8 + 4096 + 8 + 8 + 36 and not over["ok"] and rec["bound"] is None and not rec["ok"]
          and any("rec_a -> rec_b -> rec_a" in c for c in rec["cycles"]) and dyn["bound"] is None
          and any("sp set to an unknown value" in p for p in dyn["problems"]))
    print("self-test: " + ("the 4 KiB frame is over budget, the recursion and the unknown sub sp are caught"
                           if ok else "FAILED"))
    return 0 if ok else 1


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--budget-fraction", type=float, default=0.5)
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--summary", action="store_true", help="print each image's one-line summary only")
    ap.add_argument("--self-test", action="store_true")
    ap.add_argument("--priority", metavar="HANDLER=LEVEL", action="append", default=[],
                    help="the NVIC priority the firmware gives HANDLER (repeatable; unlisted: 0)")
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
