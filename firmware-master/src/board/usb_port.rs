//! The chip's own USB as a CDC-ACM serial port, for the image built with the `usb` feature:
//! the USB device with this board's identity (`protocol::serial::usb`: its serial number is
//! the chip's unique ID) and the port's two halves as the master's serial port
//! (`embedded_io_async::{Read, Write}` and `SerialRate`), one more implementation of it beside
//! USART1's. Generic over embassy-usb's driver and free of embassy-stm32, so the host tests it
//! over a fake driver (`tests/usb_port.rs`); `usb.rs` gives it the chip's driver.

use embassy_usb::class::cdc_acm::{CdcAcmClass, Receiver, Sender, State};
use embassy_usb::driver::{Driver, EndpointError};
use embassy_usb::{Builder, UsbDevice};
use embedded_io_async::{ErrorType, Read, Write};
use firmware_master::ports::SerialRate;
use protocol::serial::usb as ids;

/// Full-speed bulk packets, bytes.
pub const PACKET: usize = 64;

/// What the device and its port keep for as long as they run: descriptor and control
/// buffers sized for one CDC-ACM function, the class's state, the serial number's digits.
pub struct UsbStatics<'d> {
    config: [u8; 128],
    bos: [u8; 32],
    control: [u8; 64],
    state: State<'d>,
    serial: [u8; 24],
}

impl Default for UsbStatics<'_> {
    fn default() -> Self {
        UsbStatics {
            config: [0; 128],
            bos: [0; 32],
            control: [0; 64],
            state: State::new(),
            serial: [0; 24],
        }
    }
}

/// The host-bound half of the port.
pub struct SerialTx<'d, D: Driver<'d>>(Sender<'d, D>);

/// The host-to-master half: a packet handed on in pieces as the reader asks.
pub struct SerialRx<'d, D: Driver<'d>> {
    rx: Receiver<'d, D>,
    packet: [u8; PACKET],
    at: usize,
    len: usize,
}

/// The USB device of the master whose chip ID is `uid` on `driver` (to be run by its own
/// task), and its CDC-ACM port's two halves.
pub fn build<'d, D: Driver<'d>>(
    driver: D,
    uid: &[u8; 12],
    statics: &'d mut UsbStatics<'d>,
) -> (UsbDevice<'d, D>, SerialTx<'d, D>, SerialRx<'d, D>) {
    statics.serial = ids::serial_number(uid);
    let mut config = embassy_usb::Config::new(ids::VID, ids::PID);
    config.manufacturer = Some(ids::MANUFACTURER);
    config.product = Some(ids::PRODUCT);
    // Hex digits only: always UTF-8.
    config.serial_number = core::str::from_utf8(&statics.serial).ok();
    config.max_packet_size_0 = 64;
    let mut builder = Builder::new(
        driver,
        config,
        &mut statics.config,
        &mut statics.bos,
        &mut [],
        &mut statics.control,
    );
    let class = CdcAcmClass::new(&mut builder, &mut statics.state, PACKET as u16);
    let (tx, rx) = class.split();
    let rx = SerialRx {
        rx,
        packet: [0; PACKET],
        at: 0,
        len: 0,
    };
    (builder.build(), SerialTx(tx), rx)
}

impl<'d, D: Driver<'d>> ErrorType for SerialRx<'d, D> {
    type Error = EndpointError;
}

impl<'d, D: Driver<'d>> Read for SerialRx<'d, D> {
    /// The bytes of the host's next packet, once its port is open (a closed one: none yet).
    async fn read(&mut self, buf: &mut [u8]) -> Result<usize, Self::Error> {
        while self.at == self.len {
            self.rx.wait_connection().await;
            if let Ok(n) = self.rx.read_packet(&mut self.packet).await {
                (self.at, self.len) = (0, n);
            }
        }
        let n = buf.len().min(self.len - self.at);
        buf[..n].copy_from_slice(&self.packet[self.at..self.at + n]);
        self.at += n;
        Ok(n)
    }
}

impl<'d, D: Driver<'d>> ErrorType for SerialTx<'d, D> {
    type Error = EndpointError;
}

impl<'d, D: Driver<'d>> Write for SerialTx<'d, D> {
    async fn write(&mut self, buf: &[u8]) -> Result<usize, Self::Error> {
        // Only to a host that has the port open (DTR, which Linux's, macOS's and Windows'
        // CDC-ACM drivers raise on open and drop on close): bytes for no one are dropped, as
        // a UART's are, and never hold the sending task. An open port's driver reads
        // whatever its program does.
        if !self.0.dtr() {
            return Ok(buf.len());
        }
        for packet in buf.chunks(PACKET) {
            self.0.write_packet(packet).await?;
        }
        if buf.len().is_multiple_of(PACKET) {
            // A full last packet does not end a transfer: a zero-length one does, so the
            // host's driver hands the bytes on now.
            self.0.write_packet(&[]).await?;
        }
        Ok(buf.len())
    }

    /// Written packets are the endpoint's, sent as the host polls: nothing waits here.
    async fn flush(&mut self) -> Result<(), Self::Error> {
        Ok(())
    }
}

impl<'d, D: Driver<'d>> SerialRate for SerialTx<'d, D> {
    /// A CDC-ACM port has no line rate (the host's SET_LINE_CODING is taken and ignored): a
    /// switch is done as soon as asked.
    fn set_baud(&mut self, _baud: u32) -> bool {
        true
    }
}
