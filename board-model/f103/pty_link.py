"""The master's USART1 on a pseudo-terminal, paced to the wall clock: what `serve` and
`play-check` put between the model and a host program (`host-bench play`/`record`).

Each step of simulated time: the bytes the host wrote to the pty since the last step go to
USART1's receive line (they then arrive at the line rate, in simulated time), the model runs
the step, the bytes USART1 sent go to the pty; then the loop sleeps while the model is ahead of
the wall clock (never when it is behind: it cannot catch up, it says so every 10 s).

A host that closes the port leaves behind what it wrote and the line has not carried yet: the
model, slower than real time, takes the host's wall-clock resends at the line rate of its own
slower clock, so a `play` leaves up to a second of line time queued (9 kB measured at 0.18x),
where a board at speed would have carried it long before another host opened the port. Those
bytes would reach the master in the next host's session and hold its handshake back past the
host's 3 s (wall) answer timeout, so they are dropped when the host hangs up (said on stderr).
To see the hang-up, the link does not keep the pty's slave side open itself."""

import os
import select
import sys
import threading
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
        # raw mode stays with the pty; closed, the slave side shows the host's hang-up
        os.close(self.slave_fd)
        self.slave_fd = None
        self.hangups = 0  # counted by _watch_hangups
        self._hangups_seen = 0
        self._closed = False
        threading.Thread(target=self._watch_hangups, daemon=True).start()
        self.out = bytearray()
        usart.tx_sink = self.out.append

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
        try:
            r, _, _ = select.select([self.master_fd], [], [], 0)
            if r:
                data = os.read(self.master_fd, 4096)
                if data:
                    self.usart.receive(data)
        except (BlockingIOError, OSError):
            pass  # EIO: no host has the port open

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
