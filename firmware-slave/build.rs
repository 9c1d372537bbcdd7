//! Linker scripts for the firmware image only.
//!
//! The same package also builds on the host (the portable library for the emulator and the
//! tests, plus a stub binary), where `link.x`/`defmt.x` do not exist; so the arguments are
//! emitted only for bare-metal targets, and only for the binary.

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-changed=../bluepill/image_opt_level.rs");
    println!("cargo:rerun-if-changed=board_rate.rs");
    if std::env::var("CARGO_CFG_TARGET_OS").as_deref() == Ok("none") {
        require_image_opt_level();
        write_board_period();
        // Sections are placed at fixed flash/RAM addresses; page-aligning them would waste flash.
        println!("cargo:rustc-link-arg-bins=--nmagic");
        // cortex-m-rt's linker script; it includes memory.x, which embassy-stm32's `memory-x`
        // feature provides.
        println!("cargo:rustc-link-arg-bins=-Tlink.x");
        // defmt's interned-string section.
        println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
        // Identical code folding: functions that compiled to the same machine code are kept
        // once (the panic entry points, the unused interrupt vectors, monomorphised copies).
        // The same instructions do the same thing; what is lost is only that two such
        // functions have different addresses, which neither image compares (a debugger's
        // backtrace may then name a folded twin: the panic entry points share one address).
        // -476 B slave, -508 B master (`llvm-size`).
        println!("cargo:rustc-link-arg-bins=--icf=all");
    }
}

/// The board's update period from `OMNIBENCH_SLAVE_RATE_HZ`, as `board_period.rs` in
/// `OUT_DIR` for `src/main.rs`; a rate the slave does not run at stops the build, naming it.
fn write_board_period() {
    println!("cargo:rerun-if-env-changed=OMNIBENCH_SLAVE_RATE_HZ");
    let setting = std::env::var("OMNIBENCH_SLAVE_RATE_HZ").ok();
    let period_us = board_period_us(setting.as_deref()).unwrap_or_else(|| {
        panic!(
            "OMNIBENCH_SLAVE_RATE_HZ={:?}: the slave's update rate is one of {BOARD_RATES_HZ:?} \
             Hz (unset: {DEFAULT_RATE_HZ})",
            setting.unwrap_or_default()
        )
    });
    let out = std::path::Path::new(&std::env::var("OUT_DIR").expect("cargo sets OUT_DIR"))
        .join("board_period.rs");
    std::fs::write(
        &out,
        format!(
            "/// The board's update period, µs (`OMNIBENCH_SLAVE_RATE_HZ` at build time).\n\
             pub const BOARD_PERIOD_US: u32 = {period_us};\n"
        ),
    )
    .unwrap_or_else(|e| panic!("cannot write {}: {e}", out.display()));
}

include!("../bluepill/image_opt_level.rs");
include!("board_rate.rs");
