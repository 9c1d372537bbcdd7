//! postcard's output written into a byte slice one byte at a time.
//!
//! postcard's own `to_slice` copies every varint (1 to 5 bytes for a `u32`, up to 10 for a
//! `u64`) into the slice with `copy_from_slice` of a length known only at run time: a call to
//! the boards' `memcpy` for each. A byte at a time, each byte is one checked store: the slave builds its SPI frame in
//! 183 fewer instructions (`scripts/m3-bench`), and the master's image is 164 B smaller. The
//! slave's report records go through it too (88 B of its flash less than through postcard's
//! `to_slice`, whose flavor was the image's only other). On the host the compiler turned the
//! byte loop back into a `memcpy` call per varint, so there `try_extend` copies a short run
//! in a loop of fixed length (below).

use postcard::ser_flavors::Flavor;
use serde::Serialize;

/// A postcard output flavor: the bytes go to `buf` from its start, one checked store each.
struct ByteWriter<'a> {
    buf: &'a mut [u8],
    used: usize,
}

impl Flavor for ByteWriter<'_> {
    type Output = usize;

    // On the boards `try_extend` is the trait's: a `try_push` per byte (a loop that stops at
    // the first refusal, which the compiler does not turn back into a `memcpy` call there).
    #[inline(always)]
    fn try_push(&mut self, byte: u8) -> postcard::Result<()> {
        let slot = self
            .buf
            .get_mut(self.used)
            .ok_or(postcard::Error::SerializeBufferFull)?;
        *slot = byte;
        self.used += 1;
        Ok(())
    }

    // On the host the trait's loop became a `memcpy` call per varint (the compiler checks
    // the room once and copies): 2.9 % of an emulation's instructions. Copies up to a
    // varint's longest (10 bytes, a `u64`) as a loop of fixed length it unrolls instead.
    // The boards keep the trait's loop: at opt-level "z" it stays a loop, and it is the
    // smaller code (16 B of the slave's flash, 24 B of the master's).
    #[cfg(not(target_os = "none"))]
    fn try_extend(&mut self, data: &[u8]) -> postcard::Result<()> {
        const SHORT: usize = 10;
        let end = self.used + data.len();
        let dst = self
            .buf
            .get_mut(self.used..end)
            .ok_or(postcard::Error::SerializeBufferFull)?;
        if data.len() <= SHORT {
            for i in 0..SHORT {
                if let (Some(d), Some(&s)) = (dst.get_mut(i), data.get(i)) {
                    *d = s;
                }
            }
        } else {
            dst.copy_from_slice(data);
        }
        self.used = end;
        Ok(())
    }

    fn finalize(self) -> postcard::Result<usize> {
        Ok(self.used)
    }
}

/// `postcard::to_slice` through [`ByteWriter`]: the same bytes, the same errors.
pub fn to_slice<'b, T: Serialize + ?Sized>(
    value: &T,
    buf: &'b mut [u8],
) -> postcard::Result<&'b mut [u8]> {
    let used = postcard::serialize_with_flavor(
        value,
        ByteWriter {
            buf: &mut *buf,
            used: 0,
        },
    )?;
    Ok(&mut buf[..used])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spi::{Chunk, MasterFrame, SlaveFrame};
    use crate::{Bytes, Pose};

    /// The boards' writer: [`ByteWriter`]'s store per byte, with the trait's `try_extend` (a
    /// `try_push` per byte), which the boards use and the host's build overrides.
    struct BoardWriter<'a>(ByteWriter<'a>);

    impl Flavor for BoardWriter<'_> {
        type Output = usize;
        fn try_push(&mut self, byte: u8) -> postcard::Result<()> {
            self.0.try_push(byte)
        }
        fn finalize(self) -> postcard::Result<usize> {
            self.0.finalize()
        }
    }

    fn board_to_slice<T: Serialize>(value: &T, buf: &mut [u8]) -> postcard::Result<usize> {
        postcard::serialize_with_flavor(value, BoardWriter(ByteWriter { buf, used: 0 }))
    }

    /// The same bytes as postcard's `to_slice`, and the same refusal of a buffer too short,
    /// on both SPI frames and on varints of every width beside a byte string: as the host
    /// writes them and as the boards do.
    #[test]
    fn writes_what_postcards_to_slice_writes() {
        fn same<T: Serialize>(value: &T) {
            let (mut ours, mut theirs) = ([0u8; 300], [0u8; 300]);
            let want = postcard::to_slice(value, &mut theirs).unwrap().to_vec();
            assert_eq!(to_slice(value, &mut ours).unwrap(), &want[..]);
            let mut board = [0u8; 300];
            let n = board_to_slice(value, &mut board).unwrap();
            assert_eq!(&board[..n], &want[..]);
            for short in 0..want.len() {
                assert_eq!(
                    to_slice(value, &mut ours[..short]),
                    Err(postcard::Error::SerializeBufferFull)
                );
                assert_eq!(
                    board_to_slice(value, &mut board[..short]),
                    Err(postcard::Error::SerializeBufferFull)
                );
            }
        }
        let chunk = Chunk {
            offset: 1 << 30,
            bytes: Bytes::from_slice_truncating(&[0xab; 56]),
        };
        // Varints of every length, and a byte string.
        same(&SlaveFrame {
            seq: u16::MAX,
            time_us: u32::MAX,
            armed_us: 1 << 20,
            pose: Pose::from_si(-1.5, 2.25, 3.0),
            status: 0x1234,
            rx_rejected: 300,
            robot: 0xdead_beef,
            period_us: 100,
            events_next: 1 << 27,
            reports: chunk,
            ..SlaveFrame::default()
        });
        same(&MasterFrame {
            seq: 200,
            events: chunk,
            reports_next: 70_000,
            ..MasterFrame::default()
        });
        same(&(u64::MAX, -1i32, 300u16, [7u8; 40].as_slice()));
    }
}
