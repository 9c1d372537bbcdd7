//! The QEMU image: every case between a begin marker of its own and the common end marker,
//! then a semihosting exit.
//!
//! The markers are functions the script finds by name in QEMU's execution log (`-d exec` names
//! the function of every instruction). Each writes its own number to a volatile static, so the
//! linker cannot fold two of them into one symbol.

use core::ptr::{addr_of_mut, write_volatile};

use cortex_m_rt::entry;
use cortex_m_semihosting::debug;

use m3_bench::{self as cases, Case, Meter};

static mut MARK: u32 = 0;

macro_rules! markers {
    ($($case:ident => $name:ident = $n:literal),* $(,)?) => {
        $(
            #[no_mangle]
            #[inline(never)]
            extern "C" fn $name() {
                // SAFETY: one thread; the value is never read, only kept by `volatile`.
                unsafe { write_volatile(addr_of_mut!(MARK), $n) }
            }
        )*
        fn begin(case: Case) {
            match case {
                $(Case::$case => $name(),)*
            }
        }
    };
}

markers! {
    Empty => m3b_begin_empty = 1,
    ExactEdge => m3b_begin_exact_edge = 2,
    ExactEdgePlacing => m3b_begin_exact_edge_placing = 3,
    ExactTicksUpdate => m3b_begin_exact_ticks_update = 4,
    ExactCountsUpdate => m3b_begin_exact_counts_update = 5,
    Omni3Edge => m3b_begin_omni3_edge = 6,
    Omni3TicksUpdate => m3b_begin_omni3_ticks_update = 7,
    Omni3CountsUpdate => m3b_begin_omni3_counts_update = 8,
}

#[no_mangle]
#[inline(never)]
extern "C" fn m3b_end() {
    // SAFETY: as in the begin markers.
    unsafe { write_volatile(addr_of_mut!(MARK), 0) }
}

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

struct Markers;

impl Meter for Markers {
    #[inline(never)]
    fn measure(&mut self, case: Case, call: &mut dyn FnMut()) {
        begin(case);
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
