//! Compact byte codes for played sensor events: what the slave is fed in "play" mode instead
//! of its real encoders.
//!
//! Two kinds of stream, each a plain byte stream (the link delivers bytes, not events):
//! * **Edges** (tick-timestamp mode): time-ordered [`Event`]s, each coded by its time since the
//!   previous event. Most ticks take 1 or 2 bytes. [`EventEncoder`] / [`EventDecoder`].
//! * **Counts** (fixed-rate counts mode): one [`Sample`] per update period, count changes as
//!   zigzag varints; "nothing moved" is one byte. [`encode_sample`] / [`SampleDecoder`].
//!
//! Both decoders are streaming: they take one byte at a time and keep a partial event across
//! calls, so chunks may split events anywhere. Their state is tiny (the previous event time
//! and the event being assembled), every byte is O(1) work, and garbage yields
//! [`DecodeError`]s, never a panic. After an error the next byte is read as the start of a new
//! event; the link is reliable, so an error means a bug or a stream from another session, and
//! the caller should restart the session. Byte tables: docs/protocol.md.

/// Incremental encoders an event or sample can name (`0..MAX_ENCODERS`).
pub const MAX_ENCODERS: usize = 4;
/// Longest coded event: header, 10-byte varint time, 2-byte code.
pub const MAX_EVENT_LEN: usize = 13;
/// Longest coded sample: header, four 5-byte varints, 2-byte code.
pub const MAX_SAMPLE_LEN: usize = 1 + MAX_ENCODERS * 5 + 2;

/// Which way an incremental encoder counted.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Step {
    /// +1 count: the wheel rolled along its rolling direction.
    Forward,
    /// -1 count.
    Backward,
}

impl Step {
    /// +1 or -1.
    pub fn delta(self) -> i8 {
        match self {
            Step::Forward => 1,
            Step::Backward => -1,
        }
    }
}

/// One played sensor event; times are microseconds on the player's clock.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Event {
    /// Incremental encoder `encoder` (`0..MAX_ENCODERS`) counted one step.
    Tick { t_us: u64, encoder: u8, step: Step },
    /// The absolute encoder showed raw code `code`.
    Abs { t_us: u64, code: u16 },
}

impl Event {
    pub fn t_us(&self) -> u64 {
        match *self {
            Event::Tick { t_us, .. } | Event::Abs { t_us, .. } => t_us,
        }
    }
}

/// Why an event or sample could not be encoded. The encoder's state is unchanged.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum EncodeError {
    /// The output has room for fewer than `needed` bytes.
    BufferFull { needed: usize },
    /// Events must come in non-decreasing time order.
    TimeBackwards { prev_us: u64, t_us: u64 },
    /// A tick names an encoder outside `0..MAX_ENCODERS`.
    EncoderOutOfRange(u8),
}

/// What was wrong in a coded stream, and where.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DecodeError {
    /// Offset of the offending byte in the stream (counting every byte pushed).
    pub offset: u64,
    pub kind: DecodeErrorKind,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DecodeErrorKind {
    /// A header byte that no form uses (or with reserved bits set).
    BadHeader(u8),
    /// A varint longer than its type allows.
    VarintTooLong,
    /// The time would pass `u64::MAX`.
    TimeOverflow,
    /// A count change outside `i32`.
    CountOutOfRange,
    /// A value written in a longer form than the encoder uses (a time step that fits a
    /// shorter tick form, a varint with trailing zero bytes, a zero count change written
    /// out): every event has one encoding, so two byte strings never mean the same.
    NonCanonical,
}

// Header forms of the edges stream (see docs/protocol.md for the table).
const TICK1_MAX_DT: u64 = 0x0F;
const TICK2_TAG: u8 = 0b1000_0000;
const TICK2_MAX_DT: u64 = 0x7FF;
const TICK_VARINT_TAG: u8 = 0b1100_0000;
const ABS_TAG: u8 = 0xE0;

/// Writes [`Event`]s as edge-stream bytes. State: the previous event's time (starts at 0).
#[derive(Clone, Debug, Default)]
pub struct EventEncoder {
    prev_us: u64,
}

impl EventEncoder {
    pub const fn new() -> Self {
        EventEncoder { prev_us: 0 }
    }

    /// Code one event into the start of `out`; returns the bytes written (at most
    /// [`MAX_EVENT_LEN`]). On error nothing counts as written.
    pub fn encode(&mut self, event: &Event, out: &mut [u8]) -> Result<usize, EncodeError> {
        let t_us = event.t_us();
        let dt = t_us
            .checked_sub(self.prev_us)
            .ok_or(EncodeError::TimeBackwards {
                prev_us: self.prev_us,
                t_us,
            })?;
        let mut code = [0u8; MAX_EVENT_LEN];
        let len = match *event {
            Event::Tick { encoder, step, .. } => {
                if usize::from(encoder) >= MAX_ENCODERS {
                    return Err(EncodeError::EncoderOutOfRange(encoder));
                }
                let who = (encoder << 1) | u8::from(step == Step::Backward);
                if dt <= TICK1_MAX_DT {
                    code[0] = (who << 4) | dt as u8;
                    1
                } else if dt <= TICK2_MAX_DT {
                    code[0] = TICK2_TAG | (who << 3) | (dt >> 8) as u8;
                    code[1] = dt as u8;
                    2
                } else {
                    code[0] = TICK_VARINT_TAG | (who << 2);
                    1 + write_varint(dt, &mut code[1..])
                }
            }
            Event::Abs { code: abs, .. } => {
                code[0] = ABS_TAG;
                let n = 1 + write_varint(dt, &mut code[1..]);
                code[n..n + 2].copy_from_slice(&abs.to_le_bytes());
                n + 2
            }
        };
        let dest = out
            .get_mut(..len)
            .ok_or(EncodeError::BufferFull { needed: len })?;
        dest.copy_from_slice(&code[..len]);
        self.prev_us = t_us;
        Ok(len)
    }

    /// Code as many of `events` as fit into `out`, in order, never splitting one. Returns
    /// `(events written, bytes written)`; stops early only for lack of room.
    pub fn encode_all(
        &mut self,
        events: &[Event],
        out: &mut [u8],
    ) -> Result<(usize, usize), EncodeError> {
        let mut used = 0;
        for (i, event) in events.iter().enumerate() {
            match self.encode(event, &mut out[used..]) {
                Ok(n) => used += n,
                Err(EncodeError::BufferFull { .. }) => return Ok((i, used)),
                Err(e) => return Err(e),
            }
        }
        Ok((events.len(), used))
    }
}

/// LEB128 (postcard's varint): 7 bits a byte, low first, high bit = more follows.
/// `out` must hold 10 bytes; returns the bytes used.
fn write_varint(mut value: u64, out: &mut [u8]) -> usize {
    let mut n = 0;
    while let Some(slot) = out.get_mut(n) {
        n += 1;
        if value < 0x80 {
            *slot = value as u8;
            break;
        }
        *slot = (value as u8) | 0x80;
        value >>= 7;
    }
    n
}

/// Assembles a varint one byte at a time, refusing more than `max_len` bytes.
#[derive(Clone, Copy, Debug, Default)]
struct Varint {
    value: u64,
    len: u8,
}

impl Varint {
    /// `Ok(Some(value))` when `byte` ends the varint.
    fn push(&mut self, byte: u8, max_len: u8) -> Result<Option<u64>, DecodeErrorKind> {
        let bits = u64::from(byte & 0x7F);
        let shift = 7 * u32::from(self.len);
        // The 10th byte of a u64 holds only its top bit.
        if self.len >= max_len || (shift == 63 && bits > 1) {
            return Err(DecodeErrorKind::VarintTooLong);
        }
        self.value |= bits << shift;
        self.len += 1;
        if byte & 0x80 != 0 {
            return Ok(None);
        }
        if byte == 0 && self.len > 1 {
            return Err(DecodeErrorKind::NonCanonical); // an over-long varint
        }
        let value = self.value;
        *self = Varint::default();
        Ok(Some(value))
    }
}

#[derive(Clone, Copy, Debug, Default)]
enum EdgeState {
    #[default]
    Header,
    /// 2-byte tick: the header holds who and the top 3 bits of the time step.
    TickLow {
        who: u8,
        dt_high: u8,
    },
    TickVarint {
        who: u8,
    },
    AbsTime,
    AbsCodeLow {
        t_us: u64,
    },
    AbsCodeHigh {
        t_us: u64,
        low: u8,
    },
}

/// Streaming decoder of the edges stream: push bytes, get events. State: the previous event
/// time, the partial event, the stream offset.
#[derive(Clone, Debug, Default)]
pub struct EventDecoder {
    prev_us: u64,
    offset: u64,
    state: EdgeState,
    varint: Varint,
}

impl EventDecoder {
    pub const fn new() -> Self {
        EventDecoder {
            prev_us: 0,
            offset: 0,
            state: EdgeState::Header,
            varint: Varint { value: 0, len: 0 },
        }
    }

    /// Nothing half-decoded is pending (the stream so far ends on an event boundary).
    pub fn is_between_events(&self) -> bool {
        matches!(self.state, EdgeState::Header) && self.varint.len == 0
    }

    /// Feed every byte of `bytes`, handing each decoded event (or error) to `out` in order.
    pub fn feed(&mut self, bytes: &[u8], mut out: impl FnMut(Result<Event, DecodeError>)) {
        for &b in bytes {
            if let Some(result) = self.push(b) {
                out(result);
            }
        }
    }

    /// Feed one byte; `Some` when it completes an event or is found wrong.
    pub fn push(&mut self, byte: u8) -> Option<Result<Event, DecodeError>> {
        let offset = self.offset;
        self.offset = self.offset.wrapping_add(1);
        match self.step(byte) {
            Ok(event) => event.map(Ok),
            Err(kind) => {
                self.state = EdgeState::Header;
                self.varint = Varint::default();
                Some(Err(DecodeError { offset, kind }))
            }
        }
    }

    fn step(&mut self, byte: u8) -> Result<Option<Event>, DecodeErrorKind> {
        match self.state {
            EdgeState::Header => match byte {
                0x00..=0x7F => self.tick(byte >> 4, u64::from(byte & 0x0F)).map(Some),
                0x80..=0xBF => {
                    self.state = EdgeState::TickLow {
                        who: (byte >> 3) & 0x07,
                        dt_high: byte & 0x07,
                    };
                    Ok(None)
                }
                0xC0..=0xDF if byte & 0x03 == 0 => {
                    self.state = EdgeState::TickVarint {
                        who: (byte >> 2) & 0x07,
                    };
                    Ok(None)
                }
                ABS_TAG => {
                    self.state = EdgeState::AbsTime;
                    Ok(None)
                }
                _ => Err(DecodeErrorKind::BadHeader(byte)),
            },
            EdgeState::TickLow { who, dt_high } => {
                self.state = EdgeState::Header;
                let dt = (u64::from(dt_high) << 8) | u64::from(byte);
                if dt <= TICK1_MAX_DT {
                    return Err(DecodeErrorKind::NonCanonical);
                }
                self.tick(who, dt).map(Some)
            }
            EdgeState::TickVarint { who } => match self.varint.push(byte, 10)? {
                None => Ok(None),
                Some(dt) if dt <= TICK2_MAX_DT => Err(DecodeErrorKind::NonCanonical),
                Some(dt) => {
                    self.state = EdgeState::Header;
                    self.tick(who, dt).map(Some)
                }
            },
            EdgeState::AbsTime => {
                if let Some(dt) = self.varint.push(byte, 10)? {
                    let t_us = self
                        .prev_us
                        .checked_add(dt)
                        .ok_or(DecodeErrorKind::TimeOverflow)?;
                    self.state = EdgeState::AbsCodeLow { t_us };
                }
                Ok(None)
            }
            EdgeState::AbsCodeLow { t_us } => {
                self.state = EdgeState::AbsCodeHigh { t_us, low: byte };
                Ok(None)
            }
            EdgeState::AbsCodeHigh { t_us, low } => {
                self.state = EdgeState::Header;
                self.prev_us = t_us;
                Ok(Some(Event::Abs {
                    t_us,
                    code: u16::from_le_bytes([low, byte]),
                }))
            }
        }
    }

    /// `who` = encoder << 1 | backward.
    fn tick(&mut self, who: u8, dt: u64) -> Result<Event, DecodeErrorKind> {
        let t_us = self
            .prev_us
            .checked_add(dt)
            .ok_or(DecodeErrorKind::TimeOverflow)?;
        self.prev_us = t_us;
        Ok(Event::Tick {
            t_us,
            encoder: who >> 1,
            step: if who & 1 == 0 {
                Step::Forward
            } else {
                Step::Backward
            },
        })
    }
}

/// One update period of counts mode: how far each encoder moved, and the absolute encoder's
/// code if it was read.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Sample {
    /// Count change of each encoder during the period (unused encoders stay 0).
    pub counts_delta: [i32; MAX_ENCODERS],
    pub abs: Option<u16>,
}

const SAMPLE_ABS_BIT: u8 = 1 << MAX_ENCODERS;

/// Code one sample into the start of `out`; returns the bytes written (1 when nothing moved
/// and no code was read, at most [`MAX_SAMPLE_LEN`]). Samples need no encoder state.
pub fn encode_sample(sample: &Sample, out: &mut [u8]) -> Result<usize, EncodeError> {
    let mut code = [0u8; MAX_SAMPLE_LEN];
    let mut len = 1;
    for (i, &delta) in sample.counts_delta.iter().enumerate() {
        if delta != 0 {
            code[0] |= 1 << i;
            len += write_varint(u64::from(zigzag(delta)), &mut code[len..]);
        }
    }
    if let Some(abs) = sample.abs {
        code[0] |= SAMPLE_ABS_BIT;
        code[len..len + 2].copy_from_slice(&abs.to_le_bytes());
        len += 2;
    }
    let dest = out
        .get_mut(..len)
        .ok_or(EncodeError::BufferFull { needed: len })?;
    dest.copy_from_slice(&code[..len]);
    Ok(len)
}

fn zigzag(n: i32) -> u32 {
    ((n << 1) ^ (n >> 31)) as u32
}

fn unzigzag(z: u32) -> i32 {
    ((z >> 1) as i32) ^ -((z & 1) as i32)
}

#[derive(Clone, Copy, Debug, Default)]
enum SampleState {
    #[default]
    Header,
    /// Reading deltas; `pending` holds the mask bits (and abs bit) still to come.
    Fields {
        pending: u8,
    },
    AbsHigh {
        pending: u8,
        low: u8,
    },
}

/// Streaming decoder of the counts stream: push bytes, get samples.
#[derive(Clone, Debug, Default)]
pub struct SampleDecoder {
    offset: u64,
    state: SampleState,
    varint: Varint,
    sample: Sample,
}

impl SampleDecoder {
    pub const fn new() -> Self {
        SampleDecoder {
            offset: 0,
            state: SampleState::Header,
            varint: Varint { value: 0, len: 0 },
            sample: Sample {
                counts_delta: [0; MAX_ENCODERS],
                abs: None,
            },
        }
    }

    /// Nothing half-decoded is pending.
    pub fn is_between_samples(&self) -> bool {
        matches!(self.state, SampleState::Header)
    }

    /// Feed every byte of `bytes`, handing each decoded sample (or error) to `out` in order.
    pub fn feed(&mut self, bytes: &[u8], mut out: impl FnMut(Result<Sample, DecodeError>)) {
        for &b in bytes {
            if let Some(result) = self.push(b) {
                out(result);
            }
        }
    }

    /// Feed one byte; `Some` when it completes a sample or is found wrong.
    pub fn push(&mut self, byte: u8) -> Option<Result<Sample, DecodeError>> {
        let offset = self.offset;
        self.offset = self.offset.wrapping_add(1);
        match self.step(byte) {
            Ok(sample) => sample.map(Ok),
            Err(kind) => {
                *self = SampleDecoder {
                    offset: self.offset,
                    ..SampleDecoder::new()
                };
                Some(Err(DecodeError { offset, kind }))
            }
        }
    }

    fn step(&mut self, byte: u8) -> Result<Option<Sample>, DecodeErrorKind> {
        let pending = match self.state {
            SampleState::Header => {
                if byte >= SAMPLE_ABS_BIT << 1 {
                    return Err(DecodeErrorKind::BadHeader(byte));
                }
                self.sample = Sample::default();
                byte
            }
            SampleState::Fields { pending } => {
                if pending == SAMPLE_ABS_BIT {
                    self.state = SampleState::AbsHigh { pending, low: byte };
                    return Ok(None);
                }
                let Some(z) = self.varint.push(byte, 5)? else {
                    return Ok(None);
                };
                let z = u32::try_from(z).map_err(|_| DecodeErrorKind::CountOutOfRange)?;
                if z == 0 {
                    return Err(DecodeErrorKind::NonCanonical); // no change is left out
                }
                let i = pending.trailing_zeros() as usize;
                self.sample.counts_delta[i] = unzigzag(z);
                pending & (pending - 1)
            }
            SampleState::AbsHigh { pending, low } => {
                self.sample.abs = Some(u16::from_le_bytes([low, byte]));
                pending & !SAMPLE_ABS_BIT
            }
        };
        if pending == 0 {
            self.state = SampleState::Header;
            Ok(Some(self.sample))
        } else {
            self.state = SampleState::Fields { pending };
            Ok(None)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn varint_limits() {
        let mut buf = [0u8; 10];
        assert_eq!(write_varint(u64::MAX, &mut buf), 10);
        let mut v = Varint::default();
        for &b in &buf[..9] {
            assert_eq!(v.push(b, 10), Ok(None));
        }
        assert_eq!(v.push(buf[9], 10), Ok(Some(u64::MAX)));
        let mut v = Varint::default();
        for _ in 0..9 {
            assert_eq!(v.push(0xFF, 10), Ok(None));
        }
        assert_eq!(v.push(0x02, 10), Err(DecodeErrorKind::VarintTooLong));
    }

    #[test]
    fn zigzag_round_trips_extremes() {
        for n in [0, 1, -1, i32::MAX, i32::MIN] {
            assert_eq!(unzigzag(zigzag(n)), n);
        }
        assert_eq!(zigzag(-1), 1);
        assert_eq!(zigzag(1), 2);
    }
}
