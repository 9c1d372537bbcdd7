//! The whole system, emulated: both boards' portable firmware, linked by an in-memory SPI bus,
//! driven over the real serial protocol, closing the loop through the simulated robot.
//!
//! Bounds are set from measurement (docs/odometry.md, "The emulated robot over 30 power-on
//! phases"): over seeds 1-30 the slave's final error on the default scenario is at most
//! 0.51 mm (`host-bench emulate --sweep 30`), so 1 mm leaves a 2x margin and still fails on
//! any real regression; the heading error is bounded by half a step of the 8-bit absolute
//! encoder (the slave reads body heading through it) plus the carriage heading's count
//! quantisation.

use host_bench::sim::emulator::{self, Options, Run, Scenario};

/// Slave odometry vs ground truth at the end of the default scenario.
const FINAL_ERROR_BOUND_M: f64 = 0.001;
/// How close to the target's end point the robot must stop.
const GOAL_TOLERANCE_M: f64 = 0.005;

fn run_default(seed: u64, tweak: impl FnOnce(&mut Options)) -> Run {
    let scenario = Scenario::seed004_pursuit();
    let mut opts = Options::new(&scenario);
    opts.seed = seed;
    tweak(&mut opts);
    emulator::run(&scenario, &opts).expect("emulation runs")
}

/// Body heading = carriage heading (from the two wheels' counts, each within one count of
/// the truth) minus the swivel angle (from the absolute encoder, within half a step).
fn heading_bound() -> f64 {
    let g = firmware_slave::SlaveConfig::DEFAULT
        .layout()
        .carriage_geometry()
        .expect("the board's layout is seed 004's carriage");
    let count = g.metres_per_count[0].max(g.metres_per_count[1]);
    g.abs_step() / 2.0 + 2.0 * count / g.wheel_base + 1e-9
}

#[test]
fn default_scenario_reaches_the_goal_with_accurate_odometry() {
    let s = run_default(1, |_| {}).summary;
    assert_eq!(s.scenario, "seed004-pursuit");
    assert!((s.sim_seconds - 12.0).abs() < 1e-9, "{s:?}");
    // The robot stops on the target's end point (2.5, 3.0) m and says so.
    assert!(s.distance_to_goal_m < GOAL_TOLERANCE_M, "{s:?}");
    assert!(s.arrived, "{s:?}");
    // A pursuit curve from the origin to (2.5, 3): longer than the straight 3.9 m.
    assert!(s.path_length_m > 3.9 && s.path_length_m < 5.0, "{s:?}");
    // The slave's odometry against ground truth.
    assert!(s.final_error_m < FINAL_ERROR_BOUND_M, "{s:?}");
    assert!(s.max_error_m < FINAL_ERROR_BOUND_M, "{s:?}");
    assert!(s.final_heading_error_rad.abs() <= heading_bound(), "{s:?}");
    // Frames flowed the whole run, none rejected: 500 Hz SPI polls, 50 Hz telemetry.
    assert!(s.spi_frames >= 5_990, "{s:?}");
    assert!(s.serial_frames >= 700, "{s:?}");
    assert_eq!(s.spi_frames_rejected, 0, "{s:?}");
    assert_eq!(s.serial_frames_rejected, 0, "{s:?}");
    assert!(s.schema_fingerprint_match);
    assert_eq!(s.slave_reset_told_s, None, "no reset, none told");
    // The slave integrated at its fixed 1 kHz the whole time.
    assert!((11_990..=12_001).contains(&s.slave_updates), "{s:?}");
}

#[test]
fn at_the_goal_the_master_switches_the_motors_off_and_holds() {
    // Two minutes, most of them standing at the goal. Before the hold (issue 9) the master
    // kept chasing the swivel encoder's heading steps: 52 s of every minute driven at rest.
    let s = run_default(1, |o| o.duration = 120.0).summary;
    assert!(
        s.arrived && s.distance_to_goal_m < GOAL_TOLERANCE_M,
        "{s:?}"
    );
    assert_eq!(s.motor_switch_ons_after_arrival, Some(0), "{s:?}");
    let driven = s.motor_driven_s_after_arrival.expect("it arrived");
    assert!(driven < 0.05, "driven {driven} s after arriving");
    assert_eq!(s.motor_switch_ons, 1, "one start, one stop: {s:?}");
}

/// A standing goal just outside the 1 mm arrival band, with the motors' stiction and driver
/// dead band in the plant: the law asks for millimetres per second, the speed loops' integrators
/// wind up until the wheels break away, and the robot creeps in and stops: one switch-on, no
/// hunting round the goal, no re-switch while it stands.
#[test]
fn a_goal_a_few_millimetres_away_is_crept_into_with_one_switch_on() {
    use host_bench::sim::emulator::Motion;
    for (i, d) in [0.0015, 0.003, 0.006].into_iter().enumerate() {
        let mut scenario = Scenario::seed004_pursuit();
        scenario.motion = Motion::Pursue {
            target_from: (d, 0.0),
            target_to: (d, 0.0),
            target_speed: 0.35,
            robot_speed: 0.60,
            heading: 0.0,
        };
        let mut opts = Options::new(&scenario);
        opts.seed = 1 + i as u64;
        opts.duration = 30.0;
        let s = emulator::run(&scenario, &opts).unwrap().summary;
        let master = firmware_master::MasterConfig::DEFAULT;
        assert!(
            s.arrived && s.distance_to_goal_m < master.hold_release,
            "{d} m: {s:?}"
        );
        assert_eq!(s.motor_switch_ons, 1, "{d} m: {s:?}");
        assert_eq!(s.motor_switch_ons_after_arrival, Some(0), "{d} m: {s:?}");
        // Crept in, not given up on: inside the 1 mm arrival band.
        assert!(
            s.distance_to_goal_m < master.arrive_tolerance,
            "{d} m: {s:?}"
        );
    }
}

/// The same, with the speed loops' integrators off (a setting a user may choose): the
/// feed-forward and kp alone stay inside the drivers' dead band and the wheels never break
/// away. The master gives up after `hold_settle_us` standing still and switches off.
#[test]
fn stuck_in_the_dead_band_near_the_goal_the_master_switches_off() {
    use host_bench::sim::emulator::Motion;
    let mut scenario = Scenario::seed004_pursuit();
    scenario.motion = Motion::Pursue {
        target_from: (0.003, 0.0),
        target_to: (0.003, 0.0),
        target_speed: 0.35,
        robot_speed: 0.60,
        heading: 0.0,
    };
    scenario.drive.speed_ki_micro = 0;
    let mut opts = Options::new(&scenario);
    opts.duration = 30.0;
    let run = emulator::run(&scenario, &opts).unwrap();
    let s = &run.summary;
    let master = firmware_master::MasterConfig::DEFAULT;
    assert!(s.arrived && s.distance_to_goal_m > 0.002, "{s:?}");
    assert_eq!(s.motor_switch_ons, 1, "{s:?}");
    let off = motors_stopped_at(&run, 0.5).expect("the motors stopped");
    let settle = master.hold_settle_us as f64 * 1e-6;
    assert!(off > settle && off < settle + 0.1, "off at {off} s");
}

#[test]
fn the_same_seed_gives_the_same_run() {
    let a = run_default(7, |_| {});
    let b = run_default(7, |_| {});
    let strip = |r: &Run| {
        let mut s = r.summary.clone();
        s.wall_seconds = 0.0;
        s.speed_x = 0.0;
        format!("{s:?}")
    };
    assert_eq!(strip(&a), strip(&b));
    assert_eq!(format!("{:?}", a.log), format!("{:?}", b.log));
}

#[test]
fn every_seed_stays_within_the_bound_and_seeds_matter() {
    let errors: Vec<f64> = (1..=30)
        .step_by(5)
        .map(|seed| {
            let s = run_default(seed, |_| {}).summary;
            assert!(s.final_error_m < FINAL_ERROR_BOUND_M, "seed {seed}: {s:?}");
            assert!(
                s.distance_to_goal_m < GOAL_TOLERANCE_M,
                "seed {seed}: {s:?}"
            );
            s.final_error_m
        })
        .collect();
    // The seed sets the encoders' power-on phase: different seeds, different quantisation.
    assert!(errors.windows(2).any(|w| w[0] != w[1]), "{errors:?}");
}

/// The first logged time at or after `after` when all three duties are zero.
fn motors_stopped_at(run: &Run, after: f64) -> Option<f64> {
    run.log
        .iter()
        .find(|r| {
            r.t_s >= after && [r.duty_1_permille, r.duty_2_permille, r.duty_3_permille] == [0; 3]
        })
        .map(|r| r.t_s)
}

#[test]
fn losing_the_slave_stops_the_motors_within_the_link_timeout() {
    let run = run_default(1, |o| o.faults.slave_off_at = Some(3.0));
    // Still driving just before the fault.
    let before = run.log.iter().rev().find(|r| r.t_s < 3.0).unwrap();
    assert_ne!(
        [
            before.duty_1_permille,
            before.duty_2_permille,
            before.duty_3_permille
        ],
        [0; 3]
    );
    let cfg = firmware_master::MasterConfig::DEFAULT;
    let bound = 3.0 + (cfg.slave_timeout_us + cfg.control_period_us) as f64 * 1e-6 + 0.01;
    let stopped = motors_stopped_at(&run, 3.0).expect("motors stop");
    assert!(stopped <= bound, "stopped at {stopped}, bound {bound}");
    let last = run.log.last().unwrap();
    assert_ne!(last.status & protocol::serial::status::SLAVE_LOST, 0);
    assert!(
        run.summary.spi_frames_rejected > 0,
        "a dead slave's polls fail their CRC"
    );
}

/// Serial noise at issue 10's rates between host and master (1 % of frames bit-flipped, 5 %
/// lost, 1 % duplicated, 1 % delayed, 1 % torn, each way): the host sends each setting, the robot and
/// the goal again until the master shows them, and the runs end as clean ones do, on the
/// pursuit and on a tracked path whose robot is uploaded over the line.
#[test]
fn a_noisy_serial_line_to_the_host_still_gets_the_robot_there() {
    let noisy = |o: &mut Options| {
        o.faults.serial = host_bench::sim::serial_noise::SerialFaults {
            corrupt: 0.01,
            drop: 0.05,
            duplicate: 0.01,
            delay: 0.01,
            torn: 0.01,
        }
    };
    let mut rejected = 0;
    for seed in 1..=3 {
        let s = run_default(seed, noisy).summary;
        assert!(
            s.arrived && s.distance_to_goal_m < GOAL_TOLERANCE_M,
            "{s:?}"
        );
        assert!(s.final_error_m < FINAL_ERROR_BOUND_M, "{s:?}");
        assert_eq!(s.master_view_matches_slave, Some(true));
        let (m, h) = (s.serial_injected_to_master, s.serial_injected_to_host);
        assert!(
            m.dropped > 0 && h.dropped > 0 && h.corrupted + m.corrupted > 0,
            "{s:?}"
        );
        rejected += s.serial_frames_rejected;
        // Every refusal by why, as copies of the two decoders saw them: they add up to what
        // the master and the host counted.
        let (km, kh) = (s.serial_rejected_kinds_master, s.serial_rejected_kinds_host);
        assert_eq!(
            km.total() + kh.total(),
            s.serial_frames_rejected,
            "{km:?} {kh:?}"
        );
    }
    assert!(rejected > 0, "spoilt frames are caught and counted");
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../scenarios/seed002-square.toml"
    );
    let square = host_bench::formats::scenario::load(std::path::Path::new(path)).unwrap();
    let mut opts = Options::new(&square);
    noisy(&mut opts);
    let s = emulator::run(&square, &opts).unwrap().summary;
    assert!(s.robot_uploaded.is_some() && s.arrived, "{s:?}");
    assert!(s.tracking_rms_m.unwrap() < 2e-3, "{s:?}");
}

/// The drive geometry has no echo in the protocol: a lost one left the master driving seed
/// 002's differential chassis as its power-on 3-omni, 7 m off the path. On a noisy line the
/// host now sends it until the master's frame counters show it taken. At a quarter of the
/// frames lost, these two seeds lose it (checked, sent once: seed 8's robot ends 7 m away,
/// seed 1's slave never takes its robot, the upload going wrong on the wrong drive).
#[test]
fn a_drive_geometry_lost_on_the_line_is_sent_until_the_master_took_it() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../scenarios/seed002-square.toml"
    );
    let square = host_bench::formats::scenario::load(std::path::Path::new(path)).unwrap();
    for seed in [1, 8] {
        let mut opts = Options::new(&square);
        opts.seed = seed;
        opts.keep_log = false;
        opts.faults.serial.drop = 0.25;
        let s = emulator::run(&square, &opts).unwrap().summary;
        assert!(s.serial_drive_sends.unwrap() > 1, "{s:?}");
        assert!(s.arrived && s.tracking_rms_m.unwrap() < 2e-3, "{s:?}");
    }
}

/// A slave reset mid-run (issue 10): 5 ms later the slave runs again from power-on, its pose
/// back at its power-on pose. The master must tell (by the slave's clock starting again),
/// stop the motors at its next control step, say so to the host, and not drive on the reset
/// pose, though the host's goal stands.
#[test]
fn a_slave_reset_mid_run_stops_the_motors_and_the_host_is_told() {
    use host_bench::sim::emulator::SLAVE_BOOT_S;
    let run = run_default(1, |o| o.faults.slave_reset_at = Some(3.0));
    let s = &run.summary;
    let cfg = firmware_master::MasterConfig::DEFAULT;
    let poll_s = cfg.poll_period_us as f64 * 1e-6;
    let told = s.slave_reset_told_s.expect("the master tells");
    // Booted, then two good exchanges for the clocks' new offset.
    assert!(
        told > 3.0 + SLAVE_BOOT_S && told <= 3.0 + SLAVE_BOOT_S + 3.0 * poll_s + 1e-9,
        "told at {told}"
    );
    let r = s.slave_reset.expect("the reset is reported");
    let stopped = r.motors_stopped_s.expect("the motors stop");
    assert!(
        stopped <= told + cfg.control_period_us as f64 * 1e-6 + 1e-9,
        "stopped at {stopped}, told at {told}"
    );
    let host = r.host_told_s.expect("the host is told");
    assert!(host >= told && host <= told + 0.1, "host told at {host}");
    // Never driven again, and the status says why.
    assert_eq!(s.motor_switch_ons, 1);
    assert!(!s.arrived);
    let last = run.log.last().unwrap();
    assert_ne!(last.status & protocol::serial::status::SLAVE_RESET, 0);
    assert_eq!(last.status & protocol::serial::status::MOTORS_ON, 0);
    // Scored up to the reset, the slave was as accurate as ever; after it, its pose is its
    // power-on pose, metres from the robot.
    assert!(s.max_error_m < FINAL_ERROR_BOUND_M, "{s:?}");
    assert!(s.final_error_m > 0.5, "{s:?}");
}

/// Reset instants a float comparison misjudged (`1_100_000 µs · 1e-6 < 1.1`): the pose after the
/// reset (the power-on pose, metres off) was scored into the max error for them. And a reset
/// under SPI noise: the slave's rejected-frame count starts again from 0, which must not read
/// as 65 536 more rejections, and the fault check's clean run resets too, so the same motion
/// still ends bit for bit where it did.
#[test]
fn a_reset_is_scored_from_its_instant_and_its_counters_start_again() {
    for at in [1.1, 1.33] {
        let s = run_default(1, |o| {
            o.duration = 3.0;
            o.faults.slave_reset_at = Some(at);
        })
        .summary;
        assert!(s.max_error_m < FINAL_ERROR_BOUND_M, "reset at {at}: {s:?}");
        assert!(s.final_error_m > 0.1, "reset at {at}: {s:?}");
    }
    let scenario = Scenario::seed004_pursuit();
    let mut opts = Options::new(&scenario);
    opts.duration = 3.0;
    opts.keep_log = false;
    opts.faults.spi.corrupt = 0.3;
    opts.faults.slave_reset_at = Some(1.0);
    let faulty = emulator::run(&scenario, &opts).unwrap().summary;
    let injected = faulty.spi_injected.corrupted_to_slave;
    // Frames corrupted on their way to a slave that is booting are never read by it.
    assert!(
        faulty.spi_rejected_by_slave <= injected && faulty.spi_rejected_by_slave + 50 > injected,
        "{} rejected by the slave, {injected} corrupted to it",
        faulty.spi_rejected_by_slave
    );
    let check = emulator::fault_check(&scenario, &opts, &faulty).unwrap();
    assert!(check.same_motion_equals_clean, "{check:?}");
}

/// The slave's update rate is a setting (issue 11): at 10 kHz it integrates ten times as often
/// with the same accuracy, and the master, still polling every 2 ms, sees its pose as it is.
#[test]
fn the_slave_runs_at_10_khz_as_accurately() {
    let s = run_default(1, |o| o.slave.update_period_us = 100).summary;
    assert!((119_990..=120_001).contains(&s.slave_updates), "{s:?}");
    assert!(
        s.arrived && s.distance_to_goal_m < GOAL_TOLERANCE_M,
        "{s:?}"
    );
    assert!(s.final_error_m < FINAL_ERROR_BOUND_M, "{s:?}");
    assert!(s.max_error_m < FINAL_ERROR_BOUND_M, "{s:?}");
    assert_eq!(s.master_view_matches_slave, Some(true));
    assert_eq!(s.spi_frames_rejected, 0);
}

#[test]
fn a_silent_host_stops_the_motors_within_the_host_timeout() {
    let run = run_default(1, |o| o.faults.host_silent_after = Some(3.0));
    let cfg = firmware_master::MasterConfig::DEFAULT;
    // The last heartbeat went out at most 100 ms before the host fell silent.
    let bound = 3.0 + (cfg.host_timeout_us + cfg.control_period_us) as f64 * 1e-6 + 0.01;
    let stopped = motors_stopped_at(&run, 3.0).expect("motors stop");
    assert!(stopped > 3.0 + 0.3, "stopped too early, at {stopped}");
    assert!(stopped <= bound, "stopped at {stopped}, bound {bound}");
    let last = run.log.last().unwrap();
    assert_ne!(last.status & protocol::serial::status::HOST_LOST, 0);
    assert!(!run.summary.arrived);
}

#[test]
fn the_host_can_switch_the_slave_to_a_baseline_and_exact_wins() {
    use protocol::spi::OdometryAlgorithm;
    let exact = run_default(3, |_| {}).summary;
    let arc = run_default(3, |o| o.algorithm = OdometryAlgorithm::Arc).summary;
    assert_eq!(exact.algorithm, "exact");
    assert_eq!(arc.algorithm, "arc", "the slave reports what it runs");
    // Both close the loop on the same robot...
    assert!(arc.arrived && arc.spi_frames_rejected == 0, "{arc:?}");
    // ...but seed 004's end-heading step errs more than the exact arc (measured: 0.63 vs
    // 0.21 mm with seed 1).
    assert!(
        arc.final_error_m > exact.final_error_m,
        "{arc:?} vs {exact:?}"
    );
}

#[test]
fn an_algorithm_the_slave_cannot_run_fails_the_run_clearly() {
    use protocol::spi::OdometryAlgorithm;
    let scenario = Scenario::seed004_pursuit();
    let mut opts = Options::new(&scenario);
    opts.duration = 1.0;
    opts.slave.sensor = firmware_slave::SensorMode::Counts;
    opts.algorithm = OdometryAlgorithm::Timing;
    let err = match emulator::run(&scenario, &opts) {
        Ok(_) => panic!("a timing run on a counts-only slave must fail"),
        Err(e) => e.to_string(),
    };
    assert!(err.contains("cannot run Timing"), "{err}");
}

#[test]
fn with_tick_time_stamps_the_slave_runs_every_method() {
    use firmware_slave::SensorMode;
    use protocol::spi::OdometryAlgorithm;
    for algorithm in [
        OdometryAlgorithm::Exact,
        OdometryAlgorithm::Arc,
        OdometryAlgorithm::Lut,
        OdometryAlgorithm::Timing,
    ] {
        let run = run_default(2, |o| {
            o.slave.sensor = SensorMode::TickTimestamps;
            o.algorithm = algorithm;
        });
        let s = &run.summary;
        assert_eq!(s.algorithm, format!("{algorithm:?}").to_lowercase());
        assert!(
            s.arrived && s.final_error_m < FINAL_ERROR_BOUND_M,
            "{algorithm:?}: {s:?}"
        );
        // Every edge decoded: no lost-edge (or any other) slave fault during the run.
        assert!(
            run.log
                .iter()
                .all(|r| r.status & protocol::serial::status::SLAVE_FAULT == 0),
            "{algorithm:?}: slave reported a fault"
        );
    }
}

/// SPI faults at issue 10's rates (1 % of frames with a bit flipped each way, 5 % of
/// transactions lost): every bad frame is caught and counted where it arrives, the master's
/// last view of the slave's pose is the slave's own (cumulative counts lose nothing), and the
/// run ends as the clean one does: the same accuracy, at the goal, within a fraction of the
/// arrival band of the clean run's end (the master steered on frames a few polls older).
#[test]
fn spi_bit_errors_and_lost_transactions_lose_nothing() {
    use firmware_slave::SensorMode;
    let seed002_square = || {
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../scenarios/seed002-square.toml"
        );
        host_bench::formats::scenario::load(std::path::Path::new(path)).unwrap()
    };
    let clean = run_default(1, |_| {}).summary;
    let faulty = run_default(1, |o| {
        o.faults.spi.corrupt = 0.01;
        o.faults.spi.drop = 0.05;
    })
    .summary;
    let i = faulty.spi_injected;
    assert!(
        i.corrupted_to_master > 20 && i.corrupted_to_slave > 20 && i.dropped > 200,
        "{i:?}"
    );
    assert_eq!(
        faulty.spi_rejected_by_master,
        i.corrupted_to_master + i.dropped,
        "{faulty:?}"
    );
    assert_eq!(
        faulty.spi_rejected_by_slave, i.corrupted_to_slave,
        "{faulty:?}"
    );
    // Each rejection by why, as the wire saw the boards' decoders take them: all bad checks
    // here, adding up to what the boards counted themselves.
    let (m, sl) = (
        faulty.spi_rejected_kinds_master,
        faulty.spi_rejected_kinds_slave,
    );
    assert_eq!(
        (m.total(), sl.total()),
        (faulty.spi_rejected_by_master, faulty.spi_rejected_by_slave)
    );
    assert_eq!((m.crc, sl.crc), (m.total(), sl.total()), "{m:?} {sl:?}");
    assert_eq!(
        (
            clean.master_view_matches_slave,
            faulty.master_view_matches_slave
        ),
        (Some(true), Some(true))
    );
    assert_eq!(clean.spi_frames_rejected, 0);
    // Lost and bad frames never pass for a restarted slave (their clock stamps are skipped).
    assert_eq!(faulty.slave_reset_told_s, None);
    assert!(faulty.arrived && faulty.distance_to_goal_m < GOAL_TOLERANCE_M);
    assert!(faulty.final_error_m < FINAL_ERROR_BOUND_M && faulty.max_error_m < FINAL_ERROR_BOUND_M);
    let (a, b) = (clean.final_estimate_m, faulty.final_estimate_m);
    assert!((a.0 - b.0).hypot(a.1 - b.1) < 0.5e-3, "{a:?} {b:?}");

    // The same motion (the clean run's duties, step by step) under the same faults: the
    // slave's pose ends bit for bit where the clean run's did, on two scenarios, both sensor
    // modes and two seeds. A frame that slipped through, or link traffic that moved an
    // encoder edge, would show here.
    for (scenario, sensor, seed) in [
        (Scenario::seed004_pursuit(), SensorMode::TickTimestamps, 1),
        (Scenario::seed004_pursuit(), SensorMode::Counts, 2),
        (seed002_square(), SensorMode::TickTimestamps, 3),
    ] {
        let mut opts = Options::new(&scenario);
        opts.seed = seed;
        opts.keep_log = false;
        opts.slave.sensor = sensor;
        opts.faults.spi.corrupt = 0.01;
        opts.faults.spi.drop = 0.05;
        opts.faults.spi.torn = if seed == 2 { 0.02 } else { 0.0 };
        let faulty = emulator::run(&scenario, &opts).unwrap().summary;
        assert_eq!(
            faulty.spi_rejected_kinds_master.total(),
            faulty.spi_rejected_by_master
        );
        let check = emulator::fault_check(&scenario, &opts, &faulty).unwrap();
        assert!(
            check.same_motion_equals_clean,
            "{}: {check:?}",
            scenario.name
        );
        assert_eq!(check.same_motion_master_view_matches_slave, Some(true));
        assert!(check.same_motion_spi_frames_rejected > 300, "{check:?}");
        assert_eq!(check.clean_final_estimate_m, {
            let mut clean = opts.clone();
            clean.faults = Default::default();
            emulator::run(&scenario, &clean)
                .unwrap()
                .summary
                .final_estimate_m
        });
    }
}

/// The master's poll task late to get the CPU back after a transaction (another task held it:
/// at 2 Mbaud the serial reader once did, for 2.4 ms): chip select stays low 3 ms longer, while
/// the slave has re-armed on time. The exchange still ends when its last bit went, so the
/// boards' clock offset does not jump and no slave reset is imagined; the run still arrives.
#[test]
fn a_master_late_to_release_chip_select_imagines_no_slave_reset() {
    let scenario = Scenario::seed004_pursuit();
    let mut opts = Options::new(&scenario);
    opts.seed = 1;
    opts.keep_log = false;
    opts.faults.spi.late = 0.05;
    let faulty = emulator::run(&scenario, &opts).unwrap().summary;
    assert!(faulty.spi_injected.late > 50, "{:?}", faulty.spi_injected);
    assert_eq!(faulty.slave_reset_told_s, None);
    assert_eq!(faulty.master_view_matches_slave, Some(true));
    assert!(faulty.arrived && faulty.distance_to_goal_m < GOAL_TOLERANCE_M);
    // Driven as the clean run was, the slave (which never waited) ends bit for bit where it did.
    let check = emulator::fault_check(&scenario, &opts, &faulty).unwrap();
    assert!(check.same_motion_equals_clean, "{check:?}");
}

/// A slave late to re-arm sends its previous frame again (the only duplicate a synchronous bus
/// has). The master must know it for the frame it already read: counted with the rejected,
/// never taken as fresh, and never used to learn the boards' clock offset (its arming was not
/// the end of the exchange before). Steering on it, or learning from it, moves the run; so
/// does a missed one. Together with issue 10's rates: every injected fault is counted where it
/// lands, no slave reset is imagined, and the same motion ends bit for bit where the clean
/// run's did.
#[test]
fn frames_a_late_slave_sends_twice_are_known_and_set_aside() {
    let scenario = Scenario::seed004_pursuit();
    for (seed, drop) in [(1, 0.0), (4, 0.05)] {
        let mut opts = Options::new(&scenario);
        opts.seed = seed;
        opts.keep_log = false;
        opts.faults.spi.duplicate = 0.05;
        opts.faults.spi.drop = drop;
        opts.faults.spi.corrupt = 0.01;
        let faulty = emulator::run(&scenario, &opts).unwrap().summary;
        let (i, m) = (faulty.spi_injected, faulty.spi_rejected_kinds_master);
        assert!(i.duplicated > 200 && m.repeated > 200, "{i:?} {m:?}");
        // Only a repeat of a frame that reached the master whole is one it already had.
        assert!(m.repeated <= i.duplicated, "{i:?} {m:?}");
        assert_eq!(m.total(), faulty.spi_rejected_by_master, "{faulty:?}");
        assert_eq!(
            faulty.spi_rejected_by_master,
            i.corrupted_to_master + i.dropped + m.repeated,
            "{faulty:?}"
        );
        assert_eq!(faulty.slave_reset_told_s, None);
        assert_eq!(faulty.master_view_matches_slave, Some(true));
        assert!(faulty.arrived && faulty.distance_to_goal_m < GOAL_TOLERANCE_M);
        let check = emulator::fault_check(&scenario, &opts, &faulty).unwrap();
        assert!(check.same_motion_equals_clean, "seed {seed}: {check:?}");
    }
}
