//! Linker scripts for the QEMU image only: on the host the binary is a stub.

use std::path::PathBuf;

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-changed=../bluepill/image_opt_level.rs");
    println!("cargo:rerun-if-changed=memory.x");
    if std::env::var("CARGO_CFG_TARGET_OS").as_deref() == Ok("none") {
        require_image_opt_level();
        // cortex-m-rt's link.x includes memory.x from the search path: the machine's, put there.
        let out = PathBuf::from(std::env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
        std::fs::copy("memory.x", out.join("memory.x")).expect("memory.x copies");
        println!("cargo:rustc-link-search={}", out.display());
        println!("cargo:rustc-link-arg-bins=--nmagic");
        println!("cargo:rustc-link-arg-bins=-Tlink.x");
    }
}

include!("../bluepill/image_opt_level.rs");
