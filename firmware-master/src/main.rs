//! The motion controller's firmware image: the STM32F103 board layer around the portable
//! `firmware_master` library.
//!
//! On the board, `board::init` builds the hardware ports (SPI link to the slave, serial link to
//! the host, motor drivers) and one task runs `firmware_master::run` on them. On the host this
//! binary is only a signpost: the same library runs inside the emulator instead.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod board;

#[cfg(target_os = "none")]
mod firmware {
    use embassy_executor::Spawner;
    use firmware_master::{MasterConfig, MasterShared};

    use crate::board;

    /// State the portable code shares between its tasks. A `static` because the task that uses
    /// it never ends, so it must outlive `main`'s stack frame.
    static SHARED: MasterShared = MasterShared::new();

    /// Runs the whole portable firmware; it never returns.
    #[embassy_executor::task]
    async fn motion(
        bus: board::SlaveLink,
        serial_rx: board::SerialRx,
        serial_tx: board::SerialTx,
        motors: board::Motors,
    ) -> ! {
        firmware_master::run(
            bus,
            serial_rx,
            serial_tx,
            motors,
            &SHARED,
            &MasterConfig::DEFAULT,
        )
        .await
    }

    #[embassy_executor::main]
    async fn main(spawner: Spawner) {
        let board = board::init();
        defmt::info!(
            "omnibench master (motion controller) up, protocol v{=u16}",
            protocol::PROTOCOL_VERSION
        );

        spawner.spawn(defmt::unwrap!(bluepill::heartbeat(board.led)));
        spawner.spawn(defmt::unwrap!(motion(
            board.slave,
            board.serial_rx,
            board.serial_tx,
            board.motors
        )));
    }
}

#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!(
        "firmware-master runs on an STM32F103C8 (blue pill): build it with \
         `cargo build --release --target thumbv7m-none-eabi` and flash it with \
         `cargo run --release --target thumbv7m-none-eabi` in firmware-master/ \
         (or `cargo flash-master`); `cargo run -p host-bench -- emulate` runs it emulated \
         on this machine."
    );
}
