//! Every message that crosses an omnibench wire, and how it is framed.
//!
//! * [`serial`]: host <-> master over a UART (or a pseudo-terminal in tests). Frames are
//!   `COBS(postcard(message) ++ CRC-32)` followed by a `0x00` delimiter.
//! * [`spi`]: master <-> slave. Every transaction moves one fixed-size frame each way:
//!   `postcard(message)`, zero padding, CRC-32 in the last four bytes.
//! * [`link`]: reliable, in-order byte streams over either of them (go-back-N with a credit
//!   window), sans-IO.
//! * [`events`]: compact byte codes for played sensor events (ticks, absolute codes, count
//!   samples) and their streaming decoders.
//!
//! The firmware and the host link this same crate, so both sides agree byte for byte; the
//! golden-byte tests in `tests/golden.rs` pin the encoding, and [`schema_fingerprint`] lets the
//! host detect a master built from a different version of these types.
//!
//! Units on the wire are integers: micrometres, micrometres per second, microseconds, and
//! headings as binary angles (2^32 = one turn, so they wrap for free).
#![cfg_attr(not(test), no_std)]

mod bytes;
pub mod chunks;
pub mod crc32;
pub mod events;
pub mod link;
pub mod robot;
pub mod serial;
pub mod spi;
mod units;
mod writer;
/// `postcard::to_slice`'s bytes and errors, without a `memcpy` call per varint.
pub use writer::to_slice;

pub use bytes::Bytes;
pub use units::{metres_to_um, BinaryAngle, Point, Pose};

/// Version of the wire protocol described by this crate. Bumped on any incompatible change.
pub const PROTOCOL_VERSION: u16 = 7;

/// [`schema_fingerprint`] of this crate, as a constant: what the firmware reports.
///
/// Computing it walks every message's schema, and on the board that walk and the schemas it
/// reads cost ~5 KB of flash for one number that only changes when the code does. So the
/// boards send this constant and the golden test (`fingerprint_is_pinned`) proves it equals
/// the computed value; a message change that forgets to update it fails that test.
pub const SCHEMA_FINGERPRINT: u32 = 0x3b27_1056;

/// A CRC-32 over the postcard schemas of every message type in this crate.
///
/// The master reports it in its hello reply; the host compares it with its own. Equal
/// fingerprints mean both were built from structurally identical message types (field
/// names, types and order), whatever `PROTOCOL_VERSION` says.
pub fn schema_fingerprint() -> u32 {
    use postcard_schema::Schema;
    let mut digest = crc32::Digest::new();
    for schema in [
        serial::HostToMaster::SCHEMA,
        serial::MasterToHost::SCHEMA,
        spi::MasterFrame::SCHEMA,
        spi::SlaveFrame::SCHEMA,
        spi::Report::SCHEMA,
    ] {
        feed_digest(&mut digest, schema);
    }
    digest.finalize()
}

/// Feed `value`'s postcard form to `digest`, with no buffer between.
fn feed_digest<T: serde::Serialize + ?Sized>(digest: &mut crc32::Digest, value: &T) {
    // Serialising into a digest cannot fail: the flavor never refuses a byte.
    let _ = postcard::serialize_with_flavor(value, DigestFlavor(digest));
}

struct DigestFlavor<'a>(&'a mut crc32::Digest);

impl postcard::ser_flavors::Flavor for DigestFlavor<'_> {
    type Output = ();
    fn try_push(&mut self, data: u8) -> postcard::Result<()> {
        self.0.update(&[data]);
        Ok(())
    }
    fn try_extend(&mut self, data: &[u8]) -> postcard::Result<()> {
        self.0.update(data);
        Ok(())
    }
    fn finalize(self) -> postcard::Result<()> {
        Ok(())
    }
}
