//! The serial link's rate, negotiated as esptool does: host and master meet at the power-on
//! rate ([`MasterConfig::baud`](crate::MasterConfig::baud)), the host asks for a faster one
//! (`HostToMaster::SetBaud`), the master answers at the old rate and then both switch. A
//! switch that does not work (an adapter that cannot reach the rate, a cable too long for it)
//! must not strand the board: unless a good frame arrives at the new rate within
//! [`BAUD_TRIAL_MS`], or whenever the host falls silent for [`BAUD_SILENCE_MS`], the master goes
//! back to its power-on rate, where any host finds it again.
//!
//! Sans-IO: the controller holds it, the host-tx task sets the port's rate when it says so.

use embassy_time::{Duration, Instant};
use protocol::serial::{BAUD_SILENCE_MS, BAUD_TRIAL_MS, MAX_BAUD, MIN_BAUD};

pub struct BaudLink {
    power_on: u32,
    current: u32,
    /// Switched at this instant, no good frame at the new rate yet.
    trial_since: Option<Instant>,
    /// The last good frame from the host.
    last_good: Option<Instant>,
}

impl BaudLink {
    pub const fn new(power_on: u32) -> Self {
        BaudLink {
            power_on,
            current: power_on,
            trial_since: None,
            last_good: None,
        }
    }

    /// The rate the port runs at now.
    pub fn current(&self) -> u32 {
        self.current
    }

    /// Whether the host may ask for `baud`.
    pub fn accepts(baud: u32) -> bool {
        (MIN_BAUD..=MAX_BAUD).contains(&baud)
    }

    /// The port now runs at `baud` (the reply that announced it is out).
    pub fn switched(&mut self, now: Instant, baud: u32) {
        self.current = baud;
        self.trial_since = (baud != self.power_on).then_some(now);
    }

    /// A good frame from the host arrived: the rate works.
    pub fn on_good_frame(&mut self, now: Instant) {
        self.trial_since = None;
        self.last_good = Some(now);
    }

    /// The power-on rate, when it is time to go back to it: a switch not confirmed in time,
    /// or a host silent too long at another rate.
    pub fn fallback_due(&self, now: Instant) -> Option<u32> {
        if self.current == self.power_on {
            return None;
        }
        let past = |since: Option<Instant>, ms: u32| {
            since.is_some_and(|t| {
                now.saturating_duration_since(t) > Duration::from_millis(ms.into())
            })
        };
        let silent = past(self.last_good, BAUD_SILENCE_MS) || self.last_good.is_none();
        (past(self.trial_since, BAUD_TRIAL_MS) || (self.trial_since.is_none() && silent))
            .then_some(self.power_on)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ms(n: u64) -> Instant {
        Instant::from_millis(n)
    }

    #[test]
    fn a_switch_holds_once_a_good_frame_comes_and_falls_back_otherwise() {
        let mut b = BaudLink::new(115_200);
        b.on_good_frame(ms(0));
        assert_eq!(
            b.fallback_due(ms(10_000)),
            None,
            "at the power-on rate, never"
        );
        b.switched(ms(100), 2_000_000);
        assert_eq!(b.current(), 2_000_000);
        assert_eq!(b.fallback_due(ms(100 + BAUD_TRIAL_MS as u64)), None);
        assert_eq!(
            b.fallback_due(ms(101 + BAUD_TRIAL_MS as u64)),
            Some(115_200)
        );
        // Confirmed in time: it holds while the host talks...
        b.on_good_frame(ms(300));
        assert_eq!(b.fallback_due(ms(300 + BAUD_SILENCE_MS as u64)), None);
        // ...and goes back once it has been silent too long.
        assert_eq!(
            b.fallback_due(ms(301 + BAUD_SILENCE_MS as u64)),
            Some(115_200)
        );
        b.switched(ms(5_000), 115_200);
        assert_eq!(b.fallback_due(ms(50_000)), None);
    }

    #[test]
    fn rates_the_usart_cannot_make_are_refused() {
        assert!(BaudLink::accepts(115_200) && BaudLink::accepts(MAX_BAUD));
        assert!(!BaudLink::accepts(MAX_BAUD + 1) && !BaudLink::accepts(0));
        assert!(!BaudLink::accepts(MIN_BAUD - 1));
    }
}
