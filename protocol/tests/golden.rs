//! Golden bytes: the exact wire form of a few messages, checked in. If one of these changes,
//! the firmware and every host tool built before the change can no longer talk to the new
//! build: bump `PROTOCOL_VERSION` and update the bytes deliberately.

use protocol::serial::{self, HostToMaster, MasterToHost, MovingTarget, Telemetry};
use protocol::spi::{
    self, MasterFrame, OdometryAlgorithm, SlaveCommand, SlaveFrame, SPI_FRAME_LEN,
};
use protocol::{BinaryAngle, Point, Pose};

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

fn serial_hex<T: serde::Serialize>(msg: &T) -> String {
    let mut out = [0u8; serial::MAX_FRAME];
    hex(serial::encode(msg, &mut out).expect("fits"))
}

#[test]
fn hello_frame_bytes() {
    // postcard: variant 0, u16 1 as varint -> 00 01; then CRC-32 LE; COBS; delimiter.
    assert_eq!(
        serial_hex(&HostToMaster::Hello {
            protocol_version: 1
        }),
        GOLDEN_HELLO
    );
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
        counts: [1000, -1000, 0],
        abs_code: 64,
        pose: Pose {
            x_um: 1,
            y_um: -1,
            heading: BinaryAngle(u32::MAX),
        },
        status: 1,
        command_ack: 2,
        rx_rejected: 0,
        algorithm: OdometryAlgorithm::Exact,
    };
    let master = MasterFrame {
        seq: 9,
        command_seq: 3,
        command: SlaveCommand::SetPose(Pose::default()),
    };
    let s = spi::encode(&slave);
    let m = spi::encode(&master);
    assert_eq!(s.len(), SPI_FRAME_LEN);
    assert_eq!(hex(&s), GOLDEN_SLAVE_FRAME);
    assert_eq!(hex(&m), GOLDEN_MASTER_FRAME);
}

#[test]
fn fingerprint_is_pinned() {
    // Changes whenever any message type changes shape; pinned so that happens deliberately.
    assert_eq!(
        format!("{:08x}", protocol::schema_fingerprint()),
        GOLDEN_FINGERPRINT
    );
}

const GOLDEN_HELLO: &str = "0106016922de3600";
const GOLDEN_FOLLOW: &str = "020213809bee02c096b102809bee02b0ae15c0cf24050aeaac0a00";
const GOLDEN_TELEMETRY: &str =
    "0f01c0843dd8fc3c1744808080800401010bc8018f03d8040203060501010101060171ce365200";
const GOLDEN_SLAVE_FRAME: &str = "07c0c407e0c807d00fcf0f00400201ffffffff0f0102000000000000000000000000000000000000000000000000000000000000000000000000000000002a79";
const GOLDEN_MASTER_FRAME: &str = "09030100000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000d1b";
const GOLDEN_FINGERPRINT: &str = "603c973e";
