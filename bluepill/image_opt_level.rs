// Shared by the build scripts of the images (`firmware-slave`, `firmware-master`, `m3-bench`),
// which `include!` it: one check, three packages (Cargo shares no code between build scripts
// without a crate of its own).

/// The image's optimisation level comes from `.cargo/config.toml`'s rustflags for the
/// target (`-C opt-level=z`; the release profile's 3 is the host's). What rustc uses is the
/// last level its flags name, so that is the one checked: an environment `RUSTFLAGS`
/// replaces the config's flags (the images would be built at 3 and outgrow their flash), and
/// `CARGO_TARGET_THUMBV7M_NONE_EABI_RUSTFLAGS` or `--config` add to them. Stop with what to
/// do instead. Another level on purpose (to measure one): `OMNIBENCH_IMAGE_OPT_LEVEL=s`.
fn require_image_opt_level() {
    println!("cargo:rerun-if-env-changed=OMNIBENCH_IMAGE_OPT_LEVEL");
    let wanted = std::env::var("OMNIBENCH_IMAGE_OPT_LEVEL").unwrap_or_else(|_| "z".into());
    let flags = std::env::var("CARGO_ENCODED_RUSTFLAGS").unwrap_or_default();
    let flags: Vec<&str> = flags.split('\x1f').collect();
    // Every spelling rustc takes: `-C opt-level=z`, `-Copt-level=z`, `--codegen opt-level=z`,
    // `--codegen=opt-level=z` (and `opt_level`), and `-O`, which is level 3.
    let mut level = None;
    for (i, flag) in flags.iter().enumerate() {
        let codegen = match *flag {
            "-C" | "--codegen" => flags.get(i + 1).copied(),
            "-O" => {
                level = Some("3");
                None
            }
            f => f
                .strip_prefix("-C")
                .or_else(|| f.strip_prefix("--codegen="))
                .filter(|rest| !rest.is_empty()),
        };
        if let Some(value) = codegen.and_then(|c| {
            c.strip_prefix("opt-level=")
                .or_else(|| c.strip_prefix("opt_level="))
        }) {
            level = Some(value);
        }
    }
    if level != Some(wanted.as_str()) {
        panic!(
            "the firmware image would be built at opt-level {}, not {wanted}: its level comes \
             from .cargo/config.toml's [target.thumbv7m-none-eabi] rustflags (-C opt-level=z), \
             which an environment RUSTFLAGS replaces and a build outside the workspace does not \
             read; unset RUSTFLAGS or add `-C opt-level=z` to it (another level on purpose: \
             OMNIBENCH_IMAGE_OPT_LEVEL=s)",
            level.unwrap_or("of the profile (3)")
        );
    }
}
