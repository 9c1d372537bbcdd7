"""USART (RM0008 §27.3 functional description, §27.6 registers), asynchronous mode only.

Modelled: BRR (a bit lasts BRR periods of the APB clock, §27.3.4), word length (M) and stop
bits (CR2.STOP) to size a frame; UE/TE/RE; the transmit path TDR -> shift register -> line,
TXE and TC (§27.3.2), the receive path line -> RDR with RXNE, ORE (a byte arriving while RXNE
is set is lost, §27.3.3), IDLE (one idle frame after a reception); the clearing sequences (SR
read then DR read clears IDLE/ORE/NE/FE/PE, SR read then DR write clears TC, RXNE/TC rc_w0);
DMA requests (CR3.DMAT on TXE, CR3.DMAR on RXNE) and the interrupt line.
Bytes leave to `tx_sink(byte)` one frame time after they entered the shift register; bytes
given to `receive(data)` arrive back to back at the line rate, each one frame after the
previous (or after the moment it was given).
Not modelled: parity, framing and noise errors (the line is perfect), break, LIN, smartcard,
IrDA, half-duplex, synchronous mode, hardware flow control, multiprocessor wake-up.
"""

from collections import deque

from .periph import Streaming


class Usart(Streaming):
    def __init__(self, chip, base, name, apb, irq):
        self.name = name
        self.apb = apb
        self.irq_n = irq
        self.tx_sink = None
        super().__init__(chip, base)

    def reset(self):
        self.sr = 0xC0
        self.rdr = 0
        self.brr = 0
        self.cr1 = self.cr2 = self.cr3 = self.gtpr = 0
        self.tdr = None
        self.shift = None
        self.shift_done = None
        self.rx_in = deque()  # bytes waiting on the wire
        self.rx_next = None  # tick when the next byte completes
        self.idle_at = None
        self.sr_seen = 0
        self.bytes_out = 0
        self.bytes_in = 0
        self.overruns = 0

    # --- timing ----------------------------------------------------------------------------
    def frame_ticks(self):
        bits = 1 + (9 if self.cr1 & (1 << 12) else 8)
        stop = (self.cr2 >> 12) & 3
        bits2 = bits * 2 + {0: 2, 1: 1, 2: 4, 3: 3}[stop]  # in half bits
        per_bit = max(self.brr, 16) * (self.chip.TICK_HZ // self.chip.pclk[self.apb])
        return per_bit * bits2 // 2

    def enabled(self):
        return self.cr1 & (1 << 13)

    # --- external side -----------------------------------------------------------------------
    def drop_rx_backlog(self):
        """Forget the bytes given to `receive` that have not started on the line (the byte on
        the line completes); how many. For pty_link.PtyLink, when the host closes the port."""
        n = max(0, len(self.rx_in) - 1)
        while len(self.rx_in) > 1:
            self.rx_in.pop()
        return n

    def receive(self, data):
        now = self.chip.now
        for b in data:
            self.rx_in.append(b)
        if self.rx_next is None and self.rx_in:
            self.rx_next = now + self.frame_ticks()
        self.chip.reschedule()

    # --- engine -------------------------------------------------------------------------------
    def _start_tx(self, t):
        if self.shift is None and self.tdr is not None and self.enabled() and self.cr1 & 8:
            self.shift = self.tdr
            self.tdr = None
            self.sr |= 0x80  # TXE
            self.sr &= ~0x40  # TC
            self.shift_done = t + self.frame_ticks()
            return True
        return False

    def _sync(self, now):
        changed = False
        while self.shift is not None and self.shift_done <= now:
            t = self.shift_done
            b = self.shift
            self.shift = None
            self.bytes_out += 1
            if self.tx_sink:
                self.tx_sink(b)
            if not self._start_tx(t):
                self.sr |= 0x40  # TC
            changed = True
            self.chip.dma.kick()
        while self.rx_next is not None and self.rx_next <= now:
            t = self.rx_next
            b = self.rx_in.popleft()
            if self.enabled() and self.cr1 & 4:
                self.bytes_in += 1
                if self.sr & 0x20:
                    self.sr |= 0x08  # ORE: the new byte is lost
                    self.overruns += 1
                else:
                    self.rdr = b
                    self.sr |= 0x20
                self.idle_at = t + self.frame_ticks()
            self.rx_next = t + self.frame_ticks() if self.rx_in else None
            changed = True
            self._irq()
            self.chip.dma.kick()
        if self.idle_at is not None and self.idle_at <= now and self.rx_next is None:
            self.sr |= 0x10  # IDLE
            self.idle_at = None
            changed = True
        if changed:
            self._irq()
            self.chip.reschedule()

    def next_event(self):
        ts = [
            t
            for t in (
                self.shift_done if self.shift is not None else None,
                self.rx_next,
                self.idle_at if self.rx_next is None else None,
            )
            if t is not None
        ]
        return min(ts) if ts else None

    def dma_request(self, key):
        if key == "tx":
            return bool(
                self.cr3 & 0x80
                and self.sr & 0x80
                and self.tdr is None
                and self.enabled()
                and self.cr1 & 8
            )
        return bool(self.cr3 & 0x40 and self.sr & 0x20)

    def _irq(self):
        s, c1 = self.sr, self.cr1
        lvl = (
            (s & 0x80 and c1 & 0x80)
            or (s & 0x40 and c1 & 0x40)
            or (s & 0x28 and c1 & 0x20)
            or (s & 0x10 and c1 & 0x10)
            or (s & 0x01 and c1 & 0x100)
            or (s & 0x0E and self.cr3 & 1 and self.cr3 & 0x40)
        )
        self.irq(self.irq_n, bool(lvl))

    # --- registers -----------------------------------------------------------------------
    def read(self, off):
        self.sync(self.chip.now)
        if off == 0x00:
            self.sr_seen = self.sr
            return self.sr
        if off == 0x04:
            v = self.rdr
            self.sr &= ~0x20
            self.sr &= ~(self.sr_seen & 0x1F)  # IDLE, ORE, NE, FE, PE after an SR read
            self.sr_seen = 0
            self._irq()
            return v
        return {
            0x08: self.brr,
            0x0C: self.cr1,
            0x10: self.cr2,
            0x14: self.cr3,
            0x18: self.gtpr,
        }.get(off, 0)

    def write(self, off, value, mask):
        now = self.chip.now
        self.sync(now)
        if off == 0x00:
            clr = ~value & mask & 0x360  # rc_w0: CTS, LBD, TC, RXNE
            self.sr &= ~clr
        elif off == 0x04:
            if self.sr_seen & 0x40:
                self.sr &= ~0x40
            self.sr_seen = 0
            self.tdr = value & 0x1FF
            self.sr &= ~0x80
            self._start_tx(now)
        elif off == 0x08:
            self.brr = value & mask & 0xFFFF
        elif off == 0x0C:
            self.cr1 = self.merge(self.cr1, value, mask) & 0x3FFF
            self._start_tx(now)
        elif off == 0x10:
            self.cr2 = self.merge(self.cr2, value, mask) & 0x7FFF
        elif off == 0x14:
            self.cr3 = self.merge(self.cr3, value, mask) & 0x7FF
        elif off == 0x18:
            self.gtpr = value & 0xFFFF
        self._irq()
        self.chip.reschedule()
        self.chip.dma.kick()
