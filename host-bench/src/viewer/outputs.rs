//! The options every run-making command shares (`--mcap`, `--live`), and what they open.

use std::cell::RefCell;
use std::path::PathBuf;
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
    /// viewers can be looked at [default: until Ctrl-C].
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
    pub fn open(args: &ViewArgs, channels: Vec<Channel>, what: &str) -> Result<Self> {
        if let Some(h) = args.live_hold {
            if !(h >= 0.0 && h.is_finite()) {
                anyhow::bail!("--live-hold {h}: a number of seconds, 0 or more");
            }
        }
        let mut view = View::new(channels.clone());
        let mcap = match &args.mcap {
            Some(path) => {
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

    /// With --live, after the run: keep serving for --live-hold seconds, or until Ctrl-C.
    pub fn hold(&self, state: &str) {
        let Some(live) = &self.live else {
            return;
        };
        live.set_state(state);
        match self.hold {
            Some(s) => std::thread::sleep(Duration::from_secs_f64(s)),
            None => {
                eprintln!(
                    "live: the run is over; still serving http://{}/ (Ctrl-C to quit)",
                    live.addr()
                );
                loop {
                    std::thread::park();
                }
            }
        }
    }
}

/// Paces a run that is faster than real time (`emulate --live`) to `speed` times real time.
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
