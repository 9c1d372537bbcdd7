"""Reading a linked Cortex-M3 ELF: its disassembly split into functions, its words, its vector
table and its stack room (see ../stack-bound.py for what the bound assumes)."""

import bisect
import re
import struct
import subprocess
from pathlib import Path


EXC_FRAME = 36  # 8 stacked words + 4 B of alignment padding (no FPU on the M3)
RAM_START = 0x20000000
EXECUTOR = re.compile(
    r"^embassy_executor::(platform::.*::Executor::run|raw::(Sync)?Executor::poll)"
)
# bluepill/src/panic.rs: the panic handler logs only on its first entry (`PANICKED.swap`), so a
# panic while logging a panic re-enters it once, and that second entry calls nothing.
ONCE = re.compile(r"^(__rustc::)?rust_begin_unwind$")
WAKER = re.compile(r"^<core::task::wake::Waker( as [^>]*)?>::(wake|wake_by_ref|clone|drop)$")
TASK_POLL = re.compile(r"^embassy_executor::raw::TaskStorage<.*>::poll$")
COND = "eq|ne|cs|hs|cc|lo|mi|pl|vs|vc|hi|ls|ge|lt|gt|le"
BRANCH = re.compile(rf"^(b|b(?:{COND})|cbn?z)(\.[wn])?$")
CALL = re.compile(rf"^bl({COND})?(\.w)?$")
NO_WRITE = re.compile(
    rf"^(str|stm|push|cmp|cmn|tst|teq|b|bl|bx|blx|cbn?z|it[te]*|nop|dmb|dsb|isb|"
    rf"msr|cps[ie][de]|wf[ei]|sev|udf|bkpt|svc|tb[bh]|clrex|trap|pld)(?:{COND})?(\.[wn])?$"
)
NAME_FIXES = [
    ("$LT$", "<"),
    ("$GT$", ">"),
    ("$C$", ","),
    ("$RF$", "&"),
    ("$BP$", "*"),
    ("..", "::"),
]


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
    return (
        s
        if s
        in (
            "add",
            "sub",
            "addw",
            "subw",
            "pop",
            "push",
            "ldr",
            "str",
            "mov",
            "bx",
            "blx",
            "ldm",
            "stm",
        )
        else m
    )


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
                cur = funcs.setdefault(
                    int(m.group(1), 16), Func(clean(m.group(2)), int(m.group(1), 16))
                )
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

    def __init__(
        self, name, text, words, vectors, room, layout, data_words, aliases=None, elf=None
    ):
        self.name, self.words, self.vectors, self.room, self.layout = (
            name,
            words,
            vectors,
            room,
            layout,
        )
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
        run = subprocess.run(
            ["llvm-addr2line", "-a", "-f", "-i", "-C", "-e", self.elf] + [hex(a) for a in addrs],
            capture_output=True,
            text=True,
        )
        for n, line in enumerate(run.stdout.splitlines()):
            if re.match(r"^0x[0-9a-f]+$", line):
                cur, parity = out.setdefault(int(line, 16), []), n + 1
            elif cur is not None and (n - parity) % 2 == 0 and line != "??":
                cur.append(clean(line))
        return out


def load_elf(path):
    blob = Path(path).read_bytes()
    (shoff,) = struct.unpack_from("<I", blob, 0x20)
    shentsize, shnum, shstrndx = struct.unpack_from("<HHH", blob, 0x2E)
    hdrs = [struct.unpack_from("<IIIIIIIIII", blob, shoff + i * shentsize) for i in range(shnum)]
    strtab = hdrs[shstrndx][4]
    secs = {}
    for h in hdrs:
        name = blob[strtab + h[0] : blob.index(b"\0", strtab + h[0])].decode()
        secs[name] = (h[3], blob[h[4] : h[4] + h[5]] if h[1] != 8 else b"")  # 8 = SHT_NOBITS

    def words(addr):
        for a, data in secs.values():
            if a and a <= addr and addr + 4 <= a + len(data):
                return struct.unpack_from("<I", data, addr - a)[0]
        return None

    data_words = [
        w
        for s in (".rodata", ".data")
        if s in secs
        for w in struct.unpack_from(f"<{len(secs[s][1]) // 4}I", secs[s][1])
    ]
    vt = secs[".vector_table"][1]
    vectors = list(struct.unpack_from(f"<{len(vt) // 4}I", vt))
    syms, aliases = {}, {}
    for line in subprocess.run(
        ["llvm-nm", path], capture_output=True, text=True, check=True
    ).stdout.splitlines():
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
    text = subprocess.run(
        ["llvm-objdump", "-d", "--demangle", "--no-show-raw-insn", path],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    return Image(Path(path).name, text, words, vectors, room, layout, data_words, aliases, path)
