//! `--mcap FILE`: the run's channels in an MCAP file, whole or absent.
//!
//! Written as the run goes into a temporary file beside FILE (memory stays flat however long
//! the run) and renamed into place by [`McapFile::finish`] once the run has succeeded; a run
//! that fails or is stopped leaves no file, nor a half-written one. Uncompressed chunks (the
//! `mcap` crate without its C compression libraries), with the message and chunk indexes and
//! statistics the viewers use to seek.

use std::collections::BTreeMap;
use std::io::BufWriter;
use std::path::Path;
use std::sync::{Arc, Mutex};

use anyhow::{Context as _, Result};
use mcap::records::MessageHeader;

use super::{Channel, Sink};
use crate::formats::atomic::Partial;

type Writer = mcap::Writer<BufWriter<Partial>>;

/// The MCAP file being written. Cloned handles share it: one goes to the run's [`View`]
/// (as its [`Sink`]), one stays with the command to [`finish`](Self::finish) it.
///
/// [`View`]: super::View
#[derive(Clone)]
pub struct McapFile {
    inner: Arc<Mutex<Option<Inner>>>,
}

struct Inner {
    writer: Writer,
    /// Our channel index → the file's channel id.
    ids: Vec<u16>,
    sequence: u32,
    /// The command that wrote it (`host-bench emulate`), for the file's header.
    what: String,
}

impl McapFile {
    /// Checks `path` can be written and opens its temporary file. `what` names the command.
    pub fn create(path: &Path, what: &str) -> Result<Self> {
        let partial =
            Partial::create(path).with_context(|| format!("--mcap {}", path.display()))?;
        let writer = mcap::WriteOptions::new()
            .compression(None)
            .profile("")
            .library(format!(
                "omnibench host-bench {}",
                env!("CARGO_PKG_VERSION")
            ))
            .create(BufWriter::new(partial))
            .with_context(|| format!("--mcap {}", path.display()))?;
        Ok(McapFile {
            inner: Arc::new(Mutex::new(Some(Inner {
                writer,
                ids: Vec::new(),
                sequence: 0,
                what: what.to_string(),
            }))),
        })
    }

    /// A [`Sink`] writing into this file.
    pub fn sink(&self) -> Box<dyn Sink> {
        Box::new(self.clone())
    }

    /// Ends the file (summary, indexes, footer), syncs it and puts it in place. A run that
    /// logged nothing still leaves a valid file with its channels.
    pub fn finish(self, channels: &[Channel]) -> Result<std::path::PathBuf> {
        let mut guard = self.inner.lock().unwrap_or_else(|e| e.into_inner());
        let mut inner = guard.take().context("the MCAP file was finished twice")?;
        if inner.ids.is_empty() {
            inner.start(channels)?;
        }
        inner.writer.finish()?;
        let partial = inner
            .writer
            .into_inner()
            .into_inner()
            .map_err(|e| e.into_error())?;
        let path = partial.path().to_path_buf();
        partial.persist()?;
        Ok(path)
    }
}

impl Inner {
    fn start(&mut self, channels: &[Channel]) -> Result<()> {
        let mut meta = BTreeMap::new();
        meta.insert("command".to_string(), self.what.clone());
        meta.insert(
            "log_time".to_string(),
            "the run's own time, ns: simulated from the start (emulate, virtual-board), played \
             from the stream's start (play, replay), the board's clock since power-on (record)"
                .to_string(),
        );
        // When, on the wall clock, the file was begun: the log times carry no date.
        let now = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_secs());
        meta.insert("started_unix_s".to_string(), now.to_string());
        self.writer.write_metadata(&mcap::records::Metadata {
            name: "omnibench".into(),
            metadata: meta,
        })?;
        for c in channels {
            let schema =
                self.writer
                    .add_schema(c.schema_name, "jsonschema", c.schema.as_bytes())?;
            let id = self
                .writer
                .add_channel(schema, &c.topic, "json", &BTreeMap::new())?;
            self.ids.push(id);
        }
        Ok(())
    }
}

impl Sink for McapFile {
    fn start(&mut self, channels: &[Channel]) -> Result<()> {
        let mut guard = self.inner.lock().unwrap_or_else(|e| e.into_inner());
        match guard.as_mut() {
            Some(inner) if inner.ids.is_empty() => inner.start(channels),
            _ => Ok(()),
        }
    }

    fn message(&mut self, id: usize, t_ns: u64, data: &[u8]) -> Result<()> {
        let mut guard = self.inner.lock().unwrap_or_else(|e| e.into_inner());
        let Some(inner) = guard.as_mut() else {
            return Ok(());
        };
        inner.sequence = inner.sequence.wrapping_add(1);
        let header = MessageHeader {
            channel_id: inner.ids[id],
            sequence: inner.sequence,
            log_time: t_ns,
            publish_time: t_ns,
        };
        inner.writer.write_to_known_channel(&header, data)?;
        Ok(())
    }
}
