//! The panic handler both firmware images link (instead of `panic-probe`'s).
//!
//! It logs "panicked" over defmt and stops the core with a HardFault (`udf`), which makes
//! `probe-rs run` print a backtrace (file and line of every frame, from the debug info) and exit
//! with an error, just like `panic-probe`.
//!
//! It does not look at the `PanicInfo`, on purpose: flash. As soon as the handler reads the
//! panic's location or message, every panic site in the image (each bounds check, `RefCell`
//! borrow, `unwrap`) must build them, and `core::fmt` stays linked for the formatted ones;
//! measured on these images that is ~6.5 KB each (`panic-probe`'s `print-defmt` cost ~7 KB).
//! Panics raised through defmt (`defmt::panic!`, `defmt::unwrap!`, all of the board layers'
//! own checks) still log their full message, which defmt formats on the host.
//!
//! For a debugging session that wants the location and literal message in the log too, build
//! with `--features bluepill/panic-message` (the images then grow by those ~6.5 KB; the slave
//! may no longer fit 64 KiB).

use core::panic::PanicInfo;
use core::sync::atomic::{AtomicBool, Ordering};

#[panic_handler]
fn panic(info: &PanicInfo) -> ! {
    static PANICKED: AtomicBool = AtomicBool::new(false);

    cortex_m::interrupt::disable();
    // A panic while logging the first one must not recurse.
    if !PANICKED.swap(true, Ordering::Relaxed) {
        log(info);
    }
    hard_fault()
}

#[cfg(not(feature = "panic-message"))]
fn log(_: &PanicInfo) {
    defmt::error!("panicked (see the backtrace for where)");
}

#[cfg(feature = "panic-message")]
fn log(info: &PanicInfo) {
    match info.location() {
        Some(at) => defmt::error!("panicked at {=str}:{=u32}", at.file(), at.line()),
        None => defmt::error!("panicked"),
    }
    // Only literal messages: formatting the others would need `core::fmt`.
    if let Some(message) = info.message().as_str() {
        defmt::error!("{=str}", message);
    }
}

/// `defmt::panic!`, `defmt::unwrap!` and friends have already logged their message; without
/// this they would go through `core::panic!` into the handler above and log a second line.
#[defmt::panic_handler]
fn defmt_panic() -> ! {
    cortex_m::interrupt::disable();
    hard_fault()
}

/// Stop with a HardFault (`udf`), which the debug probe reports.
fn hard_fault() -> ! {
    // With UsageFault enabled, `udf` would raise that instead of HardFault: disable it first.
    // SAFETY: SHCSR is the System Handler Control and State Register of every Cortex-M3; only
    // its USGFAULTENA bit changes, with interrupts disabled.
    unsafe {
        let scb = &*cortex_m::peripheral::SCB::PTR;
        scb.shcsr.modify(|shcsr| shcsr & !(1 << 18));
    }
    cortex_m::asm::udf()
}
