//! Switching the link to a faster rate, esptool's way: meet the master at its power-on rate,
//! ask for the new one, both switch, and prove it with a frame each way. If that frame does
//! not come, both go back: the host at once, the master once its trial runs out
//! ([`BAUD_TRIAL_MS`]), and the session goes on at the power-on rate, saying so.

use std::time::Duration;

use anyhow::{bail, Context, Result};
use protocol::serial::{
    HostToMaster, MasterToHost, RejectReason, BAUD_SILENCE_MS, BAUD_TRIAL_MS, MAX_BAUD, MIN_BAUD,
};

use super::{Link, POWER_ON_BAUD};
use crate::serial::clock::{self, Instant};

/// How long the host waits for the master's answer at the new rate.
const PROOF_WAIT: Duration = Duration::from_millis(250);
/// Silent this long at a switched rate, the host first meets the master again: it may have
/// gone back to its power-on rate (it does after [`BAUD_SILENCE_MS`]).
pub(super) const REVIVE_AFTER: Duration = Duration::from_millis(1_200);

impl Link {
    /// Switch to the rate asked for at [`Link::open`], if the master (reporting `master_baud`)
    /// is not there already and it was not tried before. A switch that fails leaves both at
    /// the power-on rate, with [`Link::baud_note`] saying what happened; only a master that
    /// refuses the rate outright is an error.
    pub fn switch_baud(&mut self, master_baud: u32) -> Result<()> {
        let target = self.baud_asked;
        if master_baud == target || self.baud_note.is_some() {
            return Ok(());
        }
        if !(MIN_BAUD..=MAX_BAUD).contains(&target) {
            bail!(
                "--baud {target}: the master's USART1 runs from {MIN_BAUD} to {MAX_BAUD} baud \
                 (72 MHz over a divider of 16 at most)"
            );
        }
        let started = Instant::now();
        if !self.ask_for(target, 3)? {
            self.baud_note = Some(format!(
                "the master did not answer the switch to {target} baud: staying at {}",
                self.baud
            ));
            return Ok(());
        }
        self.set_port_baud(target)?;
        if self.proven(target)? {
            self.baud_note = Some(format!("switched to {target} baud"));
            return Ok(());
        }
        // Back to the power-on rate; the master goes there once its trial ran out.
        self.set_port_baud(POWER_ON_BAUD)?;
        let trial_over = started + self.wait(Duration::from_millis(BAUD_TRIAL_MS as u64 + 100));
        clock::sleep(trial_over.saturating_duration_since(Instant::now()));
        if !self.proven(POWER_ON_BAUD)? {
            bail!(
                "the switch to {target} baud failed and the master did not answer at \
                 {POWER_ON_BAUD} baud either"
            );
        }
        self.baud_note = Some(format!(
            "no answer at {target} baud within {} ms (the adapter or the cable may not carry \
             it): both went back to {POWER_ON_BAUD} baud, {:.2} s after asking",
            self.wait(PROOF_WAIT).as_millis(),
            started.elapsed().as_secs_f64()
        ));
        eprintln!("note: {}", self.baud_note.as_deref().unwrap_or_default());
        Ok(())
    }

    /// Ask the master to switch to `baud`, up to `tries` times: true once it said it will.
    fn ask_for(&mut self, baud: u32, tries: u32) -> Result<bool> {
        for _ in 0..tries {
            self.send_now(&HostToMaster::SetBaud { baud })?;
            let until = Instant::now() + self.wait(Duration::from_millis(300));
            while Instant::now() < until {
                match self.recv(Duration::from_millis(10))? {
                    Some(MasterToHost::BaudSet { baud: b }) if b == baud => return Ok(true),
                    Some(MasterToHost::Rejected(RejectReason::InvalidBaud)) => {
                        bail!("the master refuses {baud} baud (it takes {MIN_BAUD} to {MAX_BAUD})")
                    }
                    _ => {}
                }
            }
        }
        Ok(false)
    }

    /// Whether the master answers at `baud`: asked for its info until it replies at that
    /// rate, for [`PROOF_WAIT`].
    fn proven(&mut self, baud: u32) -> Result<bool> {
        let until = Instant::now() + self.wait(PROOF_WAIT);
        while Instant::now() < until {
            self.send_now(&HostToMaster::Info)?;
            let next = Instant::now() + Duration::from_millis(50);
            while Instant::now() < next {
                if let Some(MasterToHost::HelloReply(info)) = self.recv(Duration::from_millis(5))? {
                    if info.baud == baud {
                        return Ok(true);
                    }
                }
            }
        }
        Ok(false)
    }

    /// After a silence: wait until the master surely went back to its power-on rate, meet it
    /// there, and switch again.
    pub(super) fn revive(&mut self) -> Result<()> {
        let target = self.baud;
        let back_by = self.last_sent + Duration::from_millis(BAUD_SILENCE_MS as u64 + 200);
        clock::sleep(back_by.saturating_duration_since(Instant::now()));
        self.set_port_baud(POWER_ON_BAUD)?;
        if !self.proven(POWER_ON_BAUD)? {
            // Still at the switched rate after all (a master with another timeout).
            self.set_port_baud(target)?;
            return Ok(());
        }
        if self.ask_for(target, 3)? {
            self.set_port_baud(target)?;
            if !self.proven(target)? {
                self.set_port_baud(POWER_ON_BAUD)?;
            }
        }
        Ok(())
    }

    /// Leave the master at its power-on rate, where the next host looks for it.
    pub(super) fn switch_back(&mut self) {
        // Once: a board that stopped answering (the error the program ends with) must not hold
        // its exit for long; the master goes back by itself after 2 s of silence anyway.
        if self.baud != POWER_ON_BAUD && self.ask_for(POWER_ON_BAUD, 1).unwrap_or(false) {
            let _ = self.set_port_baud(POWER_ON_BAUD);
        }
    }

    fn set_port_baud(&mut self, baud: u32) -> Result<()> {
        // What is on its way at the old rate is garbage at the new one.
        clock::sleep(Duration::from_millis(2));
        self.port
            .set_baud_rate(baud)
            .with_context(|| format!("setting {} to {baud} baud", self.name))?;
        self.baud = baud;
        Ok(())
    }
}
