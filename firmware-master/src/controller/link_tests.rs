//! The controller's tests of its links: the handshake and the baud switch with the host,
//! commands to the slave until acknowledged, the played and reported streams relayed, and the
//! SPI frames' age, repeats and failures.

use super::tests::{ctl, follow, slave_frame, t};
use super::*;
use protocol::spi::SpiFrameError;
use protocol::BinaryAngle;

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
