//! SPI1 as a DMA-driven slave, framed by the master's chip select (NSS on PA4).
//!
//! # Why the SPI registers are driven through the PAC
//!
//! embassy-stm32 0.6.0 has `Spi::new_slave`, but on the F1 it does not fit this link:
//! * it configures the pins the master way: SCK and MOSI as alternate-function push-pull
//!   *outputs* (they would fight the master's drivers) and MISO as an input (the slave would
//!   never answer);
//! * its `transfer` ends with a busy-wait on BSY, and dropping it when the master ends a
//!   transaction early leaves SPE and the DMA requests enabled, with no API to reset the
//!   peripheral afterwards, which the F1 needs to realign its shift register (it does not
//!   resynchronise on NSS by itself).
//!
//! So this driver programs SPI1 (CR1/CR2/SR/DR) and its SCK/MISO/MOSI pins through the PAC, and
//! uses embassy for the rest: the DMA channels (`dma::Channel` and its `Transfer` futures, which
//! stop the channel when dropped) and the NSS edge (the board's own EXTI4 handler in
//! `board/exti.rs`: embassy's shared EXTI handler would disturb the encoder lines). On the F1 the
//! NSS input of the
//! SPI is just the pin read as an input, so PA4 serves both SPI1 (hardware NSS, SSM = 0) and
//! EXTI4.
//!
//! Mode 0 (CPOL = 0, CPHA = 0) on purpose, on both boards: the master's embassy-stm32 0.6.0 SPI
//! driver clears SPE at the start of every DMA transfer, after chip select is already low; in
//! mode 1 that disturbs SCK, the slave takes an extra edge and the whole frame arrives shifted
//! by a bit (embassy issue #6932, fixed only after 0.6.0).
//!
//! # What the master sees
//!
//! The master's first byte is whatever the slave's transmit path (data register and shift
//! register) holds when the master starts clocking. `exchange` preloads `tx[0]` when it arms,
//! so an armed slave answers with exactly `tx`; if the master starts a frame before the slave has
//! armed (or while it is disarmed between frames), it reads stale or idle bytes, which fail the
//! frame CRC and are discarded on its side.

use embassy_futures::join::join;
use embassy_futures::select::{select, Either};
use embassy_stm32::dma::{self, TransferOptions};
use embassy_stm32::gpio::{Input, Pull};
use embassy_stm32::pac::gpio::vals::{CnfIn, CnfOut, Mode};
use embassy_stm32::pac::spi::vals::{Bidimode, Cpha, Cpol, Dff, Lsbfirst, Mstr, Rxonly};
use embassy_stm32::peripherals::{DMA1_CH2, DMA1_CH3, PA4, PA5, PA6, PA7, SPI1};
use embassy_stm32::{pac, rcc, Peri};
use firmware_slave::ports::{SpiSlave, SpiSlaveError};
use protocol::spi::SPI_FRAME_LEN;

use super::exti::Nss;
use super::Irqs;

// One DMA transfer moves a whole frame, and a DMA channel's counter (CNDTR) is 16 bits.
const _: () = assert!(SPI_FRAME_LEN <= u16::MAX as usize);

/// SPI1 slave with DMA1 CH2 (RX) / CH3 (TX), framed by NSS on PA4.
pub struct SpiSlaveLink {
    /// PA4: the SPI's hardware NSS and, through EXTI4, the end-of-transaction signal.
    nss: Nss,
    /// Keeps PA4 configured as an input with pull-up.
    _nss_pin: Input<'static>,
    rx_dma: dma::Channel<'static>,
    tx_dma: dma::Channel<'static>,
    // Ownership only: nothing else may touch SPI1 or its pins while this driver exists.
    _spi: Peri<'static, SPI1>,
    _sck: Peri<'static, PA5>,
    _miso: Peri<'static, PA6>,
    _mosi: Peri<'static, PA7>,
}

impl SpiSlaveLink {
    #[allow(clippy::too_many_arguments)] // one argument per owned resource, as embassy does
    pub fn new(
        spi: Peri<'static, SPI1>,
        nss: Peri<'static, PA4>,
        sck: Peri<'static, PA5>,
        miso: Peri<'static, PA6>,
        mosi: Peri<'static, PA7>,
        tx_dma: Peri<'static, DMA1_CH3>,
        rx_dma: Peri<'static, DMA1_CH2>,
        irqs: Irqs,
    ) -> Self {
        rcc::enable_and_reset::<SPI1>();
        critical_section::with(|_| {
            // SPI1 on PA4..PA7 is the reset mapping; set it anyway so no earlier code can move
            // it. SWJ_CFG is write-only: NO_OP keeps the debug port configuration unchanged.
            pac::AFIO.mapr().modify(|w| {
                w.set_swj_cfg(pac::afio::vals::SwjCfg::NO_OP);
                w.set_spi1_remap(false);
            });
        });

        // A pull-up rather than a floating input: while the master resets or is unplugged its
        // PA4 floats, and the pull-up keeps this slave deselected instead of reacting to noise.
        let nss_pin = Input::new(nss, Pull::Up);

        critical_section::with(|_| {
            let gpioa = pac::GPIOA;
            gpioa.cr(0).modify(|w| {
                // PA5 SCK and PA7 MOSI are driven by the master: floating inputs.
                for pin in [5, 7] {
                    w.set_mode(pin, Mode::INPUT);
                    w.set_cnf_in(pin, CnfIn::FLOATING);
                }
                // PA6 MISO: the SPI drives it (alternate function push-pull). 10 MHz edges are
                // plenty for ~2 MHz SCK and ring less on the inter-board wires than 50 MHz.
                w.set_mode(6, Mode::OUTPUT10MHZ);
                w.set_cnf_out(6, CnfOut::ALT_PUSH_PULL);
            });
        });

        configure_registers();

        Self {
            nss: Nss::new(),
            _nss_pin: nss_pin,
            rx_dma: dma::Channel::new(rx_dma, irqs),
            tx_dma: dma::Channel::new(tx_dma, irqs),
            _spi: spi,
            _sck: sck,
            _miso: miso,
            _mosi: mosi,
        }
    }
}

/// Program SPI1 for this link, disabled (SPE = 0), with no DMA requests.
fn configure_registers() {
    let regs = pac::SPI1;
    regs.cr2().write(|w| {
        // NSS is an input: SSOE = 0. DMA requests are enabled per exchange.
        w.set_ssoe(false);
        w.set_rxdmaen(false);
        w.set_txdmaen(false);
    });
    regs.cr1().write(|w| {
        w.set_mstr(Mstr::SLAVE);
        // Hardware NSS (SSM = 0): the slave is selected only while PA4 is low, so clocks on a
        // shared bus, or noise while the master is away, do not shift data.
        w.set_ssm(false);
        w.set_cpol(Cpol::IDLE_LOW);
        w.set_cpha(Cpha::FIRST_EDGE);
        w.set_dff(Dff::BITS8);
        w.set_lsbfirst(Lsbfirst::MSBFIRST);
        w.set_bidimode(Bidimode::UNIDIRECTIONAL);
        w.set_rxonly(Rxonly::FULL_DUPLEX);
        w.set_crcen(false);
        w.set_spe(false);
    });
}

/// Return SPI1 to its just-configured state after an aborted transaction.
///
/// The F1 SPI does not resynchronise on NSS, and clearing SPE is not documented to reset its
/// shift register or bit counter, so after a partial frame the next one could start
/// misaligned. The RCC reset clears everything (data register, shift register, flags); then
/// the configuration is written again.
fn reset_peripheral() {
    critical_section::with(|_| {
        pac::RCC.apb2rstr().modify(|w| w.set_spi1rst(true));
        pac::RCC.apb2rstr().modify(|w| w.set_spi1rst(false));
    });
    configure_registers();
}

/// Resets SPI1 when dropped; defused with `mem::forget` once a frame has completed.
struct ResetOnDrop;

impl Drop for ResetOnDrop {
    fn drop(&mut self) {
        reset_peripheral();
    }
}

/// Stop the SPI after a complete frame: no more DMA requests, no shifting until re-armed.
///
/// No wait on BSY: the whole frame has been received, so the master has stopped clocking and
/// nothing is left to shift; spinning on a flag here could only stall the executor.
fn disarm() {
    let regs = pac::SPI1;
    regs.cr1().modify(|w| w.set_spe(false));
    regs.cr2().modify(|w| {
        w.set_rxdmaen(false);
        w.set_txdmaen(false);
    });
}

/// Empty the receive data register and clear a pending overrun, so the RX DMA's first read is
/// the first byte of the coming frame.
fn drain_receiver() {
    let regs = pac::SPI1;
    // The F1 receive buffer holds one byte: reading DR empties it, and reading DR then SR is
    // the documented sequence that clears OVR.
    let _ = regs.dr().read();
    let _ = regs.sr().read();
}

impl SpiSlave for SpiSlaveLink {
    async fn exchange(
        &mut self,
        tx: &[u8; SPI_FRAME_LEN],
        rx: &mut [u8; SPI_FRAME_LEN],
    ) -> Result<(), SpiSlaveError> {
        // Never arm in the middle of a transaction: we would shift from a random bit onwards.
        // If the master is already clocking a frame we missed, let it finish first.
        if self.nss.is_low() {
            self.nss.wait_for_high().await;
        }

        let regs = pac::SPI1;
        drain_receiver();

        // If this future is dropped while armed (the caller gave up waiting), the peripheral
        // may be mid-frame: reset it then. Declared before the transfers so it is dropped after
        // them, once both DMA channels have stopped.
        let armed = ResetOnDrop;

        // The data register serves both directions (reads pop RX, writes push TX).
        let dr = regs.dr().as_ptr() as *mut u8;
        // Arming order from ST's reference HAL for full-duplex DMA: RX request, both channels,
        // SPE, and the TX request last; the TX DMA then immediately preloads tx[0].
        regs.cr2().modify(|w| w.set_rxdmaen(true));
        // SAFETY: `dr` is SPI1's data register, valid for byte-wide DMA access. The buffers
        // outlive the transfers: both `Transfer`s are locals of this future and are dropped
        // (which stops their channel) before it returns, or with it if it is cancelled.
        let mut rx_transfer = unsafe {
            self.rx_dma
                .read((), dr, &mut rx[..], TransferOptions::default())
        };
        let mut tx_transfer = unsafe {
            self.tx_dma
                .write((), &tx[..], dr, TransferOptions::default())
        };
        regs.cr1().modify(|w| w.set_spe(true));
        regs.cr2().modify(|w| w.set_txdmaen(true));

        // Whichever comes first: the whole frame, or the master ending the transaction (NSS
        // rising). EXTI4 watches the same pin the SPI uses as NSS.
        let completed = match select(
            join(&mut rx_transfer, &mut tx_transfer),
            self.nss.wait_for_rising_edge(),
        )
        .await
        {
            Either::First(_) => true,
            // NSS rises right after the last byte, possibly before the DMA interrupt has been
            // handled: the frame is complete if the RX channel has nothing left to transfer
            // (RX finishes after TX, as it waits for the last byte's final bit).
            Either::Second(()) => rx_transfer.get_remaining_transfers() == 0,
        };
        // Stops both channels if they are still running.
        drop(rx_transfer);
        drop(tx_transfer);

        if !completed {
            // Resets the peripheral: the partial frame left its shift register misaligned.
            drop(armed);
            return Err(SpiSlaveError::Aborted);
        }
        core::mem::forget(armed);

        let status = regs.sr().read();
        disarm();
        if status.ovr() || status.modf() {
            // A byte was lost (DMA starved) or the peripheral faulted: the frame is not
            // trustworthy and the peripheral needs a clean start.
            reset_peripheral();
            return Err(SpiSlaveError::Bus);
        }
        Ok(())
    }
}
