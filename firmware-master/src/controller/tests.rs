//! The controller's tests: the state machine driven by hand-made frames and clock values.

use super::*;
use protocol::{BinaryAngle, Point};

fn t(ms: u64) -> Instant {
    Instant::from_millis(ms)
}

/// A frame as a live slave sends it, each armed at its own instant (a frame armed when the
/// last one was is that one again, and set aside).
fn slave_frame(seq: u16, ack: u8, x_um: i32) -> SlaveFrame {
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

fn follow(speed_um_s: u32) -> HostToMaster {
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

fn ctl() -> Controller {
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
fn wrong_protocol_version_is_refused() {
    let mut c = ctl();
    let reply = c.on_host_message(
        t(0),
        HostToMaster::Hello {
            protocol_version: 99,
        },
    );
    assert_eq!(
        reply,
        Some(MasterToHost::Rejected(RejectReason::ProtocolVersion {
            master: PROTOCOL_VERSION,
            host: 99
        }))
    );
    let ok = c.on_host_message(
        t(0),
        HostToMaster::Hello {
            protocol_version: PROTOCOL_VERSION,
        },
    );
    let Some(MasterToHost::HelloReply(info)) = ok else {
        panic!("hello must be answered with the board info, got {ok:?}")
    };
    assert_eq!(info.protocol_version, PROTOCOL_VERSION);
    assert_eq!(info.schema_fingerprint, protocol::schema_fingerprint());
    assert!(!info.slave_seen, "no slave frame yet");
}

#[test]
fn a_baud_switch_is_answered_at_the_old_rate_and_undone_unless_a_frame_comes_at_the_new() {
    let mut c = ctl();
    let info = |c: &mut Controller| match c.on_host_message(t(0), HostToMaster::Info) {
        Some(MasterToHost::HelloReply(i)) => i.baud,
        r => panic!("{r:?}"),
    };
    assert_eq!(info(&mut c), 115_200);
    let ask = |c: &mut Controller, baud| c.on_host_message(t(10), HostToMaster::SetBaud { baud });
    assert_eq!(
        ask(&mut c, 2_000_000),
        Some(MasterToHost::BaudSet { baud: 2_000_000 })
    );
    // Nothing switches before the host-tx task has sent the answer and says so.
    assert_eq!(c.baud_fallback_due(t(5_000)), None);
    c.baud_switched(t(10), 2_000_000);
    // No frame at the new rate within the trial: back to the power-on rate.
    let trial = protocol::serial::BAUD_TRIAL_MS as u64;
    assert_eq!(c.baud_fallback_due(t(10 + trial)), None);
    assert_eq!(c.baud_fallback_due(t(11 + trial)), Some(115_200));
    c.baud_switched(t(11 + trial), 115_200);
    assert_eq!(info(&mut c), 115_200);
    // Rates the USART cannot make are refused, and change nothing.
    for bad in [0, 300, 4_500_001] {
        assert_eq!(
            ask(&mut c, bad),
            Some(MasterToHost::Rejected(RejectReason::InvalidBaud))
        );
    }
    assert_eq!(info(&mut c), 115_200);
}

#[test]
fn set_pose_is_repeated_until_acknowledged_and_old_poses_are_ignored() {
    let mut c = ctl();
    let p = Pose {
        x_um: 5,
        y_um: 6,
        heading: BinaryAngle(7),
    };
    c.on_host_message(t(0), HostToMaster::SetPose(p));
    for _ in 0..3 {
        let f = c.next_slave_frame();
        assert_eq!((f.command_seq, f.command), (1, SlaveCommand::SetPose(p)));
        // Slave has not applied it yet: its pose is from before and must not be used.
        c.on_slave_frame(t(1), Ok(slave_frame(1, 0, 999)));
        assert!(c.estimate(t(1)).is_none());
    }
    c.on_slave_frame(t(2), Ok(slave_frame(2, 1, 5)));
    assert_eq!(c.next_slave_frame().command, SlaveCommand::None);
    assert!((c.estimate(t(2)).unwrap().x - 5e-6).abs() < 1e-12);
}

#[test]
fn frame_age_comes_from_the_slave_clock() {
    let mut c = ctl();
    // The slave's clock runs 1 s behind the master's. Polls end at 2.000 s and 2.002 s
    // (master clock); the slave armed its frame right after the first, holding a pose it
    // sampled 700 µs before that.
    c.on_slave_frame(t(2_000), Ok(slave_frame(1, 0, 0)));
    let mut f = slave_frame(2, 0, 0);
    f.armed_us = 1_000_000;
    f.time_us = 1_000_000 - 700;
    c.on_slave_frame(t(2_002), Ok(f));
    assert_eq!(c.slave.unwrap().1.as_micros(), 2_000_000 - 700);
    // The poll at 2.004 s is lost whole: the slave saw nothing and still holds the frame it
    // armed at 2.002 s. Read at 2.006 s, it is dated by the clocks' offset, not taken for a
    // frame armed at 2.004 s.
    c.on_slave_frame(t(2_004), Err(SpiFrameError::Crc));
    let mut f = slave_frame(3, 0, 0);
    f.armed_us = 1_002_000;
    f.time_us = 1_002_000 - 300;
    c.on_slave_frame(t(2_006), Ok(f));
    assert_eq!(c.slave.unwrap().1.as_micros(), 2_002_000 - 300);
    // The same after a bit error the slave did see (it armed a new frame at 2.006 s): the
    // offset dates that one right too.
    c.on_slave_frame(t(2_008), Err(SpiFrameError::Crc));
    let mut f = slave_frame(4, 0, 0);
    f.armed_us = 1_008_000;
    f.time_us = 1_008_000 - 100;
    c.on_slave_frame(t(2_010), Ok(f));
    assert_eq!(c.slave.unwrap().1.as_micros(), 2_008_000 - 100);
    assert_eq!(c.status() & status::SLAVE_RESET, 0);
    // A slave reboot (its clock back near zero) must not produce an absurd age.
    let mut f = slave_frame(5, 0, 0);
    f.time_us = 5;
    f.armed_us = 3;
    c.on_slave_frame(t(2_012), Ok(f));
    assert_eq!(c.slave.unwrap().1.as_micros(), 2_012_000);
    assert_ne!(c.status() & status::SLAVE_RESET, 0);
}

/// A slave late to re-arm sends its frame again (circular DMA). The repeat must not count as a
/// fresh frame, nor date the next one: taken as armed at the repeat's exchange, the next frame
/// would move the clocks' offset by a poll period per repeat and, two repeats in a row, pass
/// for a slave reset (the emulator's `--fault-spi-duplicate` found that).
#[test]
fn a_frame_sent_twice_is_set_aside() {
    let mut c = ctl();
    c.on_host_message(t(0), follow(500_000));
    poll(&mut c, 100, 1, 40_000_000, 0);
    poll(&mut c, 102, 2, 40_000_000, 0);
    let twice = c.slave_latest.unwrap();
    let rejected = c.counters().spi_rejected;
    // Read again at 104 and 106 ms; the slave's next frame, armed at 102 ms, comes at 108 ms.
    c.on_slave_frame(t(104), Ok(twice));
    c.on_slave_frame(t(106), Ok(twice));
    assert_eq!(c.counters().spi_rejected, rejected + 2);
    let mut f = slave_frame(3, 0, 0);
    f.armed_us = (102_000u64.wrapping_sub(40_000_000)) as u32;
    f.time_us = f.armed_us.wrapping_sub(500);
    c.on_slave_frame(t(108), Ok(f));
    assert_eq!(c.status() & status::SLAVE_RESET, 0);
    // Dated by the offset learned before the repeats: sampled 500 µs before 102 ms.
    assert_eq!(c.slave.unwrap().1.as_micros(), 102_000 - 500);
    poll(&mut c, 110, 4, 40_000_000, 0);
    assert_eq!(c.status() & status::SLAVE_RESET, 0);
    assert!(matches!(c.control(t(111)), Drive::Duty(_)));
}

/// Polls every 2 ms; the slave arms each frame `lag_us` after the exchange before ends, on a
/// clock `behind_us` behind the master's.
fn poll(c: &mut Controller, ms: u64, seq: u16, behind_us: u64, lag_us: u64) {
    let mut f = slave_frame(seq, 0, 0);
    f.armed_us = (ms * 1000 - 2000 + lag_us).wrapping_sub(behind_us) as u32;
    f.time_us = f.armed_us.wrapping_sub(500);
    c.on_slave_frame(t(ms), Ok(f));
}

#[test]
fn a_slave_whose_clock_starts_again_was_reset_the_motors_stop_until_the_pose_is_set() {
    let mut c = ctl();
    c.on_host_message(t(0), follow(500_000));
    // Arming late by up to a millisecond (a long odometry update first) is no reset.
    for (i, lag) in [0, 900, 0, 1000, 10].into_iter().enumerate() {
        poll(&mut c, 100 + 2 * i as u64, i as u16 + 1, 40_000_000, lag);
    }
    assert!(matches!(c.control(t(109)), Drive::Duty(_)));
    assert_eq!(c.status() & status::SLAVE_RESET, 0);
    // The slave restarted at 110 ms: its clock reads 2 ms at the master's 112 ms.
    poll(&mut c, 112, 1, 110_000, 0);
    poll(&mut c, 114, 2, 110_000, 0);
    assert_ne!(c.status() & status::SLAVE_RESET, 0);
    assert_eq!(c.status() & status::FOLLOWING, 0);
    assert_eq!(c.control(t(115)), Drive::Stop);
    // Its pose is its power-on pose: a goal is ignored until the host sets the pose again.
    c.on_host_message(t(116), follow(500_000));
    assert_eq!(c.control(t(117)), Drive::Stop);
    c.on_host_message(t(118), HostToMaster::SetPose(Pose::default()));
    assert_eq!(c.status() & status::SLAVE_RESET, 0);
    c.on_host_message(t(119), follow(500_000));
    assert_ne!(c.status() & status::FOLLOWING, 0);
}

#[test]
fn queued_commands_go_out_one_by_one_each_until_acknowledged() {
    use protocol::spi::OdometryAlgorithm;
    let mut c = ctl();
    let p = Pose {
        x_um: 1,
        y_um: 2,
        heading: BinaryAngle(3),
    };
    c.on_host_message(t(0), HostToMaster::SetPose(p));
    c.on_host_message(t(0), HostToMaster::SetOdometry(OdometryAlgorithm::Arc));
    let f = c.next_slave_frame();
    assert_eq!((f.command_seq, f.command), (1, SlaveCommand::SetPose(p)));
    // Not acknowledged yet: the same command again.
    c.on_slave_frame(t(1), Ok(slave_frame(1, 0, 0)));
    assert_eq!(c.next_slave_frame().command, SlaveCommand::SetPose(p));
    // Acked: the next one, under the next number.
    c.on_slave_frame(t(2), Ok(slave_frame(2, 1, 0)));
    let f = c.next_slave_frame();
    assert_eq!(
        (f.command_seq, f.command),
        (2, SlaveCommand::SetAlgorithm(OdometryAlgorithm::Arc))
    );
    assert!(
        c.estimate(t(2)).is_none(),
        "poses wait until every command is applied"
    );
    c.on_slave_frame(t(3), Ok(slave_frame(3, 2, 0)));
    let f = c.next_slave_frame();
    assert_eq!((f.command_seq, f.command), (2, SlaveCommand::None));
    assert!(c.estimate(t(3)).is_some());
    // A flood beyond the queue is refused and stops the robot.
    for _ in 0..COMMAND_QUEUE {
        assert_eq!(c.on_host_message(t(4), HostToMaster::SetPose(p)), None);
    }
    assert_eq!(
        c.on_host_message(t(4), HostToMaster::SetPose(p)),
        Some(MasterToHost::Rejected(RejectReason::Busy))
    );
}

fn events(seq: u16, bytes: &[u8]) -> HostToMaster {
    HostToMaster::Events(protocol::link::DataFrame {
        seq,
        bytes: heapless::Vec::from_slice(bytes).unwrap(),
    })
}

/// The master's ack of the host's event stream, which it sends next.
fn events_ack(c: &mut Controller, now: Instant) -> protocol::link::Ack {
    match c.poll_host_stream(now) {
        Some(MasterToHost::EventsAck(a)) => a,
        other => panic!("expected an events ack, got {other:?}"),
    }
}

#[test]
fn info_answers_without_restarting_the_streams_and_hello_restarts_them() {
    let mut c = ctl();
    let hello = HostToMaster::Hello {
        protocol_version: PROTOCOL_VERSION,
    };
    assert!(c.on_host_message(t(0), hello.clone()).is_some());
    c.on_slave_frame(
        t(0),
        Ok(SlaveFrame {
            robot: 0xabcd,
            period_us: 2_000,
            ..slave_frame(1, 0, 0)
        }),
    );
    c.on_host_message(t(1), events(0, &[1, 2, 3, 4]));
    assert_eq!(events_ack(&mut c, t(1)).next, 4);

    let reply = c.on_host_message(t(2), HostToMaster::Info);
    let Some(MasterToHost::HelloReply(info)) = reply else {
        panic!("info must be answered with the board info, got {reply:?}")
    };
    assert!(info.slave_seen);
    assert_eq!((info.robot, info.period_us), (0xabcd, 2_000));
    // The event stream goes on where it was.
    c.on_host_message(t(3), events(4, &[5, 6]));
    let ack = events_ack(&mut c, t(3));
    assert_eq!((ack.next, ack.gap), (6, false));

    // A hello starts a new session: the same continuation is now beyond the stream's start.
    assert!(c.on_host_message(t(4), hello).is_some());
    c.on_host_message(t(5), events(6, &[7]));
    let ack = events_ack(&mut c, t(5));
    assert_eq!((ack.next, ack.gap), (0, true));
}

#[test]
fn slave_commands_are_forwarded_in_order_each_until_acknowledged() {
    use protocol::robot::{ExactPart, RobotHeader, WheelPart};
    use protocol::spi::{Reports, SensorSource};
    let mut c = ctl();
    let sent = [
        SlaveCommand::RobotWheel(WheelPart {
            index: 0,
            metres_per_count: 1e-4,
            ..Default::default()
        }),
        SlaveCommand::RobotExact(ExactPart {
            index: 0,
            kx: 5,
            ky: 6,
            kth: 7,
        }),
        SlaveCommand::RobotCommit(RobotHeader {
            encoders: 1,
            fingerprint: 42,
            ..Default::default()
        }),
        SlaveCommand::SetSource {
            source: SensorSource::PlayedTicks,
            reports: Reports::Poses(protocol::spi::PoseChecks::ALL),
            start: Pose::default(),
        },
    ];
    for cmd in sent {
        assert_eq!(c.on_host_message(t(0), HostToMaster::Slave(cmd)), None);
    }
    let mut ack = 0;
    for (i, cmd) in sent.iter().enumerate() {
        let f = c.next_slave_frame();
        assert_eq!(
            (f.command_seq, &f.command),
            (i as u8 + 1, cmd),
            "command {i}"
        );
        // Not acknowledged: repeated, same number.
        c.on_slave_frame(t(1), Ok(slave_frame(2 * i as u16, ack, 0)));
        let again = c.next_slave_frame();
        assert_eq!((again.command_seq, &again.command), (f.command_seq, cmd));
        ack = f.command_seq;
        c.on_slave_frame(t(1), Ok(slave_frame(2 * i as u16 + 1, ack, 0)));
    }
    assert_eq!(c.next_slave_frame().command, SlaveCommand::None);
}

#[test]
fn played_events_wait_for_the_pending_commands() {
    use protocol::spi::{Reports, SensorSource};
    let mut c = ctl();
    let source = SlaveCommand::SetSource {
        source: SensorSource::PlayedTicks,
        reports: Reports::Poses(protocol::spi::PoseChecks::ALL),
        start: Pose::default(),
    };
    c.on_host_message(t(0), HostToMaster::Slave(source));
    c.on_host_message(t(0), events(0, &[1, 2, 3]));
    // The slave has not switched to played sensors yet: the events are held.
    for seq in 1..4 {
        let f = c.next_slave_frame();
        assert_eq!(f.command, source);
        assert!(f.events.bytes.is_empty(), "frame {seq} carried events");
        c.on_slave_frame(t(1), Ok(slave_frame(seq, 0, 0)));
    }
    // Applied: the events go out from the start of the slave's new stream.
    c.on_slave_frame(t(2), Ok(slave_frame(4, 1, 0)));
    let f = c.next_slave_frame();
    assert_eq!(f.command, SlaveCommand::None);
    assert_eq!(
        (f.events.offset, f.events.bytes.as_slice()),
        (0, &[1, 2, 3][..])
    );
}

#[test]
fn crc_failures_are_counted_not_used() {
    let mut c = ctl();
    c.on_slave_frame(t(1), Err(SpiFrameError::Crc));
    c.on_host_frame_error();
    assert_eq!(c.counters().spi_rejected, 1);
    assert_eq!(c.counters().serial_rejected, 1);
    assert!(c.estimate(t(1)).is_none());
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
