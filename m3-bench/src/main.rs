//! Instruction counts of the slave's hot paths on a Cortex-M3 (`scripts/m3-bench` builds this
//! for `thumbv7m-none-eabi`, runs it under QEMU one instruction per translation block and counts
//! the instructions between markers in the execution log).
//!
//! The measured code is the slave's own (`firmware_slave::SlaveEstimator`), built with the
//! firmware's release profile. On the host this binary is only a signpost; its cases compile
//! and run in a unit test.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod chip;

#[cfg(not(target_os = "none"))]
fn main() {
    println!("m3-bench runs on a Cortex-M3 under QEMU: scripts/m3-bench [--json]");
}
