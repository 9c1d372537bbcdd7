//! Any text as a scenario file (its robot path resolved against the repository's `robots/`):
//! an error or a scenario, never a panic.
#![no_main]

use libfuzzer_sys::fuzz_target;
// The allocation bounds (src/lib.rs): linked only when named.
use omnibench_fuzz as _;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        let here = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/fuzz.toml");
        let _ = host_bench::formats::scenario::parse(text, &here);
    }
});
