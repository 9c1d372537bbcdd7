//! Measuring-wheel encoders on timers in encoder mode: the hardware counts every edge, so no
//! interrupt and no CPU time per count, and nothing is lost while the firmware is busy.
//!
//! Set up through the registers (RM0008 §15.3.12, "Encoder interface mode") rather than
//! embassy's `Qei`: its constructor is generic over the timer, and its two copies (TIM2, TIM1)
//! took 380 B of the slave's 32 KiB more than this one shared routine. The settings are
//! `Qei`'s with [`bluepill::ENCODER_QEI`] (the master's motors still use `Qei` with it).

use embassy_stm32::gpio::{Input, Pull};
use embassy_stm32::pac::timer::{vals, TimGp16};
use embassy_stm32::peripherals::{PA0, PA1, PA8, PA9, TIM1, TIM2};
use embassy_stm32::{pac, Peri};
use firmware_slave::ports::{QuadratureCounters, MEASURING_WHEELS};

/// TIM2 (PA0 = A, PA1 = B) counts the left measuring wheel, TIM1 (PA8 = A, PA9 = B) the right.
pub struct Counters {
    // Held: the pins stay inputs with their pull-ups (dropped, embassy would disconnect them).
    _pins: [Input<'static>; 4],
    // Held: nothing else may take the timers.
    _timers: (Peri<'static, TIM2>, Peri<'static, TIM1>),
}

impl Counters {
    pub fn new(
        tim2: Peri<'static, TIM2>,
        pa0: Peri<'static, PA0>,
        pa1: Peri<'static, PA1>,
        tim1: Peri<'static, TIM1>,
        pa8: Peri<'static, PA8>,
        pa9: Peri<'static, PA9>,
    ) -> Self {
        // Pull-ups make open-collector encoders work at no cost to push-pull ones. On the F1 a
        // timer channel reads its pin in any input mode, through the reset AFIO mapping (TIM2
        // CH1/CH2 on PA0/PA1, TIM1 on PA8/PA9; AFIO_MAPR is left at its reset value).
        let pins = [
            Input::new(pa0, Pull::Up),
            Input::new(pa1, Pull::Up),
            Input::new(pa8, Pull::Up),
            Input::new(pa9, Pull::Up),
        ];
        embassy_stm32::rcc::enable_and_reset::<TIM2>();
        embassy_stm32::rcc::enable_and_reset::<TIM1>();
        // SAFETY: the advanced TIM1 has the general-purpose timer's layout for every register
        // used here (as embassy's own `regs_gp16` takes it).
        let tim1_gp = unsafe { TimGp16::from_ptr(pac::TIM1.as_ptr()) };
        for tim in [pac::TIM2, tim1_gp] {
            encoder_mode(tim);
        }
        Self {
            _pins: pins,
            _timers: (tim2, tim1),
        }
    }
}

/// CH1 and CH2 as inputs on TI1 and TI2, not inverted, their filters as
/// [`bluepill::filter_encoder_inputs`] sets them; encoder mode 3 (both edges of both channels:
/// x4), the counter wrapping through its whole 16 bits (the portable code takes differences).
#[inline(never)]
fn encoder_mode(tim: TimGp16) {
    tim.ccmr_input(0).modify(|w| {
        // `TI4` is the PAC's name for 0b01: "ICx mapped on TIx" (for CH1, TI1; CH2, TI2).
        w.set_ccs(0, vals::CcmrInputCcs::TI4);
        w.set_ccs(1, vals::CcmrInputCcs::TI4);
    });
    bluepill::filter_encoder_inputs(tim.ccmr_input(0));
    tim.ccer().modify(|w| {
        w.set_cce(0, true);
        w.set_cce(1, true);
        w.set_ccp(0, false);
        w.set_ccp(1, false);
    });
    tim.smcr().modify(|w| w.set_sms(vals::Sms::ENCODER_MODE_3));
    tim.arr().write(|w| w.set_arr(u16::MAX));
    tim.cr1().modify(|w| w.set_cen(true));
}

impl QuadratureCounters for Counters {
    fn read_raw(&mut self) -> [u16; MEASURING_WHEELS] {
        [pac::TIM2.cnt().read().cnt(), pac::TIM1.cnt().read().cnt()]
    }
}
