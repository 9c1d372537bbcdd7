//! Emulated hardware: the firmware's ports implemented in memory, against the [`Plant`].
//!
//! Everything here runs on the emulation's single thread, so shared pieces are `Rc<RefCell>`.
//! Each emulated part behaves like the real one where the firmware could tell the difference:
//! the counters are 16-bit and wrap, the absolute encoder shows inverted Gray code, SPI moves
//! whatever the slave had armed when the master asserted chip select
//! (0x00 through the master's MISO pull-down if nothing), and the UART takes its byte time.

use std::cell::RefCell;
use std::collections::VecDeque;
use std::future::poll_fn;
use std::rc::Rc;
use std::sync::{Arc, Mutex};
use std::task::{Poll, Waker};

use embassy_time::{Duration, Instant, Timer};
use firmware_master::ports::{MotorDrivers, MotorEncoders, SlaveBus, SpiMasterError};
use firmware_slave::ports::{
    AbsoluteEncoderPins, EdgeBatch, EncoderEdge, EncoderEdges, QuadratureCounters, SpiSlave,
    SpiSlaveError,
};
use protocol::spi::SPI_FRAME_LEN;
use robot_math::sensors::QuadratureDecoder;

use crate::sim::plant::Plant;

pub type SharedPlant = Rc<RefCell<Plant>>;

/// The plant, checked to stand at this virtual instant: the emulator steps the physics on a
/// grid every firmware read falls on, so a read off it would see the plant up to a step late.
fn plant_now(plant: &SharedPlant) -> std::cell::Ref<'_, Plant> {
    let p = plant.borrow();
    debug_assert!(
        (p.time() * 1e6 - embassy_time::Instant::now().as_micros() as f64).abs() < 0.5,
        "a firmware read at {} us, off the physics grid (plant at {} s)",
        embassy_time::Instant::now().as_micros(),
        p.time()
    );
    p
}

/// The slave's timer counters, reading the plant's encoders.
pub struct EmuCounters(pub SharedPlant);

impl QuadratureCounters for EmuCounters {
    fn read_raw(&mut self) -> [u16; 2] {
        // A 16-bit timer register shows the low 16 bits of the true count.
        plant_now(&self.0).encoder_counts().map(|c| c as u16)
    }
}

/// Edge interrupts on the measuring wheels' A/B channels: every edge the plant produced, time
/// stamped to the slave clock's microsecond, as an edge interrupt reading the clock would.
pub struct EmuEdges {
    pub plant: SharedPlant,
    /// The edges being handed over (the plant's buffer and this one take turns).
    batch: Vec<(f64, usize, i64)>,
}

impl EmuEdges {
    pub fn new(plant: SharedPlant) -> Self {
        EmuEdges {
            plant,
            batch: Vec::new(),
        }
    }
}

impl EncoderEdges for EmuEdges {
    fn levels(&mut self) -> [u8; 2] {
        plant_now(&self.plant)
            .encoder_counts()
            .map(QuadratureDecoder::levels_at)
    }

    fn drain(&mut self, mut f: impl FnMut(EncoderEdge)) -> EdgeBatch {
        // The plant stands still while the firmware runs: its edges so far and its counters
        // are one instant, as the board's critical section makes them.
        let counters = {
            drop(plant_now(&self.plant));
            let mut plant = self.plant.borrow_mut();
            plant.swap_edges(&mut self.batch);
            plant.encoder_counts().map(|c| c as u16)
        };
        for &(t, encoder, count) in &self.batch {
            f(EncoderEdge {
                // Rounded to the microsecond: for 0 ≤ x < 2^52, `(x + 0.5) as u64` is exactly
                // `x.round()`, without its library call (2.5 % of an emulation). Through `i64`
                // (equal for 0 ≤ x < 2^63, and no time is negative): x86-64 converts a double
                // to a signed integer in one instruction, to an unsigned one in a dozen
                // (1.8 % of the run's instructions).
                t_us: ((t * 1e6 + 0.5) as i64).max(0) as u64,
                encoder: encoder as u8,
                levels: QuadratureDecoder::levels_at(count),
            });
        }
        EdgeBatch {
            complete: true,
            counters: Some(counters),
        }
    }
}

/// The absolute encoder's eight output pins (open collector: a 1 bit pulls the pin low).
pub struct EmuAbsEncoder(pub SharedPlant);

impl AbsoluteEncoderPins for EmuAbsEncoder {
    fn read_levels(&mut self) -> u8 {
        plant_now(&self.0).abs_pins()
    }
}

/// Where the plant's motors take their duties from.
#[derive(Clone, Debug, Default)]
pub enum DutySource {
    /// The master's control steps: the closed loop.
    #[default]
    Master,
    /// The master's, and each control step's duty is written down.
    Record(Arc<Mutex<Vec<[i16; 3]>>>),
    /// A recorded run's, control step by control step; the master's own are ignored. The
    /// robot then moves exactly as it did in that run, whatever the master saw.
    Replay(Arc<Vec<[i16; 3]>>),
}

/// The three motor drivers: duties go to the plant's motors (see [`DutySource`]).
pub struct EmuMotors {
    pub plant: SharedPlant,
    pub source: DutySource,
    /// Control steps so far (each sets or stops the motors once).
    pub steps: usize,
}

impl EmuMotors {
    fn drive(&mut self, duty: [i16; 3]) {
        let duty = match &self.source {
            DutySource::Master => duty,
            DutySource::Record(log) => {
                log.lock().unwrap_or_else(|e| e.into_inner()).push(duty);
                duty
            }
            DutySource::Replay(script) => script.get(self.steps).copied().unwrap_or([0; 3]),
        };
        self.steps += 1;
        self.plant.borrow_mut().set_duty(duty);
    }
}

impl MotorDrivers for EmuMotors {
    fn set_duty(&mut self, duty: [i16; 3]) {
        self.drive(duty.map(|d| d.clamp(-1000, 1000)));
    }
    fn stop(&mut self) {
        self.drive([0; 3]);
    }
}

/// The drive motors' shaft encoders, read off the plant's wheels.
pub struct EmuMotorEncoders(pub SharedPlant);

impl MotorEncoders for EmuMotorEncoders {
    fn counts(&mut self) -> [u16; 3] {
        plant_now(&self.0).motor_counts()
    }
}

/// The SPI wires between the boards.
pub struct SpiWire {
    /// Frame the slave armed for the next transaction.
    armed: Option<[u8; SPI_FRAME_LEN]>,
    /// What the master clocked in during the last transaction, waiting for the slave.
    delivered: Option<[u8; SPI_FRAME_LEN]>,
    slave_waker: Option<Waker>,
    /// Transactions the master ran.
    pub transactions: u64,
    /// Faults injected on the wire (smoltcp style: rates per transaction), and what was done.
    pub faults: SpiFaults,
    pub injected: SpiInjected,
    /// The frames each board's decoder refuses, by why (what the boards count, by kind).
    pub rejected_by_master: SpiRejections,
    pub rejected_by_slave: SpiRejections,
    rng: rand_chacha::ChaCha8Rng,
    /// The slave has power (a lost transaction re-arms its frame only while it does).
    powered: bool,
    /// The frame the slave sent in the last transaction it took part in, and whether it
    /// reached the master unchanged (what a late re-arm sends again).
    last_from_slave: Option<([u8; SPI_FRAME_LEN], bool)>,
}

/// How much longer a late master holds chip select ([`SpiFaults::late`]): over the controller's
/// 2 ms threshold for a slave clock that jumped (a slave reset).
pub const LATE_CS: Duration = Duration::from_millis(3);

/// Fault rates on the SPI wire, each a probability per transaction in [0, 1).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct SpiFaults {
    /// One bit flipped in a frame, each direction on its own (a noisy line).
    pub corrupt: f64,
    /// The whole transaction lost: the master reads an idle line (MISO low) and the slave sees
    /// nothing, its armed frame still waiting (a chip select glitch).
    pub drop: f64,
    /// The transaction torn: chip select rises part way through, and both sides keep the bytes
    /// shifted so far, the rest of each frame idle (0x00).
    pub torn: f64,
    /// The slave late to re-arm: its transmit DMA, circular, sends the frame it sent last
    /// time again, and it misses this transaction (its new frame stays armed for the next).
    /// The master gets a valid frame that it may have had already. (A synchronous bus has no
    /// other duplicate and no delayed frame: the master clocks every bit, so a late slave
    /// shows as this, or as an idle line, which is `drop`.)
    pub duplicate: f64,
    /// The master late to release chip select after a transaction, by [`LATE_CS`]: another of
    /// its tasks held the CPU when the last bit went (the slave re-armed on time). Nothing is
    /// lost; the transaction's end is still when its last bit went.
    pub late: f64,
    /// Not noise but a bug: every master frame that carries played-event byte `event_bit`
    /// reaches the slave with that byte's lowest bit flipped, under a valid check, so the
    /// slave computes something else than the host (what `play`'s checks must catch).
    pub event_bit: Option<u32>,
}

/// What the wire did to the frames.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct SpiInjected {
    pub corrupted_to_master: u64,
    pub corrupted_to_slave: u64,
    pub dropped: u64,
    pub torn: u64,
    pub duplicated: u64,
    pub late: u64,
}

/// Frames refused, by why (`protocol::spi::SpiFrameError`), as the receiving board's decoder
/// sees them.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct SpiRejections {
    /// The check failed (a flipped bit, an idle or torn frame).
    pub crc: u64,
    /// A frame of the other direction's type.
    pub kind: u64,
    pub decode: u64,
    pub non_canonical: u64,
    /// A valid frame the master had already read (the slave sent it twice): nothing in it
    /// is new. Only the master counts these.
    pub repeated: u64,
}

impl SpiRejections {
    fn count<T: protocol::spi::SpiFrame>(&mut self, frame: &[u8; SPI_FRAME_LEN]) {
        use protocol::spi::SpiFrameError as E;
        match protocol::spi::decode::<T>(frame) {
            Ok(_) => {}
            Err(E::Crc) => self.crc += 1,
            Err(E::Kind) => self.kind += 1,
            Err(E::Decode) => self.decode += 1,
            Err(E::NonCanonical) => self.non_canonical += 1,
        }
    }

    pub fn total(&self) -> u64 {
        self.crc + self.kind + self.decode + self.non_canonical + self.repeated
    }
}

impl SpiWire {
    /// A wire with `faults`, its randomness from `seed` (a stream of its own, so a clean run
    /// draws nothing and stays as it was).
    pub fn new(faults: SpiFaults, seed: u64) -> Self {
        use rand::SeedableRng;
        SpiWire {
            armed: None,
            delivered: None,
            slave_waker: None,
            transactions: 0,
            faults,
            injected: SpiInjected::default(),
            rejected_by_master: SpiRejections::default(),
            rejected_by_slave: SpiRejections::default(),
            rng: rand_chacha::ChaCha8Rng::seed_from_u64(seed ^ 0x5350_495f_4641_554c),
            powered: true,
            last_from_slave: None,
        }
    }

    /// True with probability `rate` (no draw at all for a rate of zero).
    fn happens(&mut self, rate: f64) -> bool {
        use rand::Rng;
        rate > 0.0 && self.rng.random::<f64>() < rate
    }

    /// Flip one bit of `frame`, chosen at random.
    fn flip_a_bit(&mut self, frame: &mut [u8; SPI_FRAME_LEN]) {
        use rand::Rng;
        let bit = self.rng.random_range(0..SPI_FRAME_LEN * 8);
        frame[bit / 8] ^= 1 << (bit % 8);
    }
}

/// Time one transaction (`SPI_FRAME_LEN` bytes) takes at the master's SPI clock.
pub fn spi_transfer_time(clock_hz: u32) -> Duration {
    Duration::from_micros(protocol::spi::frame_time_us(clock_hz))
}

impl SpiWire {
    /// The slave lost power: its shift register no longer answers (MISO reads low).
    pub fn power_off(&mut self) {
        self.powered = false;
        self.armed = None;
        self.delivered = None;
        self.slave_waker = None;
        self.last_from_slave = None;
    }

    /// The slave has power again (it boots, then arms its first frame).
    pub fn power_on(&mut self) {
        self.powered = true;
    }
}

pub struct EmuSlaveSpi(pub Rc<RefCell<SpiWire>>);

impl SpiSlave for EmuSlaveSpi {
    async fn exchange(
        &mut self,
        tx: &[u8; SPI_FRAME_LEN],
        rx: &mut [u8; SPI_FRAME_LEN],
    ) -> Result<(), SpiSlaveError> {
        self.0.borrow_mut().armed = Some(*tx);
        poll_fn(|cx| {
            let mut w = self.0.borrow_mut();
            match w.delivered.take() {
                Some(bytes) => {
                    *rx = bytes;
                    Poll::Ready(Ok(()))
                }
                None => {
                    w.slave_waker = Some(cx.waker().clone());
                    Poll::Pending
                }
            }
        })
        .await
    }
}

pub struct EmuMasterBus {
    pub wire: Rc<RefCell<SpiWire>>,
    pub transfer_time: Duration,
}

impl SlaveBus for EmuMasterBus {
    async fn exchange(
        &mut self,
        tx: &[u8; SPI_FRAME_LEN],
        rx: &mut [u8; SPI_FRAME_LEN],
    ) -> Result<Instant, SpiMasterError> {
        // Chip select: the slave's shift register holds what it armed before this instant.
        let start = Instant::now();
        let from_slave = self.wire.borrow_mut().armed.take();
        Timer::after(self.transfer_time).await;
        self.transaction(tx, rx, from_slave);
        let late = {
            let mut w = self.wire.borrow_mut();
            let rate = w.faults.late;
            let late = w.happens(rate);
            w.injected.late += late as u64;
            late
        };
        if late {
            // Chip select still low: the master's task has not had the CPU back since.
            Timer::after(LATE_CS).await;
        }
        Ok(start + self.transfer_time)
    }
}

impl EmuMasterBus {
    /// The bytes of one transaction, the wire's faults done to them, once its last bit went.
    fn transaction(
        &mut self,
        tx: &[u8; SPI_FRAME_LEN],
        rx: &mut [u8; SPI_FRAME_LEN],
        from_slave: Option<[u8; SPI_FRAME_LEN]>,
    ) {
        let mut w = self.wire.borrow_mut();
        w.transactions += 1;
        let SpiFaults {
            corrupt,
            drop,
            torn,
            duplicate,
            ..
        } = w.faults;
        if let Some((again, seen)) = w.last_from_slave.filter(|_| w.happens(duplicate)) {
            w.injected.duplicated += 1;
            // The slave's new frame waits for the next transaction, as after a lost one.
            if w.powered && w.armed.is_none() {
                w.armed = from_slave;
            }
            *rx = again;
            if seen {
                w.rejected_by_master.repeated += 1;
            }
            // Read now, whole: the master has it.
            w.last_from_slave = Some((again, true));
            return;
        }
        if w.happens(drop) {
            w.injected.dropped += 1;
            // The slave never saw this transaction: its frame stays armed for the next.
            if w.powered && w.armed.is_none() {
                w.armed = from_slave;
            }
            *rx = [0x00; SPI_FRAME_LEN];
            w.rejected_by_master.count::<protocol::spi::SlaveFrame>(rx);
            return;
        }
        match from_slave {
            Some(mut bytes) => {
                let sent = bytes;
                let mut to_slave = *tx;
                if let Some(at) = w.faults.event_bit {
                    flip_event_bit(&mut to_slave, at);
                }
                // Which directions the wire changed. A frame it left alone is the sender's own
                // `spi::encode`, which always decodes (the protocol's round-trip and canonical
                // proptests), so only changed frames are classified: decoding every frame
                // twice more cost a fifth of the emulation.
                let (mut to_master_changed, mut to_slave_changed) = (false, false);
                if w.happens(torn) {
                    use rand::Rng;
                    w.injected.torn += 1;
                    let shifted = w.rng.random_range(1..SPI_FRAME_LEN);
                    bytes[shifted..].fill(0);
                    to_slave[shifted..].fill(0);
                    (to_master_changed, to_slave_changed) = (true, true);
                }
                if w.happens(corrupt) {
                    w.injected.corrupted_to_master += 1;
                    w.flip_a_bit(&mut bytes);
                    to_master_changed = true;
                }
                *rx = bytes;
                w.last_from_slave = Some((sent, !to_master_changed));
                if w.happens(corrupt) {
                    w.injected.corrupted_to_slave += 1;
                    w.flip_a_bit(&mut to_slave);
                    to_slave_changed = true;
                }
                if to_master_changed {
                    w.rejected_by_master.count::<protocol::spi::SlaveFrame>(rx);
                }
                if to_slave_changed {
                    w.rejected_by_slave
                        .count::<protocol::spi::MasterFrame>(&to_slave);
                }
                w.delivered = Some(to_slave);
                if let Some(waker) = w.slave_waker.take() {
                    waker.wake();
                }
            }
            // Nobody armed: the master's pull-down holds MISO low (docs/pinmap.md).
            None => {
                *rx = [0x00; SPI_FRAME_LEN];
                w.rejected_by_master.count::<protocol::spi::SlaveFrame>(rx);
                w.last_from_slave = None;
            }
        }
    }
}

/// `frame` (a master frame) with played-event byte `at` flipped in its lowest bit and its
/// check made good again, if it carries that byte.
fn flip_event_bit(frame: &mut [u8; SPI_FRAME_LEN], at: u32) {
    use protocol::spi::MasterFrame;
    let Ok(mut f) = protocol::spi::decode::<MasterFrame>(frame) else {
        return;
    };
    let i = at.wrapping_sub(f.events.offset) as usize;
    let mut bytes = f.events.bytes.as_slice().to_vec();
    if let Some(b) = bytes.get_mut(i) {
        *b ^= 1;
        f.events.bytes = protocol::Bytes::from_slice_truncating(&bytes);
        *frame = protocol::spi::encode(&f);
    }
}

/// One direction of a UART: bytes appear at the far end after their time on the wire.
#[derive(Default)]
pub struct UartLine {
    bytes: VecDeque<u8>,
    reader: Option<Waker>,
    /// The rate each run of `bytes` was sent at, for a reader outside the emulation that
    /// models the far end's rate ([`UartLine::with_rates`]); not kept otherwise.
    rates: Option<VecDeque<(u32, usize)>>,
}

pub type SharedLine = Rc<RefCell<UartLine>>;

impl UartLine {
    /// Bytes arriving from outside the emulation (a pseudo-terminal): the reader wakes.
    pub fn deliver(&mut self, bytes: &[u8]) {
        self.bytes.extend(bytes.iter().copied());
        if let Some(w) = self.reader.take() {
            w.wake();
        }
    }

    /// A line that keeps the rate its bytes were sent at ([`UartLine::take_runs`]).
    pub fn with_rates() -> UartLine {
        UartLine {
            rates: Some(VecDeque::new()),
            ..UartLine::default()
        }
    }

    /// Everything that has landed, in runs sent at one rate each (all at `fallback` on a
    /// line that keeps no rates).
    pub fn take_runs(&mut self, fallback: u32) -> Vec<(u32, Vec<u8>)> {
        let mut runs = Vec::new();
        for (rate, n) in self.rates.as_mut().map(std::mem::take).unwrap_or_default() {
            let n = n.min(self.bytes.len());
            runs.push((rate, self.bytes.drain(..n).collect()));
        }
        if !self.bytes.is_empty() {
            runs.push((fallback, self.bytes.drain(..).collect()));
        }
        runs
    }
}

/// Time one byte takes at `baud` with 8N1 framing (10 bits).
pub fn byte_time(baud: u32) -> Duration {
    Duration::from_micros((10 * 1_000_000u64).div_ceil(baud as u64))
}

/// Time `bytes` bytes take at `baud` with 8N1 framing, to the microsecond above (a whole
/// frame's, not a byte's rounded time over again: at 4.5 Mbaud that was a third too slow).
pub fn wire_time(baud: u32, bytes: usize) -> Duration {
    Duration::from_micros((bytes as u64 * 10_000_000).div_ceil(baud.max(1) as u64))
}

/// A serial port's rate, shared by its two directions (and with the bridge that checks the
/// far end runs at the same rate).
pub type SharedRate = Rc<core::cell::Cell<u32>>;

pub struct UartRx(pub SharedLine);
pub struct UartTx {
    pub line: SharedLine,
    /// The port's rate: each write takes its bytes' time on the wire at it.
    pub rate: SharedRate,
    /// Noise on this direction of the line, frame by frame (None: a quiet line).
    pub noise: Option<Rc<RefCell<crate::sim::serial_noise::SerialNoise>>>,
}

impl embedded_io_async::ErrorType for UartRx {
    type Error = core::convert::Infallible;
}
impl embedded_io_async::ErrorType for UartTx {
    type Error = core::convert::Infallible;
}

impl embedded_io_async::Read for UartRx {
    async fn read(&mut self, buf: &mut [u8]) -> Result<usize, Self::Error> {
        poll_fn(|cx| {
            let mut line = self.0.borrow_mut();
            if line.bytes.is_empty() {
                line.reader = Some(cx.waker().clone());
                return Poll::Pending;
            }
            let n = buf.len().min(line.bytes.len());
            for (dst, src) in buf.iter_mut().zip(line.bytes.drain(..n)) {
                *dst = src;
            }
            Poll::Ready(Ok(n))
        })
        .await
    }
}

impl firmware_master::ports::SerialRate for UartTx {
    fn set_baud(&mut self, baud: u32) -> bool {
        self.rate.set(baud);
        true
    }
}

impl embedded_io_async::Write for UartTx {
    async fn write(&mut self, buf: &[u8]) -> Result<usize, Self::Error> {
        // The frame is on the wire for its byte time; deliver it when the last byte lands.
        let rate = self.rate.get();
        Timer::after(wire_time(rate, buf.len())).await;
        let mut line = self.line.borrow_mut();
        let before = line.bytes.len();
        match &self.noise {
            Some(noise) => line.bytes.extend(noise.borrow_mut().pass(buf)),
            None => line.bytes.extend(buf.iter().copied()),
        }
        let sent = line.bytes.len() - before;
        if let Some(runs) = &mut line.rates {
            runs.push_back((rate, sent));
        }
        if let Some(w) = line.reader.take() {
            w.wake();
        }
        Ok(buf.len())
    }

    async fn flush(&mut self) -> Result<(), Self::Error> {
        // `write` only returns once the bytes have landed: nothing is ever buffered.
        Ok(())
    }
}
