"""The master's USART1 on a pseudo-terminal, paced to the wall clock: what `serve` and
`play-check` put between the model and a host program (`host-bench play`/`record`), with the
model's simulated time in a clock file beside it (clock_file.py) for the host to time its
waits by (`--clock`).

Each step of simulated time: the bytes the host wrote to the pty since the last step go to
USART1's receive line (they then arrive at the line rate, in simulated time), the model runs
the step, the bytes USART1 sent go to the pty; then the loop sleeps while the model is ahead of
the wall clock (never when it is behind: it cannot catch up, it says so every 10 s).

A host that closes the port leaves behind what it wrote and the line has not carried yet: the
model, slower than real time, takes a wall-clock host's resends (one without `--clock`) at the
line rate of its own slower clock, so a `play` leaves up to a second of line time queued (9 kB measured at 0.18x),
where a board at speed would have carried it long before another host opened the port. Those
bytes would reach the master in the next host's session and hold its handshake back past the
host's 3 s (wall) answer timeout, so they are dropped when the host hangs up (said on stderr).
To see the hang-up, the link does not keep the pty's slave side open itself.

The line carries bytes intact only while both ends run at one rate: the host's is what it set
on its end of the pty (termios2's c_ospeed, read back each step), the USART's is f_PCLK / BRR
(§27.3.4); past the receiver's tolerance, about 3.75 % with 16x oversampling (§27.3.5), every
byte arrives as something else, both ways, and is counted. `max_baud` is the fastest rate the
USB-serial adapter carries: above it the bytes are garbled too."""

import fcntl
import os
import select
import struct
import sys
import termios
import threading
import time
import tty

from .clock_file import ClockFile
from .core import Chip


# struct termios2 (asm-generic): four tcflag_t, c_line, 19 control chars, c_ispeed, c_ospeed.
_TERMIOS2 = struct.Struct("4IB19c2I")
_TCGETS2 = 0x802C542A  # _IOR('T', 0x2A, struct termios2) on x86-64 and arm64
# what a UART's receiver tolerates between its rate and the sender's (RM0008 §27.3.5)
_TOLERANCE = 0.0375


def host_baud(fd):
    """The rate the host set on its end of the pty: termios2's c_ospeed (any rate, as
    serialport sets it), else None."""
    try:
        raw = fcntl.ioctl(fd, _TCGETS2, bytes(_TERMIOS2.size))
        return _TERMIOS2.unpack(raw)[-1]
    except OSError:
        return None


def _garble(b):
    """What a byte sent at one rate reads as at another: something else."""
    return ~((b << 3 | b >> 5) & 0xFF) & 0xFF


class PtyLink:
    def __init__(self, usart, max_baud=None):
        self.usart = usart
        self.max_baud = max_baud
        self.garbled = 0
        self.master_fd, self.slave_fd = os.openpty()
        tty.setraw(self.slave_fd)
        tty.setraw(self.master_fd)
        os.set_blocking(self.master_fd, False)
        self.port = os.ttyname(self.slave_fd)
        # raw mode stays with the pty; closed, the slave side shows the host's hang-up
        os.close(self.slave_fd)
        self.slave_fd = None
        self.hangups = 0  # counted by _watch_hangups
        self._hangups_seen = 0
        self._closed = False
        threading.Thread(target=self._watch_hangups, daemon=True).start()
        self.out = bytearray()
        self.host_rate = None  # read back from the pty at each step (`pull`)
        # judged as each byte leaves the shift register, at the rate the USART sent it
        usart.tx_sink = self._sent
        # the simulated time, for a host that takes it as its clock (`--clock`)
        self.clock = ClockFile()

    def _watch_hangups(self):
        """Count the host's hang-ups: POLLHUP on the master side while no process has the
        slave side open. A thread blocked in poll, because the next host may open the port a
        few milliseconds after the last one closed it, inside one step of the model's loop."""
        p = select.poll()
        p.register(self.master_fd, 0)  # POLLHUP is reported whatever the mask
        while not self._closed:
            if p.poll(200):
                self.hangups += 1
                while not self._closed and p.poll(0):  # until a host opens the port
                    time.sleep(0.01)

    def pull(self):
        """Bytes from the host to the USART's receive line; after a host's hang-up, first drop
        what it wrote that is still waiting for the line (see above)."""
        if self.hangups != self._hangups_seen:
            self._hangups_seen = self.hangups
            n = self.usart.drop_rx_backlog()
            if n:
                print(
                    f"board model: the host closed {self.port}; {n} bytes it wrote were still "
                    "waiting for the line: dropped",
                    file=sys.stderr,
                    flush=True,
                )
        self.host_rate = host_baud(self.master_fd)
        try:
            r, _, _ = select.select([self.master_fd], [], [], 0)
            if r:
                data = os.read(self.master_fd, 4096)
                if data:
                    self.usart.receive(self._across(data))
        except (BlockingIOError, OSError):
            pass  # EIO: no host has the port open

    def usart_baud(self):
        """The USART's rate: f_PCLK / BRR (§27.3.4), None before it is set."""
        u = self.usart
        return u.chip.pclk[u.apb] // u.brr if u.brr >= 16 else None

    def line_ok(self):
        """Whether bytes cross intact: both ends at one rate, within what the adapter carries."""
        host, usart = self.host_rate, self.usart_baud()
        if not host or not usart:
            return False
        if self.max_baud and max(host, usart) > self.max_baud:
            return False
        return abs(host - usart) <= _TOLERANCE * usart

    def _across(self, data):
        """`data` as it arrives at the far end of the line."""
        if self.line_ok():
            return data
        self.garbled += len(data)
        return bytes(_garble(b) for b in data)

    def _sent(self, byte):
        """A byte the USART sent, as the host receives it."""
        if self.line_ok():
            self.out.append(byte)
        else:
            self.garbled += 1
            self.out.append(_garble(byte))

    def push(self):
        """Bytes the USART sent, to the host (a host that does not read loses the oldest)."""
        if not self.out:
            return
        try:
            n = os.write(self.master_fd, bytes(self.out))
            del self.out[:n]
        except (BlockingIOError, OSError):
            if len(self.out) > 1 << 16:
                del self.out[: len(self.out) - (1 << 16)]

    def close(self):
        self._closed = True
        self.clock.close()
        try:
            os.close(self.master_fd)
        except OSError:
            pass


def run_paced(bench, link, step_ticks, done, on_step=None):
    """Run `bench` in steps, pumping `link`, paced to the wall clock, until `done()`.
    Returns the wall seconds it took."""
    t0 = time.perf_counter()
    start = bench.now
    lag_reported = 0.0
    link.clock.set(int(bench.now) * 10**9 // Chip.TICK_HZ)
    while not done():
        link.pull()
        bench.run(step_ticks, stop_on_halt=False)
        # the time first, then the bytes: a host never reads a reply before its clock is there
        link.clock.set(int(bench.now) * 10**9 // Chip.TICK_HZ)
        link.push()
        ahead = (bench.now - start) / Chip.TICK_HZ - (time.perf_counter() - t0)
        if ahead > 0:
            time.sleep(ahead)
        elif ahead < -1.0 and time.perf_counter() - lag_reported > 10:
            lag_reported = time.perf_counter()
            print(f"board model: {-ahead:.1f} s behind real time", file=sys.stderr, flush=True)
        if on_step:
            on_step()
    return time.perf_counter() - t0
