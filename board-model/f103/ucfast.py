"""Unicorn's C entry points for the model's hottest paths, without the Python binding's layers.

The binding wraps every MMIO callback in two Python frames and builds ctypes objects for every
register read; the model makes hundreds of thousands of each per simulated second (peripheral
accesses, PC/SP after every slice). Same library, same semantics: an exception in a callback
is kept on the Uc object and the emulation stopped, as the binding does, so `emu_start`
raises it afterwards.
"""

import ctypes

from unicorn import UcError
from unicorn.unicorn_py3.unicorn import uclib, MMIO_READ_CFUNC, MMIO_WRITE_CFUNC


class FastUc:
    def __init__(self, uc):
        self.uc = uc
        self.h = uc._uch
        self._buf = ctypes.c_uint32()
        self._ref = ctypes.byref(self._buf)
        self._keep = []  # the callbacks must outlive the mapping
        self._batches = {}
        self._mem = ctypes.create_string_buffer(256)

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

    def mmio_map(self, address, size, read, write):
        """`read(offset, size) -> value`, `write(offset, size, value)`, offsets from `address`."""
        uc = self.uc

        def on_read(_h, off, size_, _ud):
            try:
                return read(off, size_)
            except BaseException as e:  # noqa: B036 (stop the CPU, re-raise after)
                if uc._hook_exception is None:
                    uc._hook_exception = e
                uc.emu_stop()
                return 0

        def on_write(_h, off, size_, value, _ud):
            try:
                write(off, size_, value)
            except BaseException as e:  # noqa: B036
                if uc._hook_exception is None:
                    uc._hook_exception = e
                uc.emu_stop()

        r, w = MMIO_READ_CFUNC(on_read), MMIO_WRITE_CFUNC(on_write)
        self._keep.append((r, w))
        status = uclib.uc_mmio_map(self.h, address, size, r, None, w, None)
        if status != 0:
            raise UcError(status)
