//! USART1 to the host (a USB-serial adapter): 8N1, both directions on DMA, at
//! `MasterConfig::baud` (115200) from power-on and at whatever rate the host negotiates after
//! (`firmware_master`'s `baud` module; one divider serves both directions).
//!
//! Reception runs continuously into a circular DMA buffer (`RingBufferedUartRx`), so bytes keep
//! arriving while the control code is busy and a read returns whatever is there: at once if
//! bytes are waiting, otherwise when the line goes idle after a burst (or the DMA reaches the
//! half/end of the buffer). After a line error (framing, noise, overrun) a read returns the
//! error once and the next read restarts reception; the COBS framing above resynchronises.

use embassy_stm32::gpio::Pull;
use embassy_stm32::mode::Async;
use embassy_stm32::peripherals::{DMA1_CH4, DMA1_CH5, PB6, PB7, USART1};
use embassy_stm32::usart::{Config, RingBufferedUartRx, Uart, UartTx};
use embassy_stm32::Peri;

use super::Irqs;

/// The host-bound half: DMA writes, `embedded_io_async::Write`, and the port's rate.
pub struct SerialTx {
    tx: UartTx<'static, Async>,
    baud: u32,
}

impl embedded_io_async::ErrorType for SerialTx {
    type Error = embassy_stm32::usart::Error;
}

impl embedded_io_async::Write for SerialTx {
    async fn write(&mut self, buf: &[u8]) -> Result<usize, Self::Error> {
        self.tx.write(buf).await.map(|()| buf.len())
    }

    async fn flush(&mut self) -> Result<(), Self::Error> {
        self.tx.flush().await
    }
}

impl firmware_master::ports::SerialRate for SerialTx {
    fn set_baud(&mut self, baud: u32) -> bool {
        // A divider it cannot make leaves the USART disabled: put the old rate back.
        if self.tx.set_baudrate(baud).is_ok() {
            self.baud = baud;
            return true;
        }
        let _ = self.tx.set_baudrate(self.baud);
        false
    }
}
/// The host-to-master half: circular DMA reception, `embedded_io_async::Read`.
pub type SerialRx = RingBufferedUartRx<'static>;

/// Receive buffer size. At 2 Mbaud (200 kB/s, a negotiated rate `play` streams events at)
/// 2 KiB absorb ~10 ms of a continuous stream without any read, more than the control code
/// ever stalls the reader (512 B, enough for ~44 ms at the power-on 115200, were 2.5 ms there).
const RX_BUFFER_LEN: usize = 2048;

/// USART1 on PB6 (TX) / PB7 (RX) (its AFIO remap: PA9 is motor 2's encoder) at `baud`, 8N1, DMA1 CH4 (TX) / CH5 (RX); reception starts
/// at once. `baud` is `MasterConfig::baud`: the one place the link's rate is chosen.
pub fn new(
    baud: u32,
    usart: Peri<'static, USART1>,
    tx: Peri<'static, PB6>,
    rx: Peri<'static, PB7>,
    tx_dma: Peri<'static, DMA1_CH4>,
    rx_dma: Peri<'static, DMA1_CH5>,
    irqs: Irqs,
) -> (SerialTx, SerialRx) {
    // 8 data bits, no parity, 1 stop bit are the defaults.
    let mut config = Config::default();
    config.baudrate = baud;
    // With the USB-serial adapter unplugged, RX would float and produce framing errors and
    // noise bytes; the pull-up holds it at the idle (mark) level. PB7 is 5 V tolerant.
    config.rx_pull = Pull::Up;

    // USART1 runs from APB2 (72 MHz): its divider reaches about 1.1 kbaud to 4.5 Mbaud.
    let uart = Uart::new(usart, rx, tx, tx_dma, rx_dma, irqs, config).unwrap_or_else(|_| {
        defmt::panic!(
            "USART1 rejected MasterConfig::baud = {=u32} (8N1 from 72 MHz: ~1100..4500000)",
            baud
        )
    });
    let (tx, rx) = uart.split();
    let tx = SerialTx { tx, baud };

    let buffer = cortex_m::singleton!(: [u8; RX_BUFFER_LEN] = [0; RX_BUFFER_LEN])
        .unwrap_or_else(|| defmt::panic!("serial::new called twice"));
    let mut rx = rx.into_ring_buffered(buffer);
    // Start receiving now rather than at the first read, so nothing the host sends while the
    // firmware starts up is lost.
    rx.start_uart();
    (tx, rx)
}
