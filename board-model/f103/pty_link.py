"""The master's USART1 on a pseudo-terminal, paced to the wall clock: what `serve` and
`play-check` put between the model and a host program (`host-bench play`/`record`).

Each step of simulated time: the bytes the host wrote to the pty since the last step go to
USART1's receive line (they then arrive at the line rate, in simulated time), the model runs
the step, the bytes USART1 sent go to the pty; then the loop sleeps while the model is ahead of
the wall clock (never when it is behind: it cannot catch up, it says so every 10 s)."""

import os
import select
import sys
import time
import tty

from .core import Chip


class PtyLink:
    def __init__(self, usart):
        self.usart = usart
        self.master_fd, self.slave_fd = os.openpty()
        tty.setraw(self.slave_fd)
        tty.setraw(self.master_fd)
        os.set_blocking(self.master_fd, False)
        self.port = os.ttyname(self.slave_fd)
        self.out = bytearray()
        usart.tx_sink = self.out.append

    def pull(self):
        """Bytes from the host to the USART's receive line."""
        try:
            r, _, _ = select.select([self.master_fd], [], [], 0)
            if r:
                data = os.read(self.master_fd, 4096)
                if data:
                    self.usart.receive(data)
        except (BlockingIOError, OSError):
            pass

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
        for fd in (self.master_fd, self.slave_fd):
            try:
                os.close(fd)
            except OSError:
                pass


def run_paced(bench, link, step_ticks, done, on_step=None):
    """Run `bench` in steps, pumping `link`, paced to the wall clock, until `done()`.
    Returns the wall seconds it took."""
    t0 = time.perf_counter()
    start = bench.now
    lag_reported = 0.0
    while not done():
        link.pull()
        bench.run(step_ticks, stop_on_halt=False)
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
