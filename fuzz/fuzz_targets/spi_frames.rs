//! Any 128 bytes on the SPI wire, either way: no panic, and whatever decodes is canonical
//! (encoding it again gives the very bytes).
#![no_main]

use libfuzzer_sys::fuzz_target;
// The allocation bounds (src/lib.rs): linked only when named.
use omnibench_fuzz as _;
use protocol::spi::{self, MasterFrame, SlaveFrame, SPI_FRAME_LEN};

fuzz_target!(|data: &[u8]| {
    let mut bytes = [0u8; SPI_FRAME_LEN];
    let n = data.len().min(SPI_FRAME_LEN);
    bytes[..n].copy_from_slice(&data[..n]);
    if let Ok(f) = spi::decode::<SlaveFrame>(&bytes) {
        assert_eq!(spi::encode(&f), bytes);
    }
    if let Ok(f) = spi::decode::<MasterFrame>(&bytes) {
        assert_eq!(spi::encode(&f), bytes);
    }
});
