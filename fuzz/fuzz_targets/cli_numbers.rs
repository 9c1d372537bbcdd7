//! Any numbers where the command line takes numbers (emulate's duration, fault times and
//! rates; replay's counts rate): refused, or accepted only inside the documented range
//! (docs/limits.md), never a panic or a hang.
#![no_main]

use host_bench::eval::replay::{self, Mode};
use host_bench::eval::replay_checks::{MAX_COUNTS_RATE_HZ, MIN_COUNTS_RATE_HZ};
use host_bench::formats::robot::Robot;
use host_bench::formats::tickstream;
use host_bench::sim::emulator::{self, Options, Scenario, MAX_DURATION_S};
use libfuzzer_sys::fuzz_target;
// The allocation bounds (src/lib.rs): linked only when named.
use omnibench_fuzz as _;
use std::path::Path;
use std::sync::OnceLock;

const ROBOT: &str = include_str!("../../robots/seed001.toml");
const STREAM: &str = "# omnibench tick stream v1\nt_ns,kind,id,value,x_m,y_m,theta_rad\n\
    0,truth,,,0,0,0\n5,tick,0,1,,,\n18000000000000000000,tick,1,1,,,\n\
    18000000000000000001,truth,,,0.0008,0,0\n";

fn number(bytes: &[u8]) -> f64 {
    let mut b = [0u8; 8];
    b[..bytes.len().min(8)].copy_from_slice(&bytes[..bytes.len().min(8)]);
    f64::from_le_bytes(b)
}

fuzz_target!(|data: &[u8]| {
    static FIXTURES: OnceLock<(Scenario, Robot, tickstream::TickStream)> = OnceLock::new();
    let (scenario, robot, stream) = FIXTURES.get_or_init(|| {
        let robot = Robot::parse(ROBOT, Path::new("seed001.toml")).unwrap();
        let stream = tickstream::read_from(STREAM.as_bytes(), Path::new("gap.csv")).unwrap();
        (Scenario::seed004_pursuit(), robot, stream)
    });
    let n: Vec<f64> = data.chunks(8).map(number).collect();
    let at = |i: usize| n.get(i).copied().unwrap_or(0.5);

    let mut opts = Options::new(scenario);
    opts.duration = at(0);
    opts.faults.slave_off_at = Some(at(1));
    opts.faults.host_silent_after = Some(at(2));
    opts.faults.spi.corrupt = at(3);
    opts.faults.spi.drop = at(4);
    opts.faults.spi.duplicate = at(6);
    opts.faults.spi.late = at(7);
    if emulator::check_options(&opts).is_ok() {
        assert!(opts.duration > 0.0 && opts.duration <= MAX_DURATION_S);
        for t in [at(1), at(2)] {
            assert!(t.is_finite() && t >= 0.0);
        }
        for r in [at(3), at(4), at(6), at(7)] {
            assert!((0.0..1.0).contains(&r));
        }
    }

    // The counts rate over a stream with a gap of 570 years between two ticks: any accepted
    // rate must finish at once.
    let rate_hz = at(5);
    if let Ok(score) = replay::replay_untracked(robot, stream, "arc", Mode::Counts { rate_hz }) {
        assert!((MIN_COUNTS_RATE_HZ..=MAX_COUNTS_RATE_HZ).contains(&rate_hz));
        assert!(score.final_error_m.is_finite());
    }
});
