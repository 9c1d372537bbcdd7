"""Unicorn's C entry points for the model's hottest paths, without the Python binding's layers.

The binding wraps every MMIO callback in two Python frames and builds ctypes objects for every
register read; the model makes hundreds of thousands of each per simulated second (peripheral
accesses, PC/SP after every slice). Same library, same semantics: an exception in a callback
is kept on the Uc object and the emulation stopped, as the binding does, so `emu_start`
raises it afterwards.
"""

import ctypes
import struct
import sys

from unicorn import Uc, UcError, UC_ARCH_ARM, UC_MODE_THUMB, UC_MODE_MCLASS
from unicorn.arm_const import UC_ARM_REG_R0, UC_CPU_ARM_CORTEX_M3
from unicorn.unicorn_py3.unicorn import uclib, MMIO_READ_CFUNC, MMIO_WRITE_CFUNC

from . import native

_COUNTER_OFFSET = []  # found once per process: [offset or None]


def _handle(uc):
    h = uc._uch
    return h.value if hasattr(h, "value") else h


def counter_offset():
    """Where unicorn keeps its instruction counter for `emu_start(count=N)`, as a byte offset
    into the engine's handle; None if it cannot be found.

    unicorn 2 counts the instructions of a counted run in a 64-bit field of its handle (set to
    0 by `emu_start`, one more before each instruction; the limit N in the next field), but no
    API reads it. Found here by running a loop of a known length on a scratch engine, counted
    against a limit it does not reach, and looking for the pair (instructions run, limit) in
    the handle; then checked on a second run of another length. The model then knows, inside a
    slice, which instruction is running: its peripherals see the time of each access, and a
    slice that stops early (a sleep) counts the instructions it ran; and lowering the limit
    from inside a register access ends the run right after the instruction making it (with
    nothing run twice: `emu_stop` there makes unicorn run that instruction again)."""
    if _COUNTER_OFFSET:
        return _COUNTER_OFFSET[0]
    found = None
    try:
        uc = Uc(UC_ARCH_ARM, UC_MODE_THUMB | UC_MODE_MCLASS)
        uc.ctl_set_cpu_model(UC_CPU_ARM_CORTEX_M3)
        uc.mem_map(0x08000000, 0x1000)
        # 1: subs r0, #1 ; bne 1b ; b .  (the run stops at the `b .`, its `until` address)
        uc.mem_write(0x08000000, bytes.fromhex("0138" "fdd1" "fee7"))
        h, limit = _handle(uc), 99_991

        def run(loops):
            uc.reg_write(UC_ARM_REG_R0, loops)
            uc.emu_start(0x08000001, 0x08000004, count=limit)
            return ctypes.string_at(h, 0x2000)

        # 8 KiB: unicorn 2.1.4's handle is 14.9 KB; a read past its allocation could fault.
        raw = run(300)[:0x2000]
        want = struct.pack("<QQ", 600, limit)
        candidates = [at for at in range(0, len(raw) - 15, 8) if raw[at : at + 16] == want]
        again = run(421)
        for at in candidates:
            if again[at : at + 16] == struct.pack("<QQ", 842, limit):
                found = at
                break
    except Exception:  # noqa: BLE001 (another engine build: the model runs without it)
        found = None
    if found is None:
        print(
            "board model: unicorn's instruction counter not found (another unicorn build?): "
            "a register access inside a slice sees the slice's start time",
            file=sys.stderr,
        )
    _COUNTER_OFFSET.append(found)
    return found


class FastUc:
    def __init__(self, uc, clock=None):
        """`clock`: an object whose `now` (ticks) is set before each peripheral access to the
        time of the instruction making it, from `slice` = [tick of the slice's first
        instruction, ticks per instruction], which the owner sets before each `emu_start`."""
        self.uc = uc
        self.h = uc._uch
        self._buf = ctypes.c_uint32()
        self._ref = ctypes.byref(self._buf)
        self._keep = []  # the callbacks must outlive the mapping
        self._batches = {}
        self._mem = ctypes.create_string_buffer(256)
        off = counter_offset()
        # The instruction running (1 for a slice's first), or None without the counter; and the
        # run's limit next to it (lowered to end a run after the running instruction).
        self.counter = None if off is None else ctypes.c_uint64.from_address(_handle(uc) + off)
        self.limit = None if off is None else ctypes.c_uint64.from_address(_handle(uc) + off + 8)
        self.clock = clock if self.counter is not None else None
        # The slice's first tick and ticks per instruction (`set_slice`), with the counter: one
        # clock, read by the Python callbacks below and by the native fast path (native.py).
        self.slice = native.Clock(
            ctypes.addressof(self.counter) if self.counter is not None else None, 0, 1.0
        )
        self.native = native.library() if self.counter is not None else None

    def set_slice(self, start, tpi):
        """Before each `emu_start`: the tick of the slice's first instruction, ticks per
        instruction."""
        self.slice.start, self.slice.tpi = start, tpi

    def instruction_time(self):
        """The tick of the instruction running now (`clock` set: inside a slice). The MMIO
        callbacks below compute the same inline: they run ~180 000 times a simulated second during a play."""
        return int(self.slice.start + (self.counter.value - 1) * self.slice.tpi)

    def reg(self, reg_id):
        """A 32-bit core register."""
        uclib.uc_reg_read(self.h, reg_id, self._ref)
        return self._buf.value

    def set_reg(self, reg_id, value):
        v = ctypes.c_uint32(value & 0xFFFFFFFF)
        uclib.uc_reg_write(self.h, reg_id, ctypes.byref(v))

    def regs(self, ids):
        """Several 32-bit core registers in one call (`ids` a tuple: its arrays are cached)."""
        arr = self._batch(ids)
        if uclib.uc_reg_read_batch(self.h, arr[0], arr[1], len(ids)) != 0:
            raise UcError(uclib.uc_errno(self.h))
        return [v.value for v in arr[2]]

    def set_regs(self, ids, values):
        arr = self._batch(ids)
        for cell, v in zip(arr[2], values):
            cell.value = v & 0xFFFFFFFF
        if uclib.uc_reg_write_batch(self.h, arr[0], arr[1], len(ids)) != 0:
            raise UcError(uclib.uc_errno(self.h))

    def _batch(self, ids):
        arr = self._batches.get(ids)
        if arr is None:
            cells = [ctypes.c_uint32() for _ in ids]
            arr = (
                (ctypes.c_int * len(ids))(*ids),
                (ctypes.c_void_p * len(ids))(*[ctypes.addressof(c) for c in cells]),
                cells,
            )
            self._batches[ids] = arr
        return arr

    def read(self, address, size):
        """Memory (RAM or flash) as bytes."""
        buf = self._mem if size <= len(self._mem) else ctypes.create_string_buffer(size)
        status = uclib.uc_mem_read(self.h, address, buf, size)
        if status != 0:
            raise UcError(status)
        return buf.raw[:size]

    def write(self, address, data):
        status = uclib.uc_mem_write(self.h, address, data, len(data))
        if status != 0:
            raise UcError(status)

    def mmio_map(self, address, size, read, write, page=None):
        """`read(offset, size) -> value`, `write(offset, size, value)`, offsets from `address`.
        With `page` (a native.Page) and the native fast path loaded, the range is mapped to the
        fast path, which calls `read`/`write` for what it does not answer itself."""
        uc, clock, counter, slice_ = self.uc, self.clock, self.counter, self.slice

        def on_read(_h, off, size_, _ud):
            if clock is not None:
                clock.now = int(slice_.start + (counter.value - 1) * slice_.tpi)
            try:
                return read(off, size_)
            except BaseException as e:  # noqa: B036 (stop the CPU, re-raise after)
                if uc._hook_exception is None:
                    uc._hook_exception = e
                uc.emu_stop()
                return 0

        def on_write(_h, off, size_, value, _ud):
            if clock is not None:
                clock.now = int(slice_.start + (counter.value - 1) * slice_.tpi)
            try:
                write(off, size_, value)
            except BaseException as e:  # noqa: B036
                if uc._hook_exception is None:
                    uc._hook_exception = e
                uc.emu_stop()

        r, w = MMIO_READ_CFUNC(on_read), MMIO_WRITE_CFUNC(on_write)
        self._keep.append((r, w))
        if page is not None and self.native is not None:
            page.slow_read = ctypes.cast(r, ctypes.c_void_p).value
            page.slow_write = ctypes.cast(w, ctypes.c_void_p).value
            page.clock = ctypes.addressof(self.slice)
            self._keep.append(page)
            fr, fw = native.functions(self.native)
            status = uclib.uc_mmio_map(self.h, address, size, fr, ctypes.addressof(page), fw, ctypes.addressof(page))
        else:
            status = uclib.uc_mmio_map(self.h, address, size, r, None, w, None)
        if status != 0:
            raise UcError(status)
