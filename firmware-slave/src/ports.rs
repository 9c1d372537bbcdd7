//! The slave's hardware seen through small traits. The board layer (`src/board/`) implements
//! them with embassy-stm32; the emulator in `host-bench` implements them against a simulated
//! robot. Nothing in this crate outside `main.rs`/`board/` knows which one it runs on.
//!
//! Time is the fourth port: the tasks use `embassy_time` (`Ticker`, `Instant`), whose driver is
//! TIM4 on the board and a virtual clock in the emulator.

use protocol::spi::SPI_FRAME_LEN;

/// Number of incremental measuring-wheel encoders the slave counts (seed 004 layout).
pub const MEASURING_WHEELS: usize = 2;

/// Hardware quadrature counters (timer encoder mode, x4 decoding).
pub trait QuadratureCounters {
    /// The raw 16-bit counter register of each measuring wheel. Wraps freely; the portable
    /// code extends it to a 64-bit total, so it must be read at least once per 32 768 counts.
    fn read_raw(&mut self) -> [u16; MEASURING_WHEELS];
}

/// The absolute encoder's parallel output (8 Gray-code bits, as levels on the pins).
pub trait AbsoluteEncoderPins {
    /// Pin levels, bit i = encoder output bit i (1 = high). Polarity and Gray decoding are
    /// done by the portable code (the layout's `AbsLayout`).
    fn read_levels(&mut self) -> u8;
}

/// Why a slave-side SPI exchange did not complete.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SpiSlaveError {
    /// The master ended the transaction (NSS rose) before a whole frame had moved.
    Aborted,
    /// The peripheral reported an overrun or mode fault.
    Bus,
}

// Both embassy executors and the emulator run tasks on one thread: no `Send` bound wanted.
#[allow(async_fn_in_trait)]
/// SPI in slave mode: the master clocks one fixed-size frame per transaction.
pub trait SpiSlave {
    /// Arm `tx` for the master's next transaction and wait until it has clocked a whole frame;
    /// `rx` then holds what the master sent. Must be re-armed promptly: while it is not armed
    /// the master reads idle bytes (which fail the frame CRC and are counted, never used).
    async fn exchange(
        &mut self,
        tx: &[u8; SPI_FRAME_LEN],
        rx: &mut [u8; SPI_FRAME_LEN],
    ) -> Result<(), SpiSlaveError>;
}

/// One edge on a measuring wheel's encoder channels, as the board saw it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct EncoderEdge {
    /// Slave clock (embassy ticks: microseconds) when the edge happened.
    pub t_us: u64,
    pub encoder: u8,
    /// A/B levels right after the edge: bit 0 = A, bit 1 = B.
    pub levels: u8,
}

/// A microsecond time's low 32 bits (how the board queues an edge's time: 8 bytes an edge,
/// not 16) made whole again against `now_us`, a time read after it: exact while the edge is
/// less than 2³² µs (71.6 minutes) older than `now_us`; queued edges are milliseconds old.
pub fn widen_us(low: u32, now_us: u64) -> u64 {
    let age = (now_us as u32).wrapping_sub(low);
    now_us.saturating_sub(age as u64)
}

/// What one [`EncoderEdges::drain`] handed over.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct EdgeBatch {
    /// False if edges were lost since the last drain (a full queue).
    pub complete: bool,
    /// The hardware counters read together with the end of the batch, with no edge in
    /// between: they have counted exactly the edges handed over so far. `None` when no such
    /// reading could be taken this time (edges kept arriving); the slave then skips its
    /// cross-check once.
    pub counters: Option<[u16; MEASURING_WHEELS]>,
}

/// Time-stamped encoder edges (edge interrupts or input capture): what tick-timestamp mode
/// runs on. The board records edges as they happen; the odometry task drains them at its
/// fixed rate.
pub trait EncoderEdges {
    /// The A/B levels of every measuring wheel now (decoding starts from them).
    fn levels(&mut self) -> [u8; MEASURING_WHEELS];
    /// Hand over the edges recorded up to one instant, oldest first, with the hardware
    /// counters at that instant (see [`EdgeBatch`]). Edges after it stay for the next call,
    /// so an edge arriving while this runs can never make the decoded count and the counters
    /// differ.
    ///
    /// Generic over `f` so that the emulator's edges (hundreds of thousands a run) reach the
    /// odometry inlined; a board keeps one copy of its drain by forwarding to a `dyn` one.
    fn drain(&mut self, f: impl FnMut(EncoderEdge)) -> EdgeBatch;
}

/// For boards or builds without edge capture: only fixed-rate counts mode is available.
pub struct NoEdges;

impl EncoderEdges for NoEdges {
    fn levels(&mut self) -> [u8; MEASURING_WHEELS] {
        [0; MEASURING_WHEELS]
    }
    fn drain(&mut self, _f: impl FnMut(EncoderEdge)) -> EdgeBatch {
        EdgeBatch {
            complete: true,
            counters: None,
        }
    }
}

/// The CPU's cycle counter, read at the start and end of every odometry update for the
/// on-board cycle report (the board's `cycles` feature: DWT CYCCNT, a line over defmt every
/// second). The emulator and the plain board build have none ([`NoCycles`]), which costs
/// nothing.
pub trait CycleCounter {
    /// The free-running 32-bit cycle count now, or None without a counter.
    fn cycles(&mut self) -> Option<u32>;
    /// A second's updates, measured.
    fn report(&mut self, _cycles: &UpdateCycles) {}
}

/// No cycle counter.
pub struct NoCycles;

impl CycleCounter for NoCycles {
    fn cycles(&mut self) -> Option<u32> {
        None
    }
}

/// Cycles per odometry update, over the updates of about a second: from the tick's wake to
/// the frame published (sensors read, pose integrated, reports staged).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct UpdateCycles {
    pub updates: u32,
    pub min: u32,
    pub max: u32,
    pub total: u64,
}

impl UpdateCycles {
    pub fn add(&mut self, cycles: u32) {
        if self.updates == 0 || cycles < self.min {
            self.min = cycles;
        }
        self.max = self.max.max(cycles);
        self.total += cycles as u64;
        self.updates += 1;
    }

    /// Mean cycles per update.
    pub fn mean(&self) -> u32 {
        (self.total / self.updates.max(1) as u64) as u32
    }
}

#[cfg(test)]
mod tests {
    use super::{widen_us, UpdateCycles};

    #[test]
    fn a_queued_edge_time_is_made_whole_across_the_32_bit_wrap() {
        for edge in [0u64, 5, (1 << 32) - 3, 1 << 32, (7 << 32) + 123_456] {
            for age in [0u64, 1, 999, (1 << 32) - 1] {
                assert_eq!(widen_us(edge as u32, edge + age), edge, "{edge} {age}");
            }
        }
    }

    #[test]
    fn update_cycles_keep_the_fewest_the_most_and_the_mean() {
        let mut c = UpdateCycles::default();
        for k in [900, 700, 1_300, 1_100] {
            c.add(k);
        }
        assert_eq!((c.updates, c.min, c.max, c.mean()), (4, 700, 1_300, 1_000));
        assert_eq!(UpdateCycles::default().mean(), 0);
    }
}
