//! Each board's defmt log, read over RTT through its debug probe and decoded with the defmt
//! table of the ELF it was flashed with. Lines are prefixed `[slave]` / `[master]`.

use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use defmt_decoder::{DecodeError, Table};
use probe_rs::rtt::{self, ScanRegion};
use probe_rs::Session;

use super::Board;

/// What the log reader needs from an ELF: its defmt table and where RTT's control block is.
pub struct LogSource {
    pub table: Table,
    /// `_SEGGER_RTT`'s address; None means scanning RAM for the control block.
    pub control_block: Option<u64>,
}

/// Reads the defmt table and RTT control block address from an image.
pub fn log_source(board: Board, elf_path: &Path) -> Result<LogSource, String> {
    let elf = super::images::read_image(elf_path)
        .map_err(|e| format!("{board}: cannot read {}: {e}", elf_path.display()))?;
    let table = Table::parse(&elf)
        .map_err(|e| {
            format!(
                "{board}: the defmt table of {} cannot be read: {e}",
                elf_path.display()
            )
        })?
        .ok_or_else(|| {
            format!(
                "{board}: {} has no defmt table (built without defmt?), so its RTT log \
                 cannot be decoded",
                elf_path.display()
            )
        })?;
    let control_block = rtt::find_rtt_control_block_in_raw_file(&elf).map_err(|e| {
        format!(
            "{board}: {} is not a readable ELF file: {e}",
            elf_path.display()
        )
    })?;
    Ok(LogSource {
        table,
        control_block,
    })
}

/// Prints one board's defmt log until `stop` is set (Ctrl-C) or the probe fails.
/// Every line goes through `emit`, already prefixed with the board's name.
pub fn follow(
    board: Board,
    session: &mut Session,
    source: &LogSource,
    stop: &AtomicBool,
    emit: &(dyn Fn(String) + Sync),
) -> Result<(), String> {
    let region = match source.control_block {
        Some(address) => ScanRegion::Exact(address),
        None => ScanRegion::Ram,
    };
    let mut core = session
        .core(0)
        .map_err(|e| format!("{board}: cannot reach the core for RTT: {e}"))?;
    // The firmware sets up its RTT control block early in main; give it time after reset.
    let mut rtt = rtt::try_attach_to_rtt(&mut core, Duration::from_secs(3), &region)
        .map_err(|e| format!("{board}: no RTT on the board: {e}"))?;
    let channel = rtt
        .up_channel(0)
        .ok_or_else(|| format!("{board}: the firmware has no RTT up channel 0 (defmt's)"))?;
    let mut decoder = source.table.new_stream_decoder();
    let mut buffer = vec![0u8; 1024];
    let prefix = format!("[{board}]");
    while !stop.load(Ordering::Relaxed) {
        let n = channel
            .read(&mut core, &mut buffer)
            .map_err(|e| format!("{board}: reading RTT failed: {e}"))?;
        if n == 0 {
            // Nothing new: poll at 100 Hz, which keeps up with defmt at 115200-baud-like rates
            // without holding the probe busy.
            std::thread::sleep(Duration::from_millis(10));
            continue;
        }
        decoder.received(&buffer[..n]);
        loop {
            match decoder.decode() {
                Ok(frame) => {
                    for line in frame.display(false).to_string().lines() {
                        emit(format!("{prefix} {line}"));
                    }
                }
                Err(DecodeError::UnexpectedEof) => break,
                Err(DecodeError::Malformed) => {
                    // rzcobs framing resynchronises at the next frame; say that data was lost.
                    emit(format!(
                        "{prefix} (malformed defmt frame skipped: does the image match the \
                         firmware on the board?)"
                    ));
                    if !source.table.encoding().can_recover() {
                        return Err(format!(
                            "{board}: the defmt stream is corrupt and its raw encoding cannot \
                             resynchronise"
                        ));
                    }
                }
            }
        }
    }
    Ok(())
}
