//! omnibench's host side: the emulator (both boards' firmware against a simulated robot),
//! the simulated robot itself, and reporting. The `host-bench` binary is the CLI over this.

pub mod accuracy;
pub mod emulator;
pub mod generate;
pub mod plant;
pub mod replay;
pub mod report;
pub mod robot;
pub mod tickstream;
pub mod trajectory;
