//! From what the user asked (flags, bench.toml) and what is attached to the jobs to run:
//! which image, which probe and which chip for each board.
//!
//! Everything that can be checked before touching a probe is checked here, and all problems
//! are reported together: a user with no image built and no probe attached learns both at
//! once instead of one per try.

use std::path::PathBuf;

use probe_rs::probe::list::Lister;

use super::bench_file::{BenchFile, DEFAULT_CHIP};
use super::flashing::{check_chip_name, FlashJob};
use super::images::{check_image, default_image};
use super::selection::{assign, ProbeSpec};
use super::Board;

/// What the user asked for, flags first, bench.toml second, defaults last.
#[derive(Clone, Debug, Default)]
pub struct FlashRequest {
    /// The boards to flash (slave first when both).
    pub boards: Vec<Board>,
    pub bench: Option<BenchFile>,
    pub slave_probe: Option<ProbeSpec>,
    pub master_probe: Option<ProbeSpec>,
    pub slave_elf: Option<PathBuf>,
    pub master_elf: Option<PathBuf>,
    pub chip: Option<String>,
    /// Where default images are looked for (`<target>/thumbv7m-none-eabi/release/...`); None
    /// outside a Cargo workspace, where an image must then be given.
    pub target_dir: Option<PathBuf>,
}

impl FlashRequest {
    fn probe_spec(&self, board: Board) -> Option<ProbeSpec> {
        let flag = match board {
            Board::Slave => &self.slave_probe,
            Board::Master => &self.master_probe,
        };
        flag.clone().or_else(|| {
            self.bench
                .as_ref()
                .and_then(|b| b.board(board).probe.clone())
        })
    }

    // The image and whether it is the default build output (for the "build it with" hint).
    fn image(&self, board: Board) -> Result<(PathBuf, bool), String> {
        let flag = match board {
            Board::Slave => &self.slave_elf,
            Board::Master => &self.master_elf,
        };
        if let Some(path) = flag.clone().or_else(|| {
            self.bench
                .as_ref()
                .and_then(|b| b.board(board).image.clone())
        }) {
            return Ok((path, false));
        }
        match &self.target_dir {
            Some(dir) => Ok((default_image(dir, board), true)),
            None => Err(format!(
                "no image for the {board}: not inside a Cargo workspace and CARGO_TARGET_DIR is \
                 not set; pass --{board}-elf FILE or set [{board}] image in bench.toml"
            )),
        }
    }

    /// The chip both boards are flashed as.
    pub fn chip(&self) -> String {
        self.chip
            .clone()
            .or_else(|| self.bench.as_ref().map(|b| b.chip.clone()))
            .unwrap_or_else(|| DEFAULT_CHIP.to_string())
    }
}

/// Checks the request against the files and the attached probes and returns one job per
/// board, or every problem found, one per line.
pub fn plan(request: &FlashRequest, lister: &Lister) -> Result<Vec<FlashJob>, String> {
    let mut problems = Vec::new();
    let chip = request.chip();
    if let Err(e) = check_chip_name(&chip) {
        problems.push(e);
    }
    let mut images = Vec::new();
    for &board in &request.boards {
        match request
            .image(board)
            .and_then(|(path, is_default)| check_image(board, &path, is_default).map(|()| path))
        {
            Ok(path) => images.push((board, path)),
            Err(e) => problems.push(e),
        }
    }
    let wanted: Vec<(Board, Option<ProbeSpec>)> = request
        .boards
        .iter()
        .map(|&b| (b, request.probe_spec(b)))
        .collect();
    // One probe named for both boards is a mistake the probes need not be asked about.
    if let [(_, Some(a)), (_, Some(b))] = wanted.as_slice() {
        if a == b {
            problems.push(format!(
                "the slave and the master are both given probe {a}: each board needs its own \
                 (--slave-probe, --master-probe, or [slave] and [master] probe in bench.toml)"
            ));
        }
    }
    let attached = lister.list_all_with_access();
    let probes = match assign(&wanted, &attached) {
        Ok(p) => p,
        Err(e) => {
            problems.push(e.to_string());
            Vec::new()
        }
    };
    match problems.len() {
        0 => {}
        1 => return Err(problems.remove(0)),
        n => {
            let list: Vec<String> = problems.iter().map(|p| format!("* {p}")).collect();
            return Err(format!("{n} problems:\n{}", list.join("\n")));
        }
    }
    Ok(probes
        .into_iter()
        .zip(images)
        .map(|((board, probe), (_, image))| FlashJob {
            board,
            probe: probe.info,
            image,
            chip: chip.clone(),
        })
        .collect())
}
