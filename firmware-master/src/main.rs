//! The motion controller's firmware image: the STM32F103 board layer around the portable
//! `firmware_master` library.
//!
//! On the board, `board::init` builds the hardware ports (SPI link to the slave, serial link to
//! the host, motor drivers) and the four tasks of `firmware_master::tasks` run on them. On the
//! host this binary is only a signpost: the same library runs inside the emulator instead.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod board;

#[cfg(target_os = "none")]
mod firmware {
    use embassy_executor::Spawner;
    use firmware_master::{tasks, MasterConfig, MasterShared};

    use crate::board;

    // The portable firmware's four tasks (`firmware_master::tasks`), each a task of its own so
    // that a wake-up polls only the one it is for.
    #[embassy_executor::task]
    async fn host_rx(rx: board::HostRx, shared: &'static MasterShared) -> ! {
        tasks::host_rx_task(rx, shared).await
    }

    #[embassy_executor::task]
    async fn host_tx(
        tx: board::HostTx,
        shared: &'static MasterShared,
        config: &'static MasterConfig,
    ) -> ! {
        tasks::host_tx_task(tx, shared, config).await
    }

    #[embassy_executor::task]
    async fn slave_poll(
        bus: board::SlaveLink,
        shared: &'static MasterShared,
        config: &'static MasterConfig,
    ) -> ! {
        tasks::slave_poll_task(bus, shared, config).await
    }

    #[embassy_executor::task]
    async fn control(
        motors: board::Motors,
        encoders: board::Encoders,
        shared: &'static MasterShared,
        config: &'static MasterConfig,
    ) -> ! {
        tasks::control_task(motors, encoders, shared, config).await
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
        let config: &'static MasterConfig = cortex_m::singleton!(: MasterConfig = config)
            .unwrap_or_else(|| defmt::panic!("main ran twice"));
        let mut motors = board.motors;
        if !tasks::start(&mut motors, shared, config) {
            // An impossible geometry is a build-time mistake: no task runs, and the motors
            // stay off. Forgotten, not dropped: a dropped pin goes to analog input and would
            // leave the drivers' enable (PB15, low for off) floating.
            core::mem::forget(motors);
            return;
        }
        let running = bluepill::already_running;
        spawner.spawn(host_rx(board.host_rx, shared).unwrap_or_else(|_| running()));
        spawner.spawn(host_tx(board.host_tx, shared, config).unwrap_or_else(|_| running()));
        spawner.spawn(slave_poll(board.slave, shared, config).unwrap_or_else(|_| running()));
        spawner
            .spawn(control(motors, board.encoders, shared, config).unwrap_or_else(|_| running()));
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
