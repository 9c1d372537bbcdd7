//! Which attached debug probe belongs to which board.
//!
//! probe-rs selects a probe by `VID:PID[:SERIAL]`; a serial number alone is not a selector
//! there. Users mostly know the serial (it is what `host-bench probes` and the probe's label
//! show), so a [`ProbeSpec`] may be a bare serial and is resolved here, against the list of
//! attached probes, into the probe itself. Cheap clone ST-Links often report the same serial:
//! that is caught and reported instead of picking one at random.

use std::fmt;
use std::str::FromStr;

use probe_rs::probe::list::{Accessibility, ProbeListItem};
use probe_rs::probe::{DebugProbeInfo, DebugProbeSelector};

use super::Board;

/// How the user names a probe: `VID:PID`, `VID:PID:SERIAL` (hex ids), or a bare `SERIAL`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ProbeSpec {
    /// USB vendor and product id, and the serial number if given.
    Usb {
        vid: u16,
        pid: u16,
        serial: Option<String>,
    },
    /// A serial number alone; the probe's VID:PID is looked up among the attached probes.
    Serial(String),
}

impl FromStr for ProbeSpec {
    type Err = String;

    fn from_str(text: &str) -> Result<Self, String> {
        let text = text.trim();
        if text.is_empty() {
            return Err(
                "empty probe selector; expected VID:PID[:SERIAL] or a serial number".into(),
            );
        }
        let mut parts = text.splitn(3, ':');
        let first = parts.next().unwrap_or_default();
        let Some(second) = parts.next() else {
            // No colon: a bare serial number.
            return Ok(ProbeSpec::Serial(text.to_string()));
        };
        let parse_id = |what: &str, s: &str| {
            if s.is_empty() || s.len() > 4 {
                return Err(format!(
                    "probe selector {text:?}: {what} {s:?} is not 1-4 hex digits \
                     (expected VID:PID[:SERIAL], e.g. 0483:3748 or 0483:3748:066DFF50)"
                ));
            }
            u16::from_str_radix(s, 16).map_err(|_| {
                format!(
                    "probe selector {text:?}: {what} {s:?} is not hexadecimal \
                     (expected VID:PID[:SERIAL], e.g. 0483:3748 or 0483:3748:066DFF50)"
                )
            })
        };
        let vid = parse_id("vendor id", first)?;
        let pid = parse_id("product id", second)?;
        let serial = match parts.next() {
            None => None,
            Some("") => {
                return Err(format!(
                    "probe selector {text:?} ends in ':' with no serial number after it"
                ))
            }
            Some(s) => Some(s.to_string()),
        };
        Ok(ProbeSpec::Usb { vid, pid, serial })
    }
}

impl fmt::Display for ProbeSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ProbeSpec::Usb {
                vid,
                pid,
                serial: None,
            } => write!(f, "{vid:04x}:{pid:04x}"),
            ProbeSpec::Usb {
                vid,
                pid,
                serial: Some(s),
            } => write!(f, "{vid:04x}:{pid:04x}:{s}"),
            ProbeSpec::Serial(s) => write!(f, "serial {s}"),
        }
    }
}

impl ProbeSpec {
    fn matches(&self, info: &DebugProbeInfo) -> bool {
        let serial_is = |wanted: &str| info.serial_number.as_deref() == Some(wanted);
        match self {
            ProbeSpec::Usb { vid, pid, serial } => {
                info.vendor_id == *vid
                    && info.product_id == *pid
                    && serial.as_deref().is_none_or(serial_is)
            }
            ProbeSpec::Serial(s) => serial_is(s),
        }
    }
}

/// The full probe-rs selector (`VID:PID:SERIAL`, or `VID:PID` for a probe with no serial) that
/// opens exactly this probe.
pub fn selector_of(info: &DebugProbeInfo) -> DebugProbeSelector {
    DebugProbeSelector::from(info)
}

/// `VID:PID:SERIAL` as text, the form bench.toml and `--slave-probe` take.
pub fn selector_text(info: &DebugProbeInfo) -> String {
    match &info.serial_number {
        Some(s) => format!("{:04x}:{:04x}:{s}", info.vendor_id, info.product_id),
        None => format!("{:04x}:{:04x}", info.vendor_id, info.product_id),
    }
}

/// One line per attached probe, for error messages.
pub fn describe_attached(attached: &[ProbeListItem]) -> String {
    if attached.is_empty() {
        return "  (no debug probe attached)".to_string();
    }
    attached
        .iter()
        .map(|item| {
            let access = match item.accessibility {
                Accessibility::Accessible => "",
                Accessibility::PermissionDenied => " (permission denied)",
            };
            format!(
                "  {}  {}{access}",
                selector_text(&item.info),
                item.info.identifier
            )
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// Why no probe could be chosen for a board. Each message says what to do next.
#[derive(Debug, Clone, PartialEq)]
pub enum SelectError {
    /// Nothing attached at all.
    NoProbes,
    /// More probes than boards could be told apart without a selector.
    Ambiguous {
        board: Board,
        attached: Vec<ProbeListItem>,
    },
    /// Both boards asked, only one probe attached.
    TooFewProbes {
        wanted: usize,
        attached: Vec<ProbeListItem>,
    },
    /// The spec matches no attached probe.
    NotFound {
        board: Board,
        spec: ProbeSpec,
        attached: Vec<ProbeListItem>,
    },
    /// The spec matches several probes (shared serial numbers, or VID:PID without serial).
    NotUnique {
        board: Board,
        spec: ProbeSpec,
        matches: Vec<ProbeListItem>,
    },
    /// Both boards resolved to the same probe.
    SameProbe { probe: ProbeListItem },
    /// The probe is there but this user may not open it (Linux: missing udev rule).
    PermissionDenied { board: Board, probe: ProbeListItem },
}

/// Where probe-rs' udev rules live and how to install them (Linux).
pub const UDEV_HELP: &str = "install probe-rs' udev rules: save \
https://probe.rs/files/69-probe-rs.rules as /etc/udev/rules.d/69-probe-rs.rules, then run \
`sudo udevadm control --reload && sudo udevadm trigger`, make sure your user is in the \
`plugdev` group, and re-plug the probe";

impl fmt::Display for SelectError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SelectError::NoProbes => write!(
                f,
                "no debug probe found; `host-bench probes` lists what is attached"
            ),
            SelectError::Ambiguous { board, attached } => write!(
                f,
                "{} debug probes attached and none chosen for the {board}; pass \
                 --{board}-probe VID:PID[:SERIAL] (or a serial number), or set \
                 [{board}] probe in bench.toml (`host-bench init-bench` writes one). Attached:\n{}",
                attached.len(),
                describe_attached(attached)
            ),
            SelectError::TooFewProbes { wanted, attached } => write!(
                f,
                "{wanted} boards to flash but only {} debug probe attached; attach one probe \
                 per board, or flash one board with --slave or --master. Attached:\n{}",
                attached.len(),
                describe_attached(attached)
            ),
            SelectError::NotFound {
                board,
                spec,
                attached,
            } => write!(
                f,
                "the {board}'s probe ({spec}) is not attached. Attached:\n{}",
                describe_attached(attached)
            ),
            SelectError::NotUnique {
                board,
                spec,
                matches,
            } => {
                let hint = if matches!(spec, ProbeSpec::Usb { serial: None, .. }) {
                    "add the serial number: VID:PID:SERIAL"
                } else {
                    "their serial numbers are identical (clone ST-Links often share one); \
                     use VID:PID:SERIAL if their VID:PID differ, or replace one of them with a \
                     probe that has its own serial number"
                };
                write!(
                    f,
                    "the {board}'s probe ({spec}) matches {} attached probes, so it cannot \
                     pick one: {hint}. Matching:\n{}",
                    matches.len(),
                    describe_attached(matches)
                )
            }
            SelectError::SameProbe { probe } => write!(
                f,
                "the slave and the master both select the same probe ({}); give each board \
                 its own probe",
                selector_text(&probe.info)
            ),
            SelectError::PermissionDenied { board, probe } => write!(
                f,
                "permission denied opening the {board}'s probe {} ({}); {UDEV_HELP}",
                selector_text(&probe.info),
                probe.info.identifier
            ),
        }
    }
}

impl std::error::Error for SelectError {}

/// Resolves one spec against the attached probes: exactly one must match.
pub fn resolve(
    board: Board,
    spec: &ProbeSpec,
    attached: &[ProbeListItem],
) -> Result<ProbeListItem, SelectError> {
    let matches: Vec<ProbeListItem> = attached
        .iter()
        .filter(|item| spec.matches(&item.info))
        .cloned()
        .collect();
    match matches.as_slice() {
        [] if attached.is_empty() => Err(SelectError::NoProbes),
        [] => Err(SelectError::NotFound {
            board,
            spec: spec.clone(),
            attached: attached.to_vec(),
        }),
        [one] => Ok(one.clone()),
        _ => Err(SelectError::NotUnique {
            board,
            spec: spec.clone(),
            matches,
        }),
    }
}

/// Picks a probe for each wanted board.
///
/// A board with a spec gets the one probe that spec matches. A board without one gets the only
/// probe left over once the others are chosen — and only if exactly one is left, so that a
/// probe is never guessed among several. Every chosen probe must be openable by this user.
pub fn assign(
    wanted: &[(Board, Option<ProbeSpec>)],
    attached: &[ProbeListItem],
) -> Result<Vec<(Board, ProbeListItem)>, SelectError> {
    if attached.is_empty() {
        return Err(SelectError::NoProbes);
    }
    let mut chosen: Vec<(Board, Option<ProbeListItem>)> = Vec::new();
    for (board, spec) in wanted {
        let probe = match spec {
            Some(spec) => Some(resolve(*board, spec, attached)?),
            None => None,
        };
        chosen.push((*board, probe));
    }
    // Two boards resolving to one probe is a configuration mistake, not a choice to make.
    for (i, (_, a)) in chosen.iter().enumerate() {
        for (_, b) in chosen.iter().skip(i + 1) {
            if let (Some(a), Some(b)) = (a, b) {
                if a.info == b.info {
                    return Err(SelectError::SameProbe { probe: a.clone() });
                }
            }
        }
    }
    let unchosen: Vec<Board> = chosen
        .iter()
        .filter(|(_, p)| p.is_none())
        .map(|(b, _)| *b)
        .collect();
    if let Some(&first_unchosen) = unchosen.first() {
        let left: Vec<&ProbeListItem> = attached
            .iter()
            .filter(|item| {
                !chosen
                    .iter()
                    .any(|(_, p)| p.as_ref().is_some_and(|p| p.info == item.info))
            })
            .collect();
        match (unchosen.len(), left.as_slice()) {
            // Exactly one board and one probe left: that probe can only be this board's.
            (1, [only]) => {
                for (_, probe) in chosen.iter_mut().filter(|(_, p)| p.is_none()) {
                    *probe = Some((*only).clone());
                }
            }
            (n, left) if left.len() < n => {
                return Err(SelectError::TooFewProbes {
                    wanted: wanted.len(),
                    attached: attached.to_vec(),
                })
            }
            // More candidates than one board, or two boards and two probes: which probe is
            // wired to which board cannot be known from the USB side.
            _ => {
                return Err(SelectError::Ambiguous {
                    board: first_unchosen,
                    attached: attached.to_vec(),
                })
            }
        }
    }
    let mut out = Vec::new();
    for (board, probe) in chosen {
        let Some(probe) = probe else {
            return Err(SelectError::NoProbes);
        };
        if probe.accessibility == Accessibility::PermissionDenied {
            return Err(SelectError::PermissionDenied { board, probe });
        }
        out.push((board, probe));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn specs_parse_in_every_documented_form() {
        assert_eq!(
            "0483:3748".parse::<ProbeSpec>().unwrap(),
            ProbeSpec::Usb {
                vid: 0x0483,
                pid: 0x3748,
                serial: None
            }
        );
        assert_eq!(
            "0483:374b:066DFF:50".parse::<ProbeSpec>().unwrap(),
            ProbeSpec::Usb {
                vid: 0x0483,
                pid: 0x374b,
                serial: Some("066DFF:50".into())
            }
        );
        assert_eq!(
            "066DFF505055".parse::<ProbeSpec>().unwrap(),
            ProbeSpec::Serial("066DFF505055".into())
        );
        for bad in ["", "zz:3748", "0483:", "0483:3748:", "12345:1"] {
            assert!(bad.parse::<ProbeSpec>().is_err(), "{bad:?} accepted");
        }
    }
}
