//! What both omnibench computers share as STM32F103C8 "blue pill" boards: the clock tree, the
//! status LED, wheel encoders on timers, the CRC unit as the CRC-32 engine, and the panic
//! handler. Each firmware's `board/` layer builds its own peripherals on top of this.
#![cfg_attr(not(test), no_std)]

#[cfg(target_os = "none")]
mod board {
    use embassy_stm32::gpio::{Level, Output, Speed};
    use embassy_stm32::peripherals::PC13;
    use embassy_stm32::Peri;
    use embassy_time::Timer;

    /// 72 MHz from the blue pill's 8 MHz crystal: PLL x9; APB1 /2 because it may not exceed
    /// 36 MHz (its timers, TIM2 and TIM4, still run at 72 MHz thanks to the x2 timer
    /// multiplier); APB2 /1 so SPI1, USART1 and TIM1 run from 72 MHz.
    pub fn clock_config() -> embassy_stm32::Config {
        use embassy_stm32::rcc::{
            AHBPrescaler, APBPrescaler, Hse, HseMode, Pll, PllMul, PllPreDiv, PllSource, Sysclk,
        };
        use embassy_stm32::time::Hertz;

        let mut config = embassy_stm32::Config::default();
        config.rcc.hse = Some(Hse {
            freq: Hertz(8_000_000),
            mode: HseMode::Oscillator,
        });
        config.rcc.pll = Some(Pll {
            src: PllSource::HSE,
            prediv: PllPreDiv::DIV1,
            mul: PllMul::MUL9,
        });
        config.rcc.sys = Sysclk::PLL1_P;
        config.rcc.ahb_pre = AHBPrescaler::DIV1;
        config.rcc.apb1_pre = APBPrescaler::DIV2;
        config.rcc.apb2_pre = APBPrescaler::DIV1;
        config
    }

    /// Mask every NVIC line whose vector is `DefaultHandler`. `embassy_stm32::init` enables
    /// the interrupts of every DMA channel and EXTI line, but a board binds handlers only for
    /// the ones it uses; the rest point at cortex-m-rt's `DefaultHandler`, an endless loop, so
    /// a stray pending bit (a DMA channel's, an EXTI line's) would hang the board. Call it
    /// right after `embassy_stm32::init`, before the board enables its own lines (each bound
    /// to a handler). The chip model (`scripts/board-model boot`) lists any line left.
    pub fn mask_unhandled_interrupts() {
        extern "C" {
            fn DefaultHandler();
        }
        /// The STM32F103C8's device interrupts, a medium-density part (RM0008 §10.1.2,
        /// table 63: positions 0 to 42, USBWakeup the last).
        const LINES: usize = 43;
        let default = DefaultHandler as *const () as usize & !1;
        // SAFETY: VTOR points at the vector table the image was linked with (cortex-m-rt sets
        // it at reset); its device entries follow the 16 system ones, a word each. Writing a
        // 1 to an ICER bit only disables that line.
        unsafe {
            let nvic = &*cortex_m::peripheral::NVIC::PTR;
            let table = (*cortex_m::peripheral::SCB::PTR).vtor.read() as *const usize;
            for line in 0..LINES {
                let vector = core::ptr::read_volatile(table.add(16 + line));
                if vector & !1 == default {
                    nvic.icer[line / 32].write(1 << (line % 32));
                }
            }
        }
    }

    /// A timer counting a wheel encoder (both boards: the slave's measuring wheels, the
    /// master's motors): mode 3 counts both edges of both channels (x4, the finest
    /// resolution), the 16-bit counter wraps through its whole range (the portable code takes
    /// differences), and pull-ups make open-collector encoders work at no cost to push-pull ones.
    pub const ENCODER_QEI: embassy_stm32::timer::qei::Config = embassy_stm32::timer::qei::Config {
        mode: embassy_stm32::timer::qei::QeiMode::Mode3,
        auto_reload: u16::MAX,
        ch1_pull: embassy_stm32::gpio::Pull::Up,
        ch2_pull: embassy_stm32::gpio::Pull::Up,
    };

    /// The Qei driver has no input-filter setting: after this an edge on CH1/CH2 must be
    /// stable for 8 timer clocks (111 ns at 72 MHz) to count. It rejects ringing and spikes on
    /// encoder cables while allowing edge rates of a few MHz, far above any wheel's. Takes the
    /// timer's `ccmr_input(0)` (general-purpose and advanced timers share its layout).
    pub fn filter_encoder_inputs(
        ccmr: embassy_stm32::pac::common::Reg<
            embassy_stm32::pac::timer::regs::CcmrInput2ch,
            embassy_stm32::pac::common::RW,
        >,
    ) {
        use embassy_stm32::pac::timer::vals::FilterValue;
        ccmr.modify(|w| {
            w.set_icf(0, FilterValue::FCK_INT_N8);
            w.set_icf(1, FilterValue::FCK_INT_N8);
        });
    }

    /// The on-board LED on PC13, off. It is wired from 3.3 V to the pin, so high = off.
    pub fn status_led(pin: Peri<'static, PC13>) -> Output<'static> {
        Output::new(pin, Level::High, Speed::Low)
    }

    /// Blink the status LED so a glance tells the firmware is alive (executor running).
    #[embassy_executor::task]
    pub async fn heartbeat(mut led: Output<'static>) -> ! {
        loop {
            led.set_low();
            Timer::after_millis(50).await;
            led.set_high();
            Timer::after_millis(950).await;
        }
    }

    /// A task spawned while its one instance still runs (a bug in a board layer): stop,
    /// saying so. Through here rather than `defmt::unwrap!`, whose message needs the
    /// executor's error type to be `defmt::Format`: embassy-executor's `defmt` feature, 48 B
    /// of the slave's flash and 68 B of the master's.
    pub fn already_running() -> ! {
        defmt::panic!("a task was spawned while it was still running")
    }
}

#[cfg(target_os = "none")]
pub use board::*;

#[cfg(target_os = "none")]
mod mem;

// On the host too, for its tests (its symbols only in the images).
pub mod divide;

#[cfg(target_os = "none")]
mod panic;

#[cfg(target_os = "none")]
pub mod crc;
