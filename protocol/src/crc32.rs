//! CRC-32/ISO-HDLC: the serial frames', the SPI frames' and the fingerprints' check.
//!
//! One function, three engines, all giving the standard checksum to the bit:
//! - The host, where the emulator checks every SPI frame of both boards, runs `crc32fast`,
//!   which folds 16 bytes at a time with the CPU's carry-less multiply (the crc crate's
//!   slice-by-16 was 6 % of an emulation's instructions).
//! - The boards run their STM32F103's CRC unit through [`checksum_by_words`]: a word per
//!   store, and no table (the `crc` crate's one-table form was 1 KiB of each image's flash).
//!   The image supplies the engine as the function `omnibench_crc32`, the way
//!   `critical-section` takes its implementation: `bluepill::crc` on both boards, the `crc`
//!   crate's table in m3-bench (QEMU's Cortex-M3 has no CRC unit).
//! - [`Digest`] (the fingerprints, a few times per upload) is the `crc` crate's bit-by-bit
//!   form on the boards: 30 bytes of code, no table.

pub use engine::{checksum, Digest};

impl Default for Digest {
    fn default() -> Self {
        Self::new()
    }
}

/// The `crc` crate's bit-by-bit CRC-32: no table. The boards' [`Digest`], the tail of
/// [`checksum_by_words`], and a board's engine while its CRC unit is busy.
const BITWISE: crc::Crc<u32, crc::NoTable> =
    crc::Crc::<u32, crc::NoTable>::new(&crc::CRC_32_ISO_HDLC);

/// [`checksum`] computed bit by bit (no table, no CRC unit).
pub fn checksum_bitwise(bytes: &[u8]) -> u32 {
    BITWISE.checksum(bytes)
}

/// A CRC unit that takes 32-bit words, as the STM32's: CRC-32/MPEG-2's polynomial
/// (0x04C1_1DB7), most significant bit first, starting from all ones, no output reflection or
/// inversion.
pub trait WordCrcUnit {
    /// Back to all ones.
    fn reset(&mut self);
    /// Shift one word in.
    fn feed(&mut self, word: u32);
    /// The register now.
    fn read(&mut self) -> u32;
}

/// [`checksum`] of `bytes` on a [`WordCrcUnit`]: each little-endian word goes in bit-reversed,
/// which turns the unit's most-significant-bit-first shifting into ISO-HDLC's
/// least-significant-first, so the unit's register is ISO-HDLC's register bit-reversed. The
/// last `len % 4` bytes continue from there bit by bit (the `crc` crate takes a start value in
/// the unreflected form, which is the unit's), and the finalisation inverts.
pub fn checksum_by_words(unit: &mut impl WordCrcUnit, bytes: &[u8]) -> u32 {
    unit.reset();
    let words = bytes.chunks_exact(4);
    let tail = words.remainder();
    for w in words {
        unit.feed(u32::from_le_bytes([w[0], w[1], w[2], w[3]]).reverse_bits());
    }
    let mut digest = BITWISE.digest_with_initial(unit.read());
    digest.update(tail);
    digest.finalize()
}

#[cfg(target_os = "none")]
mod engine {
    extern "Rust" {
        /// The image's CRC-32/ISO-HDLC of `bytes` (see the module's documentation).
        fn omnibench_crc32(bytes: &[u8]) -> u32;
    }

    /// The CRC-32 of `bytes`.
    #[inline]
    pub fn checksum(bytes: &[u8]) -> u32 {
        // SAFETY: a safe Rust function of this signature, which every image defines (a
        // missing one is a link error).
        unsafe { omnibench_crc32(bytes) }
    }

    /// A CRC-32 fed piece by piece: equal to [`checksum`] of the pieces joined.
    #[derive(Clone)]
    pub struct Digest(crc::Digest<'static, u32, crc::NoTable>);

    impl Digest {
        pub fn new() -> Self {
            Digest(super::BITWISE.digest())
        }
        #[inline]
        pub fn update(&mut self, bytes: &[u8]) {
            self.0.update(bytes)
        }
        pub fn finalize(self) -> u32 {
            self.0.finalize()
        }
    }
}

#[cfg(not(target_os = "none"))]
mod engine {
    /// The CRC-32 of `bytes`.
    #[inline]
    pub fn checksum(bytes: &[u8]) -> u32 {
        crc32fast::hash(bytes)
    }

    /// A CRC-32 fed piece by piece: equal to [`checksum`] of the pieces joined.
    #[derive(Clone)]
    pub struct Digest(crc32fast::Hasher);

    impl Digest {
        pub fn new() -> Self {
            Digest(crc32fast::Hasher::new())
        }
        #[inline]
        pub fn update(&mut self, bytes: &[u8]) {
            self.0.update(bytes)
        }
        pub fn finalize(self) -> u32 {
            self.0.finalize()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    const REFERENCE: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC);

    #[test]
    fn the_check_value_is_the_catalogues() {
        assert_eq!(checksum(b"123456789"), crc::CRC_32_ISO_HDLC.check);
    }

    proptest! {
        /// The host's engine gives the `crc` crate's checksum at lengths from 0 to 599 (the
        /// folding has paths below 16, below 128 and above), whole or in two pieces.
        #[test]
        fn the_host_engine_is_the_crc_crates(
            bytes in proptest::collection::vec(any::<u8>(), 0..600),
            cut in 0usize..600,
        ) {
            let want = REFERENCE.checksum(&bytes);
            prop_assert_eq!(checksum(&bytes), want);
            let cut = cut.min(bytes.len());
            let mut d = Digest::new();
            d.update(&bytes[..cut]);
            d.update(&bytes[cut..]);
            prop_assert_eq!(d.finalize(), want);
        }

        /// The boards' engine (on a model of their CRC unit) and the bit-by-bit one give the
        /// `crc` crate's checksum at every length, whole words or not.
        #[test]
        fn the_boards_engines_are_the_crc_crates(
            bytes in proptest::collection::vec(any::<u8>(), 0..300),
        ) {
            let want = REFERENCE.checksum(&bytes);
            prop_assert_eq!(checksum_by_words(&mut StmCrcModel::default(), &bytes), want);
            prop_assert_eq!(checksum_bitwise(&bytes), want);
        }

        /// The model is the unit: fed a byte string's big-endian words, it computes the
        /// catalogue's CRC-32/MPEG-2 of the string (what RM0008 §4 specifies the unit to do).
        #[test]
        fn the_unit_model_computes_crc32_mpeg2(
            words in proptest::collection::vec(any::<u32>(), 0..80),
        ) {
            let mut unit = StmCrcModel::default();
            unit.reset();
            let mut bytes = Vec::new();
            for &w in &words {
                unit.feed(w);
                bytes.extend_from_slice(&w.to_be_bytes());
            }
            let mpeg2 = crc::Crc::<u32>::new(&crc::CRC_32_MPEG_2);
            prop_assert_eq!(unit.read(), mpeg2.checksum(&bytes));
        }
    }

    /// The STM32F1 CRC unit as its reference manual describes it: the data register starts at
    /// all ones after a reset, and each word written shifts all 32 bits in, most significant
    /// first, through polynomial 0x04C1_1DB7.
    #[derive(Default)]
    struct StmCrcModel(u32);

    impl WordCrcUnit for StmCrcModel {
        fn reset(&mut self) {
            self.0 = u32::MAX;
        }
        fn feed(&mut self, word: u32) {
            let mut r = self.0 ^ word;
            for _ in 0..32 {
                r = if r & 0x8000_0000 != 0 {
                    (r << 1) ^ 0x04C1_1DB7
                } else {
                    r << 1
                };
            }
            self.0 = r;
        }
        fn read(&mut self) -> u32 {
            self.0
        }
    }
}
