//! STM32F103C8 ("blue pill") board layer of the motion controller: clocks, pins, and the
//! embassy-stm32 implementations of the ports in `firmware_master::ports` plus the serial link.
//!
//! Pin map (see docs/pinmap.md): PB6/PB7 USART1 (remapped) to the host with DMA1 CH4 (TX) / CH5
//! (RX), PA4 chip select + PA5..PA7 SPI1 master with DMA1 CH2 (RX) / CH3 (TX), PA0..PA2 TIM2
//! PWM, PB12..PB14 direction, PB15 driver enable, motor encoders on TIM3 (PB4/PB5), TIM1
//! (PA8/PA9) and EXTI 8/9 (PB8/PB9), PC13 LED. With the `usb` feature the host's line is the
//! chip's own USB on PA11/PA12 (CDC-ACM) instead of USART1. TIM4 is embassy's time driver. JTAG is off
//! (PB4 is a timer pin); SWD on PA13/PA14 stays.

mod motor_encoders;
mod motors;
#[cfg(not(feature = "usb"))]
mod serial;
mod slave_link;
#[cfg(feature = "usb")]
mod usb;
#[cfg(feature = "usb")]
mod usb_port;

use embassy_stm32::gpio::Output;
use embassy_stm32::{bind_interrupts, dma, peripherals};
use firmware_master::MasterConfig;
// Linked for its side effect: the RTT transport behind `defmt`. The panic handler is
// `bluepill`'s (no `panic-probe`: its `print-defmt` pulls in `core::fmt`).
use defmt_rtt as _;

pub use motor_encoders::Encoders;
pub use motors::Motors;
// The line to the host: USART1 through a USB-serial adapter, or (`usb` feature) the chip's own
// USB as a CDC-ACM port.
#[cfg(not(feature = "usb"))]
pub use serial::{SerialRx as HostRx, SerialTx as HostTx};
pub use slave_link::SlaveLink;
#[cfg(feature = "usb")]
pub use usb::{Device as UsbDevice, SerialRx as HostRx, SerialTx as HostTx};

#[cfg(not(feature = "usb"))]
bind_interrupts!(pub struct Irqs {
    USART1 => embassy_stm32::usart::InterruptHandler<peripherals::USART1>;
    DMA1_CHANNEL2 => dma::InterruptHandler<peripherals::DMA1_CH2>;
    DMA1_CHANNEL3 => dma::InterruptHandler<peripherals::DMA1_CH3>;
    DMA1_CHANNEL4 => dma::InterruptHandler<peripherals::DMA1_CH4>;
    DMA1_CHANNEL5 => dma::InterruptHandler<peripherals::DMA1_CH5>;
});

#[cfg(feature = "usb")]
bind_interrupts!(pub struct Irqs {
    DMA1_CHANNEL2 => dma::InterruptHandler<peripherals::DMA1_CH2>;
    DMA1_CHANNEL3 => dma::InterruptHandler<peripherals::DMA1_CH3>;
    USB_LP_CAN1_RX0 => embassy_stm32::usb::InterruptHandler<peripherals::USB>;
});

/// Everything `main` hands to the tasks.
pub struct Board {
    pub slave: SlaveLink,
    /// The line to the host.
    pub host_rx: HostRx,
    pub host_tx: HostTx,
    /// The USB device, to be run by its own task.
    #[cfg(feature = "usb")]
    pub usb: UsbDevice,
    pub motors: Motors,
    pub encoders: Encoders,
    pub led: Output<'static>,
}

/// This chip's 96-bit unique ID (RM0008 §30.2: factory-programmed at 0x1FFF_F7E8), as the 12
/// bytes in address order, i.e. the 96-bit value little-endian: the same bytes a debug probe
/// reads from that address, so the host can tell which probe and which serial port belong to
/// the same board.
pub fn unique_id() -> [u8; 12] {
    // embassy's `uid()` reads exactly those 12 bytes (`pac::UID` is 0x1FFF_F7E8 on the F103).
    embassy_stm32::uid::uid()
}

/// Bring up the clocks and build every port for `config` (its `baud` sets USART1). Called
/// once, from `main`.
pub fn init(config: &MasterConfig) -> Board {
    let mut chip = bluepill::clock_config();
    // JTAG off, SWD kept: frees PB4 for motor 1's encoder.
    chip.swj = embassy_stm32::gpio::SwjCfg::SwdOnly;
    let p = embassy_stm32::init(chip);
    bluepill::mask_unhandled_interrupts();

    // Motors first: the driver enable pin goes low (drivers off) as early as possible.
    let motors = Motors::new(p.TIM2, p.PA0, p.PA1, p.PA2, p.PB12, p.PB13, p.PB14, p.PB15);
    bluepill::crc::install(embassy_stm32::crc::Crc::new(p.CRC));
    let slave = SlaveLink::new(
        p.SPI1, p.PA4, p.PA5, p.PA6, p.PA7, p.DMA1_CH3, p.DMA1_CH2, Irqs,
    );
    let encoders = Encoders::new(p.TIM3, p.PB4, p.PB5, p.TIM1, p.PA8, p.PA9, p.PB8, p.PB9);
    #[cfg(not(feature = "usb"))]
    let (host_tx, host_rx) = serial::new(
        config.baud,
        p.USART1,
        p.PB6,
        p.PB7,
        p.DMA1_CH4,
        p.DMA1_CH5,
        Irqs,
    );
    #[cfg(feature = "usb")]
    let (usb, host_tx, host_rx) = usb::new(p.USB, p.PA12, p.PA11, &config.uid);
    let led = bluepill::status_led(p.PC13);

    Board {
        slave,
        host_rx,
        host_tx,
        #[cfg(feature = "usb")]
        usb,
        motors,
        encoders,
        led,
    }
}
