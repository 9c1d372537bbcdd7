//! SPI1 master towards the odometry computer, with a software chip select on PA4.

use embassy_stm32::gpio::{Level, Output, Pull, Speed};
use embassy_stm32::mode::Async;
use embassy_stm32::peripherals::{DMA1_CH2, DMA1_CH3, PA4, PA5, PA6, PA7, SPI1};
use embassy_stm32::spi::mode::Master;
use embassy_stm32::spi::{BitOrder, Config, Spi, MODE_0};
use embassy_stm32::time::Hertz;
use embassy_stm32::Peri;
use embassy_time::{Duration, Instant};
use firmware_master::ports::{SlaveBus, SpiMasterError};
use protocol::spi::SPI_FRAME_LEN;

use super::Irqs;

/// SCK rate. SPI1 runs from APB2 (72 MHz) through a power-of-two divider: /16 gives exactly
/// 4.5 MHz (`protocol::spi::SPI_CLOCK_HZ`): a `SPI_FRAME_LEN` (128-byte) frame takes ~228 us,
/// inside the 500 us stream poll period with room for the slave to re-arm, a quarter of the
/// slave's 18 MHz limit, and slow enough for a few centimetres of wire between the boards.
const SCK_HZ: u32 = protocol::spi::SPI_CLOCK_HZ;
/// A frame's time on the wire at `SCK_HZ`.
const FRAME_US: u64 = protocol::spi::frame_time_us(SCK_HZ);

/// Delay between chip select going low and the first clock edge, in CPU cycles (~5 us at
/// 72 MHz). The slave's NSS must be seen low before clocking starts; this also leaves a margin
/// for a slave that armed its transfer at the very last moment.
const CS_SETUP_CYCLES: u32 = 360;

/// SPI1 (PA5 SCK, PA6 MISO, PA7 MOSI) with DMA1 CH3 (TX) / CH2 (RX), chip select on PA4.
pub struct SlaveLink {
    spi: Spi<'static, Async, Master>,
    cs: Output<'static>,
}

impl SlaveLink {
    #[allow(clippy::too_many_arguments)] // one argument per owned resource, as embassy does
    pub fn new(
        spi: Peri<'static, SPI1>,
        cs: Peri<'static, PA4>,
        sck: Peri<'static, PA5>,
        miso: Peri<'static, PA6>,
        mosi: Peri<'static, PA7>,
        tx_dma: Peri<'static, DMA1_CH3>,
        rx_dma: Peri<'static, DMA1_CH2>,
        irqs: Irqs,
    ) -> Self {
        let mut config = Config::default();
        // Mode 0 on both boards: this driver (embassy-stm32 0.6.0) clears SPE at the start of
        // each DMA transfer, after chip select went low; in mode 1 that glitches SCK and the
        // slave receives the frame shifted by a bit (embassy issue #6932, fixed after 0.6.0).
        config.mode = MODE_0;
        config.bit_order = BitOrder::MsbFirst;
        config.frequency = Hertz(SCK_HZ);
        // An absent or unpowered slave then reads as 0x00 bytes (a CRC failure) rather than
        // as whatever noise a floating MISO picks up.
        config.miso_pull = Pull::Down;
        // 10 MHz output edges: plenty for 4.5 MHz, and less ringing on the inter-board wires.
        config.gpio_speed = Speed::Medium;

        // Deselected (high) from the start, so the slave never sees a half transaction.
        let cs = Output::new(cs, Level::High, Speed::Medium);
        let spi = Spi::new(spi, sck, mosi, miso, tx_dma, rx_dma, irqs, config);
        Self { spi, cs }
    }
}

/// Holds chip select low; releases it when dropped, so a cancelled or failed exchange never
/// leaves the slave selected.
struct ChipSelect<'a>(&'a mut Output<'static>);

impl<'a> ChipSelect<'a> {
    fn assert(pin: &'a mut Output<'static>) -> Self {
        pin.set_low();
        Self(pin)
    }
}

impl Drop for ChipSelect<'_> {
    fn drop(&mut self) {
        self.0.set_high();
    }
}

impl SlaveBus for SlaveLink {
    async fn exchange(
        &mut self,
        tx: &[u8; SPI_FRAME_LEN],
        rx: &mut [u8; SPI_FRAME_LEN],
    ) -> Result<Instant, SpiMasterError> {
        let selected = ChipSelect::assert(&mut self.cs);
        // A blocking delay: a few microseconds, shorter than an executor round trip through
        // the timer queue would be.
        cortex_m::asm::delay(CS_SETUP_CYCLES);
        // Full duplex on DMA; it returns once the last bit has been clocked (BSY clear), or
        // later if another task holds the CPU then. The clocking starts here, inside this
        // call, and takes FRAME_US: that is when the slave saw its last bit.
        let start = Instant::now();
        let result = self.spi.transfer(rx, tx).await;
        drop(selected);
        result
            .map(|()| start + Duration::from_micros(FRAME_US))
            .map_err(|_| SpiMasterError::Bus)
    }
}
