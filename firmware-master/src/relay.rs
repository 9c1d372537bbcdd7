//! The master as a relay between the host's serial streams and the slave's SPI streams, for
//! `play` (sensor events host -> slave) and `record`/`play` (reports slave -> host).
//!
//! ```text
//!  host ── Events (go-back-N, credit) ──► events_in ─► events_out ── SPI chunks ──► slave
//!  host ◄── Reports (go-back-N) ───────── reports_out ◄── reports_in ◄── SPI chunks ── slave
//! ```
//! Each buffer is bounded and each side only ever sends what the next one has room for: the
//! credit the host sees is the room in `events_in`; the slave's reports are taken only as far as
//! `reports_out` has room (the rest it sends again). Sans-IO: the controller calls it.

use core::mem::MaybeUninit;
use protocol::chunks::{ChunkReceiver, ChunkSender};
use protocol::link::{Ack, DataFrame, GbnReceiver, GbnSender, DEFAULT_TIMEOUT_US, MAX_CHUNK};
use protocol::serial::MasterToHost;
use protocol::spi::{Chunk, SlaveFrame};

/// Event bytes buffered from the host (its credit window).
pub const EVENTS_BUFFER: usize = 512;
/// Report bytes buffered for the host.
pub const REPORTS_BUFFER: usize = 512;

pub struct Relay {
    events_in: GbnReceiver<EVENTS_BUFFER>,
    events_out: ChunkSender<EVENTS_BUFFER>,
    reports_in: ChunkReceiver,
    reports_out: GbnSender<REPORTS_BUFFER, MAX_CHUNK>,
}

impl Default for Relay {
    fn default() -> Self {
        Self::new()
    }
}

impl Relay {
    /// By value, for the host's tests; the board builds its relay in place
    /// ([`init`](Self::init)).
    pub fn new() -> Self {
        let mut slot = MaybeUninit::uninit();
        Relay::init(&mut slot);
        // SAFETY: `init` wrote every field.
        unsafe { slot.assume_init() }
    }

    /// A relay written in place into `slot` (the controller's static cell), a field at a
    /// time: the relay is 1.7 KB, too much to build on the master's stack and copy.
    pub fn init(slot: &mut MaybeUninit<Relay>) -> &mut Relay {
        robot_math::init_in_place!(
            slot,
            Relay {
                events_in: GbnReceiver::new(),
                events_out: ChunkSender::new(),
                reports_in: ChunkReceiver::new(),
                reports_out: GbnSender::new(DEFAULT_TIMEOUT_US),
            }
        )
    }

    /// A new host session (hello): both serial streams restart at offset 0.
    pub fn reset_host(&mut self) {
        self.events_in.reset();
        self.reports_out.reset(DEFAULT_TIMEOUT_US);
    }

    /// The slave applied a new sensor source: both SPI streams restart at offset 0.
    pub fn reset_slave(&mut self) {
        self.events_out.reset();
        self.reports_in = ChunkReceiver::new();
    }

    pub fn on_host_events(&mut self, frame: &DataFrame) {
        self.events_in.on_data(frame);
    }

    pub fn on_host_ack(&mut self, ack: Ack, now_us: u64) {
        self.reports_out.on_ack(ack, now_us);
    }

    /// The next frame for the host: an ack of its events when one is due, else the next piece
    /// of the reports.
    pub fn poll_host(&mut self, now_us: u64) -> Option<MasterToHost> {
        if let Some(ack) = self.events_in.poll_ack() {
            return Some(MasterToHost::EventsAck(ack));
        }
        self.reports_out
            .poll_transmit(now_us)
            .map(MasterToHost::Reports)
    }

    /// Whether streams are moving (the master then polls the slave faster).
    pub fn busy(&self) -> bool {
        !self.events_in.is_empty()
            || self.events_out.unacked() > 0
            || self.reports_out.unacked() > 0
    }

    /// The event chunk for the next SPI frame. `forward` is false while slave commands are
    /// pending: events wait until the slave has applied the source they belong to.
    pub fn events_chunk(&mut self, forward: bool) -> Chunk {
        if !forward {
            return Chunk::default();
        }
        let mut tmp = [0u8; 64];
        while self.events_out.free() > 0 && !self.events_in.is_empty() {
            let want = self.events_out.free().min(tmp.len());
            let n = self.events_in.read(&mut tmp[..want]);
            self.events_out.push(&tmp[..n]);
        }
        self.events_out.next_chunk()
    }

    /// The report offset to acknowledge in the next SPI frame.
    pub fn reports_next(&self) -> u32 {
        self.reports_in.next
    }

    /// A valid slave frame: its ack of our events, and its reports as far as there is room.
    pub fn on_slave_frame(&mut self, f: &SlaveFrame) {
        self.events_out.on_ack(f.events_next);
        let taken = self.reports_in.accept(&f.reports, self.reports_out.free());
        self.reports_out.offer(taken);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use protocol::Bytes;

    #[test]
    fn events_flow_to_the_slave_and_reports_back_within_their_buffers() {
        let mut r = Relay::new();
        let frame = DataFrame {
            seq: 0,
            bytes: heapless::Vec::from_slice(&[1, 2, 3, 4]).unwrap(),
        };
        r.on_host_events(&frame);
        assert!(matches!(
            r.poll_host(0),
            Some(MasterToHost::EventsAck(Ack { next: 4, .. }))
        ));
        // Held back while commands are pending, then forwarded.
        assert!(r.events_chunk(false).bytes.is_empty());
        let c = r.events_chunk(true);
        assert_eq!((c.offset, c.bytes.as_slice()), (0, &[1u8, 2, 3, 4][..]));
        // The slave reports something; it goes to the host.
        let f = SlaveFrame {
            events_next: 4,
            reports: Chunk {
                offset: 0,
                bytes: Bytes::from_slice_truncating(&[9, 9]),
            },
            ..Default::default()
        };
        r.on_slave_frame(&f);
        assert_eq!(r.reports_next(), 2);
        // No credit from the host yet: the first transmission is an empty probe.
        match r.poll_host(0) {
            Some(MasterToHost::Reports(d)) => assert_eq!((d.seq, d.bytes.len()), (0, 0)),
            other => panic!("expected a probe, got {other:?}"),
        }
        // The host's answer opens its window: the reports follow.
        r.on_host_ack(
            Ack {
                next: 0,
                credit: 512,
                gap: false,
            },
            1,
        );
        match r.poll_host(1) {
            Some(MasterToHost::Reports(d)) => assert_eq!((d.seq, &d.bytes[..]), (0, &[9u8, 9][..])),
            other => panic!("expected the reports, got {other:?}"),
        }
    }
}
