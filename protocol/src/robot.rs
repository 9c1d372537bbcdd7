//! A robot as the slave is given it: the pieces of `robot_math::odometry::Layout` in wire
//! form. The host computes every number once (floats as their exact IEEE bits, `exact`'s
//! integer constants), so the board holds the same bits as the host's own estimator; the
//! fingerprint over the pieces proves it.
//!
//! An upload is `RobotWheel` and `RobotExact` for each encoder, then `RobotCommit` with the
//! header, each an SPI command acknowledged by sequence number (one robot does not fit one
//! 128-byte SPI frame).

use postcard::experimental::max_size::MaxSize;
use postcard_schema::Schema;
use serde::{Deserialize, Serialize};

/// One encoder's wheel: position (metres, body frame), rolling direction (unit vector) and
/// travel per count (metres). f64 on the wire is its exact 8-byte IEEE form.
#[derive(Serialize, Deserialize, Schema, MaxSize, Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct WheelPart {
    pub index: u8,
    pub x_m: f64,
    pub y_m: f64,
    pub ux: f64,
    pub uy: f64,
    pub metres_per_count: f64,
}

/// One encoder's `exact` constants: body displacement per count in Q44 metres and turn per
/// count in 2^-48 turns (`robot_math::exact::ExactParams`).
#[derive(Serialize, Deserialize, Schema, MaxSize, Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ExactPart {
    pub index: u8,
    pub kx: i64,
    pub ky: i64,
    pub kth: i64,
}

/// Seed 004's swivel carriage: encoders 0 and 1 are its left and right measuring wheels.
#[derive(Serialize, Deserialize, Schema, MaxSize, Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CarriagePart {
    pub trail_m: f64,
    /// The trail in Q40 metres (the integer path's unit).
    pub trail_q40: i64,
}

/// How the absolute encoder's raw output word becomes a position.
#[derive(Serialize, Deserialize, Schema, MaxSize, Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct AbsPart {
    pub bits: u8,
    pub gray: bool,
    pub inverted: bool,
}

/// Ends an upload.
#[derive(Serialize, Deserialize, Schema, MaxSize, Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RobotHeader {
    pub encoders: u8,
    pub carriage: Option<CarriagePart>,
    pub abs: Option<AbsPart>,
    /// [`fingerprint`] of the whole robot, as the host computed it.
    pub fingerprint: u32,
}

/// CRC-32 over the postcard form of every part, in upload order (wheels and constants of
/// encoder 0, 1, ..., then the header with `fingerprint` zero). The slave computes it over
/// what it received; equal to the host's, both hold the same bits.
pub fn fingerprint(wheels: &[WheelPart], exact: &[ExactPart], header: &RobotHeader) -> u32 {
    let mut digest = crate::crc32::Digest::new();
    for (w, e) in wheels.iter().zip(exact) {
        crate::feed_digest(&mut digest, w);
        crate::feed_digest(&mut digest, e);
    }
    let h = RobotHeader {
        fingerprint: 0,
        ..*header
    };
    crate::feed_digest(&mut digest, &h);
    digest.finalize()
}

const _: () = assert!(WheelPart::POSTCARD_MAX_SIZE <= 64);
const _: () = assert!(ExactPart::POSTCARD_MAX_SIZE <= 64);
const _: () = assert!(RobotHeader::POSTCARD_MAX_SIZE <= 64);
