//! The on-board cycle report (feature `cycles`): the Cortex-M3's DWT cycle counter read around
//! every odometry update, and a line over defmt every second, so the figure `scripts/m3-bench`
//! counts in instructions can be read off a real board in cycles (flash wait states, taken
//! branches and long multiplies included).

use firmware_slave::ports::{CycleCounter, UpdateCycles};

pub struct DwtCycles;

impl DwtCycles {
    /// Switch the cycle counter on.
    pub fn start() -> Self {
        // SAFETY: only the trace enable and the cycle counter are touched; nothing else in
        // this firmware uses DCB or DWT.
        let mut core = unsafe { cortex_m::Peripherals::steal() };
        core.DCB.enable_trace();
        core.DWT.enable_cycle_counter();
        DwtCycles
    }
}

impl CycleCounter for DwtCycles {
    fn cycles(&mut self) -> Option<u32> {
        Some(cortex_m::peripheral::DWT::cycle_count())
    }

    fn report(&mut self, c: &UpdateCycles) {
        defmt::info!(
            "odometry update: {=u32} updates, cycles min {=u32} mean {=u32} max {=u32} (72 MHz)",
            c.updates,
            c.min,
            c.mean(),
            c.max
        );
    }
}
