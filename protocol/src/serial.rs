//! Host <-> master messages and their serial framing.
//!
//! Frame on the wire: `COBS(postcard(message) ++ CRC-32/ISO-HDLC little-endian) ++ [0x00]`.
//! COBS guarantees `0x00` only appears as the delimiter, so a receiver that starts mid-stream
//! (or loses bytes) resynchronises at the next zero; the CRC catches everything else. A frame
//! that fails any check is counted by the receiver and dropped, never acted on.

use crate::link::{Ack, DataFrame};
use crate::spi::{OdometryAlgorithm, SensorSource, SlaveCommand};
use crate::{BinaryAngle, Point, Pose};
use postcard::experimental::max_size::MaxSize;
use postcard_schema::Schema;
use serde::{de::DeserializeOwned, Deserialize, Serialize};

/// Largest postcard payload of any serial message (checked against every type below).
pub const MAX_PAYLOAD: usize = 128;
/// Largest frame on the wire: payload, CRC, COBS overhead, delimiter.
pub const MAX_FRAME: usize = cobs::max_encoding_length(MAX_PAYLOAD + 4) + 1;

/// What the host asks of the master.
#[derive(Serialize, Deserialize, Schema, MaxSize, Clone, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum HostToMaster {
    /// Start of a session. The master answers with [`MasterToHost::HelloReply`].
    Hello { protocol_version: u16 },
    /// The robot is at this pose now (also resets the slave's odometry to it).
    SetPose(Pose),
    /// Follow a target that moves along a straight segment (seed 004's pursuit).
    /// A fixed goal is a segment with `from == to`.
    FollowTarget(MovingTarget),
    /// Stop the motors and forget the target.
    Stop,
    /// Which odometry algorithm the slave runs (forwarded to it; `Exact` at boot).
    SetOdometry(crate::spi::OdometryAlgorithm),
    /// "Still here". The master stops the motors when the host is silent for too long.
    Heartbeat,
    /// Ask for the board info again (answered by `HelloReply`) without starting a new session:
    /// the play/record streams keep their positions.
    Info,
    /// Queue a command for the slave (robot upload, sensor source); acknowledged by the slave
    /// in order, refused with `Rejected(Busy)` when the master's queue is full.
    Slave(SlaveCommand),
    /// A piece of the played event stream, for the slave (go-back-N, see [`crate::link`]).
    Events(DataFrame),
    /// Acknowledges the master's report stream.
    ReportsAck(Ack),
    /// Track a time-parametrised path (seed 002's law): where the tracked point should be
    /// now and how it moves. Send one every few control periods; between samples the master
    /// extrapolates with the velocity. Stale after the host timeout: the motors stop.
    Track(TrackPoint),
    /// The drive this image runs from now on (wheel layout, limits, tracking gains): one
    /// firmware serves every robot. Stops any motion; refused with `InvalidDrive`.
    SetDrive(DriveGeometry),
    /// Talk at `baud` from now on (esptool's way: meet at the power-on rate, then both switch).
    /// The master answers [`MasterToHost::BaudSet`] at the old rate and then switches; unless
    /// a good frame arrives at the new rate within [`BAUD_TRIAL_MS`], it goes back to its
    /// power-on rate, as it does whenever the host falls silent. Refused with `InvalidBaud`.
    SetBaud { baud: u32 },
}

/// How long the master waits for the host's first good frame at a new baud rate before it
/// goes back to its power-on rate, milliseconds.
pub const BAUD_TRIAL_MS: u32 = 400;
/// How long the host may stay silent at a rate other than the power-on one before the master
/// goes back to the power-on rate (a host that left without switching back), milliseconds.
pub const BAUD_SILENCE_MS: u32 = 2_000;
/// The fastest rate USART1 reaches: 72 MHz APB2 over the smallest divider, 16.
pub const MAX_BAUD: u32 = 4_500_000;
/// The slowest rate the master takes (the bench's frames would take seconds below it).
pub const MIN_BAUD: u32 = 9_600;

/// One sample of a reference path for the tracked point (seed 002's point A; an omni robot's
/// reference point), in the field frame, valid from the moment it arrives.
#[derive(Serialize, Deserialize, Schema, MaxSize, Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TrackPoint {
    pub position: Point,
    /// The reference velocity, fed forward and used to extrapolate, µm/s.
    pub velocity_um_s: [i32; 2],
    /// Heading to hold and its rate (platforms that choose their heading: omni).
    pub heading: BinaryAngle,
    pub omega_urad_s: i32,
}

/// The driven platform.
#[derive(Serialize, Deserialize, Schema, MaxSize, Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DriveKind {
    /// Seed 003's three omni wheels at distance `d` from the centre.
    Omni3 { d_um: u32 },
    /// Seed 002's differential chassis: wheels at lateral positions `y_left`, `y_right` on the
    /// axle, tracked point `offset` ahead of it (non-zero).
    OffsetDiff {
        y_left_um: i32,
        y_right_um: i32,
        offset_um: i32,
    },
}

/// Drive geometry, limits and gains, in integers (thousandths for the gains).
#[derive(Serialize, Deserialize, Schema, MaxSize, Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DriveGeometry {
    pub kind: DriveKind,
    pub v_max_um_s: u32,
    /// Wheel speed at full duty (the motors' feed-forward constant), µm/s.
    pub speed_at_full_duty_um_s: u32,
    /// Seed 002's gains, thousandths: position gains in 1/s (forward = the paper's k2,
    /// lateral = k1), feed-forward and damping shares.
    pub k_forward_milli: u32,
    pub k_lateral_milli: u32,
    pub ff_forward_milli: i32,
    pub ff_lateral_milli: i32,
    pub diff_forward_milli: i32,
    pub diff_lateral_milli: i32,
    /// The drive motors' encoders: rim travel per count, nanometres (0: no motor encoders,
    /// the duty is the feed-forward alone, open loop).
    pub motor_nm_per_count: u32,
    /// The per-motor speed PID, millionths of a duty (full = 1) per unit: `kp` per m/s, `ki`
    /// per m, `kd` per m/s².
    pub speed_kp_micro: u32,
    pub speed_ki_micro: u32,
    pub speed_kd_micro: u32,
}

/// What the master says about itself and its slave at the handshake.
#[derive(Serialize, Deserialize, Schema, MaxSize, Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BoardInfo {
    pub protocol_version: u16,
    /// [`crate::schema_fingerprint`] of the master's build.
    pub schema_fingerprint: u32,
    /// The master firmware's version (major, minor, patch).
    pub firmware_version: [u8; 3],
    /// The master chip's 96-bit unique ID (STM32F1: 0x1FFFF7E8).
    pub master_uid: [u8; 12],
    /// Whether a valid slave frame has been seen; the fields below are the slave's.
    pub slave_seen: bool,
    /// Fingerprint of the robot the slave runs.
    pub robot: u32,
    pub source: SensorSource,
    pub period_us: u32,
    pub algorithm: OdometryAlgorithm,
    /// The serial link's baud rate as the master runs it.
    pub baud: u32,
}

/// A target that starts at `from` when the command arrives and moves towards `to` at
/// `target_speed_um_s`, stopping there. The robot heads at the target's current position at up
/// to `robot_speed_um_s`, holding `heading`.
#[derive(Serialize, Deserialize, Schema, MaxSize, Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MovingTarget {
    pub from: Point,
    pub to: Point,
    pub target_speed_um_s: u32,
    pub robot_speed_um_s: u32,
    pub heading: BinaryAngle,
}

/// What the master reports to the host.
#[derive(Serialize, Deserialize, Schema, MaxSize, Clone, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum MasterToHost {
    HelloReply(BoardInfo),
    Telemetry(Telemetry),
    /// A command was well-framed but not acceptable; the motors were stopped.
    Rejected(RejectReason),
    /// A piece of the slave's report stream (go-back-N, see [`crate::link`]).
    Reports(DataFrame),
    /// Acknowledges the host's event stream, with the room left in the master's buffer.
    EventsAck(Ack),
    /// Only a simulated board sends this: the true pose at slave time `t_us`, so a recording
    /// of an emulated robot can be scored. Real boards never know the truth.
    SimTruth {
        t_us: u64,
        pose: Pose,
    },
    /// Answers [`HostToMaster::SetBaud`]: the last frame at the old rate; the master switches
    /// to `baud` once it is out.
    BaudSet {
        baud: u32,
    },
}

#[derive(Serialize, Deserialize, Schema, MaxSize, Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RejectReason {
    /// Hello carried another protocol version.
    ProtocolVersion { master: u16, host: u16 },
    /// A speed of zero or above the robot's limit, or a target out of range.
    InvalidTarget,
    /// Commands for the slave arrive faster than it applies them.
    Busy,
    /// A drive geometry the master cannot use (wheels not apart, tracked point on the axle,
    /// a limit or gain not positive).
    InvalidDrive,
    /// A baud rate outside [`MIN_BAUD`]..=[`MAX_BAUD`], or one this board's port cannot set.
    InvalidBaud,
}

/// The master's periodic report.
#[derive(Serialize, Deserialize, Schema, MaxSize, Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Telemetry {
    /// Master clock, microseconds since boot.
    pub time_us: u64,
    /// Slave clock at the odometry update that produced `slave_pose`.
    pub slave_time_us: u32,
    /// The slave's odometry, as last received over SPI.
    pub slave_pose: Pose,
    /// The master's own estimate (slave pose propagated with the commanded motion).
    pub master_pose: Pose,
    /// Wheel speed commands, micrometres per second, wheels 1..3.
    pub wheel_cmd_um_s: [i32; 3],
    /// PWM duty per wheel, per mille, signed.
    pub duty_permille: [i16; 3],
    /// [`status`] flags.
    pub status: u16,
    pub counters: LinkCounters,
    /// The algorithm the slave reports running.
    pub slave_algorithm: crate::spi::OdometryAlgorithm,
}

/// Frame counters of both links as the master sees them (all wrap at `u32::MAX`).
#[derive(Serialize, Deserialize, Schema, MaxSize, Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LinkCounters {
    /// SPI frames from the slave that passed the CRC.
    pub spi_ok: u32,
    /// SPI frames from the slave that failed the CRC or did not decode, bus errors, and
    /// frames the slave sent twice (late to re-arm: the frame the master had already).
    pub spi_rejected: u32,
    /// Master frames the slave reports as rejected (its own CRC check).
    pub slave_rx_rejected: u32,
    /// Serial frames from the host that were accepted.
    pub serial_ok: u32,
    /// Serial frames from the host that failed COBS, CRC, decoding or length.
    pub serial_rejected: u32,
}

/// Bits of [`Telemetry::status`].
pub mod status {
    /// A target is being followed.
    pub const FOLLOWING: u16 = 1 << 0;
    /// The (stopped) target has been reached.
    pub const ARRIVED: u16 = 1 << 1;
    /// Motors are being driven.
    pub const MOTORS_ON: u16 = 1 << 2;
    /// No valid slave frame for longer than the link timeout: motors stopped.
    pub const SLAVE_LOST: u16 = 1 << 3;
    /// No host message for longer than the host timeout: motors stopped.
    pub const HOST_LOST: u16 = 1 << 4;
    /// The last command was rejected: motors stopped.
    pub const COMMAND_REJECTED: u16 = 1 << 5;
    /// The slave reports a fault (see `spi::slave_status`).
    pub const SLAVE_FAULT: u16 = 1 << 6;
    /// The slave restarted (its clock did): its pose starts again from its power-on pose and
    /// its settings are its power-on ones. Motors stopped; goals are ignored until the host
    /// sets the pose again (which clears this), having sent again whatever else it had set.
    pub const SLAVE_RESET: u16 = 1 << 7;
}

const _: () = assert!(HostToMaster::POSTCARD_MAX_SIZE <= MAX_PAYLOAD);
const _: () = assert!(MasterToHost::POSTCARD_MAX_SIZE <= MAX_PAYLOAD);

/// Why a frame could not be encoded or was dropped on receipt.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FrameError {
    /// More bytes than [`MAX_FRAME`] arrived without a delimiter (or the output is too small).
    Overflow,
    /// The bytes between delimiters are not valid COBS.
    Cobs,
    /// The frame is too short to hold a CRC.
    Short,
    /// The CRC does not match.
    Crc,
    /// The CRC matched but the payload is not a valid message (or has trailing bytes).
    Decode,
    /// The message decodes but the frame is not how it encodes (an over-long number, a COBS
    /// form the encoder never makes): refused, so one message has exactly one frame.
    NonCanonical,
}

/// Encode `msg` as one delimited frame into `out`; returns the bytes to send.
pub fn encode<'a, T: Serialize>(msg: &T, out: &'a mut [u8]) -> Result<&'a [u8], FrameError> {
    let mut raw = [0u8; MAX_PAYLOAD + 4];
    let len = crate::writer::to_slice(msg, &mut raw[..MAX_PAYLOAD])
        .map_err(|_| FrameError::Overflow)?
        .len();
    let crc = crate::crc32::checksum(&raw[..len]);
    raw[len..len + 4].copy_from_slice(&crc.to_le_bytes());
    let n = cobs::try_encode(&raw[..len + 4], out).map_err(|_| FrameError::Overflow)?;
    let delim = out.get_mut(n).ok_or(FrameError::Overflow)?;
    *delim = 0;
    Ok(&out[..n + 1])
}

/// Reassembles frames from a byte stream, one byte or chunk at a time, in constant memory.
pub struct FrameDecoder {
    buf: [u8; MAX_FRAME],
    len: usize,
    /// Set after an overflow: drop bytes until the next delimiter.
    discarding: bool,
}

impl Default for FrameDecoder {
    fn default() -> Self {
        Self::new()
    }
}

impl FrameDecoder {
    pub const fn new() -> Self {
        FrameDecoder {
            buf: [0; MAX_FRAME],
            len: 0,
            discarding: false,
        }
    }

    /// Feed one byte. Returns `Some` when a delimiter closes a frame: the message, or why it
    /// was dropped. Empty frames (two delimiters in a row, used to flush a line) yield `None`.
    pub fn push<T: DeserializeOwned + Serialize>(
        &mut self,
        byte: u8,
    ) -> Option<Result<T, FrameError>> {
        if byte != 0 {
            if self.discarding {
                return None;
            }
            if self.len == self.buf.len() {
                self.discarding = true;
                self.len = 0;
                return Some(Err(FrameError::Overflow));
            }
            self.buf[self.len] = byte;
            self.len += 1;
            return None;
        }
        let len = core::mem::replace(&mut self.len, 0);
        if core::mem::replace(&mut self.discarding, false) || len == 0 {
            return None;
        }
        Some(decode_frame(&mut self.buf[..len]))
    }
}

/// Decode one frame's bytes (without the delimiter), in place. Only the frame [`encode`] makes
/// of the message decodes (checked by encoding it again).
pub fn decode_frame<T: DeserializeOwned + Serialize>(frame: &mut [u8]) -> Result<T, FrameError> {
    let mut received = [0u8; MAX_FRAME];
    let received = received
        .get_mut(..frame.len())
        .ok_or(FrameError::Overflow)?;
    received.copy_from_slice(frame);
    let n = cobs::decode_in_place(frame).map_err(|_| FrameError::Cobs)?;
    if n < 4 {
        return Err(FrameError::Short);
    }
    let (payload, crc) = frame[..n].split_at(n - 4);
    let crc = u32::from_le_bytes([crc[0], crc[1], crc[2], crc[3]]);
    if crate::crc32::checksum(payload) != crc {
        return Err(FrameError::Crc);
    }
    let msg = match postcard::take_from_bytes::<T>(payload) {
        Ok((msg, [])) => msg,
        _ => return Err(FrameError::Decode),
    };
    let mut again = [0u8; MAX_FRAME + 1];
    match encode(&msg, &mut again) {
        // The encoding ends with its delimiter, which `frame` does not hold.
        Ok(e) if e[..e.len() - 1] == *received => Ok(msg),
        _ => Err(FrameError::NonCanonical),
    }
}

/// The master's own USB port, a CDC-ACM serial port carrying this very protocol (a second
/// way to reach the master, with no USB-serial adapter): its USB identity.
pub mod usb {
    /// pid.codes' vendor ID, with its PID for tests and private use: fine for a bench's own
    /// boards; a product shipped to others registers its own PID.
    pub const VID: u16 = 0x1209;
    pub const PID: u16 = 0x0001;
    pub const MANUFACTURER: &str = "omnibench";
    pub const PRODUCT: &str = "omnibench master";

    /// The USB serial number: the chip's 96-bit unique ID (`BoardInfo::master_uid`, bytes in
    /// address order) as 24 upper-case hex digits, so a port names the board it belongs to,
    /// as the probe that flashed it reads the same ID.
    pub fn serial_number(uid: &[u8; 12]) -> [u8; 24] {
        const HEX: &[u8; 16] = b"0123456789ABCDEF";
        let mut out = [0u8; 24];
        for (i, b) in uid.iter().enumerate() {
            out[2 * i] = HEX[usize::from(b >> 4)];
            out[2 * i + 1] = HEX[usize::from(b & 0xF)];
        }
        out
    }

    #[cfg(test)]
    mod tests {
        #[test]
        fn the_serial_number_is_the_uid_in_hex_in_address_order() {
            let uid = [0x12, 0x34, 0xAB, 0xCD, 0, 1, 2, 3, 0xFE, 0xDC, 0xBA, 0x98];
            assert_eq!(&super::serial_number(&uid), b"1234ABCD00010203FEDCBA98");
        }
    }
}
