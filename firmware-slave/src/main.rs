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

    /// The board configuration (the emulator runs the same one): seed 004's sensors, every
    /// encoder edge time-stamped (EXTI, `board/exti.rs`) with the timers cross-checking, and
    /// the update rate the image was built for (1 kHz unless `OMNIBENCH_SLAVE_RATE_HZ` says
    /// otherwise; the emulator's `--slave-rate` matches it).
    static CONFIG: SlaveConfig =
        SlaveConfig::DEFAULT.with_update_period_us(board_period::BOARD_PERIOD_US);

    /// The update period the image was built for (`OMNIBENCH_SLAVE_RATE_HZ`, checked by
    /// `build.rs`; 1 kHz when unset).
    mod board_period {
        include!(concat!(env!("OUT_DIR"), "/board_period.rs"));
    }

    /// Runs the whole portable firmware; it never returns.
    #[embassy_executor::task]
    async fn odometry(
        counters: board::Counters,
        edges: board::EdgeCapture,
        abs: board::AbsoluteEncoder,
        spi: board::SpiSlaveLink,
        shared: &'static SlaveShared,
    ) -> ! {
        #[cfg(feature = "cycles")]
        let cycles = board::cycles::DwtCycles::start();
        #[cfg(not(feature = "cycles"))]
        let cycles = firmware_slave::ports::NoCycles;
        firmware_slave::run(counters, edges, abs, spi, cycles, shared, &CONFIG).await
    }

    #[embassy_executor::main]
    async fn main(spawner: Spawner) {
        let board = board::init();
        defmt::info!(
            "omnibench slave (odometry computer) up, protocol v{=u16}",
            protocol::PROTOCOL_VERSION
        );

        // State the portable code shares between its tasks; it must outlive `main`'s frame.
        // Not a plain `static`: one non-zero byte in its initial value (an enum niche) would
        // put the whole struct (kilobytes, mostly zeros) into `.data`, whose initial image
        // is stored in flash. `singleton!` keeps it in `.bss` and builds it here, once.
        let shared = cortex_m::singleton!(: SlaveShared = SlaveShared::new())
            .unwrap_or_else(|| defmt::panic!("main ran twice"));
        spawner
            .spawn(bluepill::heartbeat(board.led).unwrap_or_else(|_| bluepill::already_running()));
        spawner.spawn(
            odometry(board.counters, board.edges, board.abs, board.spi, shared)
                .unwrap_or_else(|_| bluepill::already_running()),
        );
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
