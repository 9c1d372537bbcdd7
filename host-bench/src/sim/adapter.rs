//! The USB-serial adapter between `virtual-board`'s pseudo-terminal and its master's USART1,
//! behaving as a real one does, so that what `play` and `record` reach through it is
//! measured, not computed:
//! * both ends must run at one rate, or each sees garbage (the host's rate is what it set on
//!   its port, read back from the pseudo-terminal; the master's is its USART's);
//! * an adapter carries rates only up to its own limit (`--max-baud`: CH340 2 Mbaud, CP2102N
//!   and FT232R 3 Mbaud), above which the bytes arrive garbled too;
//! * bytes take their time on the wire in each direction (8N1: ten bits a byte);
//! * bytes for the host wait in the adapter until a USB packet fills (62 bytes of data) or
//!   its latency timer runs out (`--link-latency-ms`; FTDI's default is 16 ms).

use std::collections::VecDeque;

use embassy_time::{Duration, Instant};

/// Data bytes in one full-speed USB packet from an FTDI chip (64 less two status bytes).
const PACKET_DATA: usize = 62;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AdapterSpec {
    /// The fastest rate it carries.
    pub max_baud: u32,
    /// How long bytes for the host may wait for a packet to fill.
    pub latency: Duration,
}

impl Default for AdapterSpec {
    /// One that carries any rate the master takes and holds nothing back.
    fn default() -> Self {
        AdapterSpec {
            max_baud: protocol::serial::MAX_BAUD,
            latency: Duration::from_ticks(0),
        }
    }
}

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct AdapterStats {
    /// Bytes that crossed at a rate one end or the adapter did not run at.
    pub garbled_bytes: u64,
}

pub struct Adapter {
    spec: AdapterSpec,
    /// Host-to-master bytes not yet on the wire, and when the wire is next free (ns).
    to_master: VecDeque<u8>,
    wire_free_ns: u64,
    /// The last instant the wire was looked at (ns): bytes written to an idle wire start
    /// there.
    seen_ns: u64,
    /// Bytes for the host held in the adapter, and since when the oldest waits.
    held: Vec<u8>,
    held_since: Option<Instant>,
    pub stats: AdapterStats,
}

/// Nanoseconds one 8N1 byte takes at `baud`.
fn byte_ns(baud: u32) -> u64 {
    10_000_000_000 / baud.max(1) as u64
}

impl Adapter {
    pub fn new(spec: AdapterSpec) -> Self {
        Adapter {
            spec,
            to_master: VecDeque::new(),
            wire_free_ns: 0,
            seen_ns: 0,
            held: Vec::new(),
            held_since: None,
            stats: AdapterStats::default(),
        }
    }

    /// Whether bytes cross intact with the host's port at `host` and the master's at
    /// `master`.
    pub fn carries(&self, host: u32, master: u32) -> bool {
        host == master && master <= self.spec.max_baud
    }

    /// What a byte sent at the wrong rate arrives as: something else (its bits read on
    /// another clock); the frames' CRC turns it down.
    fn garble(&mut self, bytes: &mut [u8]) {
        self.stats.garbled_bytes += bytes.len() as u64;
        for b in bytes {
            *b = !b.rotate_left(3);
        }
    }

    /// Bytes the host wrote to its port just now.
    pub fn from_host(&mut self, bytes: &[u8]) {
        if self.to_master.is_empty() {
            self.wire_free_ns = self.wire_free_ns.max(self.seen_ns);
        }
        self.to_master.extend(bytes);
    }

    /// The host's bytes that have crossed the wire by `now`, as the master's USART reads
    /// them.
    pub fn to_master(&mut self, now: Instant, host: u32, master: u32) -> Vec<u8> {
        let now_ns = now.as_micros() * 1000;
        let per_byte = byte_ns(master);
        self.seen_ns = now_ns;
        let n = (((now_ns - self.wire_free_ns) / per_byte) as usize).min(self.to_master.len());
        self.wire_free_ns += n as u64 * per_byte;
        let mut out: Vec<u8> = self.to_master.drain(..n).collect();
        if !self.carries(host, master) {
            self.garble(&mut out);
        }
        out
    }

    /// Bytes the master's USART sent (they have had their wire time there).
    pub fn from_master(&mut self, now: Instant, bytes: &[u8], host: u32, master: u32) {
        if bytes.is_empty() {
            return;
        }
        let mut bytes = bytes.to_vec();
        if !self.carries(host, master) {
            self.garble(&mut bytes);
        }
        self.from_board(now, &bytes);
    }

    /// Bytes the board sends the host outside its USART (the simulator's truth).
    pub fn from_board(&mut self, now: Instant, bytes: &[u8]) {
        if !bytes.is_empty() && self.held.is_empty() {
            self.held_since = Some(now);
        }
        self.held.extend_from_slice(bytes);
    }

    /// What the adapter passes to the host by `now`: full packets at once, the rest once the
    /// oldest byte has waited the latency.
    pub fn to_host(&mut self, now: Instant) -> Vec<u8> {
        let timed_out = self
            .held_since
            .is_some_and(|t| now.saturating_duration_since(t) >= self.spec.latency);
        let n = if timed_out {
            self.held.len()
        } else {
            self.held.len() / PACKET_DATA * PACKET_DATA
        };
        let out: Vec<u8> = self.held.drain(..n).collect();
        if self.held.is_empty() {
            self.held_since = None;
        } else if n > 0 {
            self.held_since = Some(now);
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at_us(us: u64) -> Instant {
        Instant::from_micros(us)
    }

    #[test]
    fn bytes_take_their_wire_time_at_the_masters_rate() {
        let mut a = Adapter::new(AdapterSpec::default());
        assert!(a.to_master(at_us(1_000_000), 115_200, 115_200).is_empty());
        a.from_host(&[1; 100]);
        // 115 200 baud: 86.8 µs a byte, from when the bytes were written.
        assert_eq!(a.to_master(at_us(1_000_869), 115_200, 115_200).len(), 10);
        let rest = a.to_master(at_us(2_000_000), 115_200, 115_200);
        assert_eq!(rest.len(), 90);
        assert!(rest.iter().all(|&b| b == 1));
        // A line kept full carries its rate however often it is looked at: 2 Mbaud, 5 µs a
        // byte, looked at every 0.5 ms for 100 ms.
        a.from_host(&[2; 100_000]);
        let mut got = 0;
        for k in 1..=200 {
            got += a
                .to_master(at_us(2_000_000 + 500 * k), 2_000_000, 2_000_000)
                .len();
        }
        assert_eq!(got, 20_000);
    }

    #[test]
    fn a_rate_one_end_or_the_adapter_does_not_run_at_garbles_every_byte() {
        let spec = AdapterSpec {
            max_baud: 1_000_000,
            ..AdapterSpec::default()
        };
        let mut a = Adapter::new(spec);
        for (i, (host, master, intact)) in [
            (115_200, 115_200, true),
            (115_200, 2_000_000, false),
            (2_000_000, 2_000_000, false),
            (921_600, 921_600, true),
        ]
        .into_iter()
        .enumerate()
        {
            a.from_host(&[0x00, 0x42]);
            let got = a.to_master(at_us(1_000_000 * (i as u64 + 1)), host, master);
            assert_eq!(got == [0x00, 0x42], intact, "{host} -> {master}: {got:?}");
            a.from_master(at_us(0), &[0x00, 0x42], host, master);
            assert_eq!(a.to_host(at_us(0)) == [0x00, 0x42], intact);
        }
        assert_eq!(a.stats.garbled_bytes, 8);
    }

    #[test]
    fn the_latency_timer_holds_what_does_not_fill_a_packet() {
        let spec = AdapterSpec {
            latency: Duration::from_millis(16),
            ..AdapterSpec::default()
        };
        let mut a = Adapter::new(spec);
        a.from_master(at_us(0), &[7; 70], 115_200, 115_200);
        assert_eq!(
            a.to_host(at_us(100)).len(),
            62,
            "a full packet goes at once"
        );
        assert!(a.to_host(at_us(15_000)).is_empty(), "the rest waits");
        assert_eq!(a.to_host(at_us(16_100)).len(), 8);
        assert!(a.to_host(at_us(40_000)).is_empty());
    }
}
