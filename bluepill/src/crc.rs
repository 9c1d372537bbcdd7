//! The STM32F103's CRC unit as the images' CRC-32 engine (`protocol::crc32`): a word per store
//! instead of the `crc` crate's 1 KiB table, on both boards.
//!
//! Only thread-mode code (the tasks) checks frames today, and a task never yields inside a
//! checksum, so the unit is never shared. The busy flag makes that a fact rather than a
//! promise: should a checksum ever start while another runs (in an interrupt handler, say), it
//! takes the bit-by-bit engine instead of corrupting the unit's register. A flag, not a
//! mutex: embassy-sync's cost 100 B more of the slave's flash, and a critical section per
//! frame.

use core::sync::atomic::{AtomicU8, Ordering};
use embassy_stm32::crc::Crc;
use embassy_stm32::pac::CRC;
use protocol::crc32::{checksum_bitwise, checksum_by_words, WordCrcUnit};

const ABSENT: u8 = 0;
const IDLE: u8 = 1;
const BUSY: u8 = 2;
static UNIT: AtomicU8 = AtomicU8::new(ABSENT);

/// Give the CRC unit to the engine (board set-up; until then checksums are bit by bit).
/// `Crc::new` has clocked and reset it. Taking the driver by value is the proof that nothing
/// else drives the unit (it owns nothing else, and dropping it leaves the unit clocked); the
/// engine then works the unit's registers itself.
pub fn install(_unit: Crc<'static>) {
    UNIT.store(IDLE, Ordering::Release);
    // The catalogue's check value (CRC-32/ISO-HDLC of "123456789": two words and a tail byte)
    // through the unit, once: a part whose unit computes something else (a clone of the chip,
    // say) keeps the bit-by-bit engine instead of failing every frame.
    if omnibench_crc32(b"123456789") != 0xCBF4_3926 {
        UNIT.store(ABSENT, Ordering::Release);
        defmt::warn!("the CRC unit fails the check value: CRC-32 stays in software");
    }
}

/// The unit's registers, while this engine holds the busy flag.
struct Unit;

impl WordCrcUnit for Unit {
    fn reset(&mut self) {
        CRC.cr().write(|w| w.set_reset(true));
    }
    fn feed(&mut self, word: u32) {
        // A store while the unit still works on the previous word (4 cycles) waits.
        CRC.dr().write_value(word);
    }
    fn read(&mut self) -> u32 {
        CRC.dr().read()
    }
}

/// `protocol::crc32::checksum` on the boards.
#[no_mangle]
fn omnibench_crc32(bytes: &[u8]) -> u32 {
    if UNIT
        .compare_exchange(IDLE, BUSY, Ordering::Acquire, Ordering::Relaxed)
        .is_err()
    {
        return checksum_bitwise(bytes);
    }
    let crc = checksum_by_words(&mut Unit, bytes);
    UNIT.store(IDLE, Ordering::Release);
    crc
}
