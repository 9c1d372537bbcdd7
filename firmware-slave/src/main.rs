//! The odometry computer's firmware image: the STM32F103 board layer around the portable
//! `firmware_slave` library.
//!
//! On the board, `board::init` builds the hardware ports (quadrature counters, absolute encoder
//! pins, SPI slave) and one task runs `firmware_slave::run` on them. On the host this binary is
//! only a signpost: the same library runs inside the emulator instead.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod board;

#[cfg(target_os = "none")]
mod firmware {
    use embassy_executor::Spawner;
    use firmware_slave::{SlaveConfig, SlaveShared};

    use crate::board;

    /// State the portable code shares between its tasks. A `static` because the task that uses
    /// it never ends, so it must outlive `main`'s stack frame.
    static SHARED: SlaveShared = SlaveShared::new();

    /// The board configuration (the emulator runs the same one): seed 004's sensors, every
    /// encoder edge time-stamped (EXTI, `board/exti.rs`) with the timers cross-checking.
    static CONFIG: SlaveConfig = SlaveConfig::DEFAULT;

    /// Runs the whole portable firmware; it never returns.
    #[embassy_executor::task]
    async fn odometry(
        counters: board::Counters,
        edges: board::EdgeCapture,
        abs: board::AbsoluteEncoder,
        spi: board::SpiSlaveLink,
    ) -> ! {
        firmware_slave::run(counters, edges, abs, spi, &SHARED, &CONFIG).await
    }

    #[embassy_executor::main]
    async fn main(spawner: Spawner) {
        let board = board::init();
        defmt::info!(
            "omnibench slave (odometry computer) up, protocol v{=u16}",
            protocol::PROTOCOL_VERSION
        );

        spawner.spawn(defmt::unwrap!(bluepill::heartbeat(board.led)));
        spawner.spawn(defmt::unwrap!(odometry(
            board.counters,
            board.edges,
            board.abs,
            board.spi
        )));
    }
}

#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!(
        "firmware-slave runs on an STM32F103C8 (blue pill): build it with \
         `cargo build --release --target thumbv7m-none-eabi` and flash it with \
         `cargo run --release --target thumbv7m-none-eabi` in firmware-slave/ \
         (or `cargo flash-slave`); `cargo run -p host-bench -- emulate` runs it emulated \
         on this machine."
    );
}
