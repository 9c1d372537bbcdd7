//! The stable twins of the fuzz targets in `fuzz/` (issue 10): every file parser, given
//! arbitrary bytes or the repository's own files with a few bytes changed, returns an error or a
//! value and never panics. `scripts/fuzz` runs the coverage-guided versions for longer.

use std::path::{Path, PathBuf};

use host_bench::boards::bench_file;
use host_bench::formats::robot::Robot;
use host_bench::formats::{scenario, tickstream};
use proptest::prelude::*;

fn repo(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(rel)
}

/// The files of one folder, read whole.
fn files(dir: &str) -> Vec<Vec<u8>> {
    let mut out: Vec<Vec<u8>> = std::fs::read_dir(repo(dir))
        .unwrap()
        .map(|e| std::fs::read(e.unwrap().path()).unwrap())
        .collect();
    out.sort();
    out
}

/// One of `seeds` with up to four bytes overwritten (or, sometimes, arbitrary bytes).
fn mutated(seeds: Vec<Vec<u8>>) -> impl Strategy<Value = Vec<u8>> {
    let n = seeds.len();
    prop_oneof![
        1 => prop::collection::vec(any::<u8>(), 0..512),
        4 => (0..n, prop::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..5))
            .prop_map(move |(i, edits)| {
                let mut b = seeds[i].clone();
                for (at, v) in edits {
                    if !b.is_empty() {
                        let k = at.index(b.len());
                        b[k] = v;
                    }
                }
                b
            }),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 200, ..ProptestConfig::default() })]

    #[test]
    fn tick_streams(bytes in mutated(files("host-bench/tests/data/tickstreams"))) {
        let _ = tickstream::read_from(&bytes[..], Path::new("t.ticks"));
    }

    #[test]
    fn robot_files(bytes in mutated(files("robots"))) {
        if let Ok(text) = std::str::from_utf8(&bytes) {
            if let Ok(robot) = Robot::parse(text, Path::new("r.toml")) {
                let _ = robot.drive_geometry();
                let _ = robot.carriage_geometry();
            }
        }
    }

    #[test]
    fn scenario_files(bytes in mutated(files("scenarios"))) {
        if let Ok(text) = std::str::from_utf8(&bytes) {
            let _ = scenario::parse(text, &repo("scenarios/s.toml"));
        }
    }

    #[test]
    fn bench_files(text in "\\PC{0,300}") {
        let _ = bench_file::parse(&text, Path::new("bench.toml"));
    }
}
