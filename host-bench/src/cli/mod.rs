//! The subcommands' bodies; `main.rs` holds the argument definitions.

pub mod analyse;
pub mod flash;
pub mod serial;
pub mod sweep;
