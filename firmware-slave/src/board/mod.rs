//! STM32F103C8 ("blue pill") board layer of the odometry computer: clocks, pins, and the
//! embassy-stm32 implementations of the ports in `firmware_slave::ports`.
//!
//! Pin map (see docs/pinmap.md): PA0/PA1 TIM2 encoder (left measuring wheel), PA8/PA9 TIM1
//! encoder (right), PA4..PA7 SPI1 slave (NSS, SCK, MISO, MOSI) with DMA1 CH2 (RX) / CH3 (TX),
//! PB8..PB15 absolute encoder, PC13 LED. TIM4 is embassy's time driver.

mod abs_encoder;
#[cfg(feature = "cycles")]
pub mod cycles;
mod exti;
mod qei;
mod spi_slave;

use embassy_stm32::gpio::Output;
use embassy_stm32::{bind_interrupts, dma, peripherals};
// Linked for its side effect: the RTT transport behind `defmt`. The panic handler is
// `bluepill`'s (no `panic-probe`: its `print-defmt` pulls in `core::fmt`).
use defmt_rtt as _;

pub use abs_encoder::AbsoluteEncoder;
pub use exti::EdgeCapture;
pub use qei::Counters;
pub use spi_slave::SpiSlaveLink;

bind_interrupts!(pub struct Irqs {
    DMA1_CHANNEL2 => dma::InterruptHandler<peripherals::DMA1_CH2>;
    DMA1_CHANNEL3 => dma::InterruptHandler<peripherals::DMA1_CH3>;
});

/// Everything `main` hands to the tasks.
pub struct Board {
    pub counters: Counters,
    pub edges: EdgeCapture,
    pub abs: AbsoluteEncoder,
    pub spi: SpiSlaveLink,
    pub led: Output<'static>,
}

/// Bring up the clocks and build every port. Called once, from `main`.
pub fn init() -> Board {
    let p = embassy_stm32::init(bluepill::clock_config());
    bluepill::mask_unhandled_interrupts();
    bluepill::crc::install(embassy_stm32::crc::Crc::new(p.CRC));

    let counters = Counters::new(p.TIM2, p.PA0, p.PA1, p.TIM1, p.PA8, p.PA9);
    let abs = AbsoluteEncoder::new(p.PB8, p.PB9, p.PB10, p.PB11, p.PB12, p.PB13, p.PB14, p.PB15);
    let spi = SpiSlaveLink::new(
        p.SPI1, p.PA4, p.PA5, p.PA6, p.PA7, p.DMA1_CH3, p.DMA1_CH2, Irqs,
    );
    let led = bluepill::status_led(p.PC13);
    // After the timers and the SPI slave have set up PA0/1/4/8/9: route their edges.
    exti::init();
    // SAFETY: the one `EdgeCapture` (the odometry task's).
    let edges = unsafe { EdgeCapture::new() };

    Board {
        counters,
        edges,
        abs,
        spi,
        led,
    }
}
