//! Master <-> slave SPI frames.
//!
//! Every transaction is full duplex and moves exactly [`SPI_FRAME_LEN`] bytes each way: the
//! master sends a [`MasterFrame`] while the slave sends the [`SlaveFrame`] it armed before the
//! transaction. Layout of both: a kind byte ([`SpiFrame::KIND`]: 0xA5 master, 0x5A slave),
//! `postcard(frame)`, zero padding, and CRC-32/ISO-HDLC (little-endian) over everything before
//! it in the last four bytes.
//!
//! Nothing a dead or stuck line produces can pass: the CRC's non-zero start and final XOR mean
//! an all-zero frame does not check out as it did with the old CRC-16 (`FF FF 00 … 00` passed),
//! no run of one byte value does (a floating MISO reads 0xFF, a browned-out slave 0x00; tested
//! for all 256), and the kind byte is neither; a frame sent back on the wrong line (MOSI looped
//! to MISO) has the other kind. Decoding is
//! strict: the padding must be zeros and the payload must be exactly what encoding the decoded
//! frame gives, so one frame has one byte string (postcard alone takes over-long varints).

use crate::{Bytes, Pose};
use postcard::experimental::max_size::MaxSize;
use postcard_schema::Schema;
use serde::{de::DeserializeOwned, Deserialize, Serialize};

/// The SPI clock the master drives: 72 MHz over 16. A frame then takes 228 µs, so the master
/// can poll every 500 µs while streams move (112 kB/s each way: a recording of every edge
/// of seed 004's robot at 0.6 m/s) and leave the slave 270 µs to re-arm.
pub const SPI_CLOCK_HZ: u32 = 4_500_000;

/// Bytes per SPI transaction, each way (228 µs at [`SPI_CLOCK_HZ`]).
pub const SPI_FRAME_LEN: usize = 128;

/// A frame's time on the wire at `clock_hz`, rounded up to a microsecond: from the first bit
/// clocked to the last (what the master dates an exchange by, and the emulator waits).
pub const fn frame_time_us(clock_hz: u32) -> u64 {
    (SPI_FRAME_LEN as u64 * 8 * 1_000_000).div_ceil(clock_hz as u64)
}
/// The check at the end of every frame, bytes.
pub const SPI_CHECK_LEN: usize = 4;
/// Bytes available to the postcard payload (after the kind byte, before the check).
pub const SPI_PAYLOAD_LEN: usize = SPI_FRAME_LEN - 1 - SPI_CHECK_LEN;

/// Incremental encoders a slave can be given (the board counts two in hardware; played
/// streams may carry up to this many, e.g. seed 000's triangle).
pub const ENCODER_SLOTS: usize = 4;

/// Stream bytes one SPI frame carries each way (played sensor events master -> slave, reports
/// slave -> master).
pub const STREAM_CHUNK: usize = 56;

/// A piece of a byte stream: `bytes` sit at byte `offset` of the stream (wrapping `u32`).
/// The receiver takes a chunk only when `offset` is exactly where it is (so a lost frame
/// makes it refuse the ones after it) and acknowledges the next offset it wants; the sender
/// goes back to that offset (go-back-N over the poll cycle, see `docs/protocol.md`).
#[derive(Serialize, Deserialize, Schema, MaxSize, Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Chunk {
    pub offset: u32,
    pub bytes: Bytes<STREAM_CHUNK>,
}

/// The slave's odometry frame: what the master reads on every poll.
#[derive(Serialize, Deserialize, Schema, MaxSize, Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SlaveFrame {
    /// Incremented for every odometry update; lets the master see stale or skipped updates.
    pub seq: u16,
    /// Slave clock (microseconds since boot, wrapping) at the update this frame reports.
    pub time_us: u32,
    /// Slave clock when this frame was armed for the master, right after the previous
    /// transaction ended. The master knows that instant on its own clock, so
    /// `armed_us - time_us` tells it how old the pose is without synchronised clocks.
    pub armed_us: u32,
    /// Pose of the body reference point from the slave's odometry.
    pub pose: Pose,
    /// [`slave_status`] flags.
    pub status: u16,
    /// `command_seq` of the last master command the slave applied.
    pub command_ack: u8,
    /// Master frames the slave dropped for a bad CRC or decode (wrapping).
    pub rx_rejected: u16,
    /// The odometry algorithm producing `pose`.
    pub algorithm: OdometryAlgorithm,
    /// Fingerprint of the robot the slave runs ([`crate::robot::fingerprint`]).
    pub robot: u32,
    /// Where the odometry's readings come from.
    pub source: SensorSource,
    /// Odometry update period, microseconds (of played time when playing).
    pub period_us: u32,
    /// Next byte of the master's event stream the slave wants (acknowledges all before it).
    pub events_next: u32,
    /// The next piece of the slave's report stream ([`Report`]s, postcard, back to back).
    pub reports: Chunk,
}

/// Where the slave's odometry readings come from.
#[derive(Serialize, Deserialize, Schema, MaxSize, Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SensorSource {
    /// The timers' quadrature counters, read at the fixed update rate.
    Counts,
    /// Every encoder edge time-stamped by the board (the board's default).
    #[default]
    Ticks,
    /// Played count samples from the host, one per update of played time.
    PlayedCounts,
    /// Played time-stamped ticks from the host; updates every period of played time.
    PlayedTicks,
}

impl SensorSource {
    pub fn is_played(self) -> bool {
        matches!(self, SensorSource::PlayedCounts | SensorSource::PlayedTicks)
    }
}

/// What the slave writes to its report stream.
#[derive(Serialize, Deserialize, Schema, MaxSize, Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Reports {
    /// Nothing (live odometry; the master reads the pose from every frame).
    #[default]
    Off,
    /// Playing: the pose after the updates [`PoseChecks`] picks, each with the running digest
    /// of every update's pose up to it.
    Poses(PoseChecks),
    /// Recording: every sensor event the slave reads (the [`crate::events`] code) and the
    /// pose every `pose_every` updates.
    Record { pose_every: u16 },
}

/// Which updates of a play the slave reports in full. Every update is checked all the same:
/// each report carries the running digest of every pose before it ([`pose_digest`]), so a
/// pose that differs anywhere changes every digest after it.
#[derive(Serialize, Deserialize, Schema, MaxSize, Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PoseChecks {
    /// Every `every`-th update (1: all of them; 0 is read as 1).
    pub every: u16,
    /// And every update from this one on (updates count from 1): the stream's last window,
    /// which no multiple of `every` closes, or a window played again to find which of its
    /// updates was the first to differ.
    pub all_from: u32,
}

impl PoseChecks {
    /// Every update in full.
    pub const ALL: PoseChecks = PoseChecks {
        every: 1,
        all_from: 0,
    };

    /// Whether update `update` (1, 2, ...) is reported.
    pub fn reports(&self, update: u32) -> bool {
        update >= self.all_from || update.is_multiple_of(u32::from(self.every.max(1)))
    }
}

/// One record of the slave's report stream, postcard-encoded. While playing ([`Reports::Poses`])
/// records are back to back: `play` compares every update in order, so it stops at one it
/// cannot read. While recording ([`Reports::Record`]) each record is COBS-framed
/// ([`frame_report`]: it ends in the stream's only kind of 0x00 byte), so a reader that finds
/// one it cannot decode (a bug, or a board that lies: the link's CRC catches line noise) skips
/// to the next 0x00 and reads on; the event code starts again from time 0 after every
/// `PoseAt` and at every `Lost`, where the reader places events in time again.
#[derive(Serialize, Deserialize, Schema, MaxSize, Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Report {
    /// Playing: the pose after update `update` (counted from 1 since the source was set), for
    /// the updates [`PoseChecks`] picks, in order. `digest` is the running [`pose_digest`] of
    /// every update's full-precision pose up to this one, so the host checks every update
    /// bit for bit, beyond the micrometre rounding, from a fraction of them.
    Pose {
        update: u32,
        pose: Pose,
        digest: u32,
    },
    /// Recording: the pose at slave time `t_us`.
    PoseAt { t_us: u64, pose: Pose },
    /// Recording: sensor events, a piece of one continuous [`crate::events`] stream.
    Sensors(Bytes<REPORT_SENSOR_BYTES>),
    /// Recording: the report stream was full, so this many encoder events and updates were
    /// dropped before the next record (the file gets a gap, not invented data).
    Lost { events: u32, updates: u32 },
    /// Playing: the event stream failed to decode at this byte offset; play stopped.
    BadEvents { offset: u32 },
}

/// Largest piece of the event stream in one [`Report::Sensors`].
pub const REPORT_SENSOR_BYTES: usize = 40;

/// Longest framed record ([`frame_report`]): COBS's overhead and the 0x00 at its end.
pub const REPORT_FRAME_MAX: usize = cobs::max_encoding_length(Report::POSTCARD_MAX_SIZE) + 1;

/// `r` COBS-framed into the front of `out`, ending in 0x00; the bytes used, or `None` when
/// `out` is too short.
pub fn frame_report(r: &Report, out: &mut [u8]) -> Option<usize> {
    let mut raw = [0u8; Report::POSTCARD_MAX_SIZE];
    let n = crate::to_slice(r, &mut raw).ok()?.len();
    let m = cobs::try_encode(&raw[..n], out).ok()?;
    *out.get_mut(m)? = 0;
    Some(m + 1)
}

/// The record in one frame of the report stream (its bytes up to, not with, the 0x00 at its
/// end; decoded in place), or `None` if it is none.
pub fn unframe_report(frame: &mut [u8]) -> Option<Report> {
    let n = cobs::decode_in_place(frame).ok()?;
    postcard::from_bytes(&frame[..n]).ok()
}

/// The running digest of a play after one more full-precision pose (Q40 metres x, y and a
/// 64-bit binary-angle heading, as `robot_math::exact::FixedPose` holds them): CRC-32 over
/// the digest before it (0 before the first update) and the pose, little-endian. Equal
/// digests at a report is how `play` shows the board computed the same bits at every update
/// up to it.
pub fn pose_digest(before: u32, x: i64, y: i64, theta: u64) -> u32 {
    // One checksum over the 28 bytes, not a digest fed four times: the boards' one-shot
    // checksum is their CRC unit, their digest bit by bit (~1 000 instructions an update).
    let mut bytes = [0u8; 28];
    bytes[..4].copy_from_slice(&before.to_le_bytes());
    bytes[4..12].copy_from_slice(&x.to_le_bytes());
    bytes[12..20].copy_from_slice(&y.to_le_bytes());
    bytes[20..].copy_from_slice(&theta.to_le_bytes());
    crate::crc32::checksum(&bytes)
}

/// The odometry methods (SPEC §3). The slave runs `Exact` unless told otherwise; a slave that
/// cannot run a method (`Timing` needs tick time stamps, so a slave reading only hardware
/// counters refuses it) keeps its current one and sets [`slave_status::ALGORITHM_UNSUPPORTED`].
#[derive(Serialize, Deserialize, Schema, MaxSize, Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum OdometryAlgorithm {
    /// Ours: exact SE(2) integration in fixed point from cumulative counts.
    #[default]
    Exact,
    /// Seed 004's arc algorithm.
    Arc,
    /// Seed 001's integer table method.
    Lut,
    /// Seed 000's tick-timing method.
    Timing,
}

/// Bits of [`SlaveFrame::status`].
pub mod slave_status {
    /// Odometry is running (cleared until the first update after boot or reset).
    pub const RUNNING: u16 = 1 << 0;
    /// An odometry update was late (the fixed-rate loop overran).
    pub const OVERRUN: u16 = 1 << 1;
    /// A quadrature counter moved more than half its range between two samples.
    pub const COUNTER_JUMP: u16 = 1 << 2;
    /// The last algorithm the master asked for is not available in this slave build.
    pub const ALGORITHM_UNSUPPORTED: u16 = 1 << 3;
    /// Tick-timestamp mode lost encoder edges (queue overflow or both channels changing at
    /// once): the interpolated positions may be off until the next ticks.
    pub const EDGES_LOST: u16 = 1 << 4;
    /// The last robot upload was refused (fingerprint mismatch, missing parts, a layout the
    /// estimator cannot run): the slave kept the robot it had.
    pub const ROBOT_REJECTED: u16 = 1 << 5;
    /// Played events failed to decode: play stopped (see [`super::Report::BadEvents`]).
    pub const EVENTS_BAD: u16 = 1 << 6;
}

/// What the master sends on every poll.
#[derive(Serialize, Deserialize, Schema, MaxSize, Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MasterFrame {
    pub seq: u16,
    /// Identifies `command`. The master repeats a command in every frame until the slave
    /// acknowledges this number, so a lost or rejected frame never loses a command, and the
    /// slave applies each command once.
    pub command_seq: u8,
    pub command: SlaveCommand,
    /// The next piece of the played event stream (empty when not playing).
    pub events: Chunk,
    /// Next byte of the slave's report stream the master wants (acknowledges all before it).
    pub reports_next: u32,
}

#[derive(Serialize, Deserialize, Schema, MaxSize, Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SlaveCommand {
    #[default]
    None,
    /// The body is at this pose now: restart odometry from here.
    SetPose(Pose),
    /// Switch the odometry algorithm, continuing from the current pose.
    SetAlgorithm(OdometryAlgorithm),
    /// Robot upload, one per encoder: where it is and how far a count is.
    RobotWheel(crate::robot::WheelPart),
    /// Robot upload, one per encoder: `exact`'s integer constants, computed by the host.
    RobotExact(crate::robot::ExactPart),
    /// Ends a robot upload: the slave checks the fingerprint over the parts it holds, installs
    /// the robot and restarts odometry at the origin (or keeps its robot and raises
    /// [`slave_status::ROBOT_REJECTED`]).
    RobotCommit(crate::robot::RobotHeader),
    /// Where readings come from and what to report; restarts odometry at `start` with both
    /// stream offsets at zero.
    SetSource {
        source: SensorSource,
        reports: Reports,
        /// Where odometry restarts.
        start: Pose,
    },
}

const _: () = assert!(SlaveFrame::POSTCARD_MAX_SIZE <= SPI_PAYLOAD_LEN);
const _: () = assert!(MasterFrame::POSTCARD_MAX_SIZE <= SPI_PAYLOAD_LEN);

/// A frame type that travels over SPI, with the kind byte that opens it (neither 0x00 nor 0xFF,
/// and each the other's complement, so a frame on the wrong line is told apart).
pub trait SpiFrame: Serialize + DeserializeOwned + MaxSize + PartialEq {
    const KIND: u8;
}

impl SpiFrame for MasterFrame {
    const KIND: u8 = 0xA5;
}

impl SpiFrame for SlaveFrame {
    const KIND: u8 = 0x5A;
}

/// Why a received SPI frame was dropped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SpiFrameError {
    /// The check failed: a torn, corrupted, idle or stuck frame.
    Crc,
    /// The check passed but the kind byte is not this frame type's.
    Kind,
    /// The payload is not a frame of this type.
    Decode,
    /// The payload decodes but is not how the frame encodes (non-zero padding, an over-long
    /// number): refused, so that one frame has exactly one byte string.
    NonCanonical,
}

/// Encode a frame into its fixed-size wire form.
pub fn encode<T: SpiFrame>(frame: &T) -> [u8; SPI_FRAME_LEN] {
    let mut out = [0u8; SPI_FRAME_LEN];
    out[0] = T::KIND;
    // Cannot fail: every frame type's maximum size is checked against the payload at compile
    // time above; a failure would leave a zero payload, which then fails to decode.
    let _ = crate::writer::to_slice(frame, &mut out[1..1 + SPI_PAYLOAD_LEN]);
    let crc = crate::crc32::checksum(&out[..SPI_FRAME_LEN - SPI_CHECK_LEN]);
    out[SPI_FRAME_LEN - SPI_CHECK_LEN..].copy_from_slice(&crc.to_le_bytes());
    out
}

/// Check and decode a received fixed-size frame.
// Kept out of line: on the boards the tasks are one function the executor polls, and inlined
// there (once per image) it cost 384 B of the slave's flash and 96 B of the master's more than
// a call (docs/performance.md, "Images, eleventh round").
#[inline(never)]
pub fn decode<T: SpiFrame>(bytes: &[u8; SPI_FRAME_LEN]) -> Result<T, SpiFrameError> {
    let (body, check) = bytes.split_at(SPI_FRAME_LEN - SPI_CHECK_LEN);
    if crate::crc32::checksum(body).to_le_bytes() != *check {
        return Err(SpiFrameError::Crc);
    }
    if body[0] != T::KIND {
        return Err(SpiFrameError::Kind);
    }
    let payload = &body[1..];
    let (frame, rest) =
        postcard::take_from_bytes::<T>(payload).map_err(|_| SpiFrameError::Decode)?;
    let used = payload.len() - rest.len();
    // Canonical: zero padding, and the payload is what the frame encodes to.
    // The padding ORed together, not searched for a non-zero byte: a loop without an early
    // exit, which the host's compiler turns into wide ORs (the search was 3 % of an
    // emulation) and which takes about 100 instructions a frame fewer on the M3 (48 B more
    // of the slave's flash).
    // The payload is compared by its length only, which is the same test: of everything a
    // frame holds, postcard reads more than one byte string as the same value only for a
    // varint, and then only an over-long one (the top byte's unused bits must be clear), so
    // the bytes it took are the encoding exactly when there are no more of them than the
    // encoding has. Counting spares writing the frame again and comparing it: 276 B of the
    // slave's flash and 96 B of the master's (`a_decoded_frame_encodes_to_the_bytes_it_came_from`
    // checks the equivalence on edited frames).
    let canonical = rest.iter().fold(0, |acc, &b| acc | b) == 0
        && postcard::experimental::serialized_size(&frame).is_ok_and(|n| n == used);
    if !canonical {
        return Err(SpiFrameError::NonCanonical);
    }
    Ok(frame)
}
