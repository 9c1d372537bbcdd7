//! CRC-32/ISO-HDLC: the serial frames', the SPI frames' and the fingerprints' check.
//!
//! One function, two engines. The boards run the `crc` crate's one-table form (1 KiB of
//! flash). The host, where the emulator checks every SPI frame of both boards, runs
//! `crc32fast`, which folds 16 bytes at a time with the CPU's carry-less multiply: the crc
//! crate's slice-by-16 was 6 % of an emulation's instructions. Both give the standard
//! checksum to the bit (tested against the `crc` crate at random lengths, and the framing
//! tests check frames against it too).

pub use engine::{checksum, Digest};

impl Default for Digest {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(target_os = "none")]
mod engine {
    const CRC32: crc::Crc<u32, crc::Table<1>> =
        crc::Crc::<u32, crc::Table<1>>::new(&crc::CRC_32_ISO_HDLC);

    /// The CRC-32 of `bytes`.
    #[inline]
    pub fn checksum(bytes: &[u8]) -> u32 {
        CRC32.checksum(bytes)
    }

    /// A CRC-32 fed piece by piece: equal to [`checksum`] of the pieces joined.
    #[derive(Clone)]
    pub struct Digest(crc::Digest<'static, u32, crc::Table<1>>);

    impl Digest {
        pub fn new() -> Self {
            Digest(CRC32.digest())
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
    }
}
