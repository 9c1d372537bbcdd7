//! USB-serial adapters hold the bytes they receive until a USB packet fills or a latency
//! timer runs out. FTDI's timer defaults to 16 ms, so a command and its answer can take
//! 30 ms and a play's acknowledgements arrive in bursts. Linux exposes the timer as
//! `/sys/bus/usb-serial/devices/ttyUSBn/latency_timer`: lowered to 1 ms where this user may
//! write it (root, or a udev rule; docs/bench.md), and said so either way.

use std::path::Path;

/// What was done about `port`'s latency timer under the sysfs root `sys` (`/sys`), or `None`
/// for a port with no such timer (a pseudo-terminal, an adapter without one, not Linux).
pub fn lower(port: &str, sys: &Path) -> Option<String> {
    // /dev/ttyUSB0, or a by-id link to it.
    let real = std::fs::canonicalize(port).unwrap_or_else(|_| port.into());
    let name = real.file_name()?.to_str()?.to_string();
    let timer = sys
        .join("bus/usb-serial/devices")
        .join(&name)
        .join("latency_timer");
    let now: u32 = std::fs::read_to_string(&timer).ok()?.trim().parse().ok()?;
    if now <= 1 {
        return Some(format!("{name}'s latency timer is {now} ms"));
    }
    Some(match std::fs::write(&timer, "1") {
        Ok(()) => format!("{name}'s latency timer lowered from {now} ms to 1 ms"),
        Err(e) => format!(
            "{name}'s latency timer is {now} ms and could not be lowered ({e}): bytes may wait \
             that long in the adapter; as root: echo 1 > {}",
            timer.display()
        ),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_timer_is_lowered_to_one_millisecond_where_there_is_one() {
        let sys = tempfile::tempdir().unwrap();
        let dir = sys.path().join("bus/usb-serial/devices/ttyUSB7");
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("latency_timer"), "16\n").unwrap();
        let note = lower("/dev/ttyUSB7", sys.path()).unwrap();
        assert!(note.contains("lowered from 16 ms to 1 ms"), "{note}");
        assert_eq!(
            std::fs::read_to_string(dir.join("latency_timer")).unwrap(),
            "1"
        );
        assert!(lower("/dev/ttyUSB7", sys.path())
            .unwrap()
            .contains("is 1 ms"));
        // No timer: nothing to say (a pseudo-terminal, a CDC-ACM port).
        assert_eq!(lower("/dev/pts/3", sys.path()), None);
        assert_eq!(lower("/dev/ttyACM0", sys.path()), None);
    }
}
