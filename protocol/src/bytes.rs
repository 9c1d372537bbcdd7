//! A byte string of at most `N` bytes that lives inline (no heap), for stream chunks inside
//! fixed-size messages. On the wire it is postcard's byte string: a varint length, then the
//! bytes. A longer string on the wire fails to decode, so a frame can never overflow it.

use core::fmt;
use postcard::experimental::max_size::MaxSize;
use postcard_schema::schema::{DataModelType, NamedType};
use postcard_schema::Schema;
use serde::de::Visitor;
use serde::{Deserialize, Deserializer, Serialize, Serializer};

#[derive(Clone, Copy, PartialEq, Eq)]
pub struct Bytes<const N: usize> {
    len: u32,
    buf: [u8; N],
}

impl<const N: usize> Default for Bytes<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> Bytes<N> {
    pub const CAPACITY: usize = N;

    pub const fn new() -> Self {
        Bytes {
            len: 0,
            buf: [0; N],
        }
    }

    /// The first `min(N, data.len())` bytes of `data`.
    pub fn from_slice_truncating(data: &[u8]) -> Self {
        let n = data.len().min(N);
        let mut b = Self::new();
        b.buf[..n].copy_from_slice(&data[..n]);
        b.len = n as u32;
        b
    }

    pub fn as_slice(&self) -> &[u8] {
        &self.buf[..self.len as usize]
    }

    pub fn len(&self) -> usize {
        self.len as usize
    }

    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
}

impl<const N: usize> fmt::Debug for Bytes<N> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Bytes[{}]", self.len)
    }
}

#[cfg(feature = "defmt")]
impl<const N: usize> defmt::Format for Bytes<N> {
    fn format(&self, f: defmt::Formatter) {
        defmt::write!(f, "Bytes[{}]", self.len)
    }
}

impl<const N: usize> Serialize for Bytes<N> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_bytes(self.as_slice())
    }
}

impl<'de, const N: usize> Deserialize<'de> for Bytes<N> {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V<const N: usize>;
        impl<const N: usize> Visitor<'_> for V<N> {
            type Value = Bytes<N>;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                write!(f, "at most {N} bytes")
            }
            fn visit_bytes<E: serde::de::Error>(self, v: &[u8]) -> Result<Bytes<N>, E> {
                if v.len() > N {
                    return Err(E::invalid_length(v.len(), &self));
                }
                Ok(Bytes::from_slice_truncating(v))
            }
        }
        // The deserializer's own error as it is: postcard's `DeserializeUnexpectedEnd` is how
        // a reader of records back to back tells a record not all there yet from a bad one.
        d.deserialize_bytes(V::<N>)
    }
}

impl<const N: usize> MaxSize for Bytes<N> {
    // Varint length (at most 3 bytes for any N that fits a u16) plus the bytes.
    const POSTCARD_MAX_SIZE: usize = varint_len(N) + N;
}

const fn varint_len(n: usize) -> usize {
    if n < 1 << 7 {
        1
    } else if n < 1 << 14 {
        2
    } else {
        3
    }
}

impl<const N: usize> Schema for Bytes<N> {
    const SCHEMA: &'static NamedType = &NamedType {
        name: "Bytes<N>",
        ty: &DataModelType::ByteArray,
    };
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips_and_refuses_too_long() {
        let b = Bytes::<8>::from_slice_truncating(&[1, 2, 3]);
        let mut buf = [0u8; 16];
        let wire = postcard::to_slice(&b, &mut buf).unwrap();
        assert_eq!(wire, &[3, 1, 2, 3]);
        let back: Bytes<8> = postcard::from_bytes(wire).unwrap();
        assert_eq!(back.as_slice(), &[1, 2, 3]);
        let long = Bytes::<16>::from_slice_truncating(&[7; 9]);
        let wire = postcard::to_slice(&long, &mut buf).unwrap();
        assert!(postcard::from_bytes::<Bytes<8>>(wire).is_err());
    }

    /// A reader of records back to back (`record`'s report stream) waits for the rest of a
    /// record cut short, and refuses a bad one: the two errors must differ. (They did not: a
    /// `Sensors` record cut in its bytes read as a bad record, and `record` stopped there.)
    #[test]
    fn a_record_cut_short_reads_as_unexpected_end_at_every_cut() {
        let r = crate::spi::Report::Sensors(Bytes::from_slice_truncating(&[5; 40]));
        let mut buf = [0u8; 64];
        let wire = postcard::to_slice(&r, &mut buf).unwrap();
        for cut in 0..wire.len() {
            assert_eq!(
                postcard::from_bytes::<crate::spi::Report>(&wire[..cut]),
                Err(postcard::Error::DeserializeUnexpectedEnd),
                "cut at {cut} of {}",
                wire.len()
            );
        }
    }
}
