"""The model's simulated time in a file, for the host program to take as its clock
(`host-bench play --clock FILE`; host-bench/src/serial/clock.rs reads it).

The model runs the boards at a fraction of real time. A host that times its waits for the
boards by the wall clock (go-back-N's resend after 50 ms, the stall check after 5 s, the
handshake's 3 s, the pacing of its bytes on the line) then waits too short a time of the boards'
and sends again what was only late. Reading its time from this file instead, the host waits
what it would wait for real boards, in their time, at whatever speed the model runs.

The file: 16 bytes, `OMNICLK1` then the simulated nanoseconds since power-on, a little-endian
u64, rewritten in place through a shared mapping after each step of `run_paced` (every 2 ms of
simulated time by default: the host's clock moves in those steps). The host reads it twice
and takes two reads alike, so a read between two writes of the 8 bytes is not taken."""

import mmap
import os
import shutil
import struct
import tempfile

MAGIC = b"OMNICLK1"


class ClockFile:
    def __init__(self):
        self._dir = tempfile.mkdtemp(prefix="board-model-")
        self.path = os.path.join(self._dir, "clock")
        with open(self.path, "wb") as f:
            f.write(MAGIC + bytes(8))
        self._file = open(self.path, "r+b")
        self._map = mmap.mmap(self._file.fileno(), 16)

    def set(self, ns):
        self._map[8:16] = struct.pack("<Q", ns)

    def close(self):
        if self._map is None:
            return
        self._map.close()
        self._file.close()
        self._map = None
        shutil.rmtree(self._dir, ignore_errors=True)
