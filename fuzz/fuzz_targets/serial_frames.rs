//! Any byte stream on the serial line, both message directions, through the constant-memory
//! frame decoder: no panic, and every message that comes out is exactly the frame `encode`
//! makes of it (the bytes since the last delimiter).
#![no_main]

use libfuzzer_sys::fuzz_target;
// The allocation bounds (src/lib.rs): linked only when named.
use omnibench_fuzz as _;
use protocol::serial::{self, FrameDecoder, HostToMaster, MasterToHost};

fn check<T: serde::Serialize + serde::de::DeserializeOwned>(data: &[u8]) {
    let mut decoder = FrameDecoder::new();
    let mut start = 0;
    for (i, &b) in data.iter().enumerate() {
        if let Some(Ok(msg)) = decoder.push::<T>(b) {
            let mut buf = [0u8; serial::MAX_FRAME + 1];
            let frame = serial::encode(&msg, &mut buf).expect("a decoded message encodes");
            // The frame as received, delimiter included.
            assert_eq!(frame, &data[start..=i]);
        }
        if b == 0 {
            start = i + 1;
        }
    }
}

fuzz_target!(|data: &[u8]| {
    check::<HostToMaster>(data);
    check::<MasterToHost>(data);
});
