//! Any bytes as a played event stream or a counts stream: no panic, one result at most per
//! byte, in constant memory.
#![no_main]

use libfuzzer_sys::fuzz_target;
use protocol::events::{EventDecoder, SampleDecoder};

fuzz_target!(|data: &[u8]| {
    let mut n = 0usize;
    EventDecoder::new().feed(data, |_| n += 1);
    assert!(n <= data.len());
    n = 0;
    SampleDecoder::new().feed(data, |_| n += 1);
    assert!(n <= data.len());
});
