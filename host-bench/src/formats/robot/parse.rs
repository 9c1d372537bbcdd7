//! Reading a robot file: TOML syntax, the format line and the tables' shapes, then keys and
//! types through serde; and where an error is (line, column, key path).

use std::collections::HashMap;
use std::ops::Range;
use std::path::Path;

use toml::de::{DeTable, DeValue};
use toml::Spanned;

use super::raw::RawRobot;
use super::{Robot, RobotError, FORMAT};

pub(super) struct Parser<'a> {
    pub(super) path: &'a Path,
    pub(super) text: &'a str,
}

pub(super) type Res<T> = Result<T, RobotError>;

impl Parser<'_> {
    pub(super) fn error(
        &self,
        offset: Option<usize>,
        key: Option<String>,
        message: String,
    ) -> RobotError {
        let (line, column) = match offset {
            Some(o) => {
                let (l, c) = line_col(self.text, o);
                (Some(l), Some(c))
            }
            None => (None, None),
        };
        RobotError {
            path: self.path.to_path_buf(),
            line,
            column,
            key,
            message,
        }
    }

    pub(super) fn at(
        &self,
        span: Range<usize>,
        key: &str,
        message: impl Into<String>,
    ) -> RobotError {
        self.error(Some(span.start), Some(key.to_string()), message.into())
    }

    pub(super) fn finite(&self, v: &Spanned<f64>, key: &str) -> Res<f64> {
        let x = *v.get_ref();
        if x.is_finite() {
            Ok(x)
        } else {
            Err(self.at(v.span(), key, format!("must be a finite number, got {x}")))
        }
    }

    pub(super) fn positive(&self, v: &Spanned<f64>, key: &str) -> Res<f64> {
        let x = self.finite(v, key)?;
        if x > 0.0 {
            Ok(x)
        } else {
            Err(self.at(v.span(), key, format!("must be > 0, got {x}")))
        }
    }

    pub(super) fn name(&self, v: &Spanned<String>, key: &str) -> Res<String> {
        let s = v.get_ref().trim();
        if s.is_empty() {
            return Err(self.at(v.span(), key, "must not be empty"));
        }
        Ok(s.to_string())
    }

    pub(super) fn parse(&self) -> Res<Robot> {
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
        self.check_format_and_shape(&tree)?;

        // 3. Keys and types.
        //    serde_path_to_error names the key (`encoders[2].direction_deg`); toml's error has
        //    the span, hence the line.
        let document = toml::Deserializer::parse(self.text).map_err(|e| {
            let offset = e.span().map_or(0, |s| s.start);
            self.error(Some(offset), None, format!("TOML syntax: {}", e.message()))
        })?;
        let raw: RawRobot =
            serde_path_to_error::deserialize(document).map_err(|e| self.type_error(&e))?;

        // 4. Values and geometry.
        self.check(raw)
    }

    fn check_format_and_shape(&self, tree: &Spanned<DeValue<'_>>) -> Res<()> {
        let found = match tree.get_ref() {
            DeValue::Table(t) => t.iter().find(|(k, _)| k.get_ref() == "format"),
            _ => None,
        };
        let Some((_, value)) = found else {
            return Err(self.error(
                Some(0),
                Some("format".into()),
                format!("missing: a robot file starts with format = \"{FORMAT}\""),
            ));
        };
        match value.get_ref().as_str() {
            Some(FORMAT) => {}
            Some(other) => {
                return Err(self.at(
                    value.span(),
                    "format",
                    format!("unsupported format \"{other}\": this program reads \"{FORMAT}\""),
                ))
            }
            None => {
                return Err(self.at(
                    value.span(),
                    "format",
                    format!("must be the string \"{FORMAT}\""),
                ))
            }
        }
        // The tables' shapes, which serde would report in terms of its own internals.
        let DeValue::Table(t) = tree.get_ref() else {
            return Ok(());
        };
        for (k, v) in t.iter() {
            let key = k.get_ref().as_ref();
            let array = matches!(v.get_ref(), DeValue::Array(_));
            if key == "carriage" && array {
                return Err(self.at(
                    v.span(),
                    key,
                    "a robot has at most one carriage: write [carriage], not [[carriage]]",
                ));
            }
            if ["encoders", "absolute_encoders", "drive_wheels"].contains(&key) && !array {
                return Err(self.at(
                    v.span(),
                    key,
                    format!("must be an array of tables: write [[{key}]] before each one"),
                ));
            }
        }
        Ok(())
    }

    /// A serde error (unknown key, wrong type, missing key), at the key path where it happened.
    fn type_error(&self, e: &serde_path_to_error::Error<toml::de::Error>) -> RobotError {
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
pub(super) fn line_col(text: &str, offset: usize) -> (usize, usize) {
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
pub(super) fn key_on_line(text: &str, offset: usize) -> Option<String> {
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
pub(super) fn table_header(line: &str) -> Option<(String, bool)> {
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
