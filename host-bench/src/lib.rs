//! omnibench's host side. The folders are the parts of the bench:
//! * [`formats`]: the files a user writes and reads (robot descriptions, tick streams);
//! * [`sim`]: the simulated robot, trajectories, the tick generator and the two-board emulator;
//! * [`eval`]: replay, the accuracy suite, reports and plots;
//! * [`serial`]: the serial link to the boards, `play` and `record`, and what they share;
//! * [`boards`]: the real boards: their probes and serial ports, bench.toml, flashing;
//! * [`viewer`]: runs you can look at: MCAP files, the live Foxglove server, the bench page.
//!
//! The `host-bench` binary (`src/main.rs`, `src/cli/`) is the command line over these.

pub mod boards;
pub mod calibrate;
pub mod eval;
pub mod formats;
pub mod serial;
pub mod sim;
pub mod viewer;
