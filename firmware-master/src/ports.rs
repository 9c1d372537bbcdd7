//! The master's hardware seen through small traits. The board layer (`src/board/`) implements
//! them with embassy-stm32; the emulator in `host-bench` implements them in memory. The serial
//! link to the host is `embedded_io_async::{Read, Write}` (the ecosystem's own small traits).
//!
//! Time is the last port: the tasks use `embassy_time`, whose driver is TIM4 on the board and a
//! virtual clock in the emulator.

use embassy_time::Instant;
use protocol::spi::SPI_FRAME_LEN;

/// Number of driven omni wheels (seed 003 layout).
pub const DRIVE_WHEELS: usize = 3;

/// Full PWM duty in the units `MotorDrivers::set_duty` takes (per mille).
pub const DUTY_FULL: i16 = 1000;

/// Why a master-side SPI exchange failed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SpiMasterError {
    /// The peripheral reported an error (mode fault, overrun, DMA).
    Bus,
}

// Both embassy executors and the emulator run tasks on one thread: no `Send` bound wanted.
#[allow(async_fn_in_trait)]
/// SPI master towards the slave: one chip-select-framed, full-duplex, fixed-size transaction.
pub trait SlaveBus {
    /// Assert chip select, clock `tx` out while reading `rx`, release chip select. Returns
    /// when the frame's last bit was clocked, on this board's clock: the slave re-arms from
    /// that instant, not from when this task got the CPU back to release chip select (a task
    /// holding the CPU meanwhile must not move the instant the controller learns the slave's
    /// clock from).
    async fn exchange(
        &mut self,
        tx: &[u8; SPI_FRAME_LEN],
        rx: &mut [u8; SPI_FRAME_LEN],
    ) -> Result<Instant, SpiMasterError>;
}

/// The serial port's rate, set while it runs: the host negotiates a faster one than the
/// power-on rate (`crate::baud`). Both directions share it, as USART1's one divider does.
pub trait SerialRate {
    /// Run at `baud` (8N1) from now on; false, and the rate as it was, if the port cannot.
    /// Called only once the bytes written before have left the line (`flush`).
    fn set_baud(&mut self, baud: u32) -> bool;
}

/// The drive motors' encoders (quadrature, on the motor shafts).
pub trait MotorEncoders {
    /// Each motor's count now, free-running: a 16-bit counter that wraps (the controller only
    /// takes differences over one control period, far under 32 768 counts).
    fn counts(&mut self) -> [u16; DRIVE_WHEELS];
}

/// The three motor drivers (PWM magnitude + direction pin each).
pub trait MotorDrivers {
    /// Signed duty per wheel in per mille (-1000..=1000); the sign picks the direction pin.
    /// Callers clamp; implementations may clamp again.
    fn set_duty(&mut self, duty_permille: [i16; DRIVE_WHEELS]);
    /// Stop driving every motor (zero duty, driver disabled if the board has an enable pin).
    fn stop(&mut self);
}
