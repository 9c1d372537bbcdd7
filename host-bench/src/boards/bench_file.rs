//! `bench.toml`: which debug probe is which board's, the chip, the master's serial link and
//! optionally the images (docs/bench.md). Loading is strict: an unknown key or a value of the
//! wrong kind is an error naming the file, the line and the key, never silently ignored.

use std::fmt;
use std::io::Write;
use std::path::{Path, PathBuf};

use serde::Deserialize;

use super::selection::ProbeSpec;
use super::Board;

/// The chip both boards carry unless bench.toml or `--chip` says otherwise.
pub const DEFAULT_CHIP: &str = "STM32F103C8";
/// The master's USART1 link to the host runs at this rate unless bench.toml says otherwise.
pub const DEFAULT_BAUD: u32 = 115_200;

/// A loaded bench.toml. Paths in it are resolved against the file's own folder.
#[derive(Clone, Debug, PartialEq)]
pub struct BenchFile {
    /// Where it was read from.
    pub path: PathBuf,
    /// The probe-rs chip name (both boards).
    pub chip: String,
    pub slave: BoardEntry,
    pub master: BoardEntry,
    /// The master's serial link to the host, if configured.
    pub link: Option<SerialLink>,
}

/// One board's table in bench.toml.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct BoardEntry {
    pub probe: Option<ProbeSpec>,
    /// The image to flash, absolute (made so from the file's folder).
    pub image: Option<PathBuf>,
}

/// The `[link]` table: the serial port the master's USART1 is wired to.
#[derive(Clone, Debug, PartialEq)]
pub struct SerialLink {
    pub port: String,
    pub baud: u32,
}

impl BenchFile {
    pub fn board(&self, board: Board) -> &BoardEntry {
        match board {
            Board::Slave => &self.slave,
            Board::Master => &self.master,
        }
    }
}

/// A bench.toml that could not be used. `line` and `key` are there whenever known.
#[derive(Debug, Clone, PartialEq)]
pub struct BenchFileError {
    pub path: PathBuf,
    pub line: Option<usize>,
    pub key: Option<String>,
    pub message: String,
}

impl fmt::Display for BenchFileError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.path.display())?;
        if let Some(line) = self.line {
            write!(f, ":{line}")?;
        }
        if let Some(key) = &self.key {
            write!(f, ": key `{key}`")?;
        }
        write!(f, ": {}", self.message)
    }
}

impl std::error::Error for BenchFileError {}

// The file as written. Every table refuses keys it does not know.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawBench {
    chip: Option<String>,
    #[serde(default)]
    slave: RawBoard,
    #[serde(default)]
    master: RawBoard,
    link: Option<RawLink>,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct RawBoard {
    probe: Option<String>,
    image: Option<PathBuf>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawLink {
    port: String,
    baud: Option<u32>,
}

/// Reads and checks a bench.toml.
pub fn load(path: &Path) -> Result<BenchFile, BenchFileError> {
    let text = crate::formats::toml_file::read_bounded_text(path).map_err(|e| BenchFileError {
        path: path.to_path_buf(),
        line: None,
        key: None,
        message: format!("cannot read: {e}"),
    })?;
    parse(&text, path)
}

/// Checks bench.toml text; `path` names it in errors and anchors its relative image paths.
pub fn parse(text: &str, path: &Path) -> Result<BenchFile, BenchFileError> {
    let error = |offset: Option<usize>, key: Option<String>, message: String| BenchFileError {
        path: path.to_path_buf(),
        line: offset.map(|o| text[..o.min(text.len())].matches('\n').count() + 1),
        key,
        message,
    };
    let de = toml::Deserializer::parse(text)
        .map_err(|e| error(e.span().map(|s| s.start), None, e.message().to_string()))?;
    let raw: RawBench = serde_path_to_error::deserialize(de).map_err(|e| {
        let key = e.path().to_string();
        let inner = e.inner();
        error(
            inner.span().map(|s| s.start),
            (key != ".").then_some(key),
            inner.message().to_string(),
        )
    })?;
    // Values that parse as TOML but mean nothing: their key's line is found by searching,
    // since serde has dropped the spans by now.
    let line_of = |table: &str, key: &str| key_line(text, table, key);
    let chip = match raw.chip {
        Some(c) if c.trim().is_empty() => {
            return Err(BenchFileError {
                line: line_of("", "chip"),
                ..error(None, Some("chip".into()), "must not be empty".into())
            })
        }
        Some(c) => c.trim().to_string(),
        None => DEFAULT_CHIP.to_string(),
    };
    let folder = path.parent().unwrap_or(Path::new("."));
    let mut boards = Vec::new();
    for (board, raw_board) in [(Board::Slave, raw.slave), (Board::Master, raw.master)] {
        let probe = match raw_board.probe {
            None => None,
            Some(p) => Some(p.parse::<ProbeSpec>().map_err(|m| BenchFileError {
                line: line_of(board.name(), "probe"),
                ..error(None, Some(format!("{board}.probe")), m)
            })?),
        };
        let image = raw_board.image.map(|p| folder.join(p));
        boards.push(BoardEntry { probe, image });
    }
    let link = match raw.link {
        None => None,
        Some(l) => {
            if l.port.trim().is_empty() {
                return Err(BenchFileError {
                    line: line_of("link", "port"),
                    ..error(None, Some("link.port".into()), "must not be empty".into())
                });
            }
            let baud = l.baud.unwrap_or(DEFAULT_BAUD);
            if baud == 0 {
                return Err(BenchFileError {
                    line: line_of("link", "baud"),
                    ..error(None, Some("link.baud".into()), "must be > 0".into())
                });
            }
            Some(SerialLink { port: l.port, baud })
        }
    };
    let master = boards.pop().unwrap_or_default();
    let slave = boards.pop().unwrap_or_default();
    Ok(BenchFile {
        path: path.to_path_buf(),
        chip,
        slave,
        master,
        link,
    })
}

// The 1-based line where `key` is set inside `[table]` ("" for the top level).
fn key_line(text: &str, table: &str, key: &str) -> Option<usize> {
    let mut current = String::new();
    for (i, line) in text.lines().enumerate() {
        let trimmed = line.trim();
        if let Some(name) = trimmed.strip_prefix('[') {
            current = name.trim_end_matches(']').trim().to_string();
            continue;
        }
        let Some((k, _)) = trimmed.split_once('=') else {
            continue;
        };
        if current == table && k.trim().trim_matches('"') == key {
            return Some(i + 1);
        }
    }
    None
}

/// What `init-bench` writes: the guesses, each with the comment saying what to check.
#[derive(Clone, Debug, Default)]
pub struct BenchDraft {
    pub chip: String,
    pub slave_probe: Option<String>,
    pub master_probe: Option<String>,
    pub link_port: Option<String>,
    pub baud: u32,
}

/// TOML text for a draft, with comments a user can follow without the docs.
pub fn render(draft: &BenchDraft) -> String {
    // toml's own quoting, so a serial or path with quotes or backslashes stays valid TOML.
    let quote = |s: &str| toml::Value::String(s.to_string()).to_string();
    let probe_line = |board: Board, probe: &Option<String>| {
        match probe {
        Some(p) => format!("probe = {}\n", quote(p)),
        None => format!(
            "# probe = \"VID:PID:SERIAL\"   # not found: attach the {board}'s probe, run `host-bench probes`\n"
        ),
    }
    };
    let mut out = String::new();
    out.push_str(
        "# omnibench bench: which debug probe and serial port belong to which board.\n\
         # Format: docs/bench.md. Check each guess below before flashing.\n\n",
    );
    out.push_str(&format!(
        "# probe-rs chip name of both boards.\nchip = {}\n\n",
        quote(&draft.chip)
    ));
    out.push_str("[slave]   # odometry computer (firmware-slave)\n");
    out.push_str(&probe_line(Board::Slave, &draft.slave_probe));
    out.push_str(
        "# image = \"path/to/firmware-slave\"   # default: the workspace's release build\n\n",
    );
    out.push_str("[master]  # motion controller (firmware-master)\n");
    out.push_str(&probe_line(Board::Master, &draft.master_probe));
    out.push_str("# image = \"path/to/firmware-master\"\n\n");
    out.push_str("# The serial port wired to the master's USART1 (PA9 TX, PA10 RX).\n");
    match &draft.link_port {
        Some(port) => out.push_str(&format!(
            "[link]\nport = {}\nbaud = {}\n",
            quote(port),
            draft.baud
        )),
        None => out.push_str(&format!(
            "# [link]\n# port = \"/dev/ttyUSB0\"   # no USB serial port found\n# baud = {}\n",
            draft.baud
        )),
    }
    out
}

/// Writes `text` to `path` atomically (through [`crate::formats::atomic`], as every output:
/// never over a device, FIFO or folder, removed on Ctrl-C, the usual permissions). Refuses to
/// replace an existing file unless `force`.
pub fn write_atomically(path: &Path, text: &str, force: bool) -> Result<(), String> {
    if std::fs::symlink_metadata(path).is_ok() && !force {
        return Err(format!(
            "{} already exists; pass --force to replace it",
            path.display()
        ));
    }
    let write = |f: &mut std::fs::File| Ok(f.write_all(text.as_bytes())?);
    let put = if force {
        crate::formats::atomic::write_atomically(path, write)
    } else {
        // Another process creating the file meanwhile is not overwritten.
        crate::formats::atomic::write_new(path, write)
    };
    put.map_err(|e| format!("{e:#}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(text: &str) -> Result<BenchFile, BenchFileError> {
        parse(text, Path::new("/bench/bench.toml"))
    }

    #[test]
    fn a_full_file_loads_and_resolves_images_against_its_folder() {
        let b = p(
            "chip = \"STM32F103CB\"\n[slave]\nprobe = \"0483:3748:AB\"\nimage = \"s.elf\"\n\
                   [master]\nprobe = \"CD\"\n[link]\nport = \"/dev/ttyUSB0\"\nbaud = 230400\n",
        )
        .unwrap();
        assert_eq!(b.chip, "STM32F103CB");
        assert_eq!(b.slave.image.as_deref(), Some(Path::new("/bench/s.elf")));
        assert_eq!(b.master.probe, Some(ProbeSpec::Serial("CD".into())));
        assert_eq!(
            b.link,
            Some(SerialLink {
                port: "/dev/ttyUSB0".into(),
                baud: 230400
            })
        );
    }

    #[test]
    fn defaults_fill_what_is_left_out() {
        let b = p("[link]\nport = \"COM3\"\n").unwrap();
        assert_eq!(b.chip, DEFAULT_CHIP);
        assert_eq!(b.link.unwrap().baud, DEFAULT_BAUD);
        assert_eq!(b.slave, BoardEntry::default());
    }

    #[test]
    fn unknown_keys_are_refused_with_key_and_line() {
        let e =
            p("chip = \"STM32F103C8\"\n[slave]\nprobe = \"AB\"\nprobes = \"CD\"\n").unwrap_err();
        assert_eq!(e.line, Some(4), "{e}");
        assert!(e.to_string().contains("probes"), "{e}");
        let e = p("[master]\nimage = \"x\"\n\n[lnk]\nport = \"x\"\n").unwrap_err();
        assert_eq!(e.line, Some(4), "{e}");
        assert!(e.to_string().contains("lnk"), "{e}");
    }

    #[test]
    fn bad_values_name_their_key_and_line() {
        let e = p("[link]\nport = \"/dev/ttyUSB0\"\nbaud = \"fast\"\n").unwrap_err();
        assert_eq!(
            (e.line, e.key.as_deref()),
            (Some(3), Some("link.baud")),
            "{e}"
        );
        let e = p("\n[master]\nprobe = \"zz:12\"\n").unwrap_err();
        assert_eq!(
            (e.line, e.key.as_deref()),
            (Some(3), Some("master.probe")),
            "{e}"
        );
        let e = p("[link]\nport = \"x\"\nbaud = 0\n").unwrap_err();
        assert_eq!(e.line, Some(3), "{e}");
        let e = p("chip = \n").unwrap_err();
        assert_eq!(e.line, Some(1), "{e}");
    }

    #[test]
    fn a_rendered_draft_loads_back() {
        let draft = BenchDraft {
            chip: DEFAULT_CHIP.into(),
            slave_probe: Some("0483:3748:A\"B".into()),
            master_probe: None,
            link_port: Some("/dev/ttyACM0".into()),
            baud: DEFAULT_BAUD,
        };
        let b = p(&render(&draft)).unwrap();
        assert_eq!(
            b.slave.probe,
            Some(ProbeSpec::Usb {
                vid: 0x0483,
                pid: 0x3748,
                serial: Some("A\"B".into())
            })
        );
        assert_eq!(b.master.probe, None);
        assert_eq!(b.link.unwrap().port, "/dev/ttyACM0");
        let empty = BenchDraft {
            chip: DEFAULT_CHIP.into(),
            baud: DEFAULT_BAUD,
            ..BenchDraft::default()
        };
        assert_eq!(p(&render(&empty)).unwrap().link, None);
    }
}
