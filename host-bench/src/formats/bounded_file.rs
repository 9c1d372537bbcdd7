//! Reading a whole file only when it is a regular file of bounded size.
//!
//! A path the user gives may name a device (`/dev/zero`), a FIFO, or a file of gigabytes.
//! Such a file is refused before it is read. The check is made on the opened handle, not on
//! the path beforehand, so nothing can be swapped in between; the open itself does not block
//! (a FIFO without a writer would otherwise wait forever in `open`).

use std::fs::File;
use std::io::{self, Read};
use std::path::Path;

/// Opens `path` for reading if it is a regular file.
pub fn open_regular(path: &Path) -> io::Result<File> {
    let mut options = std::fs::OpenOptions::new();
    options.read(true);
    #[cfg(unix)]
    std::os::unix::fs::OpenOptionsExt::custom_flags(&mut options, libc::O_NONBLOCK);
    let file = options.open(path)?;
    if !file.metadata()?.is_file() {
        return Err(io::Error::other(
            "not a regular file (a folder, device or pipe)",
        ));
    }
    Ok(file)
}

/// Opens `path` for streaming: a regular file, or a pipe (`<(zcat run.csv.gz)`). The open does
/// not block, so a FIFO that no program writes to reads as empty instead of hanging.
pub fn open_stream(path: &Path) -> io::Result<File> {
    let mut options = std::fs::OpenOptions::new();
    options.read(true);
    #[cfg(unix)]
    {
        use std::os::fd::AsRawFd;
        std::os::unix::fs::OpenOptionsExt::custom_flags(&mut options, libc::O_NONBLOCK);
        let file = options.open(path)?;
        // Reads block again (a pipe's writer may be slow); with no writer they end at once.
        // SAFETY: F_GETFL/F_SETFL on a descriptor this function owns.
        unsafe {
            let fd = file.as_raw_fd();
            let flags = libc::fcntl(fd, libc::F_GETFL);
            if flags < 0 || libc::fcntl(fd, libc::F_SETFL, flags & !libc::O_NONBLOCK) < 0 {
                return Err(io::Error::last_os_error());
            }
        }
        Ok(file)
    }
    #[cfg(not(unix))]
    options.open(path)
}

/// The bytes of the regular file `path`, at most `max` of them: a larger file is refused
/// (`what` says what the file should have been), and one that grows while read stops at the
/// bound. A missing file keeps its `NotFound` kind.
pub fn read_bounded(path: &Path, max: u64, what: &str) -> io::Result<Vec<u8>> {
    let file = open_regular(path)?;
    let too_big = || io::Error::other(format!("larger than {} KiB: not {what}", max >> 10));
    let len = file.metadata()?.len();
    if len > max {
        return Err(too_big());
    }
    let mut bytes = Vec::with_capacity(len as usize);
    file.take(max + 1).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > max {
        return Err(too_big());
    }
    Ok(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn devices_folders_and_large_files_are_refused_before_reading() {
        let dir = tempfile::tempdir().unwrap();
        let err = |p: &Path| {
            read_bounded(p, 1024, "a test file")
                .unwrap_err()
                .to_string()
        };
        assert!(err(Path::new("/dev/zero")).contains("not a regular file"));
        assert!(err(dir.path()).contains("not a regular file"));
        let big = dir.path().join("big");
        std::fs::write(&big, vec![b'x'; 1025]).unwrap();
        assert_eq!(err(&big), "larger than 1 KiB: not a test file");
        std::fs::write(&big, b"ok").unwrap();
        assert_eq!(read_bounded(&big, 1024, "a test file").unwrap(), b"ok");
        let missing = read_bounded(&dir.path().join("nope"), 1024, "x").unwrap_err();
        assert_eq!(missing.kind(), io::ErrorKind::NotFound);
    }

    /// A FIFO no program writes to: as a description file it is refused, as a stream it
    /// reads as empty; neither open waits for a writer.
    #[cfg(unix)]
    #[test]
    fn a_fifo_without_a_writer_is_refused_or_read_empty_without_blocking() {
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("fifo");
        let made = std::process::Command::new("mkfifo").arg(&fifo).status();
        assert!(made.unwrap().success());
        let e = read_bounded(&fifo, 1024, "x").unwrap_err().to_string();
        assert!(e.contains("not a regular file"), "{e}");
        let mut text = String::new();
        let mut stream = open_stream(&fifo).unwrap();
        stream.read_to_string(&mut text).unwrap();
        assert_eq!(text, "");
    }
}
