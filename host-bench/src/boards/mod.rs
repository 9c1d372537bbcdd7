//! The real boards on the bench: which debug probe and serial port belong to which board
//! (`bench.toml`), and flashing both images with probe-rs.
//!
//! * [`selection`]: `VID:PID[:SERIAL]` or bare-serial probe specs, resolved against what is
//!   attached, with errors that list what is there;
//! * [`discovery`]: what is attached (debug probes, serial ports), for `host-bench probes`;
//! * [`bench_file`]: the `bench.toml` format (docs/bench.md), strict loading, atomic writing;
//! * [`images`]: where the firmware images are and whether they are flashable ELF files;
//! * [`plan`]: flags + bench.toml + attached probes → one job per board, every problem at once;
//! * [`identity`]: is the chip behind the probe the one we expect;
//! * [`flashing`]: attach, download with progress, verify, reset and run — one board per thread;
//! * [`rtt_log`]: each board's defmt log over RTT, decoded with its ELF's defmt table.
//!
//! Nothing here opens a USB device on its own: everything takes a probe-rs
//! [`Lister`](probe_rs::probe::list::Lister), so tests substitute fake probes.

pub mod bench_file;
pub mod discovery;
pub mod flashing;
pub mod identity;
pub mod images;
pub mod plan;
pub mod rtt_log;
pub mod selection;

use std::fmt;

/// One of the bench's two boards.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Board {
    /// The odometry computer (firmware-slave).
    Slave,
    /// The motion controller (firmware-master).
    Master,
}

impl Board {
    /// Both boards, slave first (the order used in every listing and report).
    pub const BOTH: [Board; 2] = [Board::Slave, Board::Master];

    /// `slave` / `master`: the name in bench.toml, CLI flags and log prefixes.
    pub fn name(self) -> &'static str {
        match self {
            Board::Slave => "slave",
            Board::Master => "master",
        }
    }

    /// The Cargo package whose binary is this board's image.
    pub fn package(self) -> &'static str {
        match self {
            Board::Slave => "firmware-slave",
            Board::Master => "firmware-master",
        }
    }
}

impl fmt::Display for Board {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}
