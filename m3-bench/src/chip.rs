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

// The boards' memory copy and clear and their 64-bit division (`bluepill`'s), so the cases
// count what the boards run, and checked here on a Cortex-M3 before anything is measured.
// Included by path: this image links `firmware-slave`'s library, not `bluepill` (were the
// library ever to use `bluepill`, the symbols would be defined twice and the link would say
// so).
#[path = "../../bluepill/src/divide.rs"]
mod divide;
#[path = "../../bluepill/src/mem.rs"]
mod mem;

extern "C" {
    fn __aeabi_memcpy(dest: *mut u8, src: *const u8, n: usize);
    fn __aeabi_memcpy4(dest: *mut u8, src: *const u8, n: usize);
    fn __aeabi_memclr(dest: *mut u8, n: usize);
    fn __aeabi_memclr4(dest: *mut u8, n: usize);
    fn __aeabi_memset(dest: *mut u8, n: usize, byte: i32);
}

/// Every routine of [`mem`] on every length to 40 B from and to every offset in a word its
/// contract allows (the `4` forms word-aligned), inside guarded buffers: the bytes it was to
/// write are what a volatile byte loop computes, and no byte around them changed. A failure
/// stops the run (the script then fails): a case's count would mean nothing on a wrong copy.
fn check_mem() {
    const N: usize = 64;
    let pattern = |k: usize| (k as u8).wrapping_mul(37).wrapping_add(11);
    // (routine, aligned only, reads a source): memcpy, memcpy4, memclr, memclr4, memset.
    let routines = [
        (0, false, true),
        (1, true, true),
        (2, false, false),
        (3, true, false),
        (4, false, false),
    ];
    for (routine, aligned, copies) in routines {
        for (to, from) in (0..16).map(|k| (k / 4, k % 4)) {
            if (aligned && to + from != 0) || (!copies && from != 0) {
                continue;
            }
            for n in 0..=40 {
                let mut src = [0u32; N / 4];
                let mut dst = [0u32; N / 4];
                let (s, d) = (src.as_mut_ptr() as *mut u8, dst.as_mut_ptr() as *mut u8);
                // SAFETY: every access is inside the two N-byte buffers (4 + 3 + 40 < N).
                unsafe {
                    for k in 0..N {
                        write_volatile(s.add(k), pattern(k));
                        write_volatile(d.add(k), 0xa5);
                    }
                    let (at, src_at) = (d.add(4 + to), s.add(4 + from) as *const u8);
                    match routine {
                        0 => __aeabi_memcpy(at, src_at, n),
                        1 => __aeabi_memcpy4(at, src_at, n),
                        2 => __aeabi_memclr(at, n),
                        3 => __aeabi_memclr4(at, n),
                        _ => __aeabi_memset(at, n, 0x3c),
                    }
                    for k in 0..N {
                        if core::ptr::read_volatile(s.add(k)) != pattern(k) {
                            debug::exit(debug::EXIT_FAILURE);
                        }
                        let want = match routine {
                            _ if !(4 + to..4 + to + n).contains(&k) => 0xa5,
                            0 | 1 => pattern(k - to + from),
                            2 | 3 => 0,
                            _ => 0x3c,
                        };
                        if core::ptr::read_volatile(d.add(k)) != want {
                            debug::exit(debug::EXIT_FAILURE);
                        }
                    }
                }
            }
        }
    }
}

/// 64-bit division through the EABI's calls on numbers for every path of [`divide`]: both
/// within 32 bits, a 32-bit divisor (at every normalising shift) under a wider dividend, a
/// wider divisor, a divisor above the dividend, even and odd. The operands and each result
/// pass through `black_box`, so the compiler can neither fold a division nor derive one result
/// from another (it had turned the remainder into `n - q·d`); then the quotient times the
/// divisor plus the remainder must give the dividend back (multiplication does not divide),
/// the remainder must be below the divisor, with the dividend's sign. A failure stops the run.
fn check_divide() {
    use core::hint::black_box;
    let mut x = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        x
    };
    for k in 0..4000u32 {
        let (a, b, shift) = (next(), next(), k / 4 % 32);
        let (n, d) = match k % 4 {
            0 => (a >> 32, b >> (32 + shift)),
            1 => (a | 1 << 63 >> shift, b >> (32 + shift)),
            2 => (a, b >> shift),
            _ => (a >> (k / 4 % 64), b >> (k / 16 % 64)),
        };
        let d = d.max(1);
        let (q, r) = (
            black_box(black_box(n) / black_box(d)),
            black_box(black_box(n) % black_box(d)),
        );
        let unsigned_ok = q.checked_mul(d).and_then(|p| p.checked_add(r)) == Some(n) && r < d;
        let (sa, sb) = (n as i64, d as i64);
        let signed_ok = (sa == i64::MIN && sb == -1) || {
            let sq = black_box(black_box(sa) / black_box(sb));
            let sr = black_box(black_box(sa) % black_box(sb));
            sq.checked_mul(sb).and_then(|p| p.checked_add(sr)) == Some(sa)
                && sr.unsigned_abs() < sb.unsigned_abs()
                && (sr == 0 || (sr < 0) == (sa < 0))
        };
        if !(unsigned_ok && signed_ok) {
            debug::exit(debug::EXIT_FAILURE);
        }
    }
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
    check_mem();
    check_divide();
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
