//! A virtual board (both boards' firmware, emulated in real time behind a pseudo-terminal) on
//! its own thread, for tests that talk to it in-process or through the CLI on its port.
#![allow(dead_code)]

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use std::path::Path;

use host_bench::serial::link::Link;
use host_bench::serial::record::RecordRequest;
use host_bench::sim::virtual_board;

/// Stopped when dropped.
pub struct Board {
    pub port: String,
    stop: Arc<AtomicBool>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Board {
    pub fn start(opts: virtual_board::Options) -> Board {
        let (pty, slave_end, port) = virtual_board::open_pty().expect("pty");
        let stop = Arc::new(AtomicBool::new(false));
        let s = stop.clone();
        let thread = std::thread::spawn(move || {
            let _keep = slave_end;
            virtual_board::serve(pty, &opts, &|| s.load(Ordering::Relaxed), None, None)
                .expect("serve");
        });
        Board {
            port,
            stop,
            thread: Some(thread),
        }
    }

    pub fn link(&self) -> Link {
        Link::open(&self.port, 115_200).expect("open pty")
    }
}

impl Drop for Board {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// Two seconds recorded into `out`, with the board's own robot or `robot`, time stamps or
/// `counts`, no progress bar.
pub fn recording<'a>(out: &'a Path, robot: Option<&'a Path>, counts: bool) -> RecordRequest<'a> {
    RecordRequest {
        out,
        duration_s: Some(2.0),
        counts,
        robot,
        progress: None,
        view: None,
    }
}
