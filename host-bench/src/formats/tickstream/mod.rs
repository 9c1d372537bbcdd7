//! Tick stream files, format version 1: see `docs/tick-stream.md`.
//!
//! A tick stream is a CSV file (optionally gzip-compressed) that starts with the magic comment
//! [`MAGIC`], may name a robot description with a `# robot: PATH` comment, and then lists
//! time-ordered encoder events (`tick`, `abs`) and ground-truth poses (`truth`).
//!
//! The reader is a streaming, line-oriented parser written for this format rather than the
//! `csv` crate: comments must be kept (the `# robot:` line, generator parameters) and every
//! error must name the physical line of the file, comment and blank lines included. Each
//! record is one physical line; fields may be double-quoted (as spreadsheets sometimes do) but
//! cannot contain line breaks. Reading reuses one line buffer and one field-index buffer, so
//! the only allocation that grows with the file is the events vector.
//!
//! The parts: `event` is one row ([`Event`]), `read` the reader (line by line, gzip or not),
//! `row` the header and row lines (fields, columns, values), `write` the checked, atomic
//! writer.

use std::fmt;
use std::path::{Path, PathBuf};

pub use event::Event;
pub use lines::Lines;
pub use read::{read, read_checked, read_from, read_with_lines, RowCheck};
pub use write::{stage, write};

mod event;
mod lines;
mod read;
mod row;
#[cfg(test)]
mod tests;
mod write;

/// The first line of every version 1 tick stream (trailing whitespace is tolerated).
pub const MAGIC: &str = "# omnibench tick stream v1";

/// The part of [`MAGIC`] before the version number.
const MAGIC_PREFIX: &str = "# omnibench tick stream v";

/// The required columns, in the order the writer puts them.
pub const COLUMNS: [&str; 7] = ["t_ns", "kind", "id", "value", "x_m", "y_m", "theta_rad"];

const T_NS: usize = 0;
const KIND: usize = 1;
const ID: usize = 2;
const VALUE: usize = 3;
const X_M: usize = 4;
const Y_M: usize = 5;
const THETA_RAD: usize = 6;

/// Longest line the reader accepts, in bytes (a guard against reading a huge binary file
/// into one line).
pub const MAX_LINE_BYTES: usize = 1 << 20;

/// Largest truth coordinate, metres. The estimators' fixed point holds positions to about
/// ±8.4·10^6 m (Q40 in an `i64`); a truth pose beyond that would be scored against a wrapped
/// estimate, so it is refused when read.
pub const MAX_TRUTH_COORDINATE_M: f64 = 1e6;

/// Largest truth heading, radians (headings may be unwrapped). At 10^6 rad an `f64` still
/// resolves 10^-10 rad, and the host's trigonometry stays within a few ulp.
pub const MAX_TRUTH_HEADING_RAD: f64 = 1e6;

/// Most events (rows) a stream may hold: 2^22, 4 194 304. They are kept in memory (40 bytes
/// each), so reading one row more is refused at 160 MiB of events whatever a gzip file expands
/// to (at 6·10^6 the refusal itself took 240 MB); the events vector's capacity doubles to
/// exactly this. `generate` writes at most 2·10^6 ticks plus 2·10^6 truth and absolute rows.
pub const MAX_EVENTS: usize = 1 << 22;

/// Comment text kept from one stream, bytes. Comments are written back when a stream is
/// rewritten, so they are kept in memory; past this they are counted and dropped (a 7 MB
/// gzip of comment lines expands to gigabytes).
pub const MAX_KEPT_COMMENT_BYTES: usize = 64 * 1024;

/// Comment lines kept from one stream: an empty comment costs its `String` whatever its bytes
/// (50 M lines of `#` took 1.2 GB when only bytes were counted).
pub const MAX_KEPT_COMMENTS: usize = 1_000;

/// Lines that are neither the header nor an event (comments, blank rows) one stream may have:
/// past this it is not a tick stream, and a small gzip of blank lines would otherwise keep
/// the reader busy for minutes.
pub const MAX_OTHER_LINES: u64 = 1_000_000;

const GZIP_MAGIC: [u8; 2] = [0x1f, 0x8b];
const UTF8_BOM: &[u8] = b"\xef\xbb\xbf";
const READ_BUFFER_BYTES: usize = 64 * 1024;
const WRITE_BUFFER_BYTES: usize = 256 * 1024;

/// A whole tick stream file in memory.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TickStream {
    /// The `# robot:` path as written in the file (relative), if any.
    pub robot: Option<String>,
    /// Other comment lines after the magic line (without the leading "# "), kept in order.
    pub comments: Vec<String>,
    pub events: Vec<Event>,
}

impl TickStream {
    /// The robot path resolved against the directory of `stream_path`.
    pub fn robot_path(&self, stream_path: &Path) -> Option<PathBuf> {
        let robot = self.robot.as_deref()?;
        let dir = stream_path.parent().unwrap_or_else(|| Path::new(""));
        Some(dir.join(robot))
    }
}

/// Why a tick stream could not be read: the file, the 1-based physical line (comment and
/// blank lines count) when the problem is on a line, and what is wrong.
/// Displays as `path:LINE: message`, or `path: message` without a line.
#[derive(Debug)]
pub struct ReadError {
    pub path: PathBuf,
    pub line: Option<u64>,
    pub message: String,
}

impl fmt::Display for ReadError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.line {
            Some(line) => write!(f, "{}:{}: {}", self.path.display(), line, self.message),
            None => write!(f, "{}: {}", self.path.display(), self.message),
        }
    }
}

impl std::error::Error for ReadError {}

fn is_gz_name(path: &Path) -> bool {
    path.extension().is_some_and(|e| e == "gz")
}
