//! Played-event codes: exact round trips, size on a realistic stream, streaming across any
//! chunk split, and no panic on garbage.

use proptest::prelude::*;
use protocol::events::{
    encode_sample, DecodeError, DecodeErrorKind, EncodeError, Event, EventDecoder, EventEncoder,
    Sample, SampleDecoder, Step, MAX_ENCODERS, MAX_EVENT_LEN, MAX_SAMPLE_LEN,
};

fn encode_events(events: &[Event]) -> Vec<u8> {
    let mut enc = EventEncoder::new();
    let mut out = Vec::new();
    for e in events {
        let mut buf = [0u8; MAX_EVENT_LEN];
        let n = enc.encode(e, &mut buf).expect("valid event");
        out.extend_from_slice(&buf[..n]);
    }
    out
}

fn decode_events(chunks: &[&[u8]]) -> Vec<Result<Event, DecodeError>> {
    let mut dec = EventDecoder::new();
    let mut out = Vec::new();
    for chunk in chunks {
        dec.feed(chunk, |r| out.push(r));
    }
    out
}

/// Events with time steps from 0 to huge, all encoders, both directions, abs codes.
fn events_strategy() -> impl Strategy<Value = Vec<Event>> {
    let dt = prop_oneof![
        4 => 0u64..16,
        4 => 0u64..2048,
        2 => 0u64..10_000_000,
        1 => any::<u64>().prop_map(|d| d >> 8),
    ];
    let event = (
        dt,
        0u8..4,
        any::<bool>(),
        prop::option::weighted(0.1, any::<u16>()),
    );
    prop::collection::vec(event, 0..300).prop_map(|raw| {
        let mut t: u64 = 0;
        raw.into_iter()
            .map(|(dt, encoder, back, abs)| {
                t = t.saturating_add(dt);
                match abs {
                    Some(code) => Event::Abs { t_us: t, code },
                    None => Event::Tick {
                        t_us: t,
                        encoder,
                        step: if back { Step::Backward } else { Step::Forward },
                    },
                }
            })
            .collect()
    })
}

proptest! {
    #[test]
    fn events_round_trip_exactly(events in events_strategy()) {
        let bytes = encode_events(&events);
        let decoded: Vec<Event> = decode_events(&[&bytes]).into_iter().map(|r| r.unwrap()).collect();
        prop_assert_eq!(decoded, events);
    }

    #[test]
    fn events_decode_the_same_across_any_chunk_split(
        events in events_strategy(),
        cuts in prop::collection::vec(any::<prop::sample::Index>(), 0..20),
    ) {
        let bytes = encode_events(&events);
        let mut cuts: Vec<usize> = cuts.iter().map(|i| i.index(bytes.len() + 1)).collect();
        cuts.sort();
        let mut chunks = Vec::new();
        let mut start = 0;
        for cut in cuts {
            chunks.push(&bytes[start..cut]);
            start = cut;
        }
        chunks.push(&bytes[start..]);
        let decoded: Vec<Event> = decode_events(&chunks).into_iter().map(|r| r.unwrap()).collect();
        prop_assert_eq!(decoded, events);
    }

    #[test]
    fn event_decoder_survives_garbage(bytes in prop::collection::vec(any::<u8>(), 0..2000)) {
        let mut dec = EventDecoder::new();
        let mut prev = 0;
        for (i, &b) in bytes.iter().enumerate() {
            match dec.push(b) {
                // Decoded times never go backwards, whatever the input.
                Some(Ok(e)) => { prop_assert!(e.t_us() >= prev); prev = e.t_us(); }
                Some(Err(e)) => prop_assert_eq!(e.offset, i as u64),
                None => {}
            }
        }
    }

    #[test]
    fn samples_round_trip_across_chunk_splits(
        samples in prop::collection::vec(
            (prop::array::uniform4(prop_oneof![3 => Just(0i32), 3 => -100i32..100, 1 => any::<i32>()]),
             prop::option::of(any::<u16>())),
            0..200),
        split in 1usize..40,
    ) {
        let samples: Vec<Sample> = samples.into_iter()
            .map(|(counts_delta, abs)| Sample { counts_delta, abs }).collect();
        let mut bytes = Vec::new();
        for s in &samples {
            let mut buf = [0u8; MAX_SAMPLE_LEN];
            let n = encode_sample(s, &mut buf).unwrap();
            bytes.extend_from_slice(&buf[..n]);
        }
        let mut dec = SampleDecoder::new();
        let mut decoded = Vec::new();
        for chunk in bytes.chunks(split) {
            dec.feed(chunk, |r| decoded.push(r.unwrap()));
        }
        prop_assert!(dec.is_between_samples());
        prop_assert_eq!(decoded, samples);
    }

    #[test]
    fn sample_decoder_survives_garbage(bytes in prop::collection::vec(any::<u8>(), 0..2000)) {
        let mut dec = SampleDecoder::new();
        dec.feed(&bytes, |_| {});
    }
}

#[test]
fn tick_forms_and_their_sizes() {
    let mut enc = EventEncoder::new();
    let mut buf = [0u8; MAX_EVENT_LEN];
    let mut code = |e: Event| {
        let n = enc.encode(&e, &mut buf).unwrap();
        buf[..n].to_vec()
    };
    let tick = |t_us, encoder, step| Event::Tick {
        t_us,
        encoder,
        step,
    };
    // 1 byte: 0 EE D TTTT.
    assert_eq!(code(tick(5, 1, Step::Forward)), [0b0010_0101]);
    assert_eq!(code(tick(5, 3, Step::Backward)), [0b0111_0000]);
    // 2 bytes: 10 EE D TTT, low 8 bits of the time step.
    assert_eq!(code(tick(5 + 300, 2, Step::Forward)), [0b1010_0001, 44]);
    // varint: 110 EE D 00, LEB128 time step.
    assert_eq!(
        code(tick(305 + 2048, 0, Step::Backward)),
        [0b1100_0100, 0x80, 0x10]
    );
    // Abs: E0, varint time step, code little-endian.
    assert_eq!(
        code(Event::Abs {
            t_us: 2353,
            code: 0x1234
        }),
        [0xE0, 0x00, 0x34, 0x12]
    );
}

#[test]
fn encoder_refuses_bad_events_and_full_buffers_without_changing_state() {
    let mut enc = EventEncoder::new();
    let mut buf = [0u8; MAX_EVENT_LEN];
    let t10 = Event::Tick {
        t_us: 10,
        encoder: 0,
        step: Step::Forward,
    };
    assert_eq!(
        enc.encode(&t10, &mut buf[..0]),
        Err(EncodeError::BufferFull { needed: 1 })
    );
    assert_eq!(enc.encode(&t10, &mut buf), Ok(1));
    let earlier = Event::Abs { t_us: 9, code: 0 };
    assert_eq!(
        enc.encode(&earlier, &mut buf),
        Err(EncodeError::TimeBackwards {
            prev_us: 10,
            t_us: 9
        })
    );
    let bad = Event::Tick {
        t_us: 11,
        encoder: 4,
        step: Step::Forward,
    };
    assert_eq!(
        enc.encode(&bad, &mut buf),
        Err(EncodeError::EncoderOutOfRange(4))
    );
    // Three 1-byte events into 2 bytes: two fit, the third is left for the next chunk.
    let events = [t10, t10, t10];
    assert_eq!(enc.encode_all(&events, &mut buf[..2]), Ok((2, 2)));
}

#[test]
fn decoder_names_the_bad_byte() {
    let errors: Vec<_> = decode_events(&[&[0x05, 0xE1, 0xC1, 0xFF]]);
    assert_eq!(
        errors[0],
        Ok(Event::Tick {
            t_us: 5,
            encoder: 0,
            step: Step::Forward
        })
    );
    assert_eq!(
        errors[1],
        Err(DecodeError {
            offset: 1,
            kind: DecodeErrorKind::BadHeader(0xE1)
        })
    );
    assert_eq!(
        errors[2],
        Err(DecodeError {
            offset: 2,
            kind: DecodeErrorKind::BadHeader(0xC1)
        })
    );
    assert_eq!(
        errors[3],
        Err(DecodeError {
            offset: 3,
            kind: DecodeErrorKind::BadHeader(0xFF)
        })
    );
    // A time step that would pass u64::MAX.
    let mut bytes = encode_events(&[Event::Abs {
        t_us: u64::MAX - 1,
        code: 0,
    }]);
    bytes.push(0x0F);
    let out = decode_events(&[&bytes]);
    assert_eq!(out[1].unwrap_err().kind, DecodeErrorKind::TimeOverflow);
}

#[test]
fn nothing_moved_is_one_byte() {
    let mut buf = [0u8; MAX_SAMPLE_LEN];
    assert_eq!(encode_sample(&Sample::default(), &mut buf), Ok(1));
    assert_eq!(buf[0], 0);
    let s = Sample {
        counts_delta: [0, -3, 0, 70],
        abs: Some(0x0102),
    };
    assert_eq!(encode_sample(&s, &mut buf), Ok(1 + 1 + 2 + 2));
    assert_eq!(buf[..6], [0b0001_1010, 5, 0x8C, 0x01, 0x02, 0x01]);
    let mut dec = SampleDecoder::new();
    assert_eq!(
        dec.push(0x20),
        Some(Err(DecodeError {
            offset: 0,
            kind: DecodeErrorKind::BadHeader(0x20)
        }))
    );
    assert_eq!(MAX_ENCODERS, 4);
}

/// A 12 s run of a robot with three measuring wheels: starts, cruises up to 2 m/s (20 000
/// edges/s on a wheel, 0.1 mm per edge), turns, stops, reverses slowly, creeps, stands still;
/// quadrature edges unevenly spaced (A/B phase error) with 1-2 µs jitter, and an absolute
/// encoder reading every 10 ms.
fn realistic_stream() -> Vec<Event> {
    synthetic_stream(&[
        (1.0, [0.0, 0.0, 0.0]),
        (1.5, [20_000.0, 10_000.0, -10_000.0]),
        (3.0, [20_000.0, 10_000.0, -10_000.0]),
        (2.0, [5_000.0, 15_000.0, -18_000.0]),
        (1.0, [0.0, 0.0, 0.0]),
        (1.5, [-3_000.0, -1_500.0, 1_500.0]),
        (1.0, [30.0, 15.0, -15.0]),
        (1.0, [0.0, 0.0, 0.0]),
    ])
}

/// Ticks of three wheels through `phases`: (duration s, speed of each wheel in edges/s at the
/// end of the phase), speeds ramping linearly from the previous phase's.
fn synthetic_stream(phases: &[(f64, [f64; 3])]) -> Vec<Event> {
    let mut events = Vec::new();
    let mut pos = [0.0f64; 3];
    let mut last_edge = [0i64; 3];
    let mut speed = [0.0f64; 3];
    let mut t_us: u64 = 0;
    let mut jitter: u64 = 12345;
    for &(duration, target) in phases {
        let steps = (duration * 1e6) as u64;
        let start = speed;
        for k in 0..steps {
            let f = k as f64 / steps as f64;
            for w in 0..3 {
                speed[w] = start[w] + (target[w] - start[w]) * f;
                pos[w] += speed[w] * 1e-6;
                // Uneven quadrature: edges at 0, 0.8, 2.0, 2.8, ... (pairs 40/60 % apart).
                let phase_pos = pos[w] - 0.1 * (pos[w] * std::f64::consts::PI).sin();
                let edge = phase_pos.floor() as i64;
                while edge != last_edge[w] {
                    let step = if edge > last_edge[w] {
                        Step::Forward
                    } else {
                        Step::Backward
                    };
                    last_edge[w] += step.delta() as i64;
                    jitter = jitter
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                    // Time stamps never go backwards: jitter only delays, and by at most 2 µs.
                    let t = (t_us + (jitter >> 62)).max(events.last().map_or(0, Event::t_us));
                    events.push(Event::Tick {
                        t_us: t,
                        encoder: w as u8,
                        step,
                    });
                }
            }
            if t_us.is_multiple_of(10_000) {
                let t = t_us.max(events.last().map_or(0, Event::t_us));
                events.push(Event::Abs {
                    t_us: t,
                    code: (t_us / 1000 % 1024) as u16,
                });
            }
            t_us += 1;
        }
    }
    events
}

#[test]
fn realistic_stream_takes_at_most_two_bytes_per_tick() {
    let events = realistic_stream();
    let ticks = events
        .iter()
        .filter(|e| matches!(e, Event::Tick { .. }))
        .count();
    let bytes = encode_events(&events);
    let per_tick = bytes.len() as f64 / ticks as f64;
    println!(
        "{ticks} ticks, {} abs readings: {} bytes, {per_tick:.3} bytes per tick (abs included)",
        events.len() - ticks,
        bytes.len()
    );
    assert!(ticks > 200_000, "the stream should be dense: {ticks} ticks");
    assert!(per_tick <= 2.0, "{per_tick:.3} bytes per tick");
    let decoded: Vec<Event> = decode_events(&[&bytes])
        .into_iter()
        .map(|r| r.unwrap())
        .collect();
    assert_eq!(decoded, events);
}

#[test]
fn fast_cruise_at_60k_edges_per_second_takes_under_two_bytes_per_tick() {
    let speeds = [20_000.0, 20_000.0, -20_000.0];
    let events = synthetic_stream(&[(0.01, speeds), (1.0, speeds)]);
    let ticks = events
        .iter()
        .filter(|e| matches!(e, Event::Tick { .. }))
        .count();
    let per_tick = encode_events(&events).len() as f64 / ticks as f64;
    println!("cruise: {ticks} ticks, {per_tick:.3} bytes per tick (abs included)");
    assert!(ticks > 55_000, "{ticks} ticks");
    assert!(per_tick <= 2.0, "{per_tick:.3} bytes per tick");
}

/// Every byte string the decoders accept whole is what the encoders make of what they
/// decoded: one encoding per event stream.
fn decodes_to_canonical(bytes: &[u8]) -> (bool, bool) {
    let mut events = Vec::new();
    let mut ok = true;
    let mut dec = EventDecoder::new();
    dec.feed(bytes, |r| match r {
        Ok(e) => events.push(e),
        Err(_) => ok = false,
    });
    let events_canonical = !ok || !dec.is_between_events() || encode_events(&events) == bytes;

    let mut samples = Vec::new();
    let mut ok = true;
    let mut dec = SampleDecoder::new();
    dec.feed(bytes, |r| match r {
        Ok(s) => samples.push(s),
        Err(_) => ok = false,
    });
    let mut again = Vec::new();
    for s in &samples {
        let mut buf = [0u8; MAX_SAMPLE_LEN];
        let n = encode_sample(s, &mut buf).unwrap();
        again.extend_from_slice(&buf[..n]);
    }
    let samples_canonical = !ok || !dec.is_between_samples() || again == bytes;
    (events_canonical, samples_canonical)
}

#[test]
fn longer_forms_than_the_encoder_uses_are_refused() {
    let non_canonical: [&[u8]; 5] = [
        &[0x80, 0x05],             // a 2-byte tick of dt 5 (one byte holds it)
        &[0xC0, 0x05],             // a varint tick of dt 5
        &[0xC0, 0xFF, 0x0F],       // a varint tick of dt 2047 (two bytes hold it)
        &[0xC0, 0x80, 0x90, 0x00], // an over-long varint
        &[0xE0, 0x85, 0x00, 1, 2], // an absolute reading with an over-long time
    ];
    for bytes in &non_canonical {
        let mut errors = Vec::new();
        EventDecoder::new().feed(bytes, |r| {
            if let Err(e) = r {
                errors.push(e.kind)
            }
        });
        assert_eq!(errors, [DecodeErrorKind::NonCanonical], "{bytes:02x?}");
    }
    // A sample with encoder 0's change written out as zero.
    let mut errors = Vec::new();
    SampleDecoder::new().feed(&[0x01, 0x00], |r| {
        if let Err(e) = r {
            errors.push(e.kind)
        }
    });
    assert_eq!(errors, [DecodeErrorKind::NonCanonical]);
}

proptest! {
    #[test]
    fn whatever_decodes_whole_encodes_back_to_the_same_bytes(
        bytes in proptest::collection::vec(any::<u8>(), 0..64)
    ) {
        prop_assert_eq!(decodes_to_canonical(&bytes), (true, true));
    }

    #[test]
    fn edited_good_streams_that_still_decode_are_canonical(
        events in proptest::collection::vec((0u64..5000, 0u8..4, any::<bool>()), 1..20),
        edits in proptest::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..4),
    ) {
        let mut t = 0;
        let events: Vec<Event> = events
            .into_iter()
            .map(|(dt, encoder, back)| {
                t += dt;
                Event::Tick { t_us: t, encoder, step: if back { Step::Backward } else { Step::Forward } }
            })
            .collect();
        let mut bytes = encode_events(&events);
        for (at, b) in edits {
            let i = at.index(bytes.len());
            bytes[i] = b;
        }
        prop_assert_eq!(decodes_to_canonical(&bytes).0, true);
    }
}
