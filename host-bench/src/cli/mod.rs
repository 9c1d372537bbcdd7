//! The subcommands' bodies, and the argument structs of those with more than a few flags
//! (`main.rs` holds the rest).

pub mod analyse;
pub mod calibrate;
pub mod envelope;
pub mod flash;
pub mod generate;
pub mod pursuit_sweep;
pub mod serial;
pub mod sweep;
pub mod virtual_board;
