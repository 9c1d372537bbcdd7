"""Minimal ELF32 reader (program headers) plus symbol look-ups through llvm-nm / llvm-addr2line."""

import bisect
import shutil
import struct
import subprocess

PT_LOAD = 1


def _tool(name):
    for cand in (f"/usr/bin/{name}", shutil.which(name)):
        if cand and shutil.which(cand):
            return cand
    return None


class InputError(Exception):
    """What the user gave (or the machine lacks) keeps the model from starting: said in one
    line by scripts/board-model, exit status 2."""


def need_tool(name):
    """An LLVM tool the model cannot do without (its symbols, its traps), or a clear error."""
    tool = _tool(name)
    if tool is None:
        raise InputError(
            f"board model: {name} not found: the model reads the images' symbols and code with "
            "LLVM's tools (Debian and Ubuntu: apt install llvm)"
        )
    return tool


class Elf:
    def __init__(self, path):
        self.path = path
        try:
            with open(path, "rb") as f:
                data = f.read()
        except OSError as e:
            raise InputError(f"{path}: {e.strerror} (build the images first: cargo build -p "
                             "firmware-slave -p firmware-master --release --target "
                             "thumbv7m-none-eabi)") from None
        if len(data) < 0x34 or data[:4] != b"\x7fELF" or data[4] != 1 or data[5] != 1:
            raise InputError(f"{path}: not a little-endian ELF32 file (an image for the chip)")
        (e_phoff,) = struct.unpack_from("<I", data, 0x1C)
        e_phentsize, e_phnum = struct.unpack_from("<HH", data, 0x2A)
        self.entry = struct.unpack_from("<I", data, 0x18)[0]
        self.segments = []  # (paddr, vaddr, bytes, memsz)
        for i in range(e_phnum):
            p_type, p_off, p_vaddr, p_paddr, p_filesz, p_memsz, _flags, _align = struct.unpack_from(
                "<8I", data, e_phoff + i * e_phentsize
            )
            if p_type == PT_LOAD:
                self.segments.append((p_paddr, p_vaddr, data[p_off : p_off + p_filesz], p_memsz))
        self.symbols = {}
        self._funcs = []  # sorted (addr, name) of text symbols
        nm = need_tool("llvm-nm")
        out = subprocess.run(
            [nm, "-n", "--defined-only", path], capture_output=True, text=True, check=True
        ).stdout
        demangled = subprocess.run(
            [nm, "-n", "-C", "--defined-only", path], capture_output=True, text=True, check=True
        ).stdout.splitlines()
        for line, dline in zip(out.splitlines(), demangled):
            parts = line.split(None, 2)
            dparts = dline.split(None, 2)
            if len(parts) != 3:
                continue
            addr, kind, name = int(parts[0], 16), parts[1], parts[2]
            self.symbols.setdefault(name, addr)
            if kind in "tTwW" and 0x08000000 <= addr < 0x08100000:
                self._funcs.append((addr & ~1, dparts[2] if len(dparts) == 3 else name))
        # one name per address: aliases (identical code folded, DefaultHandler's IRQ names)
        byaddr = {}
        for a, n in self._funcs:
            byaddr.setdefault(a, []).append(n)
        self.aliases = byaddr
        self._funcs = []
        for a, names in sorted(byaddr.items()):
            pick = next((n for n in names if n == "DefaultHandler"), names[0])
            self._funcs.append((a, pick))
        self._faddrs = [a for a, _ in self._funcs]

    def sym(self, name, default=None):
        return self.symbols.get(name, default)

    def find_prefix(self, *fragments):
        """Addresses of symbols whose raw name contains every fragment."""
        return sorted({a for n, a in self.symbols.items() if all(f in n for f in fragments)})

    def name_of(self, addr):
        """Nearest text symbol at or below addr: 'name+0xoff'."""
        i = bisect.bisect_right(self._faddrs, addr & ~1) - 1
        if i < 0:
            return "?"
        a, n = self._funcs[i]
        return n if a == (addr & ~1) else f"{n}+{(addr & ~1) - a:#x}"

    def where(self, addr):
        """Inlined call chain at addr from llvm-addr2line: list of 'function (file:line)'."""
        tool = _tool("llvm-addr2line")
        if not tool:
            return []
        out = subprocess.run(
            [tool, "-f", "-C", "-i", "-e", self.path, hex(addr & ~1)],
            capture_output=True,
            text=True,
        ).stdout.splitlines()
        res = []
        for fn, loc in zip(out[0::2], out[1::2]):
            loc = loc.split("/src/", 1)[-1] if "/src/" in loc else loc
            res.append(f"{fn} ({loc})")
        return res
