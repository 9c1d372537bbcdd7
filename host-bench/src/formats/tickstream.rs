//! Tick stream files, format version 1: see `docs/tick-stream.md`.
//!
//! A tick stream is a CSV file (optionally gzip-compressed) that starts with the magic comment
//! [`MAGIC`], may name a robot description with a `# robot: PATH` comment, and then lists
//! time-ordered encoder events (`tick`, `abs`) and ground-truth poses (`truth`).
//!
//! The reader is a streaming, line-oriented parser written for this format rather than the
//! `csv` crate: comments must be kept (the `# robot:` line, generator parameters) and every
//! error must name the physical line of the file, comment and blank lines included. Each
//! record is one physical line; fields may be double-quoted (as spreadsheets sometimes do) but
//! cannot contain line breaks. Reading reuses one line buffer and one field-index buffer, so
//! the only allocation that grows with the file is the events vector.

use std::fmt;
use std::fs::File;
use std::io::{self, BufRead, BufReader, BufWriter, Read, Write};
use std::path::{Path, PathBuf};

use anyhow::{bail, Context};

use super::atomic::write_atomically;
use flate2::read::MultiGzDecoder;
use flate2::write::GzEncoder;
use flate2::Compression;

/// The first line of every version 1 tick stream (trailing whitespace is tolerated).
pub const MAGIC: &str = "# omnibench tick stream v1";

/// The part of [`MAGIC`] before the version number.
const MAGIC_PREFIX: &str = "# omnibench tick stream v";

/// The required columns, in the order the writer puts them.
pub const COLUMNS: [&str; 7] = ["t_ns", "kind", "id", "value", "x_m", "y_m", "theta_rad"];

const T_NS: usize = 0;
const KIND: usize = 1;
const ID: usize = 2;
const VALUE: usize = 3;
const X_M: usize = 4;
const Y_M: usize = 5;
const THETA_RAD: usize = 6;

/// Longest line the reader accepts, in bytes (a guard against reading a huge binary file
/// into one line).
pub const MAX_LINE_BYTES: usize = 1 << 20;

const GZIP_MAGIC: [u8; 2] = [0x1f, 0x8b];
const UTF8_BOM: &[u8] = b"\xef\xbb\xbf";
const READ_BUFFER_BYTES: usize = 64 * 1024;
const WRITE_BUFFER_BYTES: usize = 256 * 1024;

/// One row of a tick stream.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Event {
    /// An incremental encoder moved by one count; `step` is +1 (the wheel rolled along its
    /// rolling direction) or -1. `encoder` indexes the robot's `[[encoders]]`.
    Tick { t_ns: u64, encoder: u16, step: i8 },
    /// An absolute encoder read `code` (raw, as the sensor outputs it). `encoder` indexes the
    /// robot's `[[absolute_encoders]]`.
    Abs { t_ns: u64, encoder: u16, code: u32 },
    /// The true pose of the body reference point in the field frame (metres, radians CCW).
    Truth {
        t_ns: u64,
        x_m: f64,
        y_m: f64,
        theta_rad: f64,
    },
}

impl Event {
    /// When the event happened, nanoseconds from the start of the stream.
    pub fn t_ns(&self) -> u64 {
        match *self {
            Event::Tick { t_ns, .. } | Event::Abs { t_ns, .. } | Event::Truth { t_ns, .. } => t_ns,
        }
    }
}

/// A whole tick stream file in memory.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TickStream {
    /// The `# robot:` path as written in the file (relative), if any.
    pub robot: Option<String>,
    /// Other comment lines after the magic line (without the leading "# "), kept in order.
    pub comments: Vec<String>,
    pub events: Vec<Event>,
}

impl TickStream {
    /// The robot path resolved against the directory of `stream_path`.
    pub fn robot_path(&self, stream_path: &Path) -> Option<PathBuf> {
        let robot = self.robot.as_deref()?;
        let dir = stream_path.parent().unwrap_or_else(|| Path::new(""));
        Some(dir.join(robot))
    }
}

/// Why a tick stream could not be read: the file, the 1-based physical line (comment and
/// blank lines count) when the problem is on a line, and what is wrong.
/// Displays as `path:LINE: message`, or `path: message` without a line.
#[derive(Debug)]
pub struct ReadError {
    pub path: PathBuf,
    pub line: Option<u64>,
    pub message: String,
}

impl fmt::Display for ReadError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.line {
            Some(line) => write!(f, "{}:{}: {}", self.path.display(), line, self.message),
            None => write!(f, "{}: {}", self.path.display(), self.message),
        }
    }
}

impl std::error::Error for ReadError {}

/// Reads a tick stream file; gzip-compressed if its name ends in `.gz` or its data starts with
/// the gzip magic bytes.
pub fn read(path: &Path) -> Result<TickStream, ReadError> {
    let file = File::open(path).map_err(|e| ReadError {
        path: path.to_path_buf(),
        line: None,
        message: format!("cannot open: {e}"),
    })?;
    let mut input = BufReader::with_capacity(READ_BUFFER_BYTES, file);
    let head = input.fill_buf().map_err(|e| ReadError {
        path: path.to_path_buf(),
        line: None,
        message: format!("cannot read: {e}"),
    })?;
    let gzip_data = head.starts_with(&GZIP_MAGIC);
    if is_gz_name(path) && !gzip_data && !head.is_empty() {
        return Err(ReadError {
            path: path.to_path_buf(),
            line: None,
            message: "the name ends in .gz but the data is not gzip-compressed \
                      (it does not start with the bytes 1f 8b)"
                .into(),
        });
    }
    if gzip_data {
        let decoder = MultiGzDecoder::new(input);
        parse(BufReader::with_capacity(READ_BUFFER_BYTES, decoder), path)
    } else {
        parse(input, path)
    }
}

/// Reads a tick stream from plain text (gzip data is recognised by its magic bytes and
/// decompressed too); `name_for_errors` is the name error messages show.
pub fn read_from(reader: impl Read, name_for_errors: &Path) -> Result<TickStream, ReadError> {
    let mut input = BufReader::with_capacity(READ_BUFFER_BYTES, reader);
    let head = input.fill_buf().map_err(|e| ReadError {
        path: name_for_errors.to_path_buf(),
        line: None,
        message: format!("cannot read: {e}"),
    })?;
    if head.starts_with(&GZIP_MAGIC) {
        let decoder = MultiGzDecoder::new(input);
        parse(
            BufReader::with_capacity(READ_BUFFER_BYTES, decoder),
            name_for_errors,
        )
    } else {
        parse(input, name_for_errors)
    }
}

fn is_gz_name(path: &Path) -> bool {
    path.extension().is_some_and(|e| e == "gz")
}

/// Column positions found in the header.
struct Header {
    /// Field index of each of [`COLUMNS`].
    index: [usize; 7],
    /// How many fields the header has; every row must have as many.
    fields: usize,
    line: u64,
}

/// The line-by-line parser's state.
struct Parser<'a> {
    path: &'a Path,
    line_no: u64,
}

impl Parser<'_> {
    fn error(&self, message: impl Into<String>) -> ReadError {
        ReadError {
            path: self.path.to_path_buf(),
            line: Some(self.line_no),
            message: message.into(),
        }
    }
}

fn parse(mut input: impl BufRead, path: &Path) -> Result<TickStream, ReadError> {
    let mut p = Parser { path, line_no: 0 };
    let mut stream = TickStream::default();
    let mut line: Vec<u8> = Vec::with_capacity(256);
    let mut fields: Vec<(usize, usize)> = Vec::with_capacity(16);
    let mut header: Option<Header> = None;
    let mut robot_line: Option<u64> = None;
    let mut last_t: Option<(u64, u64)> = None; // (t_ns, line)

    loop {
        line.clear();
        let n = (&mut input)
            .take(MAX_LINE_BYTES as u64 + 1)
            .read_until(b'\n', &mut line)
            .map_err(|e| ReadError {
                path: path.to_path_buf(),
                line: Some(p.line_no + 1),
                message: format!("read error: {e}"),
            })?;
        if n == 0 {
            break;
        }
        p.line_no += 1;
        let mut end = line.len();
        if line[end - 1] == b'\n' {
            end -= 1;
        } else if end > MAX_LINE_BYTES {
            return Err(p.error(format!(
                "line is longer than {MAX_LINE_BYTES} bytes (is this a tick stream?)"
            )));
        }
        if end > 0 && line[end - 1] == b'\r' {
            end -= 1;
        }
        let mut start = 0;
        if p.line_no == 1 && line[..end].starts_with(UTF8_BOM) {
            start = UTF8_BOM.len();
        }
        let bytes = &line[start..end];
        if p.line_no == 1 && bytes.starts_with(&GZIP_MAGIC) {
            return Err(p.error(
                "missing magic line: the data looks gzip-compressed but was read as plain text",
            ));
        }
        let text = std::str::from_utf8(bytes).map_err(|e| {
            p.error(format!(
                "not valid UTF-8 (bad byte at column {})",
                e.valid_up_to() + 1
            ))
        })?;

        if p.line_no == 1 {
            check_magic(&p, text)?;
            continue;
        }

        let trimmed = text.trim_start();
        if let Some(comment) = trimmed.strip_prefix('#') {
            // Spreadsheets pad every row to the same number of cells: ignore trailing commas.
            let comment = comment.trim_end_matches(|c: char| c == ',' || c.is_whitespace());
            if let Some(robot) = comment.trim_start().strip_prefix("robot:") {
                if let Some(first) = robot_line {
                    return Err(p.error(format!(
                        "second `# robot:` line (the first is line {first}); a stream names \
                         at most one robot"
                    )));
                }
                let robot = robot.trim();
                if robot.is_empty() {
                    return Err(p.error("`# robot:` line without a path"));
                }
                robot_line = Some(p.line_no);
                stream.robot = Some(robot.to_string());
            } else {
                let comment = comment.strip_prefix(' ').unwrap_or(comment);
                stream.comments.push(comment.to_string());
            }
            continue;
        }
        if trimmed.is_empty() {
            continue;
        }

        split_fields(text, &mut fields).map_err(|m| p.error(m))?;
        if fields.iter().all(|&(a, b)| text[a..b].trim().is_empty()) {
            continue; // a row of empty cells, as spreadsheets write for a blank row
        }
        match &header {
            None => header = Some(parse_header(&p, text, &fields)?),
            Some(h) => {
                let event = parse_row(&p, h, text, &fields)?;
                let t = event.t_ns();
                if let Some((last, last_line)) = last_t {
                    if t < last {
                        return Err(p.error(format!(
                            "t_ns decreases: {t} after {last} (line {last_line}); rows must be \
                             in non-decreasing time order"
                        )));
                    }
                }
                last_t = Some((t, p.line_no));
                stream.events.push(event);
            }
        }
    }

    if p.line_no == 0 {
        return Err(ReadError {
            path: path.to_path_buf(),
            line: None,
            message: format!("empty file (a tick stream starts with the line `{MAGIC}`)"),
        });
    }
    if header.is_none() {
        return Err(ReadError {
            path: path.to_path_buf(),
            line: None,
            message: format!(
                "no header line: the file ends before a line naming the columns {}",
                COLUMNS.join(",")
            ),
        });
    }
    Ok(stream)
}

fn check_magic(p: &Parser<'_>, text: &str) -> Result<(), ReadError> {
    let first = text.trim_end_matches(|c: char| c == ',' || c.is_whitespace());
    if first == MAGIC {
        return Ok(());
    }
    if let Some(version) = first.strip_prefix(MAGIC_PREFIX) {
        if !version.is_empty() {
            return Err(p.error(format!(
                "unsupported version {} (this program reads version 1)",
                shown(version)
            )));
        }
    }
    let found = if first.is_empty() {
        "an empty line".to_string()
    } else {
        shown(first)
    };
    Err(p.error(format!(
        "missing magic line: the first line must be `{MAGIC}`, found {found}"
    )))
}

/// Splits one line into field ranges (byte offsets into `text`). A field that starts with `"`
/// is quoted: it ends at the next lone `"` (`""` inside stands for one quote, and the range
/// keeps it doubled: no required column can contain a quote anyway).
fn split_fields(text: &str, fields: &mut Vec<(usize, usize)>) -> Result<(), String> {
    fields.clear();
    let bytes = text.as_bytes();
    let mut i = 0;
    loop {
        if bytes.get(i) == Some(&b'"') {
            let start = i + 1;
            let mut j = start;
            loop {
                match bytes.get(j) {
                    None => {
                        return Err(format!(
                            "unterminated quoted field {} (fields cannot span lines)",
                            fields.len() + 1
                        ))
                    }
                    Some(b'"') if bytes.get(j + 1) == Some(&b'"') => j += 2,
                    Some(b'"') => break,
                    Some(_) => j += 1,
                }
            }
            fields.push((start, j));
            // After the closing quote: optional spaces, then a comma or the end of the line.
            let mut k = j + 1;
            while matches!(bytes.get(k), Some(b' ' | b'\t')) {
                k += 1;
            }
            match bytes.get(k) {
                None => return Ok(()),
                Some(b',') => i = k + 1,
                Some(_) => {
                    return Err(format!(
                        "text after the closing quote of field {}",
                        fields.len()
                    ))
                }
            }
        } else {
            let end = bytes[i..]
                .iter()
                .position(|&b| b == b',')
                .map_or(bytes.len(), |n| i + n);
            fields.push((i, end));
            if end == bytes.len() {
                return Ok(());
            }
            i = end + 1;
        }
    }
}

fn parse_header(
    p: &Parser<'_>,
    text: &str,
    fields: &[(usize, usize)],
) -> Result<Header, ReadError> {
    let mut index: [Option<usize>; 7] = [None; 7];
    for (i, &(a, b)) in fields.iter().enumerate() {
        let name = text[a..b].trim();
        if let Some(k) = COLUMNS.iter().position(|&c| c == name) {
            if let Some(first) = index[k] {
                return Err(p.error(format!(
                    "duplicate column {name} (fields {} and {})",
                    first + 1,
                    i + 1
                )));
            }
            index[k] = Some(i);
        }
    }
    let missing: Vec<&str> = COLUMNS
        .iter()
        .zip(index)
        .filter(|(_, i)| i.is_none())
        .map(|(&c, _)| c)
        .collect();
    if !missing.is_empty() {
        let first = text[fields[0].0..fields[0].1].trim();
        let hint = if first.parse::<u64>().is_ok() {
            " (is the header line missing?)"
        } else {
            ""
        };
        return Err(p.error(format!(
            "header is missing column{} {}; the header must name {}{hint}",
            if missing.len() > 1 { "s" } else { "" },
            missing.join(", "),
            COLUMNS.join(", "),
        )));
    }
    Ok(Header {
        index: index.map(|i| i.unwrap_or(0)),
        fields: fields.len(),
        line: p.line_no,
    })
}

fn parse_row(
    p: &Parser<'_>,
    h: &Header,
    text: &str,
    fields: &[(usize, usize)],
) -> Result<Event, ReadError> {
    if fields.len() != h.fields {
        return Err(p.error(format!(
            "expected {} fields as in the header (line {}), found {}",
            h.fields,
            h.line,
            fields.len()
        )));
    }
    let field = |column: usize| {
        let (a, b) = fields[h.index[column]];
        text[a..b].trim_matches(|c| c == ' ' || c == '\t')
    };
    let must_be_empty = |kind: &str, columns: &[usize]| -> Result<(), ReadError> {
        for &c in columns {
            let f = field(c);
            if !f.is_empty() {
                return Err(p.error(format!(
                    "{} must be empty in a {kind} row, got {}",
                    COLUMNS[c],
                    shown(f)
                )));
            }
        }
        Ok(())
    };

    let t = field(T_NS);
    if t.is_empty() {
        return Err(p.error("t_ns is empty"));
    }
    let t_ns: u64 = t.parse().map_err(|_| {
        p.error(format!(
            "t_ns must be a whole number of nanoseconds (0 to {}), got {}",
            u64::MAX,
            shown(t)
        ))
    })?;

    let encoder_id = |kind: &str| -> Result<u16, ReadError> {
        let id = field(ID);
        id.parse().map_err(|_| {
            p.error(format!(
                "{kind} id must be an encoder index from 0 to {}, got {}",
                u16::MAX,
                shown_or_empty(id)
            ))
        })
    };
    let coordinate = |column: usize| -> Result<f64, ReadError> {
        let f = field(column);
        let name = COLUMNS[column];
        let v: f64 = f.parse().map_err(|_| {
            p.error(format!(
                "truth {name} must be a number, got {}",
                shown_or_empty(f)
            ))
        })?;
        if !v.is_finite() {
            return Err(p.error(format!("truth {name} must be finite, got {}", shown(f))));
        }
        Ok(v)
    };

    match field(KIND) {
        "tick" => {
            let encoder = encoder_id("tick")?;
            let step = match field(VALUE) {
                "1" | "+1" => 1,
                "-1" => -1,
                other => {
                    return Err(p.error(format!(
                        "tick value must be +1 or -1, got {}",
                        shown_or_empty(other)
                    )))
                }
            };
            must_be_empty("tick", &[X_M, Y_M, THETA_RAD])?;
            Ok(Event::Tick {
                t_ns,
                encoder,
                step,
            })
        }
        "abs" => {
            let encoder = encoder_id("abs")?;
            let v = field(VALUE);
            let code = v.parse().map_err(|_| {
                p.error(format!(
                    "abs value must be a raw code from 0 to {}, got {}",
                    u32::MAX,
                    shown_or_empty(v)
                ))
            })?;
            must_be_empty("abs", &[X_M, Y_M, THETA_RAD])?;
            Ok(Event::Abs {
                t_ns,
                encoder,
                code,
            })
        }
        "truth" => {
            must_be_empty("truth", &[ID, VALUE])?;
            Ok(Event::Truth {
                t_ns,
                x_m: coordinate(X_M)?,
                y_m: coordinate(Y_M)?,
                theta_rad: coordinate(THETA_RAD)?,
            })
        }
        "" => Err(p.error("kind is empty (expected tick, abs or truth)")),
        other => Err(p.error(format!(
            "unknown kind {} (expected tick, abs or truth)",
            shown(other)
        ))),
    }
}

/// A field's text for an error message: as is if it is plain ASCII without spaces, quotes or
/// commas, else quoted and escaped; cut at 40 characters.
fn shown(s: &str) -> String {
    const MAX_CHARS: usize = 40;
    let (s, more) = match s.char_indices().nth(MAX_CHARS) {
        None => (s, ""),
        Some((cut, _)) => (&s[..cut], "..."),
    };
    if s.bytes()
        .all(|b| b.is_ascii_graphic() && b != b'"' && b != b',')
    {
        format!("{s}{more}")
    } else {
        format!("{s:?}{more}")
    }
}

fn shown_or_empty(s: &str) -> String {
    if s.is_empty() {
        "an empty field".into()
    } else {
        shown(s)
    }
}

/// Writes a tick stream: gzip-compressed if `path` ends in `.gz`. The stream is checked first
/// (time order, steps of ±1, finite truth, comments that read back as written), then written
/// atomically ([`write_atomically`]), so a failed write leaves nothing half-written.
pub fn write(path: &Path, stream: &TickStream) -> anyhow::Result<()> {
    validate(stream).with_context(|| format!("not writing {}", path.display()))?;
    write_atomically(path, |file| write_file(file, is_gz_name(path), stream))
}

fn validate(stream: &TickStream) -> anyhow::Result<()> {
    if let Some(robot) = &stream.robot {
        if robot.trim().is_empty() {
            bail!("the robot path is empty");
        }
        if robot.trim() != robot || robot.ends_with(',') || robot.contains(['\n', '\r']) {
            bail!(
                "the robot path {robot:?} has leading or trailing whitespace, a trailing comma \
                 or a line break, which would not read back as written"
            );
        }
    }
    for (i, c) in stream.comments.iter().enumerate() {
        if c.contains(['\n', '\r']) {
            bail!("comment {i} contains a line break: {c:?}");
        }
        if c.ends_with(|ch: char| ch == ',' || ch.is_whitespace()) {
            bail!("comment {i} ends with a comma or whitespace, which reading drops: {c:?}");
        }
        if c.trim_start().starts_with("robot:") {
            bail!("comment {i} would read back as the robot line: {c:?} (set `robot` instead)");
        }
    }
    let mut last = 0;
    for (i, e) in stream.events.iter().enumerate() {
        let t = e.t_ns();
        if t < last {
            bail!("event {i} (t_ns {t}) is earlier than the one before it (t_ns {last}); events must be in non-decreasing time order");
        }
        last = t;
        match *e {
            Event::Tick { step, .. } if step != 1 && step != -1 => {
                bail!("event {i} (t_ns {t}): tick step must be +1 or -1, got {step}")
            }
            Event::Truth {
                x_m,
                y_m,
                theta_rad,
                ..
            } if !(x_m.is_finite() && y_m.is_finite() && theta_rad.is_finite()) => {
                bail!("event {i} (t_ns {t}): truth pose must be finite, got ({x_m}, {y_m}, {theta_rad})")
            }
            _ => {}
        }
    }
    Ok(())
}

fn write_file(file: &mut File, gzip: bool, stream: &TickStream) -> anyhow::Result<()> {
    if gzip {
        // Buffer in front of the encoder: it is slow with many small writes.
        let encoder = GzEncoder::new(file, Compression::fast());
        let mut buffered = BufWriter::with_capacity(WRITE_BUFFER_BYTES, encoder);
        write_text(&mut buffered, stream)?;
        buffered
            .into_inner()
            .map_err(|e| e.into_error())?
            .finish()?;
    } else {
        let mut buffered = BufWriter::with_capacity(WRITE_BUFFER_BYTES, file);
        write_text(&mut buffered, stream)?;
        buffered.flush()?;
    }
    Ok(())
}

fn write_text(w: &mut impl Write, stream: &TickStream) -> io::Result<()> {
    writeln!(w, "{MAGIC}")?;
    if let Some(robot) = &stream.robot {
        writeln!(w, "# robot: {robot}")?;
    }
    for c in &stream.comments {
        if c.is_empty() {
            writeln!(w, "#")?;
        } else {
            writeln!(w, "# {c}")?;
        }
    }
    writeln!(w, "{}", COLUMNS.join(","))?;
    for e in &stream.events {
        match *e {
            Event::Tick {
                t_ns,
                encoder,
                step,
            } => writeln!(w, "{t_ns},tick,{encoder},{step},,,")?,
            Event::Abs {
                t_ns,
                encoder,
                code,
            } => writeln!(w, "{t_ns},abs,{encoder},{code},,,")?,
            Event::Truth {
                t_ns,
                x_m,
                y_m,
                theta_rad,
            } => writeln!(w, "{t_ns},truth,,,{x_m},{y_m},{theta_rad}")?,
        }
    }
    w.flush()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn split(text: &str) -> Result<Vec<&str>, String> {
        let mut fields = Vec::new();
        split_fields(text, &mut fields)?;
        Ok(fields.iter().map(|&(a, b)| &text[a..b]).collect())
    }

    #[test]
    fn splits_plain_and_quoted_fields() {
        assert_eq!(split("").unwrap(), vec![""]);
        assert_eq!(split("a,,b,").unwrap(), vec!["a", "", "b", ""]);
        assert_eq!(
            split(r#""0","tick" ,"a,""b""",x"#).unwrap(),
            vec!["0", "tick", r#"a,""b"""#, "x"]
        );
        assert_eq!(split(r#""""#).unwrap(), vec![""]);
        assert!(split(r#"1,"abc"#).unwrap_err().contains("unterminated"));
        assert!(split(r#""a"b,1"#)
            .unwrap_err()
            .contains("after the closing quote"));
    }

    #[test]
    fn shown_cuts_long_fields_at_a_char_boundary() {
        let long = "é".repeat(100);
        let s = shown(&long);
        assert!(s.ends_with("..."), "{s}");
        assert_eq!(s.chars().filter(|&c| c == 'é').count(), 40);
        assert_eq!(shown("2"), "2");
        assert_eq!(shown("a b"), "\"a b\"");
        assert_eq!(
            shown("x".repeat(50).as_str()),
            format!("{}...", "x".repeat(40))
        );
    }

    #[test]
    fn magic_prefix_is_magic_without_its_version() {
        assert_eq!(format!("{MAGIC_PREFIX}1"), MAGIC);
    }
}
