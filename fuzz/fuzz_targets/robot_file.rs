//! Any text as a robot file: an error naming the place, or a robot; never a panic.
#![no_main]

use libfuzzer_sys::fuzz_target;
// The allocation bounds (src/lib.rs): linked only when named.
use omnibench_fuzz as _;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        if let Ok(robot) = host_bench::formats::robot::Robot::parse(text, Path::new("fuzz.toml")) {
            // What the rest of the bench derives from a robot must not panic either.
            let _ = robot.drive_geometry();
            let _ = robot.carriage_geometry();
        }
    }
});
