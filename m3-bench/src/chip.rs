//! The QEMU image: each measured call between the common markers `m3b_begin` and `m3b_end`,
//! after a label naming its case; then a semihosting exit.
//!
//! The script finds the markers and labels by name in QEMU's execution log (`-d exec` names
//! the function of every instruction) and counts the instructions from `m3b_begin` to
//! `m3b_end`, so every call is counted from the same code whatever its case (the label's own
//! instructions come before `m3b_begin`). Each marker and label writes its own number to a
//! volatile static, so the linker cannot fold two of them into one symbol.

use core::ptr::{addr_of_mut, write_volatile};

use cortex_m_rt::entry;
use cortex_m_semihosting::debug;

use m3_bench::{self as cases, Case, Meter};

static mut MARK: u32 = 0;

macro_rules! marker {
    ($name:ident = $n:literal) => {
        #[no_mangle]
        #[inline(never)]
        extern "C" fn $name() {
            // SAFETY: one thread; the value is never read, only kept by `volatile`.
            unsafe { write_volatile(addr_of_mut!(MARK), $n) }
        }
    };
}

macro_rules! labels {
    ($($case:ident => $name:ident = $n:literal),* $(,)?) => {
        $(marker!($name = $n);)*
        fn label(case: Case) {
            match case {
                $(Case::$case => $name(),)*
            }
        }
    };
}

labels! {
    Empty => m3b_case_empty = 1,
    ExactEdge => m3b_case_exact_edge = 2,
    ExactEdgePlacing => m3b_case_exact_edge_placing = 3,
    ExactTicksUpdate => m3b_case_exact_ticks_update = 4,
    ExactCountsUpdate => m3b_case_exact_counts_update = 5,
    Omni3Edge => m3b_case_omni3_edge = 6,
    Omni3TicksUpdate => m3b_case_omni3_ticks_update = 7,
    Omni3CountsUpdate => m3b_case_omni3_counts_update = 8,
    SpiSlaveBuild => m3b_case_spi_slave_build = 9,
    SpiSlaveParse => m3b_case_spi_slave_parse = 10,
    SpiMasterBuild => m3b_case_spi_master_build = 11,
    SpiMasterParse => m3b_case_spi_master_parse = 12,
    Crc32Table => m3b_case_crc32_table = 14,
    Crc32Unit => m3b_case_crc32_unit = 15,
    MasterControlStep => m3b_case_master_control_step = 13,
}
marker!(m3b_begin = 100);
marker!(m3b_end = 0);

/// cortex-m-rt's `device` feature is on (through firmware-slave's board dependencies, which
/// Cargo gives its library too), so the link wants a device's interrupt vectors. The F103's
/// would drag in its HAL; QEMU raises no interrupt here, so one entry that stops the run does.
#[link_section = ".vector_table.interrupts"]
#[no_mangle]
#[used]
static __INTERRUPTS: [unsafe extern "C" fn(); 1] = [unexpected_interrupt];

unsafe extern "C" fn unexpected_interrupt() {
    debug::exit(debug::EXIT_FAILURE);
}

/// `protocol::crc32::checksum` here: the `crc` crate's one-table form, which the boards ran
/// before they took their STM32's CRC unit (QEMU's Cortex-M3 has none). The SPI frame cases
/// therefore count a table CRC, ~7 instructions a byte, where the boards store a word per 4
/// bytes: their frames cost less on the chip than these counts.
#[no_mangle]
fn omnibench_crc32(bytes: &[u8]) -> u32 {
    const TABLE: crc::Crc<u32, crc::Table<1>> =
        crc::Crc::<u32, crc::Table<1>>::new(&crc::CRC_32_ISO_HDLC);
    TABLE.checksum(bytes)
}

struct Markers;

impl Meter for Markers {
    #[inline(never)]
    fn measure(&mut self, case: Case, call: &mut dyn FnMut()) {
        label(case);
        m3b_begin();
        call();
        m3b_end();
    }
}

#[entry]
fn main() -> ! {
    cases::run(&mut Markers);
    debug::exit(debug::EXIT_SUCCESS);
    // Semihosting ends the run; without a host to end it, sleep.
    loop {
        cortex_m::asm::wfi();
    }
}

#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    debug::exit(debug::EXIT_FAILURE);
    loop {
        cortex_m::asm::wfi();
    }
}
