//! The serial line to the master: a real port (USB-serial adapter, or a pseudo-terminal of
//! `host-bench virtual-board`), COBS frames both ways, byte counts, and fault knobs that
//! damage or drop chosen frames on the way out (to show the link recovers).

use std::collections::VecDeque;
use std::io::{ErrorKind, Read, Write};
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use protocol::serial::{self, FrameDecoder, HostToMaster, MasterToHost};

/// Frames to damage on the way out, by their index among the `Events` frames sent (0-based).
#[derive(Clone, Debug, Default)]
pub struct Faults {
    /// Flip a byte inside these frames (the master's CRC check drops them).
    pub corrupt: Vec<u64>,
    /// Do not send these frames at all.
    pub drop: Vec<u64>,
}

/// What went over the line.
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct LinkStats {
    pub bytes_sent: u64,
    pub bytes_received: u64,
    pub frames_sent: u64,
    pub frames_received: u64,
    /// Frames from the master that failed COBS, CRC or decoding.
    pub frames_rejected: u64,
    pub events_frames: u64,
    pub events_frames_corrupted: u64,
    pub events_frames_dropped: u64,
}

pub struct Link {
    port: Box<dyn serialport::SerialPort>,
    name: String,
    decoder: FrameDecoder,
    inbox: VecDeque<MasterToHost>,
    pub stats: LinkStats,
    pub faults: Faults,
    /// How many times longer than a board at speed the host waits for this one.
    patience: u32,
}

impl Link {
    /// Open `path` at `baud`, 8N1. A pseudo-terminal ignores the baud rate.
    pub fn open(path: &str, baud: u32) -> Result<Link> {
        let port = serialport::new(path, baud)
            .timeout(Duration::from_millis(2))
            .open()
            .with_context(|| {
                format!(
                    "cannot open serial port {path}: is it the master's USB-serial adapter \
                     (`host-bench probes` lists the ports) and may this user open it \
                     (on Linux: member of the `dialout` group)?"
                )
            })?;
        Ok(Link {
            port,
            name: path.to_string(),
            decoder: FrameDecoder::new(),
            inbox: VecDeque::new(),
            stats: LinkStats::default(),
            faults: Faults::default(),
            patience: 1,
        })
    }

    /// Wait `patience` times longer for the board (`--patience`).
    pub fn with_patience(mut self, patience: u32) -> Link {
        self.patience = patience.max(1);
        self
    }

    /// How long to wait for what a board at speed does in `d`.
    pub fn wait(&self, d: Duration) -> Duration {
        d * self.patience
    }

    pub fn name(&self) -> &str {
        &self.name
    }

    /// Send one message as a frame (subject to the fault knobs if it is an `Events` frame).
    pub fn send(&mut self, msg: &HostToMaster) -> Result<()> {
        let mut buf = [0u8; serial::MAX_FRAME];
        let frame = serial::encode(msg, &mut buf)
            .map_err(|e| anyhow::anyhow!("cannot encode {msg:?}: {e:?}"))?;
        let mut frame = frame.to_vec();
        if matches!(msg, HostToMaster::Events(_)) {
            let k = self.stats.events_frames;
            self.stats.events_frames += 1;
            if self.faults.drop.contains(&k) {
                self.stats.events_frames_dropped += 1;
                return Ok(());
            }
            if self.faults.corrupt.contains(&k) && frame.len() > 2 {
                // A non-zero byte stays non-zero, so the frame still ends where it did and
                // only its CRC fails: what line noise inside a frame does.
                let i = frame.len() / 2;
                frame[i] = if frame[i] == 0x55 { 0xAA } else { 0x55 };
                self.stats.events_frames_corrupted += 1;
            }
        }
        // A delimiter after the frame's own: a piece of this frame torn on the line is closed
        // off by it as one bad frame, instead of running into (and spoiling) the next.
        frame.push(0);
        self.port
            .write_all(&frame)
            .with_context(|| format!("writing to {}", self.name))?;
        self.stats.bytes_sent += frame.len() as u64;
        self.stats.frames_sent += 1;
        Ok(())
    }

    /// The next message from the master, waiting at most `timeout`.
    pub fn recv(&mut self, timeout: Duration) -> Result<Option<MasterToHost>> {
        let deadline = Instant::now() + timeout;
        loop {
            if let Some(m) = self.inbox.pop_front() {
                return Ok(Some(m));
            }
            self.fill()?;
            if self.inbox.is_empty() && Instant::now() >= deadline {
                return Ok(None);
            }
        }
    }

    /// Read what the port has (waiting up to its 2 ms timeout) into the inbox.
    fn fill(&mut self) -> Result<()> {
        let mut buf = [0u8; 4096];
        let n = match self.port.read(&mut buf) {
            Ok(n) => n,
            Err(e) if e.kind() == ErrorKind::TimedOut || e.kind() == ErrorKind::WouldBlock => 0,
            Err(e) if e.kind() == ErrorKind::Interrupted => 0,
            Err(e) => bail!("reading from {}: {e}", self.name),
        };
        self.stats.bytes_received += n as u64;
        for &b in &buf[..n] {
            match self.decoder.push::<MasterToHost>(b) {
                None => {}
                Some(Ok(m)) => {
                    self.stats.frames_received += 1;
                    self.inbox.push_back(m);
                }
                Some(Err(_)) => self.stats.frames_rejected += 1,
            }
        }
        Ok(())
    }
}
