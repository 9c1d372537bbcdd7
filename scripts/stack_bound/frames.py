"""One function at a time: the constants its registers hold, its branches, and the sp offset
along its control flow (the frame at each call site)."""

import re
from .image import BRANCH, CALL, base, regs, writes


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
    defs = [
        j
        for j, (a, m, o, r) in enumerate(f.insns)
        if reg in writes(m, o) and not m.startswith(("pop", "ldm"))
    ]
    vals = [const_of(img, f, j + 1, reg, 1) for j in defs]
    return set().union(*vals) if defs and all(vals) else None


def const_from_callers(img, f, k, reg):
    """The constant(s) reg holds at f.insns[k] when f is a machine-outlined function that does not
    write reg before k: the union of what each caller's `bl f` leaves in it, or None if any
    caller's value is unknown. LLVM's outliner moves a call's argument set-up, `bx rN` included,
    into such a function, the target still loaded by the caller."""
    if not f.name.startswith("OUTLINED_FUNCTION") or any(
        reg in writes(m, o) for a, m, o, r in f.insns[:k]
    ):
        return None
    vals = set()
    for g in img.funcs.values():
        for j, (a, m, o, r) in enumerate(g.insns):
            if r == f.start and CALL.match(m) and g is not f:
                v = const_of(img, g, j, reg)
                if not v:
                    return None
                vals |= v
    return vals or None


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
                ents = [
                    int.from_bytes(table[k : k + step], "little")
                    for k in range(0, len(table) - step + 1, step)
                ]
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
        if vals is None and re.match(r"^r\d+$", ops):
            vals = const_from_callers(img, f, k, ops)
        exit_, targets = "icall" if b == "blx" else "ijump", (
            [v & ~1 for v in vals] if vals else None
        )
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
    elif (
        (b == "bx" and ops == "lr")
        or (b in ("pop", "ldm") and "pc" in ops)
        or ops.startswith("pc, ")
        or mnem.startswith(("udf", "trap"))
    ):
        exit_, flow = "return", cond and not mnem.startswith("udf")
    if flow and k + 1 < len(f.insns):
        succ.append(k + 1)
    elif flow:
        after = min((s for s in img.starts if s > f.start), default=addr + 4)
        if exit_ == "call":
            # A call that ends its function: its callee, thought to return, returns into the
            # next function. Both at this sp (the firmware's `main` ends calling its `-> !`
            # main through a function the analysis sees returning: the call was dropped).
            targets = targets + [after]
        else:
            exit_, targets = "falls into", [after]
    return exit_, targets, succ


def walk(img, f):
    """Max sp offset and call sites [(addr, offset, kind, targets or None)] of a function."""
    best, seen, visits, sites, fp, problems, work = (
        0,
        {},
        {},
        {},
        {},
        [],
        [(0, 0)] if f.insns else [],
    )
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
            or (
                BRANCH.match(m)
                and r not in f.idx
                and (img.containing(r) is None or callee_returns(img, img.containing(r)))
            )
            for a, m, o, r in f.insns
        )
    return f.returns
