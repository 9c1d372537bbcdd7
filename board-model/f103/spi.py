"""SPI (RM0008 §25.3 functional description, §25.5 registers), SPI mode only (no I2S).

Modelled, master (MSTR=1): a byte written to DR goes to the shift register as soon as it is
free (TXE sets again), is clocked out in 8 SCK periods of f_PCLK / 2^(BR+1) (§25.5.1), then the
byte clocked in lands in DR with RXNE (OVR if RXNE was still set: the new byte is lost,
§25.3.10); back-to-back bytes when TX was refilled in time; BSY while shifting; MODF when
SSM=1 and SSI=0 in master mode (§25.3.10: clears SPE and MSTR). The byte clocked in comes
from the peer (`peer`: another board's slave SPI, stage 3) or, without a peer, from the MISO
pin's level (all 0s or all 1s: a missing slave with a pull-down reads 0x00).
Slave (MSTR=0): selected when NSS is low (hardware NSS: the pin; SSM=1: SSI inverted);
`slave_exchange(mosi)` is called by the master at each byte: it returns the byte loaded from
the TX buffer into the shift register (or the previous shift register content when TX is empty:
the underrun case sends what the shift register holds) and puts the received byte in DR.
DMA requests (TXDMAEN on TXE, RXDMAEN on RXNE), the interrupt line (TXEIE, RXNEIE, ERRIE).
Not modelled: CRC, 16-bit frames' timing differences, bidirectional/RX-only modes, LSB
first (bits are not reordered: both ends use the same order), the SCK/MOSI pin waveforms.
"""

from .periph import Streaming


class Spi(Streaming):
    def __init__(self, chip, base, name, apb, irq, miso_pin=None):
        self.name = name
        self.apb = apb
        self.irq_n = irq
        self.miso_pin = miso_pin  # (gpio, pin) used without a peer
        self.peer = None
        self.nss_pin = None  # (gpio, pin) for hardware NSS in slave mode
        super().__init__(chip, base)

    def reset(self):
        self.cr1 = self.cr2 = 0
        self.sr = 0x02
        self.rxbuf = 0
        self.txbuf = None
        self.shift = None
        self.shift_done = None
        self.slave_shift = 0
        self.crcpr = 7
        self.bytes = 0

    def byte_ticks(self):
        br = (self.cr1 >> 3) & 7
        return 8 * (2 << br) * (self.chip.TICK_HZ // self.chip.pclk[self.apb])

    def master(self):
        return self.cr1 & 4 and self.cr1 & 0x40

    def selected(self):
        if self.cr1 & (1 << 9):
            return not (self.cr1 & (1 << 8))
        if self.nss_pin:
            g, p = self.nss_pin
            return g.level(p) == 0
        return False

    # --- master engine -----------------------------------------------------------------------
    def _start(self, t):
        if self.master() and self.shift is None and self.txbuf is not None:
            self.shift = self.txbuf
            self.txbuf = None
            self.sr |= 0x82  # TXE, BSY
            self.shift_done = t + self.byte_ticks()
            return True
        return False

    def _dma_pair(self):
        """(rx, tx) DMA channels when a plain DMA transfer runs both ways (8-bit, memory
        increment, not circular, no SPI interrupt), else None: then bytes can be moved in a
        burst with the same result as one by one."""
        if (
            (self.cr2 & 3) != 3
            or self.cr2 & 0xE0
            or self.sr & 1
            or self.cr1 & 0x800
            or not self.master()
        ):
            return None
        rx, tx = self.chip.dma.plain_channels(self, self.base + 0x0C)
        if rx is None or tx is None or rx.remaining == 0:
            return None
        return rx, tx

    def _burst(self, now, rx, tx):
        """The master's bytes up to `now` in one go: what it clocks out (the shift register,
        the TX buffer, then the TX channel's memory), what comes back from the peer, both
        channels advanced."""
        bt = self.byte_ticks()
        n = min(1 + (now - self.shift_done) // bt, rx.remaining)
        uc = self.chip.fast
        ntx = min(n, tx.remaining)
        src = uc.read(tx.m, ntx) if ntx else b""
        mosi = []
        shift, txbuf, i = self.shift, self.txbuf, 0
        t = self.shift_done
        for _ in range(n):
            mosi.append(shift & 0xFF)
            shift, txbuf = txbuf, None
            if i < ntx:
                txbuf = src[i]
                i += 1
            if shift is None:
                break
            t += bt
        if self.peer is not None:
            out = self.peer.slave_exchange_many(mosi)
        else:
            g, p = self.miso_pin
            out = [0xFF if g.level(p) else 0x00] * len(mosi)
        uc.write(rx.m, bytes(out))
        dma = self.chip.dma
        dma.advance(rx, len(out))
        dma.advance(tx, i)
        self.bytes += len(out)
        self.shift, self.txbuf = shift, txbuf
        if shift is None:
            self.shift_done = None
            self.sr &= ~0x80
        else:
            self.shift_done = t
        self.sr = (self.sr & ~2) | (0 if txbuf is not None else 2)

    def _sync(self, now):
        changed = False
        while self.shift is not None and self.shift_done <= now:
            pair = self._dma_pair()
            if pair is not None:
                self._burst(now, *pair)
                changed = True
                self.chip.dma.kick()
                continue
            t = self.shift_done
            out = self.shift
            self.shift = None
            if self.peer is not None:
                rx = self.peer.slave_exchange(out)
            elif self.miso_pin:
                g, p = self.miso_pin
                rx = 0xFF if g.level(p) else 0x00
            else:
                rx = 0
            self._received(rx)
            self.bytes += 1
            if not self._start(t):
                self.sr &= ~0x80  # BSY off
            changed = True
            self.chip.dma.kick()
        if changed:
            self._irq()
            self.chip.reschedule()

    def _received(self, b):
        if self.sr & 1:
            self.sr |= 0x40  # OVR, byte lost
        else:
            self.rxbuf = b
            self.sr |= 1

    # --- slave side, called by the master's model ------------------------------------------
    def slave_exchange(self, mosi):
        if not (self.cr1 & 0x40) or self.cr1 & 4 or not self.selected():
            return 0xFF if self.cr1 & 0x40 else 0x00
        if self.txbuf is not None:
            out = self.txbuf
            self.txbuf = None
            self.sr |= 0x02
        else:
            out = self.slave_shift
        self.slave_shift = mosi
        self._received(mosi)
        self.bytes += 1
        self._irq()
        self.chip.dma.kick()
        return out

    def slave_exchange_many(self, mosi):
        """`slave_exchange` for each byte of `mosi` in turn, the bytes sent back as a list;
        while both DMA channels run plainly and no SPI interrupt is enabled, in bursts."""
        out = []
        i = 0
        while i < len(mosi):
            pair = self._slave_dma_pair()
            if pair is None:
                out.append(self.slave_exchange(mosi[i]))
                i += 1
                continue
            k = min(len(mosi) - i, pair[0].remaining)
            out += self._slave_burst(mosi[i : i + k], *pair)
            i += k
        return out

    def _slave_dma_pair(self):
        """(rx, tx) when the slave's side of the next bytes can be a burst: enabled, selected,
        8-bit frames, RX and TX by plain DMA (RX with room), RXNE clear, no interrupt enable."""
        if (
            (self.cr1 & 0x844) != 0x40
            or (self.cr2 & 0xE3) != 3
            or self.sr & 1
            or not self.selected()
        ):
            return None
        rx, tx = self.chip.dma.plain_channels(self, self.base + 0x0C)
        if rx is None or tx is None or rx.remaining == 0:
            return None
        return rx, tx

    def _slave_burst(self, mosi, rx, tx):
        """len(mosi) <= rx.remaining bytes as `slave_exchange` moves them: each byte out is the
        TX buffer (refilled by the TX channel right after it is taken, while the channel has
        bytes) or, with the buffer empty, the shift register's last byte in; each byte in is
        taken from DR by the RX channel at once, so RXNE and OVR never show."""
        k = len(mosi)
        uc = self.chip.fast
        ntx = min(k, tx.remaining)
        src = uc.read(tx.m, ntx) if ntx else b""
        out = []
        txbuf, shift, taken = self.txbuf, self.slave_shift, 0
        for b in mosi:
            out.append(shift if txbuf is None else txbuf)
            shift = b
            if taken < ntx:
                txbuf = src[taken]
                taken += 1
            else:
                txbuf = None
        uc.write(rx.m, bytes(mosi))
        dma = self.chip.dma
        dma.advance(rx, k)
        dma.advance(tx, taken)
        self.txbuf, self.slave_shift = txbuf, shift
        if taken:
            self.sr |= 0x80  # BSY, as a DR write in slave mode sets it
        self.sr = (self.sr & ~3) | (2 if txbuf is None else 0)
        self.rxbuf = mosi[-1]
        self.bytes += k
        self._irq()
        return out

    def next_event(self):
        """The next byte completion that can matter to the CPU. While both DMA requests are on
        and no SPI interrupt is enabled, bytes complete unobserved until a DMA channel reaches
        a flag (half or full transfer): the model schedules that byte only (the bytes before it
        are still processed one by one, in order, by sync)."""
        if self.shift is None:
            return None
        k = 1
        if (self.cr2 & 3) == 3 and not (self.cr2 & 0xE0):
            k = None
            for n, srcs in self.chip.dma.sources.items():
                if not any(p is self for p, _ in srcs):
                    continue
                c = self.chip.dma.ch[n]
                if not (c.ccr & 1) or c.remaining == 0:
                    continue
                d = c.remaining
                half = c.total // 2
                if c.remaining > half:
                    d = c.remaining - half
                k = d if k is None else min(k, d)
            if k is None or k < 1:
                k = 1
        return self.shift_done + (k - 1) * self.byte_ticks()

    def dma_request(self, key):
        if key == "tx":
            return bool(self.cr2 & 2 and self.sr & 2 and self.cr1 & 0x40)
        return bool(self.cr2 & 1 and self.sr & 1)

    def _irq(self):
        s, c2 = self.sr, self.cr2
        lvl = (
            (s & 2 and c2 & 0x80 and self.cr1 & 0x40)
            or (s & 1 and c2 & 0x40)
            or (s & 0x70 and c2 & 0x20)
        )
        self.irq(self.irq_n, bool(lvl))

    # --- registers -----------------------------------------------------------------------
    def read(self, off):
        self.sync(self.chip.now)
        if off == 0x00:
            return self.cr1
        if off == 0x04:
            return self.cr2
        if off == 0x08:
            return self.sr
        if off == 0x0C:
            self.sr &= ~1
            self._irq()
            return self.rxbuf
        if off == 0x10:
            return self.crcpr
        return 0

    def write(self, off, value, mask):
        now = self.chip.now
        self.sync(now)
        if off == 0x00:
            self.cr1 = self.merge(self.cr1, value, mask) & 0xFFFF
            if self.cr1 & 4 and self.cr1 & (1 << 9) and not self.cr1 & (1 << 8):
                self.sr |= 0x20  # MODF
                self.cr1 &= ~0x44
            self._start(now)
        elif off == 0x04:
            self.cr2 = self.merge(self.cr2, value, mask) & 0xE7
        elif off == 0x08:
            self.sr &= ~(~value & mask & 0x10)  # CRCERR rc_w0
        elif off == 0x0C:
            self.txbuf = value & 0xFFFF
            self.sr &= ~2
            if self.master():
                self._start(now)
            else:
                self.sr |= 0x80 if self.cr1 & 0x40 else 0
        elif off == 0x10:
            self.crcpr = value & 0xFFFF
        self._irq()
        self.chip.reschedule()
        self.chip.dma.kick()
