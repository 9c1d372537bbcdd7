//! Framing behaviour: round trips, and that nothing corrupted is ever accepted.

use proptest::prelude::*;
use protocol::link::{Ack, DataFrame, MAX_CHUNK};
use protocol::serial::{self, FrameDecoder, FrameError, HostToMaster, MovingTarget};
use protocol::spi::{
    self, Chunk, MasterFrame, OdometryAlgorithm, PoseChecks, Reports, SensorSource, SlaveCommand,
    SlaveFrame, SpiFrameError, STREAM_CHUNK,
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
        (any::<u16>(), any::<u32>())
            .prop_map(|(every, all_from)| Reports::Poses(PoseChecks { every, all_from })),
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

/// What a dead, idle or stuck line shows never passes as a frame: every run of one byte value,
/// and every frame of one value switching to another once (`FF FF 00 … 00` passed the old
/// CRC-16, whose zero final XOR let an all-zero tail check out).
#[test]
fn no_stuck_or_dead_line_pattern_passes() {
    let mut patterns = Vec::new();
    for fill in 0..=255u8 {
        patterns.push([fill; spi::SPI_FRAME_LEN]);
    }
    for (a, b) in [(0xffu8, 0x00u8), (0x00, 0xff)] {
        for k in 0..=spi::SPI_FRAME_LEN {
            let mut p = [b; spi::SPI_FRAME_LEN];
            p[..k].fill(a);
            patterns.push(p);
        }
    }
    for p in &patterns {
        assert!(spi::decode::<SlaveFrame>(p).is_err(), "{p:02x?}");
        assert!(spi::decode::<MasterFrame>(p).is_err(), "{p:02x?}");
    }
}

/// A frame on the wrong line (MOSI looped back to MISO) is told apart by its kind byte.
#[test]
fn a_frame_of_the_other_kind_is_refused() {
    let m = spi::encode(&MasterFrame::default());
    let s = spi::encode(&SlaveFrame::default());
    assert_eq!(spi::decode::<SlaveFrame>(&m), Err(SpiFrameError::Kind));
    assert_eq!(spi::decode::<MasterFrame>(&s), Err(SpiFrameError::Kind));
}

/// `body` (kind byte and payload, zero-padded) made into a frame whose check passes.
fn with_check(body: &[u8]) -> [u8; spi::SPI_FRAME_LEN] {
    const CRC: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC);
    let n = spi::SPI_FRAME_LEN - spi::SPI_CHECK_LEN;
    let mut out = [0u8; spi::SPI_FRAME_LEN];
    out[..body.len().min(n)].copy_from_slice(&body[..body.len().min(n)]);
    let crc = CRC.checksum(&out[..n]);
    out[n..].copy_from_slice(&crc.to_le_bytes());
    out
}

/// Only the one encoding of a frame decodes: a non-zero padding byte or an over-long number
/// (postcard alone reads `0x87 0x00` as 7) is refused even with a good check.
#[test]
fn only_canonical_encodings_decode() {
    let f = MasterFrame {
        seq: 7,
        ..MasterFrame::default()
    };
    let good = spi::encode(&f);
    assert_eq!(spi::decode::<MasterFrame>(&good), Ok(f));
    let n = spi::SPI_FRAME_LEN - spi::SPI_CHECK_LEN;
    let mut padded = good;
    padded[n - 1] = 1;
    let padded = with_check(&padded[..n]);
    assert_eq!(
        spi::decode::<MasterFrame>(&padded),
        Err(SpiFrameError::NonCanonical)
    );
    // Any one bit of the padding set, anywhere in it.
    let used = 1 + postcard::to_slice(&f, &mut [0u8; 128]).unwrap().len();
    for at in used..n {
        for bit in 0..8 {
            let mut padded = good;
            padded[at] = 1 << bit;
            assert_eq!(
                spi::decode::<MasterFrame>(&with_check(&padded[..n])),
                Err(SpiFrameError::NonCanonical),
                "byte {at}, bit {bit}"
            );
        }
    }
    // The payload opens with `seq` as a varint: 7 is `07`; `87 00` is 7 again, over-long.
    assert_eq!(good[1], 0x07);
    let mut long = vec![good[0], 0x87, 0x00];
    long.extend_from_slice(&good[2..n - 1]);
    assert_eq!(
        spi::decode::<MasterFrame>(&with_check(&long)),
        Err(SpiFrameError::NonCanonical)
    );
}

proptest! {
    /// Whatever bytes pass the check and decode, encoding the frame gives those bytes back:
    /// good frames with one or two payload bytes changed and the check made good again (most
    /// still decode, as other values or over-long forms).
    #[test]
    fn a_decoded_frame_encodes_to_the_bytes_it_came_from(
        s in arb_slave_frame(),
        m in arb_master_frame(),
        edits in prop::collection::vec((1usize..(1 + spi::SPI_PAYLOAD_LEN), any::<u8>()), 1..3),
    ) {
        let n = spi::SPI_FRAME_LEN - spi::SPI_CHECK_LEN;
        for mut bytes in [spi::encode(&s), spi::encode(&m)] {
            for &(at, v) in &edits {
                bytes[at] = v;
            }
            let bytes = with_check(&bytes[..n]);
            if let Ok(f) = spi::decode::<SlaveFrame>(&bytes) {
                prop_assert_eq!(spi::encode(&f), bytes);
            }
            if let Ok(f) = spi::decode::<MasterFrame>(&bytes) {
                prop_assert_eq!(spi::encode(&f), bytes);
            }
        }
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

/// A serial frame (without its delimiter) around `payload` with a good CRC and COBS.
fn serial_frame(payload: &[u8]) -> Vec<u8> {
    const CRC: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC);
    let mut raw = payload.to_vec();
    raw.extend_from_slice(&CRC.checksum(payload).to_le_bytes());
    let mut out = vec![0u8; cobs::max_encoding_length(raw.len())];
    let n = cobs::encode(&raw, &mut out);
    out.truncate(n);
    out
}

/// Serial frames too: a message has one frame. `Hello { protocol_version: 5 }` is `00 05`;
/// `00 85 00` is the same message with an over-long number and a good CRC.
#[test]
fn only_canonical_serial_frames_decode() {
    let hello = HostToMaster::Hello {
        protocol_version: 5,
    };
    let mut buf = [0u8; 8];
    assert_eq!(postcard::to_slice(&hello, &mut buf).unwrap(), [0x00, 0x05]);
    let mut good = serial_frame(&[0x00, 0x05]);
    assert_eq!(serial::decode_frame::<HostToMaster>(&mut good), Ok(hello));
    let mut long = serial_frame(&[0x00, 0x85, 0x00]);
    assert_eq!(
        serial::decode_frame::<HostToMaster>(&mut long),
        Err(FrameError::NonCanonical)
    );
}

proptest! {
    /// Whatever serial frame passes its checks and decodes is the one `encode` makes of it:
    /// good messages with a payload byte changed and the CRC and COBS made good again.
    #[test]
    fn a_decoded_serial_message_encodes_to_its_frame(
        m in arb_host_msg(),
        at in any::<prop::sample::Index>(),
        v in any::<u8>(),
    ) {
        let mut buf = [0u8; serial::MAX_PAYLOAD];
        let mut payload = postcard::to_slice(&m, &mut buf).unwrap().to_vec();
        let i = at.index(payload.len());
        payload[i] = v;
        let frame = serial_frame(&payload);
        if let Ok(got) = serial::decode_frame::<HostToMaster>(&mut frame.clone()) {
            let mut buf = [0u8; serial::MAX_FRAME + 1];
            let again = serial::encode(&got, &mut buf).unwrap();
            prop_assert_eq!(&again[..again.len() - 1], &frame[..]);
        }
    }
}

#[test]
fn a_frame_takes_its_bits_at_the_clock_rounded_up_to_a_microsecond() {
    // 128 bytes at 4.5 MHz: 227.6 µs, which the master dates an exchange's end by.
    assert_eq!(spi::frame_time_us(spi::SPI_CLOCK_HZ), 228);
    assert_eq!(spi::frame_time_us(1_024_000), 1_000); // exact: no rounding up
}
