//! Go-back-N link over a simulated lossy channel: whatever the channel does (loss, corruption
//! modelled as loss, duplication, reordering, lost acks, a stalled consumer), the receiver's
//! consumer gets exactly the offered bytes, in order, within a bounded number of steps, and the
//! receiver never has to drop a byte for lack of room.

use proptest::prelude::*;
use protocol::link::{Ack, DataFrame, GbnReceiver, GbnSender, MAX_CHUNK};

/// The master's receive buffer.
const RX_BYTES: usize = 512;
const TX_BYTES: usize = 2048;
const STEP_US: u64 = 100;
/// Short timeout so lossy simulations finish quickly (20 steps).
const TIMEOUT_US: u64 = 2_000;

/// Deterministic xorshift64* generator: the same seed replays the same run.
struct Rng(u64);

impl Rng {
    fn new(seed: u64) -> Self {
        Rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1)
    }
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    fn per_mille(&mut self, p: u32) -> bool {
        (self.next() % 1000) < u64::from(p)
    }
    fn below(&mut self, n: u64) -> u64 {
        if n == 0 {
            0
        } else {
            self.next() % n
        }
    }
}

#[derive(Clone, Copy, Debug, Default)]
struct Faults {
    /// Data frames lost or corrupted (a frame failing its CRC is dropped by the caller).
    loss: u32,
    ack_loss: u32,
    /// Data frames delivered twice.
    duplicate: u32,
    /// Extra random delay per frame: frames overtake each other when > 0.
    jitter_us: u64,
}

struct Scenario {
    data: Vec<u8>,
    faults: Faults,
    seed: u64,
    /// Bytes the consumer reads per step (the master forwarding over SPI).
    read_per_step: usize,
    /// Consumer stalled (reads nothing) during these steps.
    stall_steps: std::ops::Range<u64>,
    /// Every ack sent during these steps is lost (window updates included).
    ack_blackout_steps: std::ops::Range<u64>,
    /// Drop exactly the data frames with these indices (in order of transmission).
    drop_frames: Vec<usize>,
    max_steps: u64,
}

impl Scenario {
    fn new(data: Vec<u8>) -> Self {
        Scenario {
            data,
            faults: Faults::default(),
            seed: 1,
            read_per_step: 64,
            stall_steps: 0..0,
            ack_blackout_steps: 0..0,
            drop_frames: Vec::new(),
            max_steps: 200_000,
        }
    }
}

#[derive(Debug, PartialEq)]
struct Outcome {
    steps: u64,
    frames_sent: u32,
    retransmitted: u32,
    probes: u32,
}

/// Run until every byte is delivered and acknowledged; panics (fails the test) on any wrong,
/// lost or duplicated byte, on receiver overflow, or when `max_steps` pass.
fn run(s: &Scenario) -> Outcome {
    let mut tx = GbnSender::<TX_BYTES>::new(TIMEOUT_US);
    let mut rx = GbnReceiver::<RX_BYTES>::new();
    run_on(s, &mut tx, &mut rx)
}

/// [`run`] on the given ends.
fn run_on(s: &Scenario, tx: &mut GbnSender<TX_BYTES>, rx: &mut GbnReceiver<RX_BYTES>) -> Outcome {
    let mut rng = Rng::new(s.seed);
    let latency_us = 300;
    let mut to_rx: Vec<(u64, DataFrame)> = Vec::new();
    let mut to_tx: Vec<(u64, Ack)> = Vec::new();
    let mut offered = 0;
    let mut delivered: Vec<u8> = Vec::new();
    let mut frame_index = 0;
    for step in 0..s.max_steps {
        let now = step * STEP_US;
        offered += tx.offer(&s.data[offered..]);
        // The link carries at most 3 frames per step (~3.6 MB/s): bandwidth matters for how
        // much is in flight.
        for _ in 0..3 {
            let Some(frame) = tx.poll_transmit(now) else {
                break;
            };
            let index = frame_index;
            frame_index += 1;
            if s.drop_frames.contains(&index) || rng.per_mille(s.faults.loss) {
                continue;
            }
            if rng.per_mille(s.faults.duplicate) {
                let at = now + latency_us + rng.below(s.faults.jitter_us + 1);
                to_rx.push((at, frame.clone()));
            }
            to_rx.push((now + latency_us + rng.below(s.faults.jitter_us + 1), frame));
        }
        // Deliver due frames in arrival order (stable for equal times).
        to_rx.sort_by_key(|(at, _)| *at);
        while to_rx.first().is_some_and(|(at, _)| *at <= now) {
            let (_, frame) = to_rx.remove(0);
            rx.on_data(&frame);
            assert!(rx.len() <= RX_BYTES);
        }
        if !s.stall_steps.contains(&step) {
            let mut out = vec![0; s.read_per_step];
            let n = rx.read(&mut out);
            delivered.extend_from_slice(&out[..n]);
            assert!(
                s.data.starts_with(&delivered),
                "delivered bytes diverge from the source at step {step}"
            );
        }
        if let Some(ack) = rx.poll_ack() {
            if !s.ack_blackout_steps.contains(&step) && !rng.per_mille(s.faults.ack_loss) {
                to_tx.push((now + latency_us + rng.below(s.faults.jitter_us + 1), ack));
            }
        }
        to_tx.sort_by_key(|(at, _)| *at);
        while to_tx.first().is_some_and(|(at, _)| *at <= now) {
            let (_, ack) = to_tx.remove(0);
            tx.on_ack(ack, now);
        }
        if delivered.len() == s.data.len() && tx.is_idle() {
            assert_eq!(rx.stats().bytes_overflowed, 0, "sender exceeded the credit");
            assert_eq!(tx.stats().bytes_acked as usize, s.data.len() % (1 << 32));
            let stats = tx.stats();
            return Outcome {
                steps: step,
                frames_sent: stats.frames_sent,
                retransmitted: stats.frames_retransmitted,
                probes: stats.probes_sent,
            };
        }
    }
    panic!(
        "not done after {} steps: delivered {} of {} bytes; sender {:?}; receiver {:?}",
        s.max_steps,
        delivered.len(),
        s.data.len(),
        tx.stats(),
        rx.stats()
    );
}

/// The boards reset their ends in place (`reset`, a new session) rather than build new ones
/// on their small stacks: a reset pair must then act exactly as a new pair, whatever the old
/// session left in flight, in its buffers and in its statistics.
#[test]
fn reset_ends_act_as_new_ones() {
    let mut lossy = Scenario::new(pattern(3000));
    lossy.faults.loss = 100;
    lossy.faults.ack_loss = 100;
    lossy.seed = 7;
    let mut tx = GbnSender::<TX_BYTES>::new(TIMEOUT_US);
    let mut rx = GbnReceiver::<RX_BYTES>::new();
    run_on(&lossy, &mut tx, &mut rx);
    // Leave the old session mid-flight: bytes offered, a frame sent, the timer running.
    tx.offer(&pattern(700));
    let frame = tx.poll_transmit(0).expect("a frame to send");
    rx.on_data(&frame);
    tx.reset(TIMEOUT_US);
    rx.reset();
    lossy.seed = 8;
    let after_reset = run_on(&lossy, &mut tx, &mut rx);
    assert_eq!(after_reset, run(&lossy));
}

fn pattern(len: usize) -> Vec<u8> {
    (0..len).map(|i| (i * 7 + i / 251) as u8).collect()
}

#[test]
fn lossless_transfer_sends_each_byte_once() {
    let out = run(&Scenario::new(pattern(10_000)));
    assert_eq!(out.retransmitted, 0, "{out:?}");
    assert_eq!(
        out.probes, 1,
        "only the first frame, sent before any credit is known"
    );
    // Frames are full except where the credit edge cuts one short.
    let full = 10_000_usize.div_ceil(MAX_CHUNK);
    assert!(
        (full..2 * full).contains(&(out.frames_sent as usize)),
        "{out:?}"
    );
    assert!(out.steps < 2_000, "{out:?}");
}

#[test]
fn every_single_frame_lost_once_is_recovered() {
    let data = pattern(3_000);
    let clean = run(&Scenario::new(data.clone()));
    for lost in 0..clean.frames_sent as usize {
        let mut s = Scenario::new(data.clone());
        s.drop_frames = vec![lost];
        let out = run(&s);
        // Frame 0 is the opening probe; the receiver's own first ack announces its window
        // anyway, so losing the probe costs nothing.
        assert!(lost == 0 || out.retransmitted >= 1, "frame {lost}: {out:?}");
        // One loss costs one go-back: at most a window's worth of frames is resent.
        let window_frames = RX_BYTES.div_ceil(MAX_CHUNK) as u32 + 1;
        assert!(out.retransmitted <= window_frames, "frame {lost}: {out:?}");
    }
}

#[test]
fn zero_credit_stall_recovers_even_when_window_updates_are_lost() {
    let mut s = Scenario::new(pattern(20_000));
    // The consumer stops for 0.5 s with the window closed, and every ack in the first 30 ms
    // after it restarts is lost: only the sender's probes can reopen the window.
    s.stall_steps = 100..5_100;
    s.ack_blackout_steps = 5_100..5_400;
    let out = run(&s);
    assert!(out.probes >= 1, "{out:?}");
}

#[test]
fn sequence_numbers_wrap_past_65535() {
    let mut s = Scenario::new(pattern(200_000));
    s.faults.loss = 20;
    s.faults.ack_loss = 20;
    s.read_per_step = 200;
    let out = run(&s);
    assert!(out.retransmitted > 0, "{out:?}");
}

#[test]
fn default_timeout_is_50_ms() {
    let mut tx = GbnSender::<64>::default();
    tx.offer(&[1, 2, 3]);
    assert!(tx.poll_transmit(0).unwrap().bytes.is_empty(), "probe first");
    assert_eq!(tx.poll_at(), Some(50_000));
    assert_eq!(tx.poll_transmit(49_999), None);
    assert!(
        tx.poll_transmit(50_000).unwrap().bytes.is_empty(),
        "probes again"
    );
    // Unanswered: the timeout doubles.
    assert_eq!(tx.poll_at(), Some(150_000));
}

#[test]
fn receiver_drops_gaps_and_duplicates_and_says_so() {
    let mut rx = GbnReceiver::<16>::new();
    assert_eq!(rx.on_frame(4, &[4, 5]), 0);
    assert_eq!(
        rx.poll_ack(),
        Some(Ack {
            next: 0,
            credit: 16,
            gap: true
        })
    );
    assert_eq!(rx.on_frame(0, &[0, 1, 2]), 3);
    // Overlapping resend: only the new byte is taken.
    assert_eq!(rx.on_frame(1, &[1, 2, 3]), 1);
    assert_eq!(rx.on_frame(0, &[0, 1]), 0);
    assert_eq!(
        rx.poll_ack(),
        Some(Ack {
            next: 4,
            credit: 12,
            gap: false
        })
    );
    assert_eq!(rx.poll_ack(), None);
    let mut out = [0; 8];
    assert_eq!(rx.read(&mut out), 4);
    assert_eq!(out[..4], [0, 1, 2, 3]);
    // Four bytes freed = a quarter of the buffer: a window update is due.
    assert_eq!(
        rx.poll_ack(),
        Some(Ack {
            next: 4,
            credit: 16,
            gap: false
        })
    );
    let stats = rx.stats();
    assert_eq!(
        (
            stats.frames_out_of_order,
            stats.frames_duplicate,
            stats.frames_accepted
        ),
        (1, 1, 2)
    );
}

#[test]
fn sender_ignores_acks_for_bytes_never_sent() {
    let mut tx = GbnSender::<64, 8>::new(1_000);
    tx.offer(&[0; 20]);
    tx.poll_transmit(0);
    tx.on_ack(
        Ack {
            next: 0,
            credit: 64,
            gap: false,
        },
        0,
    );
    assert_eq!(tx.poll_transmit(0).unwrap().bytes.len(), 8);
    tx.on_ack(
        Ack {
            next: 30,
            credit: 64,
            gap: false,
        },
        0,
    );
    assert_eq!(tx.stats().acks_ignored, 1);
    assert_eq!(tx.unacked(), 20);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn delivers_exactly_once_in_order_over_a_bad_channel(
        len in 0usize..6_000,
        loss in 0u32..300,
        ack_loss in 0u32..300,
        duplicate in 0u32..200,
        jitter_us in prop_oneof![Just(0u64), 0u64..2_000],
        read_per_step in 1usize..300,
        seed in any::<u64>(),
    ) {
        let mut s = Scenario::new(pattern(len));
        s.faults = Faults { loss, ack_loss, duplicate, jitter_us };
        s.read_per_step = read_per_step;
        s.seed = seed;
        run(&s);
    }
}
