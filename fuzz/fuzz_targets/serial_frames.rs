//! Any byte stream on the serial line, both message directions, through the constant-memory
//! frame decoder: no panic, and every message that comes out is one `encode` would send.
#![no_main]

use libfuzzer_sys::fuzz_target;
use protocol::serial::{self, FrameDecoder, HostToMaster, MasterToHost};

fn check<T: serde::Serialize + serde::de::DeserializeOwned>(data: &[u8]) {
    let mut decoder = FrameDecoder::new();
    for &b in data {
        if let Some(Ok(msg)) = decoder.push::<T>(b) {
            let mut buf = [0u8; serial::MAX_FRAME + 1];
            assert!(serial::encode(&msg, &mut buf).is_ok());
        }
    }
}

fuzz_target!(|data: &[u8]| {
    check::<HostToMaster>(data);
    check::<MasterToHost>(data);
});
