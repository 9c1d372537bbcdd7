//! STM32F103C8 ("blue pill") board layer of the motion controller: clocks, pins, and the
//! embassy-stm32 implementations of the ports in `firmware_master::ports` plus the serial link.
//!
//! Pin map (see docs/pinmap.md): PA9/PA10 USART1 to the host with DMA1 CH4 (TX) / CH5 (RX),
//! PA4 chip select + PA5..PA7 SPI1 master with DMA1 CH2 (RX) / CH3 (TX), PA0..PA2 TIM2 PWM,
//! PB12..PB14 direction, PB15 driver enable, PC13 LED. TIM4 is embassy's time driver.

mod motors;
mod serial;
mod slave_link;

use embassy_stm32::gpio::{Level, Output, Speed};
use embassy_stm32::{bind_interrupts, dma, peripherals, usart};
use embassy_time::Timer;
// Linked for their side effects: the RTT transport behind `defmt` and the panic handler.
use {defmt_rtt as _, panic_probe as _};

pub use motors::Motors;
pub use serial::{SerialRx, SerialTx};
pub use slave_link::SlaveLink;

bind_interrupts!(pub struct Irqs {
    USART1 => usart::InterruptHandler<peripherals::USART1>;
    DMA1_CHANNEL2 => dma::InterruptHandler<peripherals::DMA1_CH2>;
    DMA1_CHANNEL3 => dma::InterruptHandler<peripherals::DMA1_CH3>;
    DMA1_CHANNEL4 => dma::InterruptHandler<peripherals::DMA1_CH4>;
    DMA1_CHANNEL5 => dma::InterruptHandler<peripherals::DMA1_CH5>;
});

/// Everything `main` hands to the tasks.
pub struct Board {
    pub slave: SlaveLink,
    pub serial_rx: SerialRx,
    pub serial_tx: SerialTx,
    pub motors: Motors,
    pub led: Output<'static>,
}

/// 72 MHz from the blue pill's 8 MHz crystal: PLL x9; APB1 /2 because it may not exceed 36 MHz
/// (its timers, TIM2 and TIM4, still run at 72 MHz thanks to the x2 timer multiplier); APB2 /1
/// so SPI1 and USART1 run from 72 MHz.
fn clock_config() -> embassy_stm32::Config {
    use embassy_stm32::rcc::{
        AHBPrescaler, APBPrescaler, Hse, HseMode, Pll, PllMul, PllPreDiv, PllSource, Sysclk,
    };
    use embassy_stm32::time::Hertz;

    let mut config = embassy_stm32::Config::default();
    config.rcc.hse = Some(Hse {
        freq: Hertz(8_000_000),
        mode: HseMode::Oscillator,
    });
    config.rcc.pll = Some(Pll {
        src: PllSource::HSE,
        prediv: PllPreDiv::DIV1,
        mul: PllMul::MUL9,
    });
    config.rcc.sys = Sysclk::PLL1_P;
    config.rcc.ahb_pre = AHBPrescaler::DIV1;
    config.rcc.apb1_pre = APBPrescaler::DIV2;
    config.rcc.apb2_pre = APBPrescaler::DIV1;
    config
}

/// Bring up the clocks and build every port. Called once, from `main`.
pub fn init() -> Board {
    let p = embassy_stm32::init(clock_config());

    // Motors first: the driver enable pin goes low (drivers off) as early as possible.
    let motors = Motors::new(p.TIM2, p.PA0, p.PA1, p.PA2, p.PB12, p.PB13, p.PB14, p.PB15);
    let slave = SlaveLink::new(
        p.SPI1, p.PA4, p.PA5, p.PA6, p.PA7, p.DMA1_CH3, p.DMA1_CH2, Irqs,
    );
    let (serial_tx, serial_rx) = serial::new(p.USART1, p.PA9, p.PA10, p.DMA1_CH4, p.DMA1_CH5, Irqs);
    // The blue pill's LED is wired from 3.3 V to PC13, so high = off.
    let led = Output::new(p.PC13, Level::High, Speed::Low);

    Board {
        slave,
        serial_rx,
        serial_tx,
        motors,
        led,
    }
}

/// Blink the status LED so a glance tells the firmware is alive (executor running).
#[embassy_executor::task]
pub async fn heartbeat(mut led: Output<'static>) -> ! {
    loop {
        led.set_low();
        Timer::after_millis(50).await;
        led.set_high();
        Timer::after_millis(950).await;
    }
}
