//! Writing a tick stream: checked first, then written atomically.

use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::Path;

use anyhow::{bail, Context};
use flate2::write::GzEncoder;
use flate2::Compression;

use super::{
    is_gz_name, Event, TickStream, COLUMNS, MAGIC, MAX_TRUTH_COORDINATE_M, MAX_TRUTH_HEADING_RAD,
    WRITE_BUFFER_BYTES,
};
use crate::formats::atomic::{write_atomically, Staged};

/// Writes a tick stream: gzip-compressed if `path` ends in `.gz`. The stream is checked first
/// (time order, steps of ±1, finite truth, comments that read back as written), then written
/// atomically ([`write_atomically`]), so a failed write leaves nothing half-written.
pub fn write(path: &Path, stream: &TickStream) -> anyhow::Result<()> {
    validate(stream).with_context(|| format!("not writing {}", path.display()))?;
    write_atomically(path, |file| write_file(file, is_gz_name(path), stream))
}

/// [`write`] as one of several files that appear together ([`Staged::commit`]).
pub fn stage(staged: &mut Staged, path: &Path, stream: &TickStream) -> anyhow::Result<()> {
    validate(stream).with_context(|| format!("not writing {}", path.display()))?;
    staged.write(path, |file| write_file(file, is_gz_name(path), stream))
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
            } if !(x_m.abs() <= MAX_TRUTH_COORDINATE_M
                && y_m.abs() <= MAX_TRUTH_COORDINATE_M
                && theta_rad.abs() <= MAX_TRUTH_HEADING_RAD) =>
            {
                bail!(
                    "event {i} (t_ns {t}): truth pose must be finite, within ±{MAX_TRUTH_COORDINATE_M:e} m \
                     and ±{MAX_TRUTH_HEADING_RAD:e} rad (what a reader takes), got ({x_m}, {y_m}, {theta_rad})"
                )
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
