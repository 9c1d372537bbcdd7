//! The host's clock on the serial link: the wall clock, or the simulated clock of a board
//! model that runs at another speed than real time.
//!
//! Every wait the host makes for a board (the handshake's answer, go-back-N's resend, the
//! stall check, the pacing of bytes on the line) is a span of the board's time. Against real
//! boards that is the wall clock. The chip model (`scripts/board-model`) runs the release
//! images at a fraction of real time, and against it the wall clock makes every wait too short
//! (`--patience` stretches them all by one guessed factor). With `--clock FILE` the host takes
//! its time from the model itself, from the file the model keeps its simulated time in: every
//! wait, every pace and every duration the host reports is then in the boards' own time,
//! whatever speed the model runs at, and the host behaves towards the modelled boards as it
//! would towards real ones. `host-bench virtual-board` writes one too ([`ClockFile`]), and
//! with `--time-scale` runs its emulated boards faster or slower than real time.
//!
//! One clock per process, chosen before the link opens ([`use_model_clock`]), as embassy-time
//! has one time driver per build: the link, the session and the jobs read it through
//! [`Instant::now`] and [`sleep`].
//!
//! The file ([`MAGIC`], then the simulated time in nanoseconds as a little-endian u64) is
//! rewritten by the model as it runs. A model that stops (killed, stuck) must not leave the
//! host waiting for ever: once its time has not moved for [`STOPPED_AFTER`] of wall time, the
//! host's clock runs on at the wall's pace from there, so every wait ends and says what it
//! waited for.

use std::fs::File;
use std::io::{Read, Seek, SeekFrom};
use std::ops::{Add, AddAssign, Sub};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Mutex, OnceLock};
use std::time::Duration;

use anyhow::{bail, Context, Result};

use crate::formats::atomic::ScratchFile;

/// The clock file's first 8 bytes.
pub const MAGIC: &[u8; 8] = b"OMNICLK1";

/// Wall time without a move after which a model's clock is taken as stopped.
pub const STOPPED_AFTER: Duration = Duration::from_secs(3);

/// How often [`sleep`] looks at a model's clock (wall time).
const POLL: Duration = Duration::from_millis(1);

/// A point in the host's time: `std::time::Instant`'s interface, on the clock in use.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Instant(Duration);

impl Instant {
    pub fn now() -> Instant {
        match MODEL.get() {
            None => Instant(wall_epoch().elapsed()),
            // A poisoned lock only means another thread panicked mid-read; the state is whole.
            Some(m) => Instant(m.lock().unwrap_or_else(|e| e.into_inner()).now()),
        }
    }

    /// The time since `self` (zero if `self` is later).
    pub fn elapsed(&self) -> Duration {
        Instant::now().saturating_duration_since(*self)
    }

    pub fn saturating_duration_since(&self, earlier: Instant) -> Duration {
        self.0.saturating_sub(earlier.0)
    }
}

impl Add<Duration> for Instant {
    type Output = Instant;
    fn add(self, d: Duration) -> Instant {
        Instant(self.0.saturating_add(d))
    }
}

impl AddAssign<Duration> for Instant {
    fn add_assign(&mut self, d: Duration) {
        *self = *self + d;
    }
}

impl Sub<Instant> for Instant {
    type Output = Duration;
    fn sub(self, earlier: Instant) -> Duration {
        self.saturating_duration_since(earlier)
    }
}

/// Waits `d` of the host's time.
pub fn sleep(d: Duration) {
    if MODEL.get().is_none() {
        std::thread::sleep(d);
        return;
    }
    let until = Instant::now() + d;
    loop {
        let now = Instant::now();
        if now >= until {
            return;
        }
        std::thread::sleep(POLL.min(until - now));
    }
}

/// From now on take the time from the board model's clock file `path`. Once per process,
/// before anything reads the time: an instant of the wall's and one of the model's cannot be
/// compared, so a clock chosen after the wall's was read is refused.
pub fn use_model_clock(path: &Path) -> Result<()> {
    if MODEL.get().is_none() {
        if WALL_READ.load(Ordering::Relaxed) {
            bail!(
                "the host read the wall clock before it was told to take {}'s: open the \
                 clock before the link",
                path.display()
            );
        }
        let clock = ModelClock::open(path)?;
        // Another thread may have set one meanwhile: checked below like any earlier one.
        let _ = MODEL.set(Mutex::new(clock));
    }
    let chosen = MODEL
        .get()
        .map(|m| m.lock().unwrap_or_else(|e| e.into_inner()).path.clone());
    if chosen.as_deref() != Some(path) {
        bail!(
            "the host already takes its time from another clock file than {}",
            path.display()
        );
    }
    Ok(())
}

/// Whether the time is a board model's ([`use_model_clock`]), not the wall's.
pub fn is_model() -> bool {
    MODEL.get().is_some()
}

static MODEL: OnceLock<Mutex<ModelClock>> = OnceLock::new();

/// Whether an instant of the wall's was handed out ([`use_model_clock`] then refuses).
static WALL_READ: AtomicBool = AtomicBool::new(false);

fn wall_epoch() -> std::time::Instant {
    static EPOCH: OnceLock<std::time::Instant> = OnceLock::new();
    WALL_READ.store(true, Ordering::Relaxed);
    *EPOCH.get_or_init(std::time::Instant::now)
}

struct ModelClock {
    path: PathBuf,
    file: File,
    /// The last time read from the file, ns.
    read_ns: u64,
    /// When (wall) that time was first read.
    moved_at: std::time::Instant,
    /// The last time handed out, ns: the clock never goes back, even when a model that
    /// seemed stopped goes on from an earlier time.
    given_ns: u64,
    /// [`STOPPED_AFTER`] (shorter in tests).
    stopped_after: Duration,
}

impl ModelClock {
    fn open(path: &Path) -> Result<ModelClock> {
        ModelClock::open_stopping_after(path, STOPPED_AFTER)
    }

    fn open_stopping_after(path: &Path, stopped_after: Duration) -> Result<ModelClock> {
        // A FIFO or a device would block the reads below: only a file is a clock.
        if !std::fs::metadata(path).is_ok_and(|m| m.is_file()) && path.exists() {
            bail!(
                "{} is not a board model's clock: not a regular file",
                path.display()
            );
        }
        let mut file = File::open(path).with_context(|| {
            format!(
                "cannot open the clock file {}: pass the path `host-bench virtual-board` or \
                 `scripts/board-model serve` printed after `clock: `",
                path.display()
            )
        })?;
        let reading = read(&mut file)
            .with_context(|| format!("reading the clock file {}", path.display()))?;
        let ns = match reading {
            Reading::Time(ns) => ns,
            Reading::Unsettled => bail!(
                "the clock file {} changes under every read: is more than one model writing it?",
                path.display()
            ),
            Reading::NotAClock => bail!(
                "{} is not a board model's clock: it must hold 16 bytes, starting with {:?}",
                path.display(),
                String::from_utf8_lossy(MAGIC)
            ),
        };
        Ok(ModelClock {
            path: path.to_path_buf(),
            file,
            read_ns: ns,
            moved_at: std::time::Instant::now(),
            given_ns: ns,
            stopped_after,
        })
    }

    fn now(&mut self) -> Duration {
        let wall = std::time::Instant::now();
        // An unreadable file counts as a stopped clock (below): the waits still end.
        if let Ok(Reading::Time(ns)) = read(&mut self.file) {
            if ns != self.read_ns {
                self.read_ns = ns;
                self.moved_at = wall;
            }
        }
        let still = wall.duration_since(self.moved_at);
        let ns = match still.checked_sub(self.stopped_after) {
            None => self.read_ns,
            // Stopped: on at the wall's pace from where it stopped.
            Some(on) => self
                .read_ns
                .saturating_add(u64::try_from(on.as_nanos()).unwrap_or(u64::MAX)),
        };
        // Never back: a model that went on from before a stop leaves the clock where it was
        // until the model passes it (and a value read wrong, which two reads alike make
        // unlikely, would hold the clock ahead as long).
        self.given_ns = self.given_ns.max(ns);
        Duration::from_nanos(self.given_ns)
    }
}

/// What a read of a clock file found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Reading {
    /// The time, ns.
    Time(u64),
    /// Not a clock file: too short, or another first 8 bytes.
    NotAClock,
    /// The time changed under every read (the model rewrites it while the host reads).
    Unsettled,
}

/// Reads a clock file. Twice at least: the model rewrites the 8 bytes while the host may read
/// them, and a time torn between two writes could be anything, so only two reads alike are
/// taken.
fn read(file: &mut File) -> std::io::Result<Reading> {
    let mut last = None;
    for _ in 0..4 {
        let mut buf = [0u8; 16];
        file.seek(SeekFrom::Start(0))?;
        match file.read_exact(&mut buf) {
            Ok(()) => {}
            Err(e) if e.kind() == std::io::ErrorKind::UnexpectedEof => {
                return Ok(Reading::NotAClock)
            }
            Err(e) => return Err(e),
        }
        let (magic, time) = buf.split_at(8);
        if magic != MAGIC {
            return Ok(Reading::NotAClock);
        }
        let mut ns = [0u8; 8];
        ns.copy_from_slice(time);
        let ns = u64::from_le_bytes(ns);
        if last == Some(ns) {
            return Ok(Reading::Time(ns));
        }
        last = Some(ns);
    }
    Ok(Reading::Unsettled)
}

/// The writing end of a clock file, for a model of the boards in this process (`host-bench
/// virtual-board`): a file of its own in a folder of its own, both removed when it is
/// dropped, and by a signal ([`ScratchFile`]). Each [`ClockFile::set`] rewrites the time in
/// place; a reader that catches a write half done reads two values that differ and reads
/// again ([`read`]).
pub struct ClockFile(ScratchFile);

impl ClockFile {
    /// A new clock file at time zero.
    pub fn create() -> Result<ClockFile> {
        ScratchFile::create("host-bench-clock-", "clock", &clock_file_bytes(0))
            .map(ClockFile)
            .context("creating the clock file")
    }

    /// Where the file is: what `--clock` takes.
    pub fn path(&self) -> &Path {
        self.0.path()
    }

    /// The model's time is now `ns`.
    pub fn set(&self, ns: u64) -> Result<()> {
        use std::os::unix::fs::FileExt;
        self.0
            .file()
            .write_all_at(&ns.to_le_bytes(), MAGIC.len() as u64)
            .with_context(|| format!("writing the clock file {}", self.path().display()))
    }
}

/// A clock file's 16 bytes for the time `ns` (for tests, and tools that model boards).
pub fn clock_file_bytes(ns: u64) -> [u8; 16] {
    let mut b = [0u8; 16];
    b[..8].copy_from_slice(MAGIC);
    b[8..].copy_from_slice(&ns.to_le_bytes());
    b
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    fn clock_file(dir: &tempfile::TempDir, bytes: &[u8]) -> std::path::PathBuf {
        let path = dir.path().join("clock");
        std::fs::File::create(&path)
            .and_then(|mut f| f.write_all(bytes))
            .unwrap();
        path
    }

    fn rewrite_in_place(path: &Path, ns: u64) {
        use std::os::unix::fs::FileExt;
        let f = std::fs::OpenOptions::new().write(true).open(path).unwrap();
        f.write_all_at(&clock_file_bytes(ns), 0).unwrap();
    }

    #[test]
    fn the_time_is_the_models_and_follows_it() {
        let dir = tempfile::tempdir().unwrap();
        let path = clock_file(&dir, &clock_file_bytes(5_000_000));
        let mut clock = ModelClock::open(&path).unwrap();
        assert_eq!(clock.now(), Duration::from_millis(5));
        // The model rewrites the file in place (its mmap): the host sees each new time.
        rewrite_in_place(&path, 7_250_000);
        assert_eq!(clock.now(), Duration::from_micros(7_250));
    }

    #[test]
    fn a_file_that_is_not_a_clock_is_refused_naming_it() {
        let dir = tempfile::tempdir().unwrap();
        for bytes in [&b"OMNICLK1\x01\x02"[..], &b"not a clock file"[..], &[][..]] {
            let path = clock_file(&dir, bytes);
            let err = ModelClock::open(&path).err().unwrap().to_string();
            assert!(err.contains("is not a board model's clock"), "{err}");
            assert!(err.contains(&path.display().to_string()), "{err}");
        }
        let not_a_file = ModelClock::open(dir.path()).err().unwrap().to_string();
        assert!(not_a_file.contains("not a regular file"), "{not_a_file}");
        let missing = dir.path().join("nowhere");
        let err = format!("{:#}", ModelClock::open(&missing).err().unwrap());
        assert!(
            err.contains("cannot open the clock file") && err.contains("nowhere"),
            "{err}"
        );
    }

    #[test]
    fn a_stopped_model_leaves_the_clock_running_at_the_walls_pace_and_never_back() {
        let dir = tempfile::tempdir().unwrap();
        let path = clock_file(&dir, &clock_file_bytes(1_000_000_000));
        let mut clock = ModelClock::open_stopping_after(&path, Duration::from_millis(20)).unwrap();
        assert_eq!(clock.now(), Duration::from_secs(1));
        std::thread::sleep(Duration::from_millis(60));
        // 60 ms without a move, 20 of them allowed: on by at least the other 40.
        let on = clock.now() - Duration::from_secs(1);
        assert!(on >= Duration::from_millis(40), "{on:?}");
        // The model goes on from where it stopped: the clock does not go back.
        rewrite_in_place(&path, 1_000_000_001);
        assert!(clock.now() >= Duration::from_secs(1) + on);
    }

    #[test]
    fn a_clock_file_written_here_is_read_as_written_and_removed_when_dropped() {
        let writer = ClockFile::create().unwrap();
        let mut clock = ModelClock::open(writer.path()).unwrap();
        assert_eq!(clock.now(), Duration::ZERO);
        writer.set(2_500_000_000).unwrap();
        assert_eq!(clock.now(), Duration::from_millis(2_500));
        let path = writer.path().to_path_buf();
        drop(writer);
        assert!(!path.exists() && !path.parent().unwrap().exists());
    }

    #[test]
    fn instants_add_and_subtract_without_wrapping() {
        let a = Instant(Duration::from_millis(10));
        let b = a + Duration::from_millis(5);
        assert_eq!(b - a, Duration::from_millis(5));
        assert_eq!(a - b, Duration::ZERO);
        assert_eq!(a.saturating_duration_since(b), Duration::ZERO);
        let mut c = a;
        c += Duration::MAX;
        assert!(c > b);
    }
}
