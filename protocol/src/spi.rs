//! Master <-> slave SPI frames.
//!
//! Every transaction is full duplex and moves exactly [`SPI_FRAME_LEN`] bytes each way: the
//! master sends a [`MasterFrame`] while the slave sends the [`SlaveFrame`] it armed before the
//! transaction. Layout of both: `postcard(frame)`, zero padding, CRC-16/IBM-3740 (big-endian)
//! over everything before it in the last two bytes. Idle lines (all `0xFF` or all `0x00`) and
//! torn frames fail the CRC, are counted, and are never acted on.

use crate::Pose;
use postcard::experimental::max_size::MaxSize;
use postcard_schema::Schema;
use serde::{de::DeserializeOwned, Deserialize, Serialize};

/// Bytes per SPI transaction, each way.
pub const SPI_FRAME_LEN: usize = 64;
/// Bytes available to the postcard payload.
pub const SPI_PAYLOAD_LEN: usize = SPI_FRAME_LEN - 2;

const CRC: crc::Crc<u16> = crc::Crc::<u16>::new(&crc::CRC_16_IBM_3740);

/// Incremental encoder slots in a slave frame (the seed 004 slave uses two; three leaves room
/// for seed 000's triangle of measuring wheels without a protocol change).
pub const ENCODER_SLOTS: usize = 3;

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
    /// Cumulative encoder counts since the slave's last reset (low 32 bits of 64-bit totals).
    pub counts: [i32; ENCODER_SLOTS],
    /// Absolute encoder code as decoded from Gray (0..2^bits).
    pub abs_code: u16,
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
}

/// What the master sends on every poll.
#[derive(Serialize, Deserialize, Schema, MaxSize, Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MasterFrame {
    pub seq: u16,
    /// Identifies `command`. The master repeats a command in every frame until the slave
    /// acknowledges this number, so a lost or rejected frame never loses a command, and the
    /// slave applies each command once.
    pub command_seq: u8,
    pub command: SlaveCommand,
}

#[derive(Serialize, Deserialize, Schema, MaxSize, Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SlaveCommand {
    #[default]
    None,
    /// The body is at this pose now: restart odometry from here.
    SetPose(Pose),
    /// Switch the odometry algorithm, continuing from the current pose.
    SetAlgorithm(OdometryAlgorithm),
}

const _: () = assert!(SlaveFrame::POSTCARD_MAX_SIZE <= SPI_PAYLOAD_LEN);
const _: () = assert!(MasterFrame::POSTCARD_MAX_SIZE <= SPI_PAYLOAD_LEN);

/// Why a received SPI frame was dropped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SpiFrameError {
    Crc,
    Decode,
}

/// Encode a frame into its fixed-size wire form.
pub fn encode<T: Serialize + MaxSize>(frame: &T) -> [u8; SPI_FRAME_LEN] {
    let mut out = [0u8; SPI_FRAME_LEN];
    // Cannot fail: every frame type's maximum size is checked against the payload at compile
    // time above; a failure would leave a zero payload, which then fails its CRC downstream.
    let _ = postcard::to_slice(frame, &mut out[..SPI_PAYLOAD_LEN]);
    let crc = CRC.checksum(&out[..SPI_PAYLOAD_LEN]);
    out[SPI_PAYLOAD_LEN..].copy_from_slice(&crc.to_be_bytes());
    out
}

/// Check and decode a received fixed-size frame.
pub fn decode<T: DeserializeOwned>(bytes: &[u8; SPI_FRAME_LEN]) -> Result<T, SpiFrameError> {
    let crc = u16::from_be_bytes([bytes[SPI_PAYLOAD_LEN], bytes[SPI_PAYLOAD_LEN + 1]]);
    if CRC.checksum(&bytes[..SPI_PAYLOAD_LEN]) != crc {
        return Err(SpiFrameError::Crc);
    }
    postcard::from_bytes(&bytes[..SPI_PAYLOAD_LEN]).map_err(|_| SpiFrameError::Decode)
}
