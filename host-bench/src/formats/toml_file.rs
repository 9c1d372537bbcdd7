//! Reading one of the bench's TOML files (robots, scenarios): TOML syntax, the format line and
//! the tables' shapes, then keys and types through serde; and where an error is (line,
//! column, key path). Each format adds its own value checks on top.

use std::collections::HashMap;
use std::fmt;
use std::ops::Range;
use std::path::{Path, PathBuf};

use serde::de::DeserializeOwned;
use toml::de::{DeTable, DeValue};
use toml::Spanned;

/// A file being read: where it is (for errors), its text, and the format line it must carry.
pub struct TomlFile<'a> {
    pub path: &'a Path,
    pub text: &'a str,
    /// The value of the `format` key, e.g. `"omnibench robot v1"`.
    pub format: &'static str,
    /// What the file is, for messages: "robot file", "scenario".
    pub kind: &'static str,
}

/// Why a file was refused. Displays as `path:LINE:COL: key `k`: message`, with the parts that
/// are unknown left out (an unreadable file has neither line nor key).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FileError {
    pub path: PathBuf,
    /// 1-based line of the offending key or value.
    pub line: Option<usize>,
    /// 1-based column (in characters) on that line.
    pub column: Option<usize>,
    /// Dotted key path with array indices, e.g. `encoders[1].metres_per_count`.
    pub key: Option<String>,
    pub message: String,
}

impl fmt::Display for FileError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.path.display())?;
        match (self.line, self.column) {
            (Some(l), Some(c)) => write!(f, ":{l}:{c}")?,
            (Some(l), None) => write!(f, ":{l}")?,
            _ => {}
        }
        write!(f, ": ")?;
        if let Some(k) = &self.key {
            write!(f, "key `{k}`: ")?;
        }
        write!(f, "{}", self.message)
    }
}

impl std::error::Error for FileError {}

pub type Res<T> = Result<T, FileError>;

/// The largest description file (robot, scenario, bench) read, bytes: the seed robots are
/// about 3 KB.
pub const MAX_TEXT_FILE_BYTES: u64 = 1 << 20;

/// Read `path`'s text, or say why not.
/// A number for a message: plain when it reads well, else in e-notation (1e300, not 301
/// digits).
pub fn short(x: f64) -> String {
    if x == 0.0 || (1e-4..1e6).contains(&x.abs()) {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}

pub fn read_text(path: &Path, kind: &str) -> Res<String> {
    read_bounded_text(path).map_err(|e| FileError {
        path: path.to_path_buf(),
        line: None,
        column: None,
        key: None,
        message: format!("cannot read the {kind}: {e}"),
    })
}

/// A regular file's text, at most [`MAX_TEXT_FILE_BYTES`]: a device, a pipe or a huge file is
/// refused before anything is read, and a file that grows while read stops at the bound.
pub fn read_bounded_text(path: &Path) -> Result<String, String> {
    let bytes = super::bounded_file::read_bounded(path, MAX_TEXT_FILE_BYTES, "a description file")
        .map_err(|e| e.to_string())?;
    String::from_utf8(bytes).map_err(|e| {
        format!(
            "not UTF-8 text (bad byte at offset {})",
            e.utf8_error().valid_up_to()
        )
    })
}

/// A table's shape at the top level: `[name]` (false) or `[[name]]` (true).
pub struct Shape<'k> {
    pub key: &'k str,
    pub array: bool,
    pub span: Range<usize>,
}

impl TomlFile<'_> {
    pub fn error(&self, offset: Option<usize>, key: Option<String>, message: String) -> FileError {
        let (line, column) = match offset {
            Some(o) => {
                let (l, c) = line_col(self.text, o);
                (Some(l), Some(c))
            }
            None => (None, None),
        };
        FileError {
            path: self.path.to_path_buf(),
            line,
            column,
            key,
            message,
        }
    }

    pub fn at(&self, span: Range<usize>, key: &str, message: impl Into<String>) -> FileError {
        self.error(Some(span.start), Some(key.to_string()), message.into())
    }

    pub fn finite(&self, v: &Spanned<f64>, key: &str) -> Res<f64> {
        let x = *v.get_ref();
        if x.is_finite() {
            Ok(x)
        } else {
            Err(self.at(v.span(), key, format!("must be a finite number, got {x}")))
        }
    }

    pub fn positive(&self, v: &Spanned<f64>, key: &str) -> Res<f64> {
        let x = self.finite(v, key)?;
        if x > 0.0 {
            Ok(x)
        } else {
            Err(self.at(v.span(), key, format!("must be > 0, got {x}")))
        }
    }

    /// A finite number in `[lo, hi]` (`unit` for the message): the documented range of a
    /// field, checked where it is read so nothing downstream meets an absurd magnitude.
    pub fn within(&self, v: &Spanned<f64>, key: &str, lo: f64, hi: f64, unit: &str) -> Res<f64> {
        let x = self.finite(v, key)?;
        if (lo..=hi).contains(&x) {
            Ok(x)
        } else {
            Err(self.at(
                v.span(),
                key,
                format!(
                    "must be in [{}, {}] {unit}, got {}",
                    short(lo),
                    short(hi),
                    short(x)
                ),
            ))
        }
    }

    pub fn non_negative(&self, v: &Spanned<f64>, key: &str) -> Res<f64> {
        let x = self.finite(v, key)?;
        if x < 0.0 {
            return Err(self.at(v.span(), key, format!("must be >= 0, got {x}")));
        }
        Ok(x)
    }

    pub fn name(&self, v: &Spanned<String>, key: &str) -> Res<String> {
        let s = v.get_ref().trim();
        if s.is_empty() {
            return Err(self.at(v.span(), key, "must not be empty"));
        }
        // Names are printed to terminals and written into files' headers: an escape sequence
        // or a line break in one would rewrite what the user sees or split a header line.
        if let Some(c) = s.chars().find(|c| c.is_control()) {
            return Err(self.at(
                v.span(),
                key,
                format!(
                    "must not hold control characters (found U+{:04X})",
                    c as u32
                ),
            ));
        }
        Ok(s.to_string())
    }

    /// Syntax, the format line, `shape` on every top-level key, then keys and types into `T`.
    pub fn read<T: DeserializeOwned>(&self, shape: impl Fn(&Self, Shape) -> Res<()>) -> Res<T> {
        // 1. TOML syntax.
        let (tree, errors) = DeTable::parse_recoverable(self.text);
        if let Some(e) = errors.first() {
            let offset = e.span().map_or(0, |s| s.start);
            return Err(self.error(
                Some(offset),
                key_on_line(self.text, offset),
                format!("TOML syntax: {}", e.message()),
            ));
        }
        let tree = Spanned::new(tree.span(), DeValue::Table(tree.into_inner()));

        // 2. The format line, before anything else: a file of another version must be told so,
        //    not have its new keys called unknown.
        self.check_format_and_shape(&tree, &shape)?;

        // 3. Keys and types.
        //    serde_path_to_error names the key (`encoders[2].direction_deg`); toml's error has
        //    the span, hence the line.
        let document = toml::Deserializer::parse(self.text).map_err(|e| {
            let offset = e.span().map_or(0, |s| s.start);
            self.error(Some(offset), None, format!("TOML syntax: {}", e.message()))
        })?;
        serde_path_to_error::deserialize(document).map_err(|e| self.type_error(&e))
    }

    fn check_format_and_shape(
        &self,
        tree: &Spanned<DeValue<'_>>,
        shape: &impl Fn(&Self, Shape) -> Res<()>,
    ) -> Res<()> {
        let format = self.format;
        let found = match tree.get_ref() {
            DeValue::Table(t) => t.iter().find(|(k, _)| k.get_ref() == "format"),
            _ => None,
        };
        let Some((_, value)) = found else {
            return Err(self.error(
                Some(0),
                Some("format".into()),
                format!("missing: a {} starts with format = \"{format}\"", self.kind),
            ));
        };
        match value.get_ref().as_str() {
            Some(f) if f == format => {}
            Some(other) => {
                return Err(self.at(
                    value.span(),
                    "format",
                    format!("unsupported format \"{other}\": this program reads \"{format}\""),
                ))
            }
            None => {
                return Err(self.at(
                    value.span(),
                    "format",
                    format!("must be the string \"{format}\""),
                ))
            }
        }
        // The tables' shapes, which serde would report in terms of its own internals.
        let DeValue::Table(t) = tree.get_ref() else {
            return Ok(());
        };
        for (k, v) in t.iter() {
            shape(
                self,
                Shape {
                    key: k.get_ref().as_ref(),
                    array: matches!(v.get_ref(), DeValue::Array(_)),
                    span: v.span(),
                },
            )?;
        }
        Ok(())
    }

    /// A serde error (unknown key, wrong type, missing key), at the key path where it happened.
    fn type_error(&self, e: &serde_path_to_error::Error<toml::de::Error>) -> FileError {
        let span = e.inner().span().unwrap_or(0..0);
        let mut path = key_path(e.path());
        let mut message = e
            .inner()
            .message()
            .replace("expected f64", "expected a number");
        message = message.replace("expected i64", "expected an integer");
        if let Some(missing) = message
            .strip_prefix("missing field `")
            .and_then(|m| m.strip_suffix('`'))
        {
            path = if path.is_empty() {
                missing.to_string()
            } else {
                format!("{path}.{missing}")
            };
            message = "missing (required)".into();
        }
        self.error(
            Some(span.start),
            Some(path).filter(|p| !p.is_empty()),
            message,
        )
    }
}

/// 1-based line and column (in characters) of a byte offset.
pub fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let mut off = offset.min(text.len());
    while !text.is_char_boundary(off) {
        off -= 1;
    }
    let before = &text[..off];
    let line = before.matches('\n').count() + 1;
    let line_start = before.rfind('\n').map_or(0, |i| i + 1);
    (line, before[line_start..].chars().count() + 1)
}

/// A serde path as the file's key path, `encoders[2].direction_deg` (empty for the document
/// itself), leaving out the fields `toml::Spanned` deserializes through.
fn key_path(path: &serde_path_to_error::Path) -> String {
    use serde_path_to_error::Segment;
    let mut out = String::new();
    for segment in path.iter() {
        match segment {
            Segment::Seq { index } => out.push_str(&format!("[{index}]")),
            // Spanned<T> is read as a map of private fields (serde_spanned's naming; a change
            // there fails `inline_tables_are_located_too` and `missing_keys_are_named`).
            Segment::Map { key } if key.starts_with("$__serde_spanned_private_") => {}
            Segment::Map { key } | Segment::Enum { variant: key } => {
                if !out.is_empty() {
                    out.push('.');
                }
                out.push_str(key);
            }
            Segment::Unknown => out.push_str(if out.is_empty() { "?" } else { ".?" }),
        }
    }
    out
}

/// For a syntax error (no parsed tree to consult): the key path of the line at `offset`, from
/// the table headers above it and the `key =` on that line. Covers one-key-per-line files.
pub fn key_on_line(text: &str, offset: usize) -> Option<String> {
    let (line, _) = line_col(text, offset);
    let mut prefix = String::new();
    let mut counts: HashMap<String, usize> = HashMap::new();
    for (n, l) in text.lines().enumerate() {
        let t = l.trim();
        let header = table_header(t);
        if let Some((name, array)) = &header {
            prefix = if *array {
                let c = counts.entry(name.clone()).or_insert(0);
                *c += 1;
                format!("{name}[{}]", *c - 1)
            } else {
                name.clone()
            };
        }
        if n + 1 == line {
            if header.is_some() {
                return Some(prefix);
            }
            let key = t.split_once('=').map(|(k, _)| k.trim()).filter(|k| {
                !k.is_empty()
                    && k.chars()
                        .all(|c| c.is_ascii_alphanumeric() || "_-.\"' ".contains(c))
            });
            return match key {
                Some(k) if prefix.is_empty() => Some(k.to_string()),
                Some(k) => Some(format!("{prefix}.{k}")),
                None if prefix.is_empty() => None,
                None => Some(prefix),
            };
        }
    }
    None
}

/// `[name]` → (name, false), `[[name]]` → (name, true), anything else → None.
pub fn table_header(line: &str) -> Option<(String, bool)> {
    let line = match line.find('#') {
        Some(i) => line[..i].trim(),
        None => line,
    };
    let (inner, array) = if let Some(r) = line.strip_prefix("[[") {
        (r.strip_suffix("]]")?, true)
    } else {
        (line.strip_prefix('[')?.strip_suffix(']')?, false)
    };
    let inner = inner.trim();
    let ok = !inner.is_empty()
        && inner
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || "_-.\"' ".contains(c));
    ok.then(|| (inner.to_string(), array))
}
