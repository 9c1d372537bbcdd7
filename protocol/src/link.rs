//! Reliable, in-order delivery of a byte stream over a lossy frame link: go-back-N with a
//! credit window (the host streams played encoder events to the master with it).
//!
//! Sans-IO: [`GbnSender`] and [`GbnReceiver`] are plain state machines. The caller moves
//! [`DataFrame`]s and [`Ack`]s over whatever link it has, drops frames that fail their CRC
//! (a corrupted frame is a lost frame here), and passes the time in explicitly (`now_us`).
//! No heap, no panics, the same code on the host and on an STM32F103.
//!
//! Sequence numbers count **bytes** (like TCP), modulo 2^16: a frame's `seq` is the stream
//! offset of its first byte, an ack's `next` is the offset of the first byte the receiver has
//! not got yet, and `credit` is how many bytes beyond `next` it can still buffer. Offsets are
//! compared with wrapping arithmetic, which is unambiguous because neither end ever holds more
//! than [`MAX_WINDOW`] bytes. Both ends start at offset 0; to start a new session, make new
//! ones.
//!
//! Rules (docs/protocol.md has the whole story, with an example):
//! * The receiver takes only bytes that continue the stream at `next`; it drops a frame that
//!   starts beyond `next` (one before it was lost) and answers with `gap = true`, and drops a
//!   frame it already has (answering with a plain ack, in case the earlier ack was lost).
//! * The sender never lets bytes in flight pass `next + credit` of the newest ack. It goes
//!   back to its oldest unacked byte after `timeout` without progress (doubling the timeout up
//!   to 8x while nothing progresses) and at once on a `gap` ack, then resends from there.
//! * A closed window cannot deadlock: the receiver sends a window update on its own when its
//!   consumer frees a quarter of its buffer, and a sender that has data but no credit and
//!   nothing in flight sends an empty probe frame every timeout, which any receiver answers.

use heapless::Vec;
use postcard::experimental::max_size::MaxSize;
use postcard_schema::Schema;
use serde::{Deserialize, Serialize};

/// Payload bytes per data frame on the serial link: a `DataFrame` plus a message tag fits in
/// one serial message payload (checked below).
pub const MAX_CHUNK: usize = 120;
/// Default retransmission (and probe) timeout.
pub const DEFAULT_TIMEOUT_US: u64 = 50_000;
/// Largest buffer at either end: everything unacknowledged must span less than half of the
/// 16-bit sequence space, so wrapping comparisons stay unambiguous.
pub const MAX_WINDOW: usize = 32_767;
/// The timeout doubles on every expiry without progress, up to `timeout << MAX_BACKOFF_SHIFT`.
const MAX_BACKOFF_SHIFT: u32 = 3;

/// Stream bytes starting at stream offset `seq` (modulo 2^16). An empty frame is a probe: it
/// asks the receiver for an ack.
#[derive(Serialize, Deserialize, Schema, Clone, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DataFrame<const N: usize = MAX_CHUNK> {
    pub seq: u16,
    pub bytes: Vec<u8, N>,
}

// postcard derives `MaxSize` only for heapless 0.7; the rule is simple enough to write down:
// seq varint, length varint, the bytes.
impl<const N: usize> MaxSize for DataFrame<N> {
    const POSTCARD_MAX_SIZE: usize = u16::POSTCARD_MAX_SIZE + varint_len(N) + N;
}

const fn varint_len(mut n: usize) -> usize {
    let mut len = 1;
    while n >= 0x80 {
        n >>= 7;
        len += 1;
    }
    len
}

// One byte for the tag of the enum variant that will carry the frame.
const _: () = assert!(DataFrame::<MAX_CHUNK>::POSTCARD_MAX_SIZE < crate::serial::MAX_PAYLOAD);

/// The receiver's answer: "I have everything before `next` and room for `credit` more bytes".
#[derive(Serialize, Deserialize, Schema, MaxSize, Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Ack {
    /// Stream offset (mod 2^16) of the first byte not received yet.
    pub next: u16,
    /// Bytes the receiver can still take beyond `next`.
    pub credit: u16,
    /// Since the previous ack, a frame arrived that started beyond `next`: an earlier frame was
    /// lost, so the sender should go back to `next` now instead of waiting for its timeout.
    pub gap: bool,
}

/// `a - b` in sequence space: positive when `a` is after `b`.
fn seq_diff(a: u16, b: u16) -> i32 {
    i32::from(a.wrapping_sub(b) as i16)
}

/// Advance a sequence number by a byte count no larger than [`MAX_WINDOW`].
fn seq_add(seq: u16, n: usize) -> u16 {
    seq.wrapping_add(n as u16)
}

/// Sender counters (all wrap).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SenderStats {
    /// Data frames handed out by `poll_transmit`, retransmissions included, probes not.
    pub frames_sent: u32,
    /// Of those, frames that resent at least one byte sent before.
    pub frames_retransmitted: u32,
    /// Empty frames sent to ask a receiver with a closed window for an ack.
    pub probes_sent: u32,
    /// Timeouts that sent the sender back to its oldest unacked byte.
    pub timeouts: u32,
    /// `gap` acks that sent it back.
    pub gap_go_backs: u32,
    pub acks_received: u32,
    /// Acks for bytes never sent or older than the newest progress (reordered, other session).
    pub acks_ignored: u32,
    /// Bytes the receiver acknowledged: delivered.
    pub bytes_acked: u32,
}

/// Sending end: buffers up to `BYTES` offered bytes until they are acknowledged, and cuts
/// them into frames of up to `CHUNK` bytes.
pub struct GbnSender<const BYTES: usize, const CHUNK: usize = MAX_CHUNK> {
    buf: [u8; BYTES],
    /// Ring index of the oldest unacked byte, whose stream offset is `base`.
    head: usize,
    /// Bytes held from `head`: in flight, then never sent.
    len: usize,
    base: u16,
    /// Bytes from `head` sent at least once.
    sent_hi: usize,
    /// Next byte to send, from `head` (below `sent_hi` while resending after a go-back).
    cursor: usize,
    /// The receiver's window edge: bytes before this offset may be in flight.
    edge: u16,
    /// After a go-back, `gap` acks are ignored until the acks reach this offset: the ones
    /// still arriving were caused by frames sent before the go-back.
    recover_end: Option<u16>,
    timeout_us: u64,
    backoff: u32,
    /// When the wait for progress (or for a probe's answer) began; `None`: nothing awaited.
    timer_us: Option<u64>,
    stats: SenderStats,
}

impl<const BYTES: usize, const CHUNK: usize> Default for GbnSender<BYTES, CHUNK> {
    fn default() -> Self {
        Self::new(DEFAULT_TIMEOUT_US)
    }
}

impl<const BYTES: usize, const CHUNK: usize> GbnSender<BYTES, CHUNK> {
    const SIZES_OK: () = assert!(
        BYTES > 0 && BYTES <= MAX_WINDOW && CHUNK > 0,
        "GbnSender needs 0 < BYTES <= MAX_WINDOW and CHUNK > 0"
    );

    /// A sender at stream offset 0 that retransmits after `timeout_us` without progress.
    /// It knows no credit yet, so its first frame is a probe.
    pub const fn new(timeout_us: u64) -> Self {
        #[allow(clippy::let_unit_value)]
        let () = Self::SIZES_OK;
        GbnSender {
            buf: [0; BYTES],
            head: 0,
            len: 0,
            base: 0,
            sent_hi: 0,
            cursor: 0,
            edge: 0,
            recover_end: None,
            timeout_us,
            backoff: 0,
            timer_us: None,
            stats: SenderStats {
                frames_sent: 0,
                frames_retransmitted: 0,
                probes_sent: 0,
                timeouts: 0,
                gap_go_backs: 0,
                acks_received: 0,
                acks_ignored: 0,
                bytes_acked: 0,
            },
        }
    }

    /// [`new`](Self::new) again, in place: the buffer's old bytes are never read again
    /// (`len` is 0), and a new sender built on a board's stack to be copied over this one
    /// would be its whole buffer there.
    pub fn reset(&mut self, timeout_us: u64) {
        self.head = 0;
        self.len = 0;
        self.base = 0;
        self.sent_hi = 0;
        self.cursor = 0;
        self.edge = 0;
        self.recover_end = None;
        self.timeout_us = timeout_us;
        self.backoff = 0;
        self.timer_us = None;
        self.stats = SenderStats::default();
    }

    /// Room for [`offer`](Self::offer), in bytes.
    pub fn free(&self) -> usize {
        BYTES - self.len
    }

    /// Bytes offered but not acknowledged yet (in flight or waiting).
    pub fn unacked(&self) -> usize {
        self.len
    }

    /// Everything offered has been acknowledged.
    pub fn is_idle(&self) -> bool {
        self.len == 0
    }

    /// Copy as many of `bytes` as fit into the window buffer; returns how many were taken.
    /// Offer as much as you have before polling: `poll_transmit` sends what is there at once,
    /// so offering a byte at a time between polls makes tiny frames.
    pub fn offer(&mut self, bytes: &[u8]) -> usize {
        let n = bytes.len().min(self.free());
        for (i, &b) in bytes[..n].iter().enumerate() {
            self.buf[(self.head + self.len + i) % BYTES] = b;
        }
        self.len += n;
        n
    }

    pub fn stats(&self) -> SenderStats {
        self.stats
    }

    /// When `poll_transmit` will next have something to do if nothing else happens (a timeout
    /// or a probe), or `None` while it waits for nothing.
    pub fn poll_at(&self) -> Option<u64> {
        self.timer_us.map(|t| t.saturating_add(self.rto()))
    }

    fn rto(&self) -> u64 {
        self.timeout_us.saturating_mul(1 << self.backoff)
    }

    /// Bytes from `head` the receiver's window allows in flight.
    fn window(&self) -> usize {
        seq_diff(self.edge, self.base).max(0) as usize
    }

    fn recovering(&self) -> bool {
        self.recover_end
            .is_some_and(|end| seq_diff(end, self.base) > 0)
    }

    fn go_back(&mut self) {
        self.cursor = 0;
        self.recover_end = Some(seq_add(self.base, self.sent_hi));
    }

    /// The next frame to put on the link, if any: a retransmission, new data within the
    /// receiver's credit, or a probe. Call until it returns `None`, and again by
    /// [`poll_at`](Self::poll_at).
    pub fn poll_transmit(&mut self, now_us: u64) -> Option<DataFrame<CHUNK>> {
        if self
            .timer_us
            .is_some_and(|t| now_us.saturating_sub(t) >= self.rto())
        {
            if self.sent_hi > 0 {
                self.stats.timeouts = self.stats.timeouts.wrapping_add(1);
                self.go_back();
            }
            self.backoff = (self.backoff + 1).min(MAX_BACKOFF_SHIFT);
            // Re-armed by whatever is sent next.
            self.timer_us = None;
        }
        // Bytes below `sent_hi` were inside an earlier window, and windows never shrink.
        let allowed = self.len.min(self.window().max(self.sent_hi));
        if self.cursor < allowed {
            let n = (allowed - self.cursor).min(CHUNK);
            let mut bytes = Vec::new();
            for i in 0..n {
                // Cannot fail: n <= CHUNK.
                let _ = bytes.push(self.buf[(self.head + self.cursor + i) % BYTES]);
            }
            let frame = DataFrame {
                seq: seq_add(self.base, self.cursor),
                bytes,
            };
            self.stats.frames_sent = self.stats.frames_sent.wrapping_add(1);
            if self.cursor < self.sent_hi {
                self.stats.frames_retransmitted = self.stats.frames_retransmitted.wrapping_add(1);
            }
            self.cursor += n;
            self.sent_hi = self.sent_hi.max(self.cursor);
            self.timer_us.get_or_insert(now_us);
            return Some(frame);
        }
        // Data waiting, no credit, nothing in flight whose ack could bring some: probe.
        if self.len > 0 && self.sent_hi == 0 && self.timer_us.is_none() {
            self.stats.probes_sent = self.stats.probes_sent.wrapping_add(1);
            self.timer_us = Some(now_us);
            return Some(DataFrame {
                seq: self.base,
                bytes: Vec::new(),
            });
        }
        None
    }

    /// Take in an ack from the receiver.
    pub fn on_ack(&mut self, ack: Ack, now_us: u64) {
        self.stats.acks_received = self.stats.acks_received.wrapping_add(1);
        let advance = seq_diff(ack.next, self.base);
        if advance < 0 || advance as usize > self.sent_hi {
            self.stats.acks_ignored = self.stats.acks_ignored.wrapping_add(1);
            return;
        }
        let advance = advance as usize;
        let edge = seq_add(ack.next, usize::from(ack.credit).min(MAX_WINDOW));
        // An edge behind the known one comes from an older ack that arrived late.
        if seq_diff(edge, self.edge) > 0 {
            self.edge = edge;
        }
        if advance > 0 {
            self.head = (self.head + advance) % BYTES;
            self.len -= advance;
            self.sent_hi -= advance;
            self.cursor = self.cursor.saturating_sub(advance);
            self.base = ack.next;
            self.stats.bytes_acked = self.stats.bytes_acked.wrapping_add(advance as u32);
            self.backoff = 0;
            self.timer_us = (self.sent_hi > 0).then_some(now_us);
        }
        if self.sent_hi == 0 {
            // Nothing in flight: the receiver answered. With a closed window, wait a timeout
            // before probing again (its window update may come first).
            self.backoff = 0;
            self.timer_us = (self.len > 0 && self.window() == 0).then_some(now_us);
        } else if ack.gap && !self.recovering() {
            self.stats.gap_go_backs = self.stats.gap_go_backs.wrapping_add(1);
            self.go_back();
        }
    }
}

/// Receiver counters (all wrap).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ReceiverStats {
    /// Frames that brought new bytes.
    pub frames_accepted: u32,
    /// Frames holding only bytes already received.
    pub frames_duplicate: u32,
    /// Frames that started beyond `next` (an earlier frame was lost) and were dropped.
    pub frames_out_of_order: u32,
    /// Empty frames (probes).
    pub probes: u32,
    /// New bytes that did not fit the buffer and were dropped: stays 0 with a sender that
    /// respects the credit.
    pub bytes_overflowed: u32,
    /// New bytes accepted into the buffer.
    pub bytes_received: u32,
    pub acks_sent: u32,
}

/// Receiving end: owns a ring buffer of `BYTES`, which the consumer drains with
/// [`read`](Self::read). The credit it advertises is that buffer's free room, so it can never
/// overflow.
pub struct GbnReceiver<const BYTES: usize> {
    buf: [u8; BYTES],
    head: usize,
    len: usize,
    next: u16,
    /// A frame arrived since the last ack.
    ack_due: bool,
    gap: bool,
    /// `next + credit` of the last ack sent.
    advertised_edge: u16,
    stats: ReceiverStats,
}

impl<const BYTES: usize> Default for GbnReceiver<BYTES> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const BYTES: usize> GbnReceiver<BYTES> {
    const SIZE_OK: () = assert!(
        BYTES > 0 && BYTES <= MAX_WINDOW,
        "GbnReceiver needs 0 < BYTES <= MAX_WINDOW"
    );
    /// Free room growth past the last advertised edge that makes a window update due.
    const UPDATE_THRESHOLD: usize = if BYTES >= 4 { BYTES / 4 } else { 1 };

    /// A receiver expecting stream offset 0.
    pub const fn new() -> Self {
        #[allow(clippy::let_unit_value)]
        let () = Self::SIZE_OK;
        GbnReceiver {
            buf: [0; BYTES],
            head: 0,
            len: 0,
            next: 0,
            ack_due: false,
            gap: false,
            advertised_edge: 0,
            stats: ReceiverStats {
                frames_accepted: 0,
                frames_duplicate: 0,
                frames_out_of_order: 0,
                probes: 0,
                bytes_overflowed: 0,
                bytes_received: 0,
                acks_sent: 0,
            },
        }
    }

    /// [`new`](Self::new) again, in place (see [`GbnSender::reset`]).
    pub fn reset(&mut self) {
        self.head = 0;
        self.len = 0;
        self.next = 0;
        self.ack_due = false;
        self.gap = false;
        self.advertised_edge = 0;
        self.stats = ReceiverStats::default();
    }

    /// Bytes received and not read yet.
    pub fn len(&self) -> usize {
        self.len
    }

    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Free room in the buffer: the credit the next ack will carry.
    pub fn free(&self) -> usize {
        BYTES - self.len
    }

    pub fn stats(&self) -> ReceiverStats {
        self.stats
    }

    /// Take in a data frame (one that passed its CRC); returns how many new bytes it added.
    pub fn on_data<const N: usize>(&mut self, frame: &DataFrame<N>) -> usize {
        self.on_frame(frame.seq, &frame.bytes)
    }

    /// [`on_data`](Self::on_data) for a frame's parts.
    pub fn on_frame(&mut self, seq: u16, bytes: &[u8]) -> usize {
        self.ack_due = true;
        let ahead = seq_diff(seq, self.next);
        if ahead > 0 {
            self.gap = true;
            self.stats.frames_out_of_order = self.stats.frames_out_of_order.wrapping_add(1);
            return 0;
        }
        // The frame may start before `next` (a resend after a lost ack): skip what we have.
        let known = ahead.unsigned_abs() as usize;
        let Some(fresh) = bytes.get(known..).filter(|fresh| !fresh.is_empty()) else {
            if bytes.is_empty() {
                self.stats.probes = self.stats.probes.wrapping_add(1);
            } else {
                self.stats.frames_duplicate = self.stats.frames_duplicate.wrapping_add(1);
            }
            return 0;
        };
        let n = fresh.len().min(self.free());
        for (i, &b) in fresh[..n].iter().enumerate() {
            self.buf[(self.head + self.len + i) % BYTES] = b;
        }
        self.len += n;
        self.next = seq_add(self.next, n);
        self.stats.frames_accepted = self.stats.frames_accepted.wrapping_add(1);
        self.stats.bytes_received = self.stats.bytes_received.wrapping_add(n as u32);
        self.stats.bytes_overflowed = self
            .stats
            .bytes_overflowed
            .wrapping_add((fresh.len() - n) as u32);
        n
    }

    /// Move up to `out.len()` received bytes, oldest first, into `out`; returns how many.
    /// The room this frees is advertised by the next ack (or a window update, see
    /// [`poll_ack`](Self::poll_ack)).
    pub fn read(&mut self, out: &mut [u8]) -> usize {
        let n = out.len().min(self.len);
        for (i, slot) in out[..n].iter_mut().enumerate() {
            *slot = self.buf[(self.head + i) % BYTES];
        }
        self.head = (self.head + n) % BYTES;
        self.len -= n;
        n
    }

    /// The ack to send now, if one is due: a frame arrived since the last ack, or the consumer
    /// freed a quarter of the buffer beyond what the last ack advertised (a window update,
    /// which is what reopens a closed window). Call after taking in frames and after reading.
    pub fn poll_ack(&mut self) -> Option<Ack> {
        let grown = seq_diff(seq_add(self.next, self.free()), self.advertised_edge);
        if self.ack_due || grown >= Self::UPDATE_THRESHOLD as i32 {
            Some(self.ack())
        } else {
            None
        }
    }

    /// An ack for the current state, due or not (e.g. to piggy-back on other traffic).
    pub fn ack(&mut self) -> Ack {
        let ack = Ack {
            next: self.next,
            credit: self.free() as u16,
            gap: self.gap,
        };
        self.advertised_edge = seq_add(self.next, self.free());
        self.ack_due = false;
        self.gap = false;
        self.stats.acks_sent = self.stats.acks_sent.wrapping_add(1);
        ack
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn first_frame_is_a_probe_then_data_within_credit() {
        let mut tx = GbnSender::<64, 8>::new(1_000);
        let mut rx = GbnReceiver::<16>::new();
        assert_eq!(tx.offer(&[7; 40]), 40);
        let probe = tx.poll_transmit(0).unwrap();
        assert!(probe.bytes.is_empty());
        assert_eq!(tx.poll_transmit(0), None);
        rx.on_data(&probe);
        tx.on_ack(rx.poll_ack().unwrap(), 10);
        // Credit 16 = two frames of 8.
        assert_eq!(tx.poll_transmit(10).unwrap().bytes.len(), 8);
        assert_eq!(tx.poll_transmit(10).unwrap().seq, 8);
        assert_eq!(tx.poll_transmit(10), None);
    }

    #[test]
    fn sequence_comparison_wraps() {
        assert_eq!(seq_diff(2, 65_534), 4);
        assert_eq!(seq_diff(65_534, 2), -4);
        assert_eq!(seq_add(65_530, 10), 4);
    }

    #[test]
    fn data_frame_max_size_matches_postcard() {
        let frame = DataFrame::<MAX_CHUNK> {
            seq: u16::MAX,
            bytes: Vec::from_slice(&[0xFF; MAX_CHUNK]).unwrap(),
        };
        let mut out = [0u8; 256];
        let used = postcard::to_slice(&frame, &mut out).unwrap().len();
        assert_eq!(used, DataFrame::<MAX_CHUNK>::POSTCARD_MAX_SIZE);
    }
}
