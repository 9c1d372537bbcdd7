//! The controller's side of the SPI link to the slave: the frame each poll sends (the queued
//! command, until acknowledged; the played events' next chunk), and what each frame that comes
//! back says: acknowledgements, the report stream, the slave's pose and when it was sampled,
//! a slave that restarted.

use embassy_time::Instant;
use protocol::serial::status;
use protocol::spi::{MasterFrame, SlaveCommand, SlaveFrame, SpiFrameError};

use super::{us_since, Controller};

impl Controller {
    /// The frame to send on the next SPI poll. A command is repeated until acknowledged.
    pub fn next_slave_frame(&mut self) -> MasterFrame {
        self.spi_seq = self.spi_seq.wrapping_add(1);
        MasterFrame {
            seq: self.spi_seq,
            command_seq: self.command_seq,
            command: self.commands.front().cloned().unwrap_or(SlaveCommand::None),
            events: self.relay.events_chunk(self.commands.is_empty()),
            reports_next: self.relay.reports_next(),
        }
    }

    /// The outcome of an SPI poll that ended at `end`: when its last bit was clocked, the
    /// instant the slave re-arms from ([`crate::ports::SlaveBus::exchange`]).
    pub fn on_slave_frame(&mut self, end: Instant, frame: Result<SlaveFrame, SpiFrameError>) {
        let armed_at = self.prev_good_exchange_end.take();
        // A frame armed at the same instant as the last one read is that frame again: a
        // slave late to re-arm sends it twice. Nothing in it is new, and its arming was not
        // the end of the exchange before, so it goes with the rejected. (Its error is never
        // read; written this way the check costs the master 20 B of flash, not 100.)
        let latest = self.slave_latest.as_ref().map(|p| p.armed_us);
        let frame = frame.and_then(|f| {
            if Some(f.armed_us) == latest {
                Err(SpiFrameError::Crc)
            } else {
                Ok(f)
            }
        });
        let Ok(f) = frame else {
            self.counters.spi_rejected = self.counters.spi_rejected.wrapping_add(1);
            return;
        };
        self.counters.spi_ok = self.counters.spi_ok.wrapping_add(1);
        self.prev_good_exchange_end = Some(end);
        if let Some(armed_at) = armed_at {
            let offset = (armed_at.as_micros() as u32).wrapping_sub(f.armed_us);
            // The boards' crystals drift by parts per million: an offset that jumps by
            // milliseconds means the slave's clock started again, so the slave did (a
            // brown-out, its watchdog, a flash). Its pose is its power-on pose now: never
            // steer on it.
            if self
                .slave_clock_offset
                .is_some_and(|old| (offset.wrapping_sub(old) as i32).unsigned_abs() > 2_000)
            {
                self.slave = None;
                self.stop_following(status::SLAVE_RESET);
            }
            self.slave_clock_offset = Some(offset);
        }
        self.slave_latest = Some(f);
        self.counters.slave_rx_rejected = f.rx_rejected as u32;
        if f.command_ack == self.command_seq {
            if let Some(done) = self.commands.pop_front() {
                if matches!(done, SlaveCommand::SetSource { .. }) {
                    // The slave restarted both SPI streams when it applied this.
                    self.relay.reset_slave();
                }
                if !self.commands.is_empty() {
                    // The next queued command goes out under a new number.
                    self.command_seq = self.command_seq.wrapping_add(1);
                }
            }
        }
        // A recording's reports come and go; stay in streaming mode across short pauses.
        if !f.reports.bytes.is_empty() || self.relay.busy() {
            self.last_stream_at = Some(end);
        }
        self.stream_recent = us_since(end, self.last_stream_at) < 100_000;
        self.relay.on_slave_frame(&f);
        // A frame whose seq did not move means the slave's odometry loop is stuck: the SPI
        // peripheral still answers, but with stale data. Only moving frames count as alive.
        let fresh = self.slave.is_none_or(|(prev, _)| prev.seq != f.seq);
        if fresh {
            self.last_fresh_slave = Some(end);
        }
        // Until the slave has applied every queued command (a set-pose among them), its poses
        // may be from before them.
        if self.commands.is_empty() {
            let sampled = self.sample_time(end, &f);
            self.slave = Some((f, sampled));
        }
    }

    /// When, on the master's clock, the slave sampled the pose in frame `f` that arrived at
    /// `now`.
    ///
    /// A frame can be up to a poll period plus an odometry period old, over a millimetre at
    /// 0.6 m/s. The clocks are not synchronised, but the slave arms each frame right after the
    /// previous transaction ends (an instant the master knows on its own clock) and stamps
    /// both that moment and the pose's sampling time on its clock; their difference is the
    /// pose's age at arming, and arming time minus `armed_us` is the clocks' offset. The
    /// offset is learned only when the arming instant is known (the exchange before was good)
    /// and dates every frame, so a frame read after a lost transaction (armed a poll earlier
    /// than the master's last exchange) is not taken for a fresher one. Ages that make no
    /// sense (no offset yet, a slave reboot) fall back to the arrival time.
    fn sample_time(&self, now: Instant, f: &SlaveFrame) -> Instant {
        const MAX_AGE_US: i32 = 20_000;
        let Some(offset) = self.slave_clock_offset else {
            return now;
        };
        if (f.armed_us.wrapping_sub(f.time_us) as i32) < 0 {
            return now; // a pose sampled after its frame was armed: the slave's clock restarted
        }
        let age = (now.as_micros() as u32).wrapping_sub(f.time_us.wrapping_add(offset)) as i32;
        if !(0..=MAX_AGE_US).contains(&age) || now.as_micros() < age as u64 {
            return now;
        }
        Instant::from_micros(now.as_micros() - age as u64)
    }

    /// A bus error on the SPI side.
    pub fn on_slave_bus_error(&mut self, _now: Instant) {
        self.prev_good_exchange_end = None;
        self.counters.spi_rejected = self.counters.spi_rejected.wrapping_add(1);
    }
}
