"""The native fast path (native/fastpath.c): built once with the C compiler that links Rust
programs (`cc`), loaded with ctypes, and put behind the peripherals whose registers the images
touch most (the CRC unit, the timers' CNT and DIER, DMA1's CCRx).

`BOARD_MODEL_NATIVE=0` runs the model on Python alone: the two must agree to the last
instruction (tests/test_boot.py runs both and compares the boards' RAM). Without a C compiler
the model says so once and runs on Python alone.
"""

import ctypes
import hashlib
import os
import shlex
import shutil
import subprocess
import sys
import tempfile

SOURCE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "native", "fastpath.c")
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
BUILD_DIR = os.path.join(ROOT, "target", "board-model")

SLOW, MIRROR, TIM_CNT, CRC_DR, CRC_CR = 0, 1, 2, 3, 4

class Clock(ctypes.Structure):
    _fields_ = [("counter", ctypes.c_void_p), ("start", ctypes.c_int64), ("tpi", ctypes.c_double)]


class Page(ctypes.Structure):
    _fields_ = [
        ("regs", ctypes.c_uint32 * 256),
        ("read_kind", ctypes.c_uint8 * 256),
        ("write_kind", ctypes.c_uint8 * 256),
        ("slow_read", ctypes.c_void_p),
        ("slow_write", ctypes.c_void_p),
        ("clock", ctypes.c_void_p),
        ("gate_on", ctypes.c_uint32),
        ("tim_div", ctypes.c_uint32),
        ("tim_cr1", ctypes.c_uint32),
        ("tim_smcr", ctypes.c_uint32),
        ("tim_cnt", ctypes.c_uint32),
        ("tim_psc", ctypes.c_uint32),
        ("tim_psc_active", ctypes.c_uint32),
        ("tim_arr", ctypes.c_uint32),
        ("tim_arr_active", ctypes.c_uint32),
        ("tim_anchor", ctypes.c_int64),
        ("tim_ccr_active", ctypes.c_uint32 * 4),
        ("is_timer", ctypes.c_uint32),
    ]


_LIB = []  # loaded once per process: [library or None]


# -ffp-contract=off: the time of an instruction, start + (n - 1) * tpi, in two roundings as
# Python computes it, never fused into one (an FMA on aarch64, or with -march=native).
FLAGS = ["-O2", "-shared", "-fPIC", "-ffp-contract=off"]


def _build():
    """The shared library's path, built if this source has not been built yet with this
    compiler and these flags."""
    cc = shlex.split(os.environ.get("CC", "")) or [shutil.which("cc") or shutil.which("gcc")]
    if cc[0] is None:
        raise OSError("no C compiler (cc) found")
    with open(SOURCE, "rb") as f:
        digest = hashlib.sha256(f.read() + repr((cc, FLAGS)).encode()).hexdigest()[:16]
    path = os.path.join(BUILD_DIR, f"fastpath-{digest}.so")
    if os.path.exists(path):
        return path
    os.makedirs(BUILD_DIR, exist_ok=True)
    # built beside its final name and renamed: a second process sees the whole file or none
    fd, tmp = tempfile.mkstemp(dir=BUILD_DIR, suffix=".so.partial")
    os.close(fd)
    try:
        subprocess.run(
            [*cc, *FLAGS, "-o", tmp, SOURCE],
            check=True,
            capture_output=True,
            text=True,
        )
        os.replace(tmp, path)
        for old in os.listdir(BUILD_DIR):  # earlier builds, and what a killed build left
            if old.startswith("fastpath-") and old != os.path.basename(path):
                try:
                    os.unlink(os.path.join(BUILD_DIR, old))
                except OSError:
                    pass  # another process's: it cleans up after itself
    except subprocess.CalledProcessError as e:
        raise OSError(f"{' '.join(cc)} failed on {SOURCE}:\n{e.stderr}") from None
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return path


def library():
    """The loaded fast path, or None (turned off, or it could not be built)."""
    if _LIB:
        return _LIB[0]
    lib = None
    if os.environ.get("BOARD_MODEL_NATIVE", "1") != "0":
        try:
            lib = ctypes.CDLL(_build())
            lib.fp_layout.restype = ctypes.c_size_t
            lib.fp_crc32_word.restype = ctypes.c_uint32
            lib.fp_crc32_word.argtypes = [ctypes.c_uint32, ctypes.c_uint32]
            want = [
                ctypes.sizeof(Page),
                Page.slow_read.offset,
                Page.clock.offset,
                Page.tim_anchor.offset,
                ctypes.sizeof(Clock),
                Clock.tpi.offset,
                Page.tim_ccr_active.offset,
                Page.is_timer.offset,
            ]
            got = [lib.fp_layout(i) for i in range(len(want))]
            if got != want:
                raise OSError(f"layout of fastpath.c {got} is not native.py's {want}")
            lib.fp_init()
        except (OSError, AttributeError) as e:  # AttributeError: a symbol missing from the build
            print(f"board model: running without the native fast path: {e}", file=sys.stderr)
            lib = None
    _LIB.append(lib)
    return lib


def functions(lib):
    """(read, write) callback addresses for `uc_mmio_map`."""
    read = ctypes.cast(lib.fp_read, ctypes.c_void_p).value
    write = ctypes.cast(lib.fp_write, ctypes.c_void_p).value
    return read, write
