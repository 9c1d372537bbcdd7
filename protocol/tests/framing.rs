//! Framing behaviour: round trips, and that nothing corrupted is ever accepted.

use proptest::prelude::*;
use protocol::link::{Ack, DataFrame, MAX_CHUNK};
use protocol::serial::{self, FrameDecoder, FrameError, HostToMaster, MovingTarget};
use protocol::spi::{
    self, Chunk, MasterFrame, OdometryAlgorithm, Reports, SensorSource, SlaveCommand, SlaveFrame,
    SpiFrameError, STREAM_CHUNK,
};
use protocol::{BinaryAngle, Bytes, Point, Pose};

fn arb_pose() -> impl Strategy<Value = Pose> {
    (any::<i32>(), any::<i32>(), any::<u32>()).prop_map(|(x_um, y_um, h)| Pose {
        x_um,
        y_um,
        heading: BinaryAngle(h),
    })
}

fn arb_host_msg() -> impl Strategy<Value = HostToMaster> {
    prop_oneof![
        any::<u16>().prop_map(|v| HostToMaster::Hello {
            protocol_version: v
        }),
        arb_pose().prop_map(HostToMaster::SetPose),
        (any::<[i32; 4]>(), any::<u32>(), any::<u32>(), any::<u32>()).prop_map(|(p, ts, rs, h)| {
            HostToMaster::FollowTarget(MovingTarget {
                from: Point {
                    x_um: p[0],
                    y_um: p[1],
                },
                to: Point {
                    x_um: p[2],
                    y_um: p[3],
                },
                target_speed_um_s: ts,
                robot_speed_um_s: rs,
                heading: BinaryAngle(h),
            })
        }),
        Just(HostToMaster::Stop),
        Just(HostToMaster::Heartbeat),
        Just(HostToMaster::Info),
        (arb_source(), arb_reports(), arb_pose()).prop_map(|(source, reports, start)| {
            HostToMaster::Slave(SlaveCommand::SetSource {
                source,
                reports,
                start,
            })
        }),
        (
            any::<u16>(),
            prop::collection::vec(any::<u8>(), 0..=MAX_CHUNK)
        )
            .prop_map(|(seq, bytes)| {
                HostToMaster::Events(DataFrame {
                    seq,
                    bytes: heapless::Vec::from_slice(&bytes).expect("at most MAX_CHUNK bytes"),
                })
            }),
        any::<(u16, u16, bool)>().prop_map(|(next, credit, gap)| {
            HostToMaster::ReportsAck(Ack { next, credit, gap })
        }),
    ]
}

fn arb_source() -> impl Strategy<Value = SensorSource> {
    prop_oneof![
        Just(SensorSource::Counts),
        Just(SensorSource::Ticks),
        Just(SensorSource::PlayedCounts),
        Just(SensorSource::PlayedTicks),
    ]
}

fn arb_reports() -> impl Strategy<Value = Reports> {
    prop_oneof![
        Just(Reports::Off),
        Just(Reports::Poses),
        any::<u16>().prop_map(|pose_every| Reports::Record { pose_every }),
    ]
}

/// A stream chunk anywhere in the stream, from empty to full.
fn arb_chunk() -> impl Strategy<Value = Chunk> {
    (
        any::<u32>(),
        prop::collection::vec(any::<u8>(), 0..=STREAM_CHUNK),
    )
        .prop_map(|(offset, bytes)| Chunk {
            offset,
            bytes: Bytes::from_slice_truncating(&bytes),
        })
}

fn arb_slave_frame() -> impl Strategy<Value = SlaveFrame> {
    (
        any::<(u16, u32, u32)>(),
        arb_pose(),
        any::<(u16, u8, u16)>(),
        prop_oneof![
            Just(OdometryAlgorithm::Exact),
            Just(OdometryAlgorithm::Arc),
            Just(OdometryAlgorithm::Lut),
            Just(OdometryAlgorithm::Timing)
        ],
        any::<(u32, u32, u32)>(),
        arb_source(),
        arb_chunk(),
    )
        .prop_map(
            |(
                (seq, time_us, armed_us),
                pose,
                (status, command_ack, rx_rejected),
                algorithm,
                (robot, period_us, events_next),
                source,
                reports,
            )| {
                SlaveFrame {
                    seq,
                    time_us,
                    armed_us,
                    pose,
                    status,
                    command_ack,
                    rx_rejected,
                    algorithm,
                    robot,
                    source,
                    period_us,
                    events_next,
                    reports,
                }
            },
        )
}

fn arb_master_frame() -> impl Strategy<Value = MasterFrame> {
    (
        any::<(u16, u8, u32)>(),
        prop_oneof![
            Just(SlaveCommand::None),
            arb_pose().prop_map(SlaveCommand::SetPose),
            (arb_source(), arb_reports(), arb_pose()).prop_map(|(source, reports, start)| {
                SlaveCommand::SetSource {
                    source,
                    reports,
                    start,
                }
            }),
        ],
        arb_chunk(),
    )
        .prop_map(
            |((seq, command_seq, reports_next), command, events)| MasterFrame {
                seq,
                command_seq,
                command,
                events,
                reports_next,
            },
        )
}

fn feed_all(dec: &mut FrameDecoder, bytes: &[u8]) -> Vec<Result<HostToMaster, FrameError>> {
    bytes.iter().filter_map(|&b| dec.push(b)).collect()
}

proptest! {
    #[test]
    fn serial_round_trip_through_a_stream(msgs in prop::collection::vec(arb_host_msg(), 1..8)) {
        let mut wire = Vec::new();
        for m in &msgs {
            let mut buf = [0u8; serial::MAX_FRAME];
            wire.extend_from_slice(serial::encode(m, &mut buf).unwrap());
        }
        let mut dec = FrameDecoder::new();
        let got: Vec<_> = feed_all(&mut dec, &wire).into_iter().map(|r| r.unwrap()).collect();
        prop_assert_eq!(got, msgs);
    }

    #[test]
    fn serial_single_bit_flip_is_never_accepted(m in arb_host_msg(), bit in any::<usize>()) {
        let mut buf = [0u8; serial::MAX_FRAME];
        let mut frame = serial::encode(&m, &mut buf).unwrap().to_vec();
        let body = frame.len() - 1; // keep the delimiter
        let bit = bit % (body * 8);
        frame[bit / 8] ^= 1 << (bit % 8);
        let mut dec = FrameDecoder::new();
        // A flip may create a zero (splitting the frame) or break COBS; whatever happens, the
        // original message must not come out, and nothing may decode as a different message
        // unless its CRC-32 matches by chance (ruled out for single-bit errors).
        for r in feed_all(&mut dec, &frame) {
            prop_assert!(r.is_err(), "corrupted frame accepted: {:?}", r);
        }
    }

    #[test]
    fn serial_decoder_survives_garbage(noise in prop::collection::vec(any::<u8>(), 0..600), m in arb_host_msg()) {
        // Garbage first, then a delimiter and a good frame: the good frame must come through.
        let mut dec = FrameDecoder::new();
        let _ = feed_all(&mut dec, &noise);
        let _ = dec.push::<HostToMaster>(0);
        let mut buf = [0u8; serial::MAX_FRAME];
        let got = feed_all(&mut dec, serial::encode(&m, &mut buf).unwrap());
        prop_assert_eq!(got, vec![Ok(m)]);
    }

    #[test]
    fn spi_round_trip(f in arb_slave_frame()) {
        prop_assert_eq!(spi::decode::<SlaveFrame>(&spi::encode(&f)), Ok(f));
    }

    #[test]
    fn spi_bit_flip_is_rejected(f in arb_slave_frame(), bit in 0usize..(spi::SPI_FRAME_LEN * 8)) {
        let mut bytes = spi::encode(&f);
        bytes[bit / 8] ^= 1 << (bit % 8);
        prop_assert_eq!(spi::decode::<SlaveFrame>(&bytes), Err(SpiFrameError::Crc));
    }

    #[test]
    fn spi_master_round_trip(f in arb_master_frame()) {
        prop_assert_eq!(spi::decode::<MasterFrame>(&spi::encode(&f)), Ok(f));
    }

    #[test]
    fn spi_master_bit_flip_is_rejected(f in arb_master_frame(), bit in 0usize..(spi::SPI_FRAME_LEN * 8)) {
        let mut bytes = spi::encode(&f);
        bytes[bit / 8] ^= 1 << (bit % 8);
        prop_assert_eq!(spi::decode::<MasterFrame>(&bytes), Err(SpiFrameError::Crc));
    }
}

#[test]
fn idle_spi_lines_are_rejected() {
    for fill in [0x00u8, 0xff] {
        let bytes = [fill; spi::SPI_FRAME_LEN];
        assert_eq!(
            spi::decode::<SlaveFrame>(&bytes),
            Err(SpiFrameError::Crc),
            "{fill:#x}"
        );
        assert_eq!(
            spi::decode::<MasterFrame>(&bytes),
            Err(SpiFrameError::Crc),
            "{fill:#x}"
        );
    }
}

#[test]
fn master_frame_round_trip() {
    let f = MasterFrame {
        seq: 65535,
        command_seq: 255,
        command: SlaveCommand::SetPose(Pose {
            x_um: i32::MIN,
            y_um: i32::MAX,
            heading: BinaryAngle(12345),
        }),
        events: Chunk {
            offset: u32::MAX,
            bytes: Bytes::from_slice_truncating(&[0xff; STREAM_CHUNK]),
        },
        reports_next: u32::MAX,
    };
    assert_eq!(spi::decode(&spi::encode(&f)), Ok(f));
}

#[test]
fn overlong_frame_is_dropped_and_decoder_recovers() {
    let mut dec = FrameDecoder::new();
    let long = vec![0x55u8; serial::MAX_FRAME + 10];
    let errs = feed_all(&mut dec, &long);
    assert_eq!(errs, vec![Err(FrameError::Overflow)]);
    // The tail of the long frame is discarded up to its delimiter, then all is well.
    assert!(dec.push::<HostToMaster>(0).is_none());
    let mut buf = [0u8; serial::MAX_FRAME];
    let got = feed_all(
        &mut dec,
        serial::encode(&HostToMaster::Stop, &mut buf).unwrap(),
    );
    assert_eq!(got, vec![Ok(HostToMaster::Stop)]);
}

#[test]
fn valid_crc_with_trailing_bytes_is_a_decode_error() {
    // postcard(Stop) is one byte; add a stray byte and a correct CRC over both.
    let payload = [3u8, 0x42];
    let crc = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC).checksum(&payload);
    let mut raw = payload.to_vec();
    raw.extend_from_slice(&crc.to_le_bytes());
    let mut enc = vec![0u8; 16];
    let n = cobs::encode(&raw, &mut enc);
    assert_eq!(
        serial::decode_frame::<HostToMaster>(&mut enc[..n]),
        Err(FrameError::Decode)
    );
}
