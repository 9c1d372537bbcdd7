//! Files that appear whole or not at all.
//!
//! Every file the bench writes (tick streams, reports, tracks) goes through
//! [`write_atomically`]: the content is written to a temporary file in the target's own folder
//! (so the final rename never crosses a file system), flushed to disk, and only then renamed
//! over the target. If the writer fails or panics, the temporary file is deleted (by
//! [`tempfile::NamedTempFile`]'s drop) and an existing target is left untouched, so a reader
//! never sees a half-written file and nothing half-written is left behind.

use std::fs::File;
use std::path::Path;

use anyhow::Context;

/// Writes `path` through `write`, atomically: `write` gets a temporary file in the same
/// folder, which is synced and renamed to `path` only if `write` returns `Ok`.
///
/// The temporary file is named `.NAME.XXXXXX.partial` (hidden, and recognisable as unfinished
/// should the process be killed outright). Errors name `path`.
pub fn write_atomically<T>(
    path: &Path,
    write: impl FnOnce(&mut File) -> anyhow::Result<T>,
) -> anyhow::Result<T> {
    let folder = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let name = path
        .file_name()
        .with_context(|| format!("cannot write {}: not a file name", path.display()))?;
    let mut builder = tempfile::Builder::new();
    let prefix = format!(".{}.", name.to_string_lossy());
    builder.prefix(&prefix).suffix(".partial");
    // NamedTempFile's default is owner-only (0600); an output file gets the permissions
    // `File::create` would give it (0666 less the umask).
    #[cfg(unix)]
    builder.permissions(std::os::unix::fs::PermissionsExt::from_mode(0o666));
    let mut tmp = builder.tempfile_in(folder).with_context(|| {
        format!(
            "cannot write {}: cannot create a temporary file in {}",
            path.display(),
            folder.display()
        )
    })?;
    let value = write(tmp.as_file_mut())
        .and_then(|value| {
            tmp.as_file().sync_all()?;
            Ok(value)
        })
        .with_context(|| format!("cannot write {}", path.display()))?;
    tmp.persist(path).map_err(|e| {
        anyhow::Error::new(e.error).context(format!(
            "cannot rename {} to {}",
            e.file.path().display(),
            path.display()
        ))
    })?;
    Ok(value)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    fn entries(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }

    #[test]
    fn a_successful_write_leaves_only_the_target() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.csv");
        let n = write_atomically(&path, |f| Ok(f.write(b"a,b\n")?)).unwrap();
        assert_eq!(n, 4);
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "a,b\n");
        assert_eq!(entries(dir.path()), ["out.csv"]);
    }

    #[test]
    fn a_failing_writer_leaves_neither_the_target_nor_a_temporary_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.csv");
        let err = write_atomically(&path, |f| -> anyhow::Result<()> {
            f.write_all(b"half of it")?;
            anyhow::bail!("the writer gave up")
        })
        .unwrap_err();
        let chain = format!("{err:#}");
        assert!(chain.contains("the writer gave up"), "{chain}");
        assert!(chain.contains(&path.display().to_string()), "{chain}");
        assert!(entries(dir.path()).is_empty(), "{:?}", entries(dir.path()));
    }

    #[test]
    fn a_failing_writer_keeps_the_previous_file_as_it_was() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.csv");
        std::fs::write(&path, "old\n").unwrap();
        let _ = write_atomically(&path, |f| -> anyhow::Result<()> {
            f.write_all(b"new, but not finished")?;
            anyhow::bail!("interrupted")
        })
        .unwrap_err();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "old\n");
        assert_eq!(entries(dir.path()), ["out.csv"]);
    }

    #[test]
    fn a_panicking_writer_leaves_nothing_behind() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.csv");
        let panicked = std::panic::catch_unwind(|| {
            let _ = write_atomically(&path, |f| -> anyhow::Result<()> {
                f.write_all(b"half of it").unwrap();
                panic!("the writer panicked");
            });
        });
        assert!(panicked.is_err());
        assert!(entries(dir.path()).is_empty(), "{:?}", entries(dir.path()));
    }

    #[test]
    fn a_missing_folder_is_named_in_the_error() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("no/such/out.csv");
        let err = write_atomically(&path, |_| Ok(())).unwrap_err();
        let chain = format!("{err:#}");
        assert!(chain.contains("no/such/out.csv"), "{chain}");
        assert!(chain.contains("temporary file in"), "{chain}");
    }

    #[cfg(unix)]
    #[test]
    fn the_file_gets_the_usual_permissions_not_owner_only() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.csv");
        write_atomically(&path, |_| Ok(())).unwrap();
        let plain = dir.path().join("plain.csv");
        File::create(&plain).unwrap();
        let mode = |p: &Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode(&path), mode(&plain));
    }
}
