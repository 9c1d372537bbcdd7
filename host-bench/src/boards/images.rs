//! Where each board's firmware image is, and whether the file there can be flashed.
//! `host-bench flash` builds nothing: a missing image is an error that says how to build it.

use std::path::{Path, PathBuf};

use super::Board;

/// The firmware's target triple (Cortex-M3, the STM32F103's core).
pub const FIRMWARE_TARGET: &str = "thumbv7m-none-eabi";

/// The largest image file read, bytes. A release ELF of either board with its debug info is
/// about 1-3 MB; a device or a stray huge file named by --*-elf is refused before reading.
pub const MAX_IMAGE_BYTES: u64 = 64 << 20;

/// An image file's bytes: a regular file of at most [`MAX_IMAGE_BYTES`].
pub fn read_image(path: &Path) -> std::io::Result<Vec<u8>> {
    crate::formats::bounded_file::read_bounded(path, MAX_IMAGE_BYTES, "a firmware image")
}

/// The command that builds one board's image, as the errors print it.
pub fn build_command(board: Board) -> String {
    format!(
        "cargo build --release --target {FIRMWARE_TARGET} -p {}",
        board.package()
    )
}

/// The Cargo target folder: `$CARGO_TARGET_DIR` if set (relative to `cwd`), else `target/`
/// in the workspace root found by walking up from `cwd`. None outside any workspace.
pub fn target_dir(cargo_target_dir: Option<&str>, cwd: &Path) -> Option<PathBuf> {
    if let Some(dir) = cargo_target_dir.filter(|d| !d.is_empty()) {
        return Some(cwd.join(dir));
    }
    workspace_root(cwd).map(|root| root.join("target"))
}

// The outermost folder from `start` upwards whose Cargo.toml has a [workspace] table (the
// outermost, as cargo does: a member's own Cargo.toml is no workspace root).
fn workspace_root(start: &Path) -> Option<PathBuf> {
    let mut found = None;
    for dir in start.ancestors() {
        let manifest = dir.join("Cargo.toml");
        if let Ok(text) = std::fs::read_to_string(&manifest) {
            if text.lines().any(|l| l.trim() == "[workspace]") {
                found = Some(dir.to_path_buf());
            }
        }
    }
    found
}

/// Where the release build of a board's image lands under `target_dir`.
pub fn default_image(target_dir: &Path, board: Board) -> PathBuf {
    target_dir
        .join(FIRMWARE_TARGET)
        .join("release")
        .join(board.package())
}

/// Checks that `path` is a 32-bit little-endian ARM ELF file: what a Cortex-M image is.
/// The error says what the file is instead, or how to build the image if it is missing.
pub fn check_image(board: Board, path: &Path, is_default: bool) -> Result<(), String> {
    let bytes = match read_image(path) {
        Ok(b) => b,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            return Err(if is_default {
                format!(
                    "the {board}'s firmware image is not built ({} does not exist); build it \
                     with `{}`, or pass --{board}-elf FILE",
                    path.display(),
                    build_command(board)
                )
            } else {
                format!("the {board}'s image {} does not exist", path.display())
            });
        }
        Err(e) => {
            return Err(format!(
                "cannot read the {board}'s image {}: {e}",
                path.display()
            ))
        }
    };
    const ELF_MAGIC: &[u8] = b"\x7fELF";
    const ELFCLASS32: u8 = 1;
    const ELFDATA2LSB: u8 = 1;
    const EM_ARM: u16 = 40;
    if bytes.len() < 20 || &bytes[..4] != ELF_MAGIC {
        return Err(format!(
            "the {board}'s image {} is not an ELF file (give the firmware binary cargo built, \
             not a .bin or .hex)",
            path.display()
        ));
    }
    let machine = u16::from_le_bytes([bytes[18], bytes[19]]);
    if bytes[4] != ELFCLASS32 || bytes[5] != ELFDATA2LSB || machine != EM_ARM {
        return Err(format!(
            "the {board}'s image {} is an ELF file for another machine (class {}, machine {}), \
             not for a 32-bit ARM Cortex-M; build it with `{}`",
            path.display(),
            bytes[4],
            machine,
            build_command(board)
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_target_dir_comes_from_the_environment_first() {
        let cwd = Path::new("/somewhere");
        assert_eq!(
            target_dir(Some("/t"), cwd),
            Some(PathBuf::from("/t")),
            "absolute"
        );
        assert_eq!(
            target_dir(Some("rel"), cwd),
            Some(PathBuf::from("/somewhere/rel"))
        );
    }

    #[test]
    fn the_workspace_root_is_found_from_a_member_folder() {
        let here = Path::new(env!("CARGO_MANIFEST_DIR"));
        let root = workspace_root(here).unwrap();
        assert!(root.join("firmware-slave").is_dir(), "{}", root.display());
        assert_eq!(
            default_image(&root.join("target"), Board::Master),
            root.join("target/thumbv7m-none-eabi/release/firmware-master")
        );
    }

    #[test]
    fn image_errors_say_what_to_do() {
        let dir = tempfile::tempdir().unwrap();
        let missing = dir.path().join("firmware-slave");
        let e = check_image(Board::Slave, &missing, true).unwrap_err();
        assert!(
            e.contains("cargo build --release --target thumbv7m-none-eabi -p firmware-slave"),
            "{e}"
        );
        let hex = dir.path().join("image.hex");
        std::fs::write(&hex, ":020000040800F2\n").unwrap();
        let e = check_image(Board::Master, &hex, false).unwrap_err();
        assert!(e.contains("not an ELF file"), "{e}");
        // The start of the host-bench test binary itself: an ELF header, but not for a
        // Cortex-M. (Only its start: the whole debug binary is past the 64 MiB an image may
        // be, which is checked first.)
        if cfg!(target_os = "linux") {
            let own = std::fs::read(std::env::current_exe().unwrap()).unwrap();
            let head = dir.path().join("host-elf");
            std::fs::write(&head, &own[..4096]).unwrap();
            let e = check_image(Board::Slave, &head, false).unwrap_err();
            assert!(e.contains("another machine"), "{e}");
        }
    }
}
