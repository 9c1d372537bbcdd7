//! Any text as a bench file (`bench.toml`: the two boards' probes and serial ports): an error
//! or a bench, never a panic.
#![no_main]

use libfuzzer_sys::fuzz_target;
// The allocation bounds (src/lib.rs): linked only when named.
use omnibench_fuzz as _;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = host_bench::boards::bench_file::parse(text, Path::new("bench.toml"));
    }
});
