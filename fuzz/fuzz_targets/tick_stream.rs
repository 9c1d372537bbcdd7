//! Any bytes as a tick stream file, plain or gzip (recognised by its magic bytes): an error or
//! a stream, never a panic.
#![no_main]

use libfuzzer_sys::fuzz_target;
// The allocation bounds (src/lib.rs): linked only when named.
use omnibench_fuzz as _;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let _ = host_bench::formats::tickstream::read_from(data, Path::new("fuzz.ticks"));
});
