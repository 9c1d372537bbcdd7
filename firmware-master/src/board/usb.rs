//! The blue pill's own USB port (PA11 D-, PA12 D+) as the host's line, in the image built with
//! the `usb` feature (USART1 then unused): `usb_port.rs` on the chip's USB driver.
//!
//! The blue pill pulls D+ up with R10, which must be 1.5 kOhm for a full-speed device; many
//! boards carry 10 kOhm or 4.7 kOhm, and then enumeration fails or comes and goes
//! (docs/pinmap.md says what to do about it). USART1 works whatever R10 is.

use embassy_stm32::peripherals::{PA11, PA12, USB};
use embassy_stm32::usb::Driver;
use embassy_stm32::Peri;
use embassy_usb::UsbDevice;

use super::usb_port::{self, UsbStatics};
use super::Irqs;

type UsbDriver = Driver<'static, USB>;
/// The USB device, run by its own task (enumeration, the port's control requests).
pub type Device = UsbDevice<'static, UsbDriver>;
pub type SerialTx = usb_port::SerialTx<'static, UsbDriver>;
pub type SerialRx = usb_port::SerialRx<'static, UsbDriver>;

/// The device and the port's two halves, for the chip whose ID is `uid`.
pub fn new(
    usb: Peri<'static, USB>,
    dp: Peri<'static, PA12>,
    dm: Peri<'static, PA11>,
    uid: &[u8; 12],
) -> (Device, SerialTx, SerialRx) {
    let driver = Driver::new(usb, Irqs, dp, dm);
    // In a static cell: the device runs for ever, and its buffers are too big for `main`'s
    // stack.
    let statics = cortex_m::singleton!(: UsbStatics<'static> = UsbStatics::default())
        .unwrap_or_else(|| defmt::panic!("usb::new called twice"));
    usb_port::build(driver, uid, statics)
}
