//! The header and row lines of a tick stream: splitting fields, finding the columns, reading
//! each value, and showing a field in an error message.

use super::read::Parser;
use super::*;

/// Column positions found in the header.
pub(super) struct Header {
    /// Field index of each of [`COLUMNS`].
    index: [usize; 7],
    /// How many fields the header has; every row must have as many.
    fields: usize,
    line: u64,
}

/// Splits one line into field ranges (byte offsets into `text`). A field that starts with `"`
/// is quoted: it ends at the next lone `"` (`""` inside stands for one quote, and the range
/// keeps it doubled: no required column can contain a quote anyway).
pub(super) fn split_fields(text: &str, fields: &mut Vec<(usize, usize)>) -> Result<(), String> {
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

pub(super) fn parse_header(
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

pub(super) fn parse_row(
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
        let (limit, unit) = if column == THETA_RAD {
            (MAX_TRUTH_HEADING_RAD, "rad")
        } else {
            (MAX_TRUTH_COORDINATE_M, "m")
        };
        if v.abs() > limit {
            return Err(p.error(format!(
                "truth {name} must be within ±{limit:e} {unit}, got {}",
                shown(f)
            )));
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
pub(super) fn shown(s: &str) -> String {
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
