//! Golden bytes: the exact wire form of a few messages, checked in. If one of these changes,
//! the firmware and every host tool built before the change can no longer talk to the new
//! build: bump `PROTOCOL_VERSION` and update the bytes deliberately.

use protocol::serial::{self, BoardInfo, HostToMaster, MasterToHost, MovingTarget, Telemetry};
use protocol::spi::{
    self, Chunk, MasterFrame, OdometryAlgorithm, Report, Reports, SensorSource, SlaveCommand,
    SlaveFrame, SPI_FRAME_LEN,
};
use protocol::{BinaryAngle, Bytes, Point, Pose, PROTOCOL_VERSION};

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

fn serial_hex<T: serde::Serialize>(msg: &T) -> String {
    let mut out = [0u8; serial::MAX_FRAME];
    hex(serial::encode(msg, &mut out).expect("fits"))
}

#[test]
fn hello_frame_bytes() {
    // postcard: variant 0, u16 2 as varint -> 00 02; then CRC-32 LE; COBS; delimiter.
    assert_eq!(PROTOCOL_VERSION, 7, "a new version needs new golden bytes");
    assert_eq!(
        serial_hex(&HostToMaster::Hello {
            protocol_version: PROTOCOL_VERSION
        }),
        GOLDEN_HELLO
    );
}

#[test]
fn set_source_frame_bytes() {
    // Host -> master, new in v2: a command queued for the slave.
    let msg = HostToMaster::Slave(SlaveCommand::SetSource {
        source: SensorSource::PlayedTicks,
        reports: Reports::Record { pose_every: 300 },
        start: Pose {
            x_um: 1_000,
            y_um: -2_000,
            heading: BinaryAngle(1 << 31),
        },
    });
    assert_eq!(serial_hex(&msg), GOLDEN_SET_SOURCE);
}

#[test]
fn hello_reply_frame_bytes() {
    // Master -> host, new in v2: the board info answering Hello and Info.
    let msg = MasterToHost::HelloReply(BoardInfo {
        protocol_version: PROTOCOL_VERSION,
        schema_fingerprint: 0x1234_5678,
        firmware_version: [0, 2, 1],
        master_uid: [1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12],
        slave_seen: true,
        robot: 0xdead_beef,
        source: SensorSource::Ticks,
        period_us: 1_000,
        algorithm: OdometryAlgorithm::Exact,
        baud: 921_600,
    });
    assert_eq!(serial_hex(&msg), GOLDEN_HELLO_REPLY);
}

#[test]
fn baud_switch_frame_bytes() {
    // New in v7: the host asks for a faster link, the master answers before it switches.
    assert_eq!(
        serial_hex(&HostToMaster::SetBaud { baud: 2_000_000 }),
        GOLDEN_SET_BAUD
    );
    assert_eq!(
        serial_hex(&MasterToHost::BaudSet { baud: 2_000_000 }),
        GOLDEN_BAUD_SET
    );
    // And a play's checks: every 50th update, all from the 1 201st.
    let msg = HostToMaster::Slave(SlaveCommand::SetSource {
        source: SensorSource::PlayedCounts,
        reports: Reports::Poses(spi::PoseChecks {
            every: 50,
            all_from: 1_201,
        }),
        start: Pose::default(),
    });
    assert_eq!(serial_hex(&msg), GOLDEN_SET_SOURCE_POSES);
}

#[test]
fn follow_target_frame_bytes() {
    let msg = HostToMaster::FollowTarget(MovingTarget {
        from: Point {
            x_um: 0,
            y_um: 3_000_000,
        },
        to: Point {
            x_um: 2_500_000,
            y_um: 3_000_000,
        },
        target_speed_um_s: 350_000,
        robot_speed_um_s: 600_000,
        heading: BinaryAngle(0),
    });
    assert_eq!(serial_hex(&msg), GOLDEN_FOLLOW);
}

#[test]
fn track_and_set_drive_frame_bytes() {
    // Host -> master, new in v3: seed 002's path samples and the drive of the robot.
    let track = HostToMaster::Track(protocol::serial::TrackPoint {
        position: Point {
            x_um: 500_000,
            y_um: -250_000,
        },
        velocity_um_s: [400_000, 0],
        heading: BinaryAngle(0x4000_0000),
        omega_urad_s: -1_570_796,
    });
    assert_eq!(serial_hex(&track), GOLDEN_TRACK);
    let drive = HostToMaster::SetDrive(protocol::serial::DriveGeometry {
        kind: protocol::serial::DriveKind::OffsetDiff {
            y_left_um: 150_000,
            y_right_um: -150_000,
            offset_um: 150_000,
        },
        v_max_um_s: 800_000,
        speed_at_full_duty_um_s: 800_000,
        k_forward_milli: 8_000,
        k_lateral_milli: 8_000,
        ff_forward_milli: 1_000,
        ff_lateral_milli: 1_000,
        diff_forward_milli: 200,
        diff_lateral_milli: 200,
        motor_nm_per_count: 94_248,
        speed_kp_micro: 1_000_000,
        speed_ki_micro: 8_000_000,
        speed_kd_micro: 5_000,
    });
    assert_eq!(serial_hex(&drive), GOLDEN_SET_DRIVE);
}

#[test]
fn telemetry_frame_bytes() {
    let msg = MasterToHost::Telemetry(Telemetry {
        time_us: 1_000_000,
        slave_time_us: 999_000,
        slave_pose: Pose {
            x_um: -12,
            y_um: 34,
            heading: BinaryAngle(1 << 30),
        },
        master_pose: Pose::default(),
        wheel_cmd_um_s: [100, -200, 300],
        duty_permille: [1, -2, 3],
        status: 0b101,
        counters: Default::default(),
        slave_algorithm: OdometryAlgorithm::Arc,
    });
    assert_eq!(serial_hex(&msg), GOLDEN_TELEMETRY);
}

#[test]
fn spi_frames_bytes() {
    let slave = SlaveFrame {
        seq: 7,
        time_us: 123_456,
        armed_us: 124_000,
        pose: Pose {
            x_um: 1,
            y_um: -1,
            heading: BinaryAngle(u32::MAX),
        },
        status: 1,
        command_ack: 2,
        rx_rejected: 0,
        algorithm: OdometryAlgorithm::Exact,
        robot: 0x0102_0304,
        source: SensorSource::PlayedTicks,
        period_us: 2_000,
        events_next: 300,
        reports: Chunk {
            offset: 70_000,
            bytes: report_bytes(),
        },
    };
    let master = MasterFrame {
        seq: 9,
        command_seq: 3,
        command: SlaveCommand::SetPose(Pose::default()),
        events: Chunk {
            offset: 256,
            bytes: Bytes::from_slice_truncating(&[0x10, 0x20, 0x30]),
        },
        reports_next: 70_000,
    };
    let s = spi::encode(&slave);
    let m = spi::encode(&master);
    assert_eq!(s.len(), SPI_FRAME_LEN);
    assert_eq!(hex(&s), GOLDEN_SLAVE_FRAME);
    assert_eq!(hex(&m), GOLDEN_MASTER_FRAME);
}

/// A report chunk holding one `Report::Pose` record, as the slave streams it while playing.
fn report_bytes() -> Bytes<{ spi::STREAM_CHUNK }> {
    let report = Report::Pose {
        update: 300,
        pose: Pose {
            x_um: 5,
            y_um: -6,
            heading: BinaryAngle(7),
        },
        digest: 0xcafe_f00d,
    };
    let mut buf = [0u8; spi::STREAM_CHUNK];
    let wire = postcard::to_slice(&report, &mut buf).expect("a pose report fits a chunk");
    Bytes::from_slice_truncating(wire)
}

#[test]
fn fingerprint_is_pinned() {
    // Changes whenever any message type changes shape; pinned so that happens deliberately.
    assert_eq!(
        format!("{:08x}", protocol::schema_fingerprint()),
        GOLDEN_FINGERPRINT
    );
    // What the boards report is the same number, computed at build time by hand.
    assert_eq!(protocol::SCHEMA_FINGERPRINT, protocol::schema_fingerprint());
}

const GOLDEN_SET_BAUD: &str = "090c80897a04c036d000";
const GOLDEN_BAUD_SET: &str = "090680897a60208bbf00";
const GOLDEN_SET_SOURCE_POSES: &str = "080706020132b109010105c4ce038f00";
const GOLDEN_HELLO: &str = "0106075c87bddf00";
const GOLDEN_SET_SOURCE: &str = "1407060302ac02d00f9f1f8080808008f6a586b400";
const GOLDEN_HELLO_REPLY: &str =
    "010707f8acd191011802010102030405060708090a0b0c01effdb6f50d01e8070880a038b627659e00";
const GOLDEN_TRACK: &str = "0b0ac0843d9fc21e80ea300e8080808004d7dfbf0103f853e100";
const GOLDEN_SET_DRIVE: &str =
    "2e0b01e0a712dfa712e0a71280ea3080ea30c03ec03ed00fd00f90039003a8e005c0843d80a4e8038827682bf55c00";
const GOLDEN_FOLLOW: &str = "020213809bee02c096b102809bee02b0ae15c0cf24050aeaac0a00";
const GOLDEN_TELEMETRY: &str =
    "0f01c0843dd8fc3c1744808080800401010bc8018f03d8040203060501010101060171ce365200";
const GOLDEN_SLAVE_FRAME: &str = "5a07c0c407e0c8070201ffffffff0f010200008486880803d00fac02f0a2040b00ac020a0b078de0fbd70c0000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000009779c1ac";
const GOLDEN_MASTER_FRAME: &str = "a5090301000000800203102030f0a204000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000343ab21d";
const GOLDEN_FINGERPRINT: &str = "3b271056";
