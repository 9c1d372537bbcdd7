//! Any bytes as a played event stream or a counts stream: no panic, one result at most per
//! byte, in constant memory; and what decodes whole is what the encoder makes of it (one
//! encoding per stream).
#![no_main]

use libfuzzer_sys::fuzz_target;
// The allocation bounds (src/lib.rs): linked only when named.
use omnibench_fuzz as _;
use protocol::events::{
    encode_sample, EventDecoder, EventEncoder, SampleDecoder, MAX_EVENT_LEN, MAX_SAMPLE_LEN,
};

fuzz_target!(|data: &[u8]| {
    let (mut n, mut ok, mut again) = (0usize, true, Vec::new());
    let mut enc = EventEncoder::new();
    let mut dec = EventDecoder::new();
    dec.feed(data, |r| {
        n += 1;
        match r {
            Ok(e) => {
                let mut buf = [0u8; MAX_EVENT_LEN];
                let k = enc.encode(&e, &mut buf).expect("a decoded event encodes");
                again.extend_from_slice(&buf[..k]);
            }
            Err(_) => ok = false,
        }
    });
    assert!(n <= data.len());
    if ok && dec.is_between_events() {
        assert_eq!(again, data, "an event stream decoded whole re-encodes differently");
    }

    let (mut n, mut ok, mut again) = (0usize, true, Vec::new());
    let mut dec = SampleDecoder::new();
    dec.feed(data, |r| {
        n += 1;
        match r {
            Ok(s) => {
                let mut buf = [0u8; MAX_SAMPLE_LEN];
                let k = encode_sample(&s, &mut buf).expect("a decoded sample encodes");
                again.extend_from_slice(&buf[..k]);
            }
            Err(_) => ok = false,
        }
    });
    assert!(n <= data.len());
    if ok && dec.is_between_samples() {
        assert_eq!(again, data, "a counts stream decoded whole re-encodes differently");
    }
});
