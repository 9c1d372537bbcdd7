//! Measuring-wheel encoders on timers in encoder mode: the hardware counts every edge, so no
//! interrupt and no CPU time per count, and nothing is lost while the firmware is busy.

use embassy_stm32::gpio::AfioRemap;
use embassy_stm32::peripherals::{PA0, PA1, PA8, PA9, TIM1, TIM2};
use embassy_stm32::timer::qei::Qei;
use embassy_stm32::timer::{Ch1, Ch2};
use embassy_stm32::{pac, Peri};
use firmware_slave::ports::{QuadratureCounters, MEASURING_WHEELS};

/// TIM2 (PA0 = A, PA1 = B) counts the left measuring wheel, TIM1 (PA8 = A, PA9 = B) the right.
pub struct Counters {
    left: Qei<'static, TIM2>,
    right: Qei<'static, TIM1>,
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
        // On the F1 a pin can reach a timer channel through several AFIO remaps, so the remap is
        // named explicitly: 0 = the reset mapping (TIM2 CH1/CH2 on PA0/PA1, TIM1 on PA8/PA9).
        let left = Qei::new::<Ch1, Ch2, AfioRemap<0>>(tim2, pa0, pa1, bluepill::ENCODER_QEI);
        let right = Qei::new::<Ch1, Ch2, AfioRemap<0>>(tim1, pa8, pa9, bluepill::ENCODER_QEI);
        bluepill::filter_encoder_inputs(pac::TIM2.ccmr_input(0));
        bluepill::filter_encoder_inputs(pac::TIM1.ccmr_input(0));

        Self { left, right }
    }
}

impl QuadratureCounters for Counters {
    fn read_raw(&mut self) -> [u16; MEASURING_WHEELS] {
        [self.left.count(), self.right.count()]
    }
}
