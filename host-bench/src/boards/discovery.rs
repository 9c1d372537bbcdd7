//! What is attached to this computer: debug probes (through probe-rs) and serial ports
//! (through serialport, reading sysfs on Linux: no libudev needed).

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
}

impl SerialPortEntry {
    pub fn is_usb(&self) -> bool {
        self.kind == "usb"
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
            let usb = if s.is_usb() {
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
