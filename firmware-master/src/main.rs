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

    /// Runs the whole portable firmware; it never returns.
    #[embassy_executor::task]
    async fn motion(
        bus: board::SlaveLink,
        serial_rx: board::HostRx,
        serial_tx: board::HostTx,
        motors: board::Motors,
        encoders: board::Encoders,
        shared: &'static MasterShared,
        config: MasterConfig,
    ) -> ! {
        firmware_master::run(bus, serial_rx, serial_tx, motors, encoders, shared, &config).await
    }

    /// The chip's USB device: enumeration, and the CDC-ACM port's endpoints.
    #[cfg(feature = "usb")]
    #[embassy_executor::task]
    async fn usb(mut device: board::UsbDevice) -> ! {
        device.run().await
    }

    #[embassy_executor::main]
    async fn main(spawner: Spawner) {
        // The emulator runs the same defaults; only this chip's identity is added here.
        let config = MasterConfig {
            uid: board::unique_id(),
            ..MasterConfig::DEFAULT
        };
        let board = board::init(&config);
        defmt::info!(
            "omnibench master (motion controller) up, protocol v{=u16}, {=u32} baud, uid {=[u8]:02x}",
            protocol::PROTOCOL_VERSION,
            config.baud,
            config.uid
        );

        // State the portable code shares between its tasks; it must outlive `main`'s frame.
        // Not a plain `static`: one non-zero byte in its initial value (an enum niche) would
        // put the whole struct (kilobytes, mostly zeros) into `.data`, whose initial image
        // is stored in flash. `singleton!` keeps it in `.bss` and builds it here, once.
        let shared = cortex_m::singleton!(: MasterShared = MasterShared::new())
            .unwrap_or_else(|| defmt::panic!("main ran twice"));
        spawner
            .spawn(bluepill::heartbeat(board.led).unwrap_or_else(|_| bluepill::already_running()));
        #[cfg(feature = "usb")]
        spawner.spawn(usb(board.usb).unwrap_or_else(|_| bluepill::already_running()));
        spawner.spawn(
            motion(
                board.slave,
                board.host_rx,
                board.host_tx,
                board.motors,
                board.encoders,
                shared,
                config,
            )
            .unwrap_or_else(|_| bluepill::already_running()),
        );
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
