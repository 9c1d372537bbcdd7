"""The call graph: frames added along every path from reset and from each handler, indirect calls
resolved or bounded, recursion found; `analyse` makes an image's bound."""

import re
from .image import EXC_FRAME, EXECUTOR, ONCE, TASK_POLL, WAKER, base
from .frames import const_of, escapes, load_slot, walk


class Analysis:
    def __init__(self, img):
        self.img, self.memo, self.stack, self.cycles, self.problems, self.indirect = (
            img,
            {},
            [],
            [],
            [],
            {},
        )
        self.reentries, is_fn = set(), lambda w: w is not None and w & 1 and (w & ~1) in img.funcs
        self.frames = {
            s: walk(img, f) for s, f in img.funcs.items()
        }  # problems count where reached
        taken, refs = {w & ~1 for w in img.data_words if is_fn(w)}, set(img.data_words)
        for f in img.funcs.values():
            refs |= {
                int.from_bytes(d[i : i + 4], "little")
                for a, d in f.data
                for i in range(0, len(d) - 3, 4)
            }
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
        self.waker_tables = sorted(
            r for r in refs if all(is_fn(img.word(r + 4 * n)) for n in range(4))
        )
        sites = [s[0] for fr in self.frames.values() for s in fr[1] if s[3] is None]
        self.inline = img.inline_frames(sites)

    def resolve(self, f, site):
        addr, off, kind, targets = site
        if targets is not None:
            return [
                t if t in self.img.funcs else getattr(self.img.containing(t), "start", t)
                for t in targets
            ]
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
            self.problems.append(
                f"{f.name}: indirect {kind} at {addr:#x} with no address-taken function"
            )
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
            self.reentries.add(
                f"{f.name} re-entered from {self.img.funcs[self.stack[-1]].name}: counted as a leaf"
            )
            return own, [(f.name + " (re-entered)", own, self.frame_addr(f), None)]
        loop = (
            self.stack[len(self.stack) - 1 - self.stack[::-1].index(start) :]
            if start in self.stack
            else []
        )
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
        subs = [
            (a, m, o)
            for a, m, o, r in f.insns
            if base(m) in ("push", "sub", "subw") and o.startswith(("sp", "{"))
        ]
        return (
            max(subs, key=lambda s: int((re.findall(r"#(\d+)", s[2]) or ["0"])[-1]))[0]
            if subs
            else f.start
        )


def analyse(img, fraction, priorities=None):
    """The image's bound. `priorities` maps handler names to their NVIC priority (the value
    the firmware sets; unlisted: 0, the NVIC's reset value): handlers of one priority cannot
    preempt each other, so each level adds its deepest handler once."""
    priorities = priorities or {}
    an = Analysis(img)
    reset = img.vectors[1] & ~1
    thread, chain = an.depth(reset)
    handlers, default = [], [
        v
        for v in img.vectors[2:]
        if "DefaultHandler" in img.aliases.get(v & ~1, ())
        or getattr(img.funcs.get(v & ~1), "name", "") == "DefaultHandler"
    ]
    for n, v in enumerate(img.vectors[2:]):
        if v and (v not in default or v not in img.vectors[2 : n + 2]):
            name = (
                "DefaultHandler"
                if v in default
                else getattr(img.funcs.get(v & ~1), "name", f"{v:#x}")
            )
            # NMI and HardFault have fixed priorities above every configurable one.
            level = {2: -2, 3: -1}.get(n + 2, priorities.get(name, 0))
            handlers.append(
                (f"{name} (vector {n + 2}, priority {level})", an.depth(v & ~1)[0], level)
            )
    known = (
        thread is not None
        and all(d is not None for _, d, _ in handlers)
        and not an.cycles
        and not an.problems
    )
    deepest = {}
    for _, d, level in handlers:
        if known:
            deepest[level] = max(deepest.get(level, 0), d + EXC_FRAME)
    irq = sum(deepest.values()) if known else None
    bound = thread + irq if known else None
    budget = int(fraction * img.room)
    return dict(
        name=img.name,
        bound=bound,
        thread=thread,
        interrupts=irq,
        room=img.room,
        budget=budget,
        layout=img.layout,
        ok=known and bound <= budget,
        chain=[
            dict(function=n, frame=o, sub_sp_at=hex(a), call_at=c and hex(c))
            for n, o, a, c in chain
        ],
        handlers=[dict(function=n, depth=d, priority=lv) for n, d, lv in handlers],
        indirect=[
            dict(
                function=f.name,
                at=hex(a),
                kind=k,
                bound=rule,
                targets=len(c),
                deepest=max(
                    ((an.memo.get((t, False), (0,))[0] or 0, img.funcs[t].name) for t in c),
                    default=None,
                ),
            )
            for f, a, k, rule, c in sorted(an.indirect.values(), key=lambda i: i[1])
        ],
        direct=[
            dict(
                function=img.funcs[s].name,
                at=hex(a),
                targets=[img.funcs[t].name for t in ts if t in img.funcs],
            )
            for s in sorted({s for s, _ in an.memo})
            for a, o, k, ts in an.frames[s][1]
            if k[0] == "i" and ts
        ],
        reentries=sorted(an.reentries),
        cycles=sorted(set(an.cycles)),
        problems=sorted(set(an.problems)),
    )
