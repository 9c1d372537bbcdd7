//! The options every run-making command shares (`--mcap`, `--live`), and what they open.

use std::cell::RefCell;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::Result;

use super::live::{LiveServer, DEFAULT_ADDR};
use super::mcap_file::McapFile;
use super::{Channel, View};

/// `--mcap FILE`, `--live [ADDR]`, `--live-hold SECS`.
#[derive(clap::Args, Clone, Debug, Default)]
pub struct ViewArgs {
    /// Write the run as an MCAP file for Foxglove, Lichtblick, PlotJuggler or Rerun (log time
    /// is the run's own time). Written whole when the run succeeds; no file otherwise.
    #[arg(long, value_name = "FILE")]
    pub mcap: Option<PathBuf>,
    /// Serve the run live while it goes: a Foxglove WebSocket server (Foxglove, Lichtblick:
    /// "open connection", ws://ADDR) and a bench page for any browser at http://ADDR/.
    /// This machine only unless another interface is named.
    #[arg(long, value_name = "ADDR", num_args = 0..=1, default_missing_value = DEFAULT_ADDR)]
    pub live: Option<String>,
    /// With --live: keep serving this many seconds after the run ends, so the page and the
    /// viewers can be looked at [default: until Ctrl-C, then the run's own exit status].
    #[arg(long, value_name = "SECS", requires = "live")]
    pub live_hold: Option<f64>,
}

/// A run's view and the outputs behind it.
pub struct Outputs {
    /// Shared by the parts of a command that show the run (a play's passes).
    pub view: RefCell<View>,
    channels: Vec<Channel>,
    mcap: Option<McapFile>,
    live: Option<LiveServer>,
    hold: Option<f64>,
}

impl Outputs {
    /// Opens what `args` asks for: the MCAP file's temporary file (its folder and name are
    /// checked now, before the run), the live server's port. `what` names the command.
    /// `files` are the command's other files, inputs and outputs: the MCAP file may not be
    /// one of them.
    pub fn open(
        args: &ViewArgs,
        channels: Vec<Channel>,
        what: &str,
        files: &[&std::path::Path],
    ) -> Result<Self> {
        if let Some(h) = args.live_hold {
            if !(0.0..=MAX_HOLD_S).contains(&h) {
                anyhow::bail!("--live-hold {h}: seconds, 0 to {MAX_HOLD_S}");
            }
        }
        let mut view = View::new(channels.clone());
        let mcap = match &args.mcap {
            Some(path) => {
                if let Some(other) = files.iter().find(|f| same_file(path, f)) {
                    anyhow::bail!(
                        "--mcap {}: that is {} too; name another file",
                        path.display(),
                        other.display()
                    );
                }
                let f = McapFile::create(path, what)?;
                view.add(f.sink());
                Some(f)
            }
            None => None,
        };
        let live = match &args.live {
            Some(addr) => {
                let s = LiveServer::start(addr)?;
                eprintln!(
                    "live: ws://{0} (Foxglove, Lichtblick: open connection) and the bench page at http://{0}/",
                    s.addr()
                );
                view.add(s.sink());
                Some(s)
            }
            None => None,
        };
        Ok(Outputs {
            view: RefCell::new(view),
            channels,
            mcap,
            live,
            hold: args.live_hold,
        })
    }

    pub fn is_live(&self) -> bool {
        self.live.is_some()
    }

    /// Tells the page what the run is doing.
    pub fn set_state(&self, state: &str) {
        if let Some(l) = &self.live {
            l.set_state(state);
        }
    }

    /// The run succeeded: the MCAP file is put in place (its path returned).
    pub fn finish(&mut self) -> Result<Option<PathBuf>> {
        match self.mcap.take() {
            Some(f) => Ok(Some(f.finish(&self.channels)?)),
            None => Ok(None),
        }
    }

    /// With --live, after the run: keep serving for --live-hold seconds, or until Ctrl-C,
    /// then return, so the command ends with the run's own status and message.
    pub fn hold(&self, state: &str) {
        let Some(live) = &self.live else {
            return;
        };
        live.set_state(state);
        let dropped = live.dropped();
        if dropped > 0 {
            eprintln!(
                "live: {dropped} messages were not delivered to clients too slow to take them"
            );
        }
        let until = self
            .hold
            .map(|s| Instant::now() + Duration::from_secs_f64(s));
        if until.is_none() {
            eprintln!(
                "live: the run is over ({state}); still serving http://{}/ (Ctrl-C to end)",
                live.addr()
            );
        }
        // Ctrl-C ends the holding, not the process.
        let stop = Arc::new(AtomicBool::new(false));
        let _own = crate::formats::atomic::OwnCtrlC::take();
        let _ = signal_hook::flag::register(signal_hook::consts::SIGINT, stop.clone());
        while !stop.load(Ordering::Relaxed) && until.is_none_or(|u| Instant::now() < u) {
            std::thread::sleep(Duration::from_millis(50));
        }
    }
}

/// The longest --live-hold, seconds (a day).
const MAX_HOLD_S: f64 = 86_400.0;

/// Whether `a` and `b` name one file (through `.`, `..` and symbolic links in their folders).
fn same_file(a: &std::path::Path, b: &std::path::Path) -> bool {
    let full = |p: &std::path::Path| {
        let name = p.file_name()?;
        let folder = match p.parent() {
            Some(f) if !f.as_os_str().is_empty() => f,
            _ => std::path::Path::new("."),
        };
        Some(std::fs::canonicalize(folder).ok()?.join(name))
    };
    match (full(a), full(b)) {
        (Some(x), Some(y)) => x == y,
        _ => a == b,
    }
}

/// The range of `--live-speed`.
pub const LIVE_SPEEDS: std::ops::RangeInclusive<f64> = 0.01..=1000.0;

/// Paces a run that is faster than real time (`emulate --live`) to `speed` times real time
/// (within [`LIVE_SPEEDS`]).
pub struct Pacer {
    start: Instant,
    speed: f64,
}

impl Pacer {
    pub fn new(speed: f64) -> Self {
        Pacer {
            start: Instant::now(),
            speed,
        }
    }

    /// Sleeps until `t_s` of the run's time is due on the wall clock.
    pub fn wait_for(&self, t_s: f64) {
        let due = Duration::from_secs_f64((t_s / self.speed).max(0.0));
        if let Some(left) = due.checked_sub(self.start.elapsed()) {
            std::thread::sleep(left);
        }
    }
}
