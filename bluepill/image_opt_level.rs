// Shared by the build scripts of the images (`firmware-slave`, `firmware-master`, `m3-bench`),
// which `include!` it: one check, three packages (Cargo shares no code between build scripts
// without a crate of its own).

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
