//! Reading a tick stream: the file or a reader, gzip or not, parsed line by line.

use std::io::{BufRead, BufReader, Read};
use std::path::Path;

use super::row::{parse_header, parse_row, shown, split_fields, Header};
use super::{
    is_gz_name, Event, Lines, ReadError, TickStream, COLUMNS, GZIP_MAGIC, MAGIC, MAGIC_PREFIX,
    MAX_EVENTS, MAX_KEPT_COMMENTS, MAX_KEPT_COMMENT_BYTES, MAX_LINE_BYTES, MAX_OTHER_LINES,
    READ_BUFFER_BYTES, UTF8_BOM,
};
use flate2::read::MultiGzDecoder;

/// Reads a tick stream file; gzip-compressed if its name ends in `.gz` or its data starts with
/// the gzip magic bytes.
pub fn read(path: &Path) -> Result<TickStream, ReadError> {
    read_with_lines(path).map(|(stream, _)| stream)
}

/// What a command asks of every row beyond the format (`play`: a span it can play), checked as
/// the row is read, so that its error names the row's line.
pub type RowCheck<'a> = &'a mut dyn FnMut(&Event) -> Result<(), String>;

/// [`read`], with `check` run on every row as it is read: a row it refuses is an error at its
/// line, and reading stops there.
pub fn read_checked(path: &Path, check: RowCheck) -> Result<TickStream, ReadError> {
    read_lines_checked(path, check).map(|(stream, _)| stream)
}

/// [`read`], and where each event was in the file, for errors found after reading.
pub fn read_with_lines(path: &Path) -> Result<(TickStream, Lines), ReadError> {
    read_lines_checked(path, &mut |_| Ok(()))
}

fn read_lines_checked(path: &Path, check: RowCheck) -> Result<(TickStream, Lines), ReadError> {
    let file = crate::formats::bounded_file::open_stream(path).map_err(|e| ReadError {
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
        parse_with_lines(
            BufReader::with_capacity(READ_BUFFER_BYTES, decoder),
            path,
            check,
        )
    } else {
        parse_with_lines(input, path, check)
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
    let parsed = if head.starts_with(&GZIP_MAGIC) {
        let decoder = MultiGzDecoder::new(input);
        parse_with_lines(
            BufReader::with_capacity(READ_BUFFER_BYTES, decoder),
            name_for_errors,
            &mut |_| Ok(()),
        )
    } else {
        parse_with_lines(input, name_for_errors, &mut |_| Ok(()))
    };
    parsed.map(|(stream, _)| stream)
}

/// The line-by-line parser's state.
pub(super) struct Parser<'a> {
    pub(super) path: &'a Path,
    pub(super) line_no: u64,
}

impl Parser<'_> {
    pub(super) fn error(&self, message: impl Into<String>) -> ReadError {
        ReadError {
            path: self.path.to_path_buf(),
            line: Some(self.line_no),
            message: message.into(),
        }
    }
}

/// Counts a comment or blank line: past [`MAX_OTHER_LINES`] the file is refused (a small gzip of
/// them would keep the reader busy for minutes). After the header, notes where it fell.
fn other_line(
    p: &Parser<'_>,
    count: &mut u64,
    lines: &mut Lines,
    events: usize,
    header: bool,
) -> Result<(), ReadError> {
    *count += 1;
    if *count > MAX_OTHER_LINES {
        return Err(p.error(format!(
            "more than {MAX_OTHER_LINES} comment or blank lines (is this a tick stream?)"
        )));
    }
    if header {
        // At most MAX_OTHER_LINES of these; events fit a u32 (MAX_EVENTS is 2^22).
        lines.gaps.push(events as u32);
    }
    Ok(())
}

/// A carriage return that does not end the line or precede its line feed: the file's line
/// endings are CR alone (classic Mac OS), which makes all of it one line.
fn lone_cr(line: &[u8]) -> bool {
    let body = line.strip_suffix(b"\n").unwrap_or(line);
    let body = body.strip_suffix(b"\r").unwrap_or(body);
    body.contains(&b'\r')
}

const CR_ONLY: &str = "the line endings are CR alone (classic Mac OS): not supported; save the \
                       file with LF or CR LF line endings";

pub(super) fn parse_with_lines(
    mut input: impl BufRead,
    path: &Path,
    check: RowCheck,
) -> Result<(TickStream, Lines), ReadError> {
    let mut p = Parser { path, line_no: 0 };
    let mut stream = TickStream::default();
    let mut lines = Lines::default();
    let mut line: Vec<u8> = Vec::with_capacity(256);
    let mut fields: Vec<(usize, usize)> = Vec::with_capacity(16);
    let mut header: Option<Header> = None;
    let mut robot_line: Option<u64> = None;
    let mut last_t: Option<(u64, u64)> = None; // (t_ns, line)
    let mut comment_bytes = 0usize;
    let mut comments_dropped = 0u64;
    let mut other_lines = 0u64;

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
            // A file with CR line endings alone reads as one long line.
            return Err(p.error(if lone_cr(&line) {
                CR_ONLY.to_string()
            } else {
                format!("line is longer than {MAX_LINE_BYTES} bytes (is this a tick stream?)")
            }));
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
        if p.line_no == 1 && lone_cr(bytes) {
            return Err(p.error(CR_ONLY));
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
        let (events, after_header) = (stream.events.len(), header.is_some());
        if let Some(comment) = trimmed.strip_prefix('#') {
            other_line(&p, &mut other_lines, &mut lines, events, after_header)?;
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
                comment_bytes = comment_bytes.saturating_add(comment.len());
                if comment_bytes <= MAX_KEPT_COMMENT_BYTES
                    && stream.comments.len() < MAX_KEPT_COMMENTS
                {
                    stream.comments.push(comment.to_string());
                } else {
                    comments_dropped += 1;
                }
            }
            continue;
        }
        if trimmed.is_empty() {
            other_line(&p, &mut other_lines, &mut lines, events, after_header)?;
            continue;
        }

        split_fields(text, &mut fields).map_err(|m| p.error(m))?;
        // A row of empty cells, as spreadsheets write for a blank row: `,,,` or `"",""` (the
        // quoted ones too, or a gzip of them would take minutes to refuse).
        if fields.iter().all(|&(a, b)| text[a..b].trim().is_empty()) {
            other_line(&p, &mut other_lines, &mut lines, events, after_header)?;
            continue;
        }
        match &header {
            None => {
                header = Some(parse_header(&p, text, &fields)?);
                lines.header = p.line_no;
            }
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
                check(&event).map_err(|m| p.error(m))?;
                if stream.events.len() == MAX_EVENTS {
                    return Err(p.error(format!(
                        "more than {MAX_EVENTS} events: a stream is replayed in memory, so it \
                         holds at most {MAX_EVENTS} rows (split the recording)"
                    )));
                }
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
    if comments_dropped > 0 {
        stream.comments.push(format!(
            "({comments_dropped} more comment lines not kept: a stream keeps at most \
             {MAX_KEPT_COMMENTS} comment lines and {MAX_KEPT_COMMENT_BYTES} bytes of them)"
        ));
    }
    Ok((stream, lines))
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
