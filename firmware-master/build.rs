//! Linker scripts for the firmware image only.
//!
//! The same package also builds on the host (the portable library for the emulator and the
//! tests, plus a stub binary), where `link.x`/`defmt.x` do not exist; so the arguments are
//! emitted only for bare-metal targets, and only for the binary.

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    if std::env::var("CARGO_CFG_TARGET_OS").as_deref() == Ok("none") {
        require_image_opt_level();
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
        // functions have different addresses, which neither image compares. -476 B slave,
        // -508 B master (`llvm-size`).
        println!("cargo:rustc-link-arg-bins=--icf=all");
    }
}

/// The image's optimisation level comes from `.cargo/config.toml`'s rustflags for the
/// target (`-C opt-level=z`; the release profile's 3 is the host's). An environment
/// `RUSTFLAGS` replaces those, and the image would then be built at 3 and outgrow its flash:
/// stop with what to do instead.
fn require_image_opt_level() {
    let flags = std::env::var("CARGO_ENCODED_RUSTFLAGS").unwrap_or_default();
    let flags: Vec<&str> = flags.split('\x1f').collect();
    let set = flags
        .windows(2)
        .any(|w| w[0] == "-C" && w[1].starts_with("opt-level="))
        || flags.iter().any(|f| f.starts_with("-Copt-level="));
    if !set {
        panic!(
            "the firmware image's opt-level comes from .cargo/config.toml's \
             [target.thumbv7m-none-eabi] rustflags (-C opt-level=z), and they are not in effect \
             (RUSTFLAGS in the environment replaces them, and a build outside the workspace \
             does not read them): add `-C opt-level=z` to RUSTFLAGS, or unset it"
        );
    }
}
