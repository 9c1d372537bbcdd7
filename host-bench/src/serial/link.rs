//! The serial line to the master: a real port (USB-serial adapter, or a pseudo-terminal of
//! `host-bench virtual-board`), COBS frames both ways, byte counts, and fault knobs that
//! damage or drop chosen frames on the way out (to show the link recovers).

use std::collections::VecDeque;
use std::io::{ErrorKind, Read, Write};
use std::time::Duration;

use anyhow::{bail, Context, Result};
use protocol::link::GbnReceiver;
use protocol::serial::{self, FrameDecoder, HostToMaster, MasterToHost};

use crate::serial::clock::Instant;

mod baud;
use baud::REVIVE_AFTER;

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
    /// The rate the port runs at, and the one asked for (`--baud`, bench.toml).
    baud: u32,
    baud_asked: u32,
    /// What became of the switch to `baud_asked`, once tried.
    pub baud_note: Option<String>,
    /// What was done about the adapter's latency timer.
    pub latency_note: Option<String>,
    /// When the host last sent: a master left silent too long at a switched rate goes back to
    /// its power-on rate.
    last_sent: Instant,
    /// When what was written so far will have left the line, at the port's rate.
    line_free_at: Instant,
    /// The board's report stream while a recording runs ([`Link::receive_reports`]).
    reports: Option<Box<GbnReceiver<REPORTS_WINDOW>>>,
}

/// Report bytes the host takes in ahead of its reader (a recording's).
pub const REPORTS_WINDOW: usize = 8192;

/// The rate every master starts at and goes back to (`MasterConfig::baud`).
pub const POWER_ON_BAUD: u32 = 115_200;

impl Link {
    /// Open `path` at the power-on rate, 8N1; the session's handshake then switches to
    /// `baud` ([`Link::switch_baud`]). A pseudo-terminal keeps the rate only as a setting,
    /// which `virtual-board` reads back to model the line.
    pub fn open(path: &str, baud: u32) -> Result<Link> {
        let port = serialport::new(path, POWER_ON_BAUD)
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
            baud: POWER_ON_BAUD,
            baud_asked: baud,
            baud_note: None,
            latency_note: super::adapter_latency::lower(path, std::path::Path::new("/sys")),
            last_sent: Instant::now(),
            line_free_at: Instant::now(),
            reports: None,
        })
    }

    /// From now on take in the board's report stream (from offset 0: a new session) and
    /// acknowledge it at once, whatever the caller is waiting for: a recording's first
    /// records come while the host still waits for the board to confirm it started, and
    /// unacknowledged they would fill the board's buffers and be dropped there.
    pub fn receive_reports(&mut self) {
        self.reports = Some(Box::new(GbnReceiver::new()));
    }

    /// The report bytes taken in since the last call, appended to `out`.
    pub fn read_reports(&mut self, out: &mut Vec<u8>) {
        if let Some(rx) = &mut self.reports {
            let mut buf = [0u8; REPORTS_WINDOW];
            let n = rx.read(&mut buf);
            out.extend_from_slice(&buf[..n]);
        }
    }

    /// How long what was written so far still takes on the line. A sender that writes more
    /// than the line carries only builds a queue in the port and the adapter, where its
    /// retransmissions wait behind it (go-back-N's timeout then fires for frames that were
    /// never lost, and their copies queue too): `play` keeps this short.
    pub fn backlog(&self) -> Duration {
        self.line_free_at.saturating_duration_since(Instant::now())
    }

    /// The rate the port runs at now.
    /// The link's rate and counters as an `omnibench.Link` message, with `more` fields of the
    /// command's own (`--mcap`, `--live`).
    pub fn view_counters(&self, more: serde_json::Value) -> serde_json::Value {
        let s = &self.stats;
        let mut v = serde_json::json!({
            "baud": self.baud(),
            "bytes_out": s.bytes_sent,
            "bytes_in": s.bytes_received,
            "frames_out": s.frames_sent,
            "frames_in": s.frames_received,
            "frames_rejected": s.frames_rejected,
        });
        if let (Some(v), serde_json::Value::Object(more)) = (v.as_object_mut(), more) {
            v.extend(more);
        }
        v
    }

    pub fn baud(&self) -> u32 {
        self.baud
    }

    /// The rate asked for.
    pub fn baud_asked(&self) -> u32 {
        self.baud_asked
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
    /// After a silence long enough for the master to have gone back to its power-on rate,
    /// meet it there and switch again first.
    pub fn send(&mut self, msg: &HostToMaster) -> Result<()> {
        if self.baud != POWER_ON_BAUD && self.last_sent.elapsed() > REVIVE_AFTER {
            self.revive()?;
        }
        self.send_now(msg)
    }

    fn send_now(&mut self, msg: &HostToMaster) -> Result<()> {
        self.last_sent = Instant::now();
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
        let on_the_line =
            Duration::from_nanos(frame.len() as u64 * 10_000_000_000 / self.baud as u64);
        self.line_free_at = self.line_free_at.max(Instant::now()) + on_the_line;
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
                Some(Ok(MasterToHost::Reports(frame))) if self.reports.is_some() => {
                    self.stats.frames_received += 1;
                    let ack = self.reports.as_mut().and_then(|rx| {
                        rx.on_data(&frame);
                        rx.poll_ack()
                    });
                    if let Some(a) = ack {
                        self.send_now(&HostToMaster::ReportsAck(a))?;
                    }
                }
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

impl Drop for Link {
    fn drop(&mut self) {
        self.switch_back();
    }
}
