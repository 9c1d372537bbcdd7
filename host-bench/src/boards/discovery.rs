//! What is attached to this computer: debug probes (through probe-rs) and serial ports
//! (through serialport, reading sysfs on Linux: no libudev needed).

use protocol::serial::usb as usb_ids;
use std::path::Path;

use probe_rs::probe::list::{Accessibility, Lister, ProbeListItem};
use serde::Serialize;

use super::selection::selector_text;

/// One debug probe as `host-bench probes --json` prints it.
#[derive(Clone, Debug, Serialize, PartialEq, Eq)]
pub struct ProbeEntry {
    /// The probe's product name (e.g. "STLink V2").
    pub name: String,
    /// USB vendor id, 4 hex digits.
    pub vid: String,
    /// USB product id, 4 hex digits.
    pub pid: String,
    /// USB serial number, if the probe reports one.
    pub serial: Option<String>,
    /// What to write in bench.toml or pass to `--slave-probe` to choose exactly this probe.
    pub selector: String,
    /// False when the probe is there but this user may not open it (missing udev rule).
    pub accessible: bool,
}

impl ProbeEntry {
    pub fn from_item(item: &ProbeListItem) -> Self {
        ProbeEntry {
            name: item.info.identifier.clone(),
            vid: format!("{:04x}", item.info.vendor_id),
            pid: format!("{:04x}", item.info.product_id),
            serial: item.info.serial_number.clone(),
            selector: selector_text(&item.info),
            accessible: item.accessibility == Accessibility::Accessible,
        }
    }
}

/// One serial port as `host-bench probes --json` prints it.
#[derive(Clone, Debug, Serialize, PartialEq, Eq)]
pub struct SerialPortEntry {
    /// The device to open, e.g. `/dev/ttyUSB0`.
    pub path: String,
    /// `usb`, `pci`, `bluetooth` or `unknown`.
    pub kind: String,
    pub vid: Option<String>,
    pub pid: Option<String>,
    pub manufacturer: Option<String>,
    pub product: Option<String>,
    pub serial: Option<String>,
    /// An omnibench master's own USB port (the `usb` image, CDC-ACM): its chip's unique ID,
    /// which is its USB serial number. `[link] port = "uid:ID"` in bench.toml names it.
    pub master_uid: Option<String>,
}

impl SerialPortEntry {
    pub fn is_usb(&self) -> bool {
        self.kind == "usb"
    }

    /// The chip ID of the omnibench master this is the USB port of, if it is one.
    fn omnibench_master(&self) -> Option<String> {
        let ids = (
            format!("{:04x}", usb_ids::VID),
            format!("{:04x}", usb_ids::PID),
        );
        let ours = self.vid.as_deref() == Some(ids.0.as_str())
            && self.pid.as_deref() == Some(ids.1.as_str())
            && self.product.as_deref() == Some(usb_ids::PRODUCT);
        ours.then(|| self.serial.clone()).flatten()
    }
}

/// The port `spec` names: a path as it is, or `uid:ID`, the USB port of the omnibench master
/// whose chip's unique ID (24 hex digits, as `host-bench probes` lists it) is ID.
pub fn resolve_port(spec: &str, ports: &[SerialPortEntry]) -> Result<String, String> {
    let Some(uid) = spec.strip_prefix("uid:") else {
        return Ok(spec.to_string());
    };
    let found: Vec<&SerialPortEntry> = ports
        .iter()
        .filter(|p| {
            p.master_uid
                .as_deref()
                .is_some_and(|u| u.eq_ignore_ascii_case(uid))
        })
        .collect();
    match found[..] {
        [one] => Ok(one.path.clone()),
        [] => Err(format!(
            "no omnibench master's USB port with chip ID {uid} is attached (`host-bench probes` \
             lists the ports; the master must run the image built with `--features usb`)"
        )),
        _ => Err(format!(
            "{} ports say they are the master with chip ID {uid}",
            found.len()
        )),
    }
}

/// Everything `host-bench probes` reports.
#[derive(Clone, Debug, Serialize, Default)]
pub struct Inventory {
    pub probes: Vec<ProbeEntry>,
    pub serial_ports: Vec<SerialPortEntry>,
    /// Problems met while looking (e.g. no /sys/class/tty); the lists above are then partial.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
}

/// Lists the attached debug probes (with whether this user may open them) and serial ports.
pub fn inventory(lister: &Lister) -> Inventory {
    let probes = lister.list_all_with_access();
    let (serial_ports, warnings) = match serial_ports() {
        Ok(ports) => (ports, Vec::new()),
        Err(e) => (Vec::new(), vec![e]),
    };
    Inventory {
        probes: probes.iter().map(ProbeEntry::from_item).collect(),
        serial_ports,
        warnings,
    }
}

/// The serial ports, sorted by path; USB ones carry their USB identity.
pub fn serial_ports() -> Result<Vec<SerialPortEntry>, String> {
    // serialport's sysfs scan (the no-libudev path) panics when /sys/class/tty is missing, as
    // in some containers; there is nothing to list then.
    if cfg!(target_os = "linux") && !Path::new("/sys/class/tty").is_dir() {
        return Ok(Vec::new());
    }
    let ports =
        serialport::available_ports().map_err(|e| format!("could not list serial ports: {e}"))?;
    let mut entries: Vec<SerialPortEntry> = ports
        .into_iter()
        .map(|port| {
            let mut entry = SerialPortEntry {
                path: port.port_name,
                kind: String::new(),
                vid: None,
                pid: None,
                manufacturer: None,
                product: None,
                serial: None,
                master_uid: None,
            };
            entry.kind = match port.port_type {
                serialport::SerialPortType::UsbPort(usb) => {
                    entry.vid = Some(format!("{:04x}", usb.vid));
                    entry.pid = Some(format!("{:04x}", usb.pid));
                    entry.manufacturer = usb.manufacturer;
                    entry.product = usb.product;
                    entry.serial = usb.serial_number;
                    "usb"
                }
                serialport::SerialPortType::PciPort => "pci",
                serialport::SerialPortType::BluetoothPort => "bluetooth",
                serialport::SerialPortType::Unknown => "unknown",
            }
            .to_string();
            entry.master_uid = entry.omnibench_master();
            entry
        })
        .collect();
    entries.sort_by(|a, b| a.path.cmp(&b.path));
    Ok(entries)
}

/// The human-readable listing `host-bench probes` prints.
pub fn inventory_text(inv: &Inventory) -> String {
    let mut out = String::new();
    if inv.probes.is_empty() {
        out.push_str("no probes found (debug probes: ST-Link, CMSIS-DAP, J-Link, ...)\n");
    } else {
        out.push_str("debug probes:\n");
        for p in &inv.probes {
            let access = if p.accessible {
                ""
            } else {
                "  (permission denied: install probe-rs' udev rules, see docs/bench.md)"
            };
            out.push_str(&format!(
                "  {:<40} {}:{}  serial {:<26} selector {}{access}\n",
                p.name,
                p.vid,
                p.pid,
                p.serial.as_deref().unwrap_or("(none)"),
                p.selector
            ));
        }
    }
    if inv.serial_ports.is_empty() {
        out.push_str("no serial ports found\n");
    } else {
        out.push_str("serial ports:\n");
        for s in &inv.serial_ports {
            let usb = if let Some(uid) = &s.master_uid {
                format!(
                    "  the omnibench master with chip ID {uid} (its own USB: port = \"uid:{uid}\")"
                )
            } else if s.is_usb() {
                format!(
                    "  usb {}:{}  {} {}  serial {}",
                    s.vid.as_deref().unwrap_or("?"),
                    s.pid.as_deref().unwrap_or("?"),
                    s.manufacturer.as_deref().unwrap_or("?"),
                    s.product.as_deref().unwrap_or("?"),
                    s.serial.as_deref().unwrap_or("(none)"),
                )
            } else {
                format!("  {}", s.kind)
            };
            out.push_str(&format!("  {:<20}{usb}\n", s.path));
        }
    }
    for w in &inv.warnings {
        out.push_str(&format!("warning: {w}\n"));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn port(path: &str, ids: (&str, &str), product: &str, serial: &str) -> SerialPortEntry {
        let mut p = SerialPortEntry {
            path: path.into(),
            kind: "usb".into(),
            vid: Some(ids.0.into()),
            pid: Some(ids.1.into()),
            manufacturer: Some("omnibench".into()),
            product: Some(product.into()),
            serial: Some(serial.into()),
            master_uid: None,
        };
        p.master_uid = p.omnibench_master();
        p
    }

    #[test]
    fn a_masters_own_usb_port_is_known_by_its_chip_id_and_named_by_it() {
        let uid = "35FF6D064E57363835391343";
        let ports = [
            port(
                "/dev/ttyUSB0",
                ("0403", "6001"),
                "FT232R USB UART",
                "A50285BI",
            ),
            port("/dev/ttyACM0", ("1209", "0001"), "omnibench master", uid),
            // Another device on pid.codes' test PID is not taken for a master.
            port("/dev/ttyACM1", ("1209", "0001"), "someone's gadget", "1234"),
        ];
        assert_eq!(ports[1].master_uid.as_deref(), Some(uid));
        assert!(ports[0].master_uid.is_none() && ports[2].master_uid.is_none());
        let lower = format!("uid:{}", uid.to_lowercase());
        assert_eq!(resolve_port(&lower, &ports).unwrap(), "/dev/ttyACM0");
        assert_eq!(
            resolve_port("/dev/ttyUSB0", &ports).unwrap(),
            "/dev/ttyUSB0"
        );
        let e = resolve_port("uid:0123", &ports).unwrap_err();
        assert!(
            e.contains("no omnibench master") && e.contains("--features usb"),
            "{e}"
        );
        let inv = Inventory {
            serial_ports: ports.to_vec(),
            ..Inventory::default()
        };
        let text = inventory_text(&inv);
        assert!(
            text.contains(&format!("the omnibench master with chip ID {uid}")),
            "{text}"
        );
    }
}
