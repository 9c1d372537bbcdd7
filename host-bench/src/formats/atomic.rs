//! Files that appear whole or not at all.
//!
//! Every file the bench writes (tick streams, reports, tracks) goes through
//! [`write_atomically`]: the content is written to a temporary file in the target's own folder
//! (so the final rename never crosses a file system), flushed to disk, and only then renamed
//! over the target. If the writer fails or panics, the temporary file is deleted (by
//! [`tempfile::NamedTempFile`]'s drop) and an existing target is left untouched, so a reader
//! never sees a half-written file and nothing half-written is left behind. A command that
//! writes several files stages them ([`Staged`]) and renames them together at the end, so a
//! run that fails part way replaces none of them.
//!
//! A process stopped by a signal runs no drops, so the temporary files in the making are also
//! listed here, and [`remove_partials_on_signals`] (installed by `main`) deletes them on
//! Ctrl-C, SIGTERM or SIGHUP before the process exits. Only SIGKILL (or a power cut) can leave
//! a `.partial` file, and its name says what it is.

use std::fs::File;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Mutex, MutexGuard};

use anyhow::Context;

/// The temporary files being written now.
static PARTIALS: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// Output folders made for files still being written, deepest last: a run that fails or is
/// stopped by a signal removes them again (each only if empty).
static NEW_DIRS: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

fn new_dirs() -> MutexGuard<'static, Vec<PathBuf>> {
    NEW_DIRS.lock().unwrap_or_else(|e| e.into_inner())
}

fn remove_empty_dirs(dirs: &[PathBuf]) {
    for d in dirs.iter().rev() {
        let _ = std::fs::remove_dir(d); // fails, as it should, on a folder with files in it
    }
}

/// An output folder, made with any missing parents for files about to be written. Dropped
/// without [`keep`](Self::keep) (the run failed), or on a signal, what it made goes again.
pub struct OutputDir {
    made: Vec<PathBuf>,
}

impl OutputDir {
    pub fn create(dir: &Path) -> anyhow::Result<Self> {
        let mut made: Vec<PathBuf> = dir
            .ancestors()
            .take_while(|d| !d.as_os_str().is_empty() && !d.exists())
            .map(Path::to_path_buf)
            .collect();
        made.reverse();
        {
            // Listed before they exist: a signal between the two removes nothing it should not.
            let mut list = new_dirs();
            list.extend(made.iter().cloned());
            if let Err(e) = std::fs::create_dir_all(dir) {
                remove_empty_dirs(&made);
                list.retain(|d| !made.contains(d));
                return Err(e)
                    .with_context(|| format!("cannot create directory {}", dir.display()));
            }
        }
        Ok(OutputDir { made })
    }

    /// The run succeeded: the folders stay.
    pub fn keep(mut self) {
        let made = std::mem::take(&mut self.made);
        new_dirs().retain(|d| !made.contains(d));
    }
}

impl Drop for OutputDir {
    fn drop(&mut self) {
        if self.made.is_empty() {
            return;
        }
        let mut list = new_dirs();
        remove_empty_dirs(&self.made);
        list.retain(|d| !self.made.contains(d));
    }
}

/// How many [`OwnCtrlC`] guards are alive: while any is, Ctrl-C belongs to them.
static OWN_CTRL_C: AtomicUsize = AtomicUsize::new(0);

fn partials() -> MutexGuard<'static, Vec<PathBuf>> {
    PARTIALS.lock().unwrap_or_else(|e| e.into_inner())
}

/// Starts a thread that, on SIGINT, SIGTERM or SIGHUP, deletes every temporary file being
/// written and exits with 128 + the signal's number (the shell's convention). SIGINT is left
/// alone while an [`OwnCtrlC`] guard is alive.
pub fn remove_partials_on_signals() -> anyhow::Result<()> {
    use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
    let mut signals = signal_hook::iterator::Signals::new([SIGINT, SIGTERM, SIGHUP])
        .context("installing the signal handler")?;
    std::thread::spawn(move || {
        for signal in signals.forever() {
            if signal == SIGINT && OWN_CTRL_C.load(Ordering::SeqCst) > 0 {
                continue;
            }
            // Held to the exit: no new temporary file can appear after the sweep.
            let list = partials();
            for path in list.iter() {
                let _ = std::fs::remove_file(path);
            }
            remove_empty_dirs(&new_dirs());
            std::process::exit(128 + signal);
        }
    });
    Ok(())
}

/// A file in a folder of its own, both removed when it is dropped and, as the temporary files
/// being written are, by a signal: for a process that serves until it is killed
/// (`virtual-board`'s clock file).
pub struct ScratchFile {
    file: std::fs::File,
    path: PathBuf,
    dir: Option<tempfile::TempDir>,
}

impl ScratchFile {
    /// `NAME` in a new folder `PREFIX...` under the system's temporary folder, holding `bytes`.
    pub fn create(prefix: &str, name: &str, bytes: &[u8]) -> anyhow::Result<Self> {
        use std::io::Write;
        // Made and listed under the locks the signal's sweep takes (in its order), so a
        // signal finds both listed or neither made.
        let mut files = partials();
        let mut dirs = new_dirs();
        let dir = tempfile::Builder::new()
            .prefix(prefix)
            .tempdir()
            .context("cannot create a temporary folder")?;
        let path = dir.path().join(name);
        dirs.push(dir.path().to_path_buf());
        files.push(path.clone());
        let made = std::fs::File::create(&path).and_then(|mut f| f.write_all(bytes).map(|_| f));
        match made {
            Ok(file) => Ok(ScratchFile {
                file,
                path,
                dir: Some(dir),
            }),
            Err(e) => {
                files.retain(|p| *p != path);
                dirs.retain(|d| d != dir.path());
                Err(e).with_context(|| format!("cannot write {}", path.display()))
            }
        }
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    pub fn file(&self) -> &std::fs::File {
        &self.file
    }
}

impl Drop for ScratchFile {
    fn drop(&mut self) {
        // Removed first, then no longer the signal's: a signal between finds nothing to do.
        if let Some(dir) = self.dir.take() {
            let gone = dir.path().to_path_buf();
            let _ = dir.close();
            partials().retain(|p| *p != self.path);
            new_dirs().retain(|d| *d != gone);
        }
    }
}

/// While alive, Ctrl-C does not end the process: its owner (`record`, which stops and then
/// writes its file) watches a flag of its own instead.
pub struct OwnCtrlC(());

impl OwnCtrlC {
    pub fn take() -> Self {
        OWN_CTRL_C.fetch_add(1, Ordering::SeqCst);
        OwnCtrlC(())
    }
}

impl Drop for OwnCtrlC {
    fn drop(&mut self) {
        OWN_CTRL_C.fetch_sub(1, Ordering::SeqCst);
    }
}

/// Checks that `path` can take an output file: it is a regular file (replaced) or nothing yet,
/// in a folder that exists. The rename would otherwise put a file where a device, a FIFO or a
/// folder was (`record --out /dev/null`, as root, replaced /dev/null). Callers that write
/// several files, or work a long time first, call it on each before they start.
pub fn check_output(path: &Path) -> anyhow::Result<()> {
    // `x.csv/` names a folder: the rename would fail only after all the work, and say so
    // about a temporary file.
    if path
        .as_os_str()
        .to_string_lossy()
        .ends_with(std::path::MAIN_SEPARATOR)
    {
        anyhow::bail!(
            "cannot write {}: the name ends in {}, a folder's; name a file",
            path.display(),
            std::path::MAIN_SEPARATOR
        );
    }
    match std::fs::symlink_metadata(path) {
        Ok(m) if m.file_type().is_file() => {}
        Ok(m) => anyhow::bail!(
            "cannot write {}: it exists and is not a regular file (a {}); name a new file or a \
             regular one to replace",
            path.display(),
            if m.is_dir() {
                "folder"
            } else if m.file_type().is_symlink() {
                "symbolic link"
            } else {
                "device, FIFO or socket"
            }
        ),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
        Err(e) => anyhow::bail!("cannot write {}: {e}", path.display()),
    }
    let folder = folder_of(path);
    if !folder.is_dir() {
        anyhow::bail!(
            "cannot write {}: its folder {} does not exist",
            path.display(),
            folder.display()
        );
    }
    Ok(())
}

/// Refuses outputs that are one of the run's `inputs` (what each is, and its path), compared
/// as canonical paths (an output not there yet is no input). `flag` names the option.
pub fn refuse_inputs(
    flag: &str,
    outputs: &[PathBuf],
    inputs: &[(&str, &Path)],
) -> anyhow::Result<()> {
    for file in outputs {
        let Ok(canonical) = file.canonicalize() else {
            continue;
        };
        for (what, input) in inputs {
            if input.canonicalize().is_ok_and(|i| i == canonical) {
                anyhow::bail!(
                    "{flag}: {} is {what} ({}): the run would write over its own input",
                    file.display(),
                    input.display()
                );
            }
        }
    }
    Ok(())
}

/// Takes a temporary file off the list when the write is over, whichever way it ended.
struct Listed(Option<PathBuf>);

impl Drop for Listed {
    fn drop(&mut self) {
        if let Some(path) = self.0.take() {
            partials().retain(|p| *p != path);
        }
    }
}

/// Writes `path` through `write`, atomically: `write` gets a temporary file in the same
/// folder, which is synced and renamed to `path` only if `write` returns `Ok`.
///
/// The temporary file is named `.NAME.XXXXXX.partial` (hidden, and recognisable as unfinished
/// should the process be killed outright). Errors name `path`.
pub fn write_atomically<T>(
    path: &Path,
    write: impl FnOnce(&mut File) -> anyhow::Result<T>,
) -> anyhow::Result<T> {
    let (tmp, _listed, value) = write_temporary(path, write)?;
    rename(tmp, path)?;
    Ok(value)
}

/// [`write_atomically`] that will not replace a file: one made at `path` meanwhile (by another
/// process) is left alone and this fails (`init-bench` without `--force`).
pub fn write_new(
    path: &Path,
    write: impl FnOnce(&mut File) -> anyhow::Result<()>,
) -> anyhow::Result<()> {
    let (tmp, _listed, ()) = write_temporary(path, write)?;
    tmp.persist_noclobber(path).map_err(|e| {
        anyhow::Error::new(e.error)
            .context(format!("cannot write {} (it exists now)", path.display()))
    })
}

/// `write` into a synced temporary file beside `path`, listed for the signal handler; the
/// caller renames it (or drops it, which deletes it, then the listing).
fn write_temporary<T>(
    path: &Path,
    write: impl FnOnce(&mut File) -> anyhow::Result<T>,
) -> anyhow::Result<(tempfile::TempPath, Listed, T)> {
    let (mut tmp, listed) = create_temporary(path)?;
    let value = write(tmp.as_file_mut())
        .and_then(|value| {
            tmp.as_file().sync_all()?;
            Ok(value)
        })
        .with_context(|| format!("cannot write {}", path.display()))?;
    // Closed: a run staging hundreds of files holds no descriptor for each.
    Ok((tmp.into_temp_path(), listed, value))
}

/// An empty temporary file beside `path`, listed for the signal handler.
fn create_temporary(path: &Path) -> anyhow::Result<(tempfile::NamedTempFile, Listed)> {
    check_output(path)?;
    let folder = folder_of(path);
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
    // Declared before the file, so dropped after it: the file is gone before it is unlisted.
    let mut listed = Listed(None);
    let tmp = {
        // Created and listed under the lock: a signal cannot fall between the two.
        let mut list = partials();
        let tmp = builder.tempfile_in(folder).with_context(|| {
            format!(
                "cannot write {}: cannot create a temporary file in {}",
                path.display(),
                folder.display()
            )
        })?;
        list.push(tmp.path().to_path_buf());
        listed.0 = Some(tmp.path().to_path_buf());
        tmp
    };
    Ok((tmp, listed))
}

/// A file written as a run goes (an MCAP file fed message by message), into its temporary
/// file beside `path`; [`Partial::persist`] syncs it and renames it into place. Dropped
/// before that (the run failed), or on a signal, it is deleted.
pub struct Partial {
    // Before `listed`: the file is gone before it is unlisted.
    tmp: tempfile::NamedTempFile,
    _listed: Listed,
    path: PathBuf,
}

impl Partial {
    pub fn create(path: &Path) -> anyhow::Result<Self> {
        let (tmp, listed) = create_temporary(path)?;
        Ok(Partial {
            tmp,
            _listed: listed,
            path: path.to_path_buf(),
        })
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Synced and renamed over its path.
    pub fn persist(self) -> anyhow::Result<()> {
        let Partial { tmp, _listed, path } = self;
        tmp.as_file()
            .sync_all()
            .with_context(|| format!("cannot write {}", path.display()))?;
        rename(tmp.into_temp_path(), &path)
    }
}

impl std::io::Write for Partial {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.tmp.write(buf)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.tmp.flush()
    }
}

impl std::io::Seek for Partial {
    fn seek(&mut self, pos: std::io::SeekFrom) -> std::io::Result<u64> {
        self.tmp.seek(pos)
    }
}

fn rename(tmp: tempfile::TempPath, path: &Path) -> anyhow::Result<()> {
    tmp.persist(path).map_err(|e| {
        anyhow::Error::new(e.error).context(format!(
            "cannot rename {} to {}",
            e.path.display(),
            path.display()
        ))
    })
}

/// Several files written whole now and renamed into place together by [`commit`]: a run that
/// writes more than one file, and fails (or is stopped) part way, replaces none of them. Each
/// is written to its temporary file as it is ready (no file's content waits in memory for the
/// others); dropped without `commit`, they are deleted.
///
/// [`commit`]: Staged::commit
#[derive(Default)]
pub struct Staged {
    files: Vec<(tempfile::TempPath, Listed, PathBuf)>,
}

impl Staged {
    /// Writes `path`'s content through `write` to its temporary file, as [`write_atomically`]
    /// does, without the rename.
    pub fn write(
        &mut self,
        path: &Path,
        write: impl FnOnce(&mut File) -> anyhow::Result<()>,
    ) -> anyhow::Result<()> {
        // Twice the same name: the first would be lost without a word.
        if self.files.iter().any(|(_, _, p)| p == path) {
            anyhow::bail!("{} is written twice in one run", path.display());
        }
        let (tmp, listed, ()) = write_temporary(path, write)?;
        self.files.push((tmp, listed, path.to_path_buf()));
        Ok(())
    }

    /// Renames every file into place, in the order written, as one step: a signal that comes
    /// meanwhile waits for the last rename (the handler takes the list's lock before it
    /// sweeps and exits), and a rename that fails puts back what the renames before it
    /// replaced. Either every file is new or every file is as it was.
    pub fn commit(self) -> anyhow::Result<()> {
        let mut list = partials();
        let mut files = self.files;
        // Unlisted here, under the lock we hold (their own drop would take it again).
        for (_, listed, _) in &mut files {
            if let Some(p) = listed.0.take() {
                list.retain(|q| *q != p);
            }
        }
        // Each file being replaced, kept under a second name until all renames are done.
        let mut previous = Vec::new();
        for (_, _, path) in &files {
            previous.push(keep_aside(path)?);
        }
        let mut renamed: Vec<(PathBuf, Option<tempfile::TempPath>)> = Vec::new();
        let mut previous = previous.into_iter();
        for (tmp, _, path) in files {
            let aside = previous.next().flatten();
            if let Err(e) = rename(tmp, &path) {
                // Back as they were: the renamed ones get their previous file (or go). A
                // previous file that cannot be put back keeps its second name, and says so.
                let mut stranded = Vec::new();
                for (path, aside) in renamed.into_iter().rev() {
                    match aside {
                        Some(a) => {
                            if let Err(failed) = a.persist(&path) {
                                if let Ok(kept) = failed.path.keep() {
                                    stranded.push(format!(
                                        "the previous {} is kept as {}",
                                        path.display(),
                                        kept.display()
                                    ));
                                }
                            }
                        }
                        None => {
                            let _ = std::fs::remove_file(&path);
                        }
                    }
                }
                if stranded.is_empty() {
                    return Err(e);
                }
                return Err(e.context(stranded.join("; ")));
            }
            renamed.push((path, aside));
        }
        // The previous files' second names go before the lock does: a signal's exit must
        // not leave them.
        drop(renamed);
        drop(list);
        Ok(())
    }
}

/// The folder `path` is in (`.` for a bare name).
fn folder_of(path: &Path) -> &Path {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    }
}

/// A second name (a hard link, `.NAME.XXXXXX.previous`, beside it) for the file at `path`, if
/// there is one: removed when dropped, renamed back over `path` to restore it.
fn keep_aside(path: &Path) -> anyhow::Result<Option<tempfile::TempPath>> {
    // What is there itself (a symbolic link is kept as a link), if anything but a folder.
    match std::fs::symlink_metadata(path) {
        Ok(m) if !m.is_dir() => {}
        _ => return Ok(None),
    }
    let folder = folder_of(path);
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy())
        .unwrap_or_default();
    let link = tempfile::Builder::new()
        .prefix(&format!(".{name}."))
        .suffix(".previous")
        // A file system without hard links (FAT on a USB stick), or one the kernel will not
        // link for this user (protected_hardlinks): a copy does as well for putting it back.
        .make_in(folder, |aside| {
            std::fs::hard_link(path, aside).or_else(|_| std::fs::copy(path, aside).map(|_| ()))
        })
        .with_context(|| format!("cannot keep the previous {} aside", path.display()))?;
    Ok(Some(link.into_temp_path()))
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
        assert!(
            chain.contains("its folder") && chain.contains("does not exist"),
            "{chain}"
        );
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

    #[test]
    fn staged_files_appear_only_on_commit_and_are_gone_if_dropped() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("a.csv"), dir.path().join("b.csv"));
        std::fs::write(&a, "old\n").unwrap();
        let mut staged = Staged::default();
        staged.write(&a, |f| Ok(f.write_all(b"new a\n")?)).unwrap();
        staged.write(&b, |f| Ok(f.write_all(b"new b\n")?)).unwrap();
        assert_eq!(std::fs::read_to_string(&a).unwrap(), "old\n");
        assert_eq!(entries(dir.path()).len(), 3, "{:?}", entries(dir.path()));
        drop(staged);
        assert_eq!(entries(dir.path()), ["a.csv"]);
        assert_eq!(std::fs::read_to_string(&a).unwrap(), "old\n");

        let mut staged = Staged::default();
        staged.write(&a, |f| Ok(f.write_all(b"new a\n")?)).unwrap();
        staged.write(&b, |f| Ok(f.write_all(b"new b\n")?)).unwrap();
        staged.commit().unwrap();
        assert_eq!(entries(dir.path()), ["a.csv", "b.csv"]);
        assert_eq!(std::fs::read_to_string(&b).unwrap(), "new b\n");
    }

    #[test]
    fn a_name_staged_twice_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let a = dir.path().join("a.csv");
        let mut staged = Staged::default();
        staged.write(&a, |f| Ok(f.write_all(b"1\n")?)).unwrap();
        let e = staged.write(&a, |f| Ok(f.write_all(b"2\n")?)).unwrap_err();
        assert!(format!("{e:#}").contains("twice"), "{e:#}");
    }

    #[test]
    fn a_rename_that_fails_puts_back_the_files_renamed_before_it() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b, c) = (
            dir.path().join("a.csv"),
            dir.path().join("b.csv"),
            dir.path().join("c.csv"),
        );
        std::fs::write(&a, "old a\n").unwrap();
        let mut staged = Staged::default();
        for p in [&a, &b, &c] {
            staged.write(p, |f| Ok(f.write_all(b"new\n")?)).unwrap();
        }
        // c.csv becomes a folder with a file in it after staging: its rename fails.
        std::fs::create_dir(&c).unwrap();
        std::fs::write(c.join("x"), "").unwrap();
        let e = staged.commit().unwrap_err();
        assert!(format!("{e:#}").contains("c.csv"), "{e:#}");
        // a.csv as it was, b.csv (new) gone again, no temporary or second name left.
        assert_eq!(std::fs::read_to_string(&a).unwrap(), "old a\n");
        assert_eq!(entries(dir.path()), ["a.csv", "c.csv"]);
    }
}
