//! The controller's tests of its motion: pursuit, tracking, arriving and holding, the watchdogs;
//! driven by hand-made frames and clock values (its links: `link_tests.rs`).

use super::*;
use protocol::{BinaryAngle, Point};

pub(super) fn t(ms: u64) -> Instant {
    Instant::from_millis(ms)
}

/// A frame as a live slave sends it, each armed at its own instant (a frame armed when the
/// last one was is that one again, and set aside).
pub(super) fn slave_frame(seq: u16, ack: u8, x_um: i32) -> SlaveFrame {
    static ARMED_US: core::sync::atomic::AtomicU32 = core::sync::atomic::AtomicU32::new(1);
    let armed_us = ARMED_US.fetch_add(1, core::sync::atomic::Ordering::Relaxed);
    SlaveFrame {
        seq,
        // Its pose sampled as it was armed.
        armed_us,
        time_us: armed_us,
        command_ack: ack,
        pose: Pose {
            x_um,
            y_um: 0,
            heading: BinaryAngle(0),
        },
        status: protocol::spi::slave_status::RUNNING,
        ..Default::default()
    }
}

/// Hand the master `f` as it arrives at `ms`, stamped as a live slave stamps it: its clock runs
/// with the master's, and it armed the frame right after the exchange before, here 1 µs
/// earlier (two polls, the first bringing the same pose), so the pose is as fresh as these
/// hand-made poses mean it to be and the clocks' offset stays put.
fn poll_now(c: &mut Controller, ms: u64, mut f: SlaveFrame) {
    let now = ms * 1000;
    let armed_before = c.prev_good_exchange_end.map_or(now - 2, |t| t.as_micros());
    f.armed_us = armed_before as u32;
    f.time_us = f.armed_us;
    c.on_slave_frame(Instant::from_micros(now - 1), Ok(f));
    f.armed_us = (now - 1) as u32;
    f.time_us = f.armed_us;
    c.on_slave_frame(t(ms), Ok(f));
}

pub(super) fn follow(speed_um_s: u32) -> HostToMaster {
    HostToMaster::FollowTarget(MovingTarget {
        from: Point {
            x_um: 1_000_000,
            y_um: 0,
        },
        to: Point {
            x_um: 1_000_000,
            y_um: 0,
        },
        target_speed_um_s: 0,
        robot_speed_um_s: speed_um_s,
        heading: BinaryAngle(0),
    })
}

pub(super) fn ctl() -> Controller {
    Controller::new(MasterConfig::DEFAULT).unwrap()
}

#[test]
fn drives_towards_the_target_and_stops_when_the_slave_goes_quiet() {
    let mut c = ctl();
    c.on_host_message(t(0), follow(500_000));
    c.on_slave_frame(t(1), Ok(slave_frame(1, 0, 0)));
    let Drive::Duty(d) = c.control(t(2)) else {
        panic!("should drive")
    };
    // Straight ahead along +x: wheel 1 (rolling along +y) idle, wheels 2 and 3 opposite.
    assert_eq!(d[0], 0);
    assert!(d[1] < 0 && d[2] > 0, "{d:?}");
    // No fresh frame for longer than the timeout: motors stop and the goal is dropped.
    c.on_host_message(t(60), HostToMaster::Heartbeat);
    assert_eq!(c.control(t(2 + 51)), Drive::Stop);
    assert_ne!(c.status() & status::SLAVE_LOST, 0);
    assert_eq!(c.status() & status::FOLLOWING, 0);
}

#[test]
fn at_the_goal_the_motors_switch_off_and_stay_off_until_pushed_away() {
    let mut c = ctl();
    c.on_host_message(t(0), follow(500_000));
    let mut seq = 0;
    let mut at = |c: &mut Controller, ms: u64, x_um: i32, heading: u32| {
        seq += 1;
        let mut f = slave_frame(seq, 0, x_um);
        f.pose.heading = BinaryAngle(heading);
        poll_now(c, ms, f);
        c.on_host_message(t(ms), HostToMaster::Heartbeat);
        c.control(t(ms))
    };
    // 3 mm short: still driving.
    assert!(matches!(at(&mut c, 10, 997_000, 0), Drive::Duty(_)));
    assert_eq!(c.status() & status::ARRIVED, 0);
    // Within 1 mm but turned 0.05 rad: the heading is not there yet, still driving.
    let turned = (0.05 / core::f64::consts::TAU * 4_294_967_296.0) as u32;
    assert!(matches!(at(&mut c, 20, 999_500, turned), Drive::Duty(_)));
    // Within 1 mm and the heading within tolerance: arrived, motors off.
    assert_eq!(at(&mut c, 30, 999_500, 0), Drive::Stop);
    let arrived = status::FOLLOWING | status::ARRIVED;
    assert_eq!(c.status() & (arrived | status::MOTORS_ON), arrived);
    // Coasting 3 mm further (inside the 5 mm release band) and a heading step of the sensor:
    // the motors stay off, for as long as it stays there.
    for ms in (40..9_980).step_by(10) {
        assert_eq!(at(&mut c, ms, 1_003_000, turned), Drive::Stop, "{ms} ms");
    }
    // Turned 0.1 rad by hand: it turns back, then holds again.
    let turned_far = (0.1 / core::f64::consts::TAU * 4_294_967_296.0) as u32;
    assert!(matches!(
        at(&mut c, 10_000 - 20, 1_003_000, turned_far),
        Drive::Duty(_)
    ));
    assert_eq!(at(&mut c, 10_000 - 10, 1_000_000, 0), Drive::Stop);
    // Pushed 6 mm away: it drives back, and is no longer arrived.
    assert!(matches!(at(&mut c, 10_000, 1_006_000, 0), Drive::Duty(_)));
    assert_eq!(c.status() & status::ARRIVED, 0);
    assert_ne!(c.status() & status::MOTORS_ON, 0);
    // Back at the goal it holds again. The same standing target sent again keeps the hold;
    // another target lets it go.
    assert_eq!(at(&mut c, 10_010, 1_000_000, 0), Drive::Stop);
    c.on_host_message(t(10_020), follow(400_000));
    assert_ne!(c.status() & status::ARRIVED, 0);
    assert_eq!(at(&mut c, 10_030, 1_003_000, 0), Drive::Stop);
    let elsewhere = HostToMaster::FollowTarget(MovingTarget {
        from: Point { x_um: 0, y_um: 0 },
        to: Point { x_um: 0, y_um: 0 },
        target_speed_um_s: 0,
        robot_speed_um_s: 400_000,
        heading: BinaryAngle(0),
    });
    c.on_host_message(t(10_040), elsewhere);
    assert_eq!(c.status() & status::ARRIVED, 0);
    assert!(matches!(at(&mut c, 10_050, 1_003_000, 0), Drive::Duty(_)));
}

/// One control step at `ms` with the slave reporting the robot at `x_um` (a fresh frame: its
/// sequence number from the time, every 10 ms) and the host still there.
fn at(c: &mut Controller, ms: u64, x_um: i32) -> Drive {
    poll_now(c, ms, slave_frame((ms / 10) as u16, 0, x_um));
    c.on_host_message(t(ms), HostToMaster::Heartbeat);
    c.control(t(ms))
}

#[test]
fn stuck_just_outside_the_arrival_band_it_settles_and_switches_off() {
    let mut c = ctl();
    c.on_host_message(t(0), follow(500_000));
    let settle_ms = MasterConfig::DEFAULT.hold_settle_us as u64 / 1000;
    // Creeping: 0.3 mm every 0.5 s (more than a quarter of the 1 mm band) keeps it driving.
    let mut x = 996_000;
    for ms in (10..=4_000).step_by(10) {
        if ms % 500 == 0 {
            x += 300;
        }
        assert!(matches!(at(&mut c, ms, x), Drive::Duty(_)), "{ms} ms");
    }
    // Stuck 1.6 mm short (inside the 5 mm release band): driven for the settle time, then off.
    let stuck = x;
    let mut ms = 4_010;
    while ms < 4_000 + settle_ms - 10 {
        assert!(matches!(at(&mut c, ms, stuck), Drive::Duty(_)), "{ms} ms");
        ms += 10;
    }
    let mut stopped_at = None;
    for ms in (ms..ms + 100).step_by(10) {
        if at(&mut c, ms, stuck) == Drive::Stop {
            stopped_at.get_or_insert(ms);
        }
    }
    assert!(
        matches!(stopped_at, Some(ms) if ms <= 4_000 + settle_ms + 10),
        "settled at {stopped_at:?}"
    );
    assert_ne!(c.status() & status::ARRIVED, 0);
    assert_eq!(c.status() & status::MOTORS_ON, 0);
    // Stuck 8 mm short (outside the release band) it keeps trying: that is no hold.
    let mut c = ctl();
    c.on_host_message(t(0), follow(500_000));
    for ms in (10..10_000).step_by(10) {
        assert!(matches!(at(&mut c, ms, 992_000), Drive::Duty(_)), "{ms} ms");
    }
}

/// Standing still at one goal does not count towards settling at the next: a standing goal
/// 3 mm on (inside the release band) is driven to, not declared reached at once.
#[test]
fn a_new_goal_starts_its_settle_time_afresh() {
    let mut c = ctl();
    c.on_host_message(t(0), follow(500_000));
    let settle_ms = MasterConfig::DEFAULT.hold_settle_us as u64 / 1000;
    // Arrived and standing at 1.000 m for longer than the settle time.
    let mut ms = 10;
    while ms < settle_ms + 1_000 {
        assert_eq!(at(&mut c, ms, 1_000_000), Drive::Stop, "{ms} ms");
        ms += 10;
    }
    let next = HostToMaster::FollowTarget(MovingTarget {
        from: Point {
            x_um: 1_003_000,
            y_um: 0,
        },
        to: Point {
            x_um: 1_003_000,
            y_um: 0,
        },
        target_speed_um_s: 0,
        robot_speed_um_s: 500_000,
        heading: BinaryAngle(0),
    });
    c.on_host_message(t(ms), next);
    assert!(matches!(at(&mut c, ms + 10, 1_000_000), Drive::Duty(_)));
    assert_eq!(c.status() & status::ARRIVED, 0);
}

#[test]
fn a_stuck_slave_counts_as_lost() {
    let mut c = ctl();
    c.on_host_message(t(0), follow(500_000));
    for ms in 1..100 {
        // Valid CRC, but the same seq: odometry is not running.
        c.on_slave_frame(t(ms), Ok(slave_frame(7, 0, 0)));
        c.on_host_message(t(ms), HostToMaster::Heartbeat);
    }
    assert_eq!(c.control(t(100)), Drive::Stop);
}

#[test]
fn host_silence_stops_the_motors() {
    let mut c = ctl();
    c.on_host_message(t(0), follow(500_000));
    for ms in 1..=600 {
        c.on_slave_frame(t(ms), Ok(slave_frame(ms as u16, 0, 0)));
    }
    assert!(matches!(c.control(t(400)), Drive::Duty(_)));
    assert_eq!(c.control(t(600)), Drive::Stop);
    assert_ne!(c.status() & status::HOST_LOST, 0);
}

#[test]
fn invalid_target_is_rejected_and_stops() {
    let mut c = ctl();
    c.on_host_message(t(0), follow(500_000));
    let reply = c.on_host_message(t(1), follow(5_000_000));
    assert_eq!(
        reply,
        Some(MasterToHost::Rejected(RejectReason::InvalidTarget))
    );
    c.on_slave_frame(t(2), Ok(slave_frame(1, 0, 0)));
    assert_eq!(c.control(t(3)), Drive::Stop);
    assert_ne!(c.status() & status::COMMAND_REJECTED, 0);
}

#[test]
fn default_config_is_valid() {
    assert!(Controller::new(MasterConfig::DEFAULT).is_some());
    let mut bad = MasterConfig::DEFAULT;
    bad.drive.v_max_um_s = 0;
    assert!(Controller::new(bad).is_none());
}

fn seed_002_drive() -> protocol::serial::DriveGeometry {
    protocol::serial::DriveGeometry {
        kind: protocol::serial::DriveKind::OffsetDiff {
            y_left_um: 150_000,
            y_right_um: -150_000,
            offset_um: 150_000,
        },
        v_max_um_s: 800_000,
        speed_at_full_duty_um_s: 800_000,
        ..crate::drive_setup::SEED_004_DRIVE
    }
}

fn track(x_um: i32, vx_um_s: i32) -> HostToMaster {
    HostToMaster::Track(protocol::serial::TrackPoint {
        position: Point { x_um, y_um: 0 },
        velocity_um_s: [vx_um_s, 0],
        heading: BinaryAngle(0x4000_0000),
        omega_urad_s: 0,
    })
}

#[test]
fn an_impossible_drive_is_refused_and_stops_the_motors() {
    let mut c = ctl();
    c.on_host_message(t(0), follow(500_000));
    let mut bad = seed_002_drive();
    bad.kind = protocol::serial::DriveKind::OffsetDiff {
        y_left_um: 150_000,
        y_right_um: -150_000,
        offset_um: 0,
    };
    assert_eq!(
        c.on_host_message(t(1), HostToMaster::SetDrive(bad)),
        Some(MasterToHost::Rejected(RejectReason::InvalidDrive))
    );
    assert_eq!(c.status() & status::FOLLOWING, 0);
    assert_eq!(c.control(t(2)), Drive::Stop);
}

/// Seed 002's chassis, tracked point 0.15 m ahead of the slave's pose: a path sample ahead of
/// A drives both wheels forward alike and leaves motor 3 off; a standing sample on A holds,
/// whatever the heading the sample asks (the chassis cannot choose it).
#[test]
fn seed_002s_chassis_tracks_its_point_a_and_holds_on_it() {
    let mut c = ctl();
    assert_eq!(
        c.on_host_message(t(0), HostToMaster::SetDrive(seed_002_drive())),
        None
    );
    c.on_slave_frame(t(1), Ok(slave_frame(1, 0, 0)));
    c.on_host_message(t(1), track(200_000, 100_000));
    let Drive::Duty(d) = c.control(t(2)) else {
        panic!("should drive")
    };
    assert!(d[0] > 0 && d[0] == d[1] && d[2] == 0, "{d:?}");
    // A is at x = 0.15 m: a standing sample there is arrival. (Two frames in a row: the
    // second was armed, and its pose sampled, right then, so nothing is extrapolated.)
    c.on_slave_frame(t(3), Ok(slave_frame(2, 0, 0)));
    c.on_slave_frame(t(3), Ok(slave_frame(3, 0, 0)));
    c.on_host_message(t(3), track(150_000, 0));
    assert_eq!(c.control(t(3)), Drive::Stop);
    assert_ne!(c.status() & status::ARRIVED, 0);
    // The same standing sample again keeps the hold.
    c.on_host_message(t(5), track(150_000, 0));
    c.on_slave_frame(t(5), Ok(slave_frame(4, 0, 0)));
    assert_eq!(c.control(t(6)), Drive::Stop);
    // Faster than any wheel allows: refused.
    assert_eq!(
        c.on_host_message(t(7), track(150_000, 900_000)),
        Some(MasterToHost::Rejected(RejectReason::InvalidTarget))
    );
}
