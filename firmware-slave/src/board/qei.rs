//! Measuring-wheel encoders on timers in encoder mode: the hardware counts every edge, so no
//! interrupt and no CPU time per count, and nothing is lost while the firmware is busy.

use embassy_stm32::gpio::{AfioRemap, Pull};
use embassy_stm32::pac::timer::vals::FilterValue;
use embassy_stm32::peripherals::{PA0, PA1, PA8, PA9, TIM1, TIM2};
use embassy_stm32::timer::qei::{Config, Qei, QeiMode};
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
        let config = Config {
            // Mode 3 counts both edges of both channels: x4 decoding, the finest resolution.
            mode: QeiMode::Mode3,
            // Let the 16-bit counter wrap through its whole range; the portable code unwraps it.
            auto_reload: u16::MAX,
            // Pull-ups make open-collector encoders work and cost nothing with push-pull ones.
            ch1_pull: Pull::Up,
            ch2_pull: Pull::Up,
        };

        // On the F1 a pin can reach a timer channel through several AFIO remaps, so the remap is
        // named explicitly: 0 = the reset mapping (TIM2 CH1/CH2 on PA0/PA1, TIM1 on PA8/PA9).
        let left = Qei::new::<Ch1, Ch2, AfioRemap<0>>(tim2, pa0, pa1, config);
        let right = Qei::new::<Ch1, Ch2, AfioRemap<0>>(tim1, pa8, pa9, config);

        // The Qei driver has no input-filter setting. An edge must now be stable for 8 timer
        // clocks (111 ns at 72 MHz) to count: it rejects ringing and spikes on the encoder
        // cables while still allowing edge rates of a few MHz, far above any wheel speed.
        pac::TIM2.ccmr_input(0).modify(|w| {
            w.set_icf(0, FilterValue::FCK_INT_N8);
            w.set_icf(1, FilterValue::FCK_INT_N8);
        });
        pac::TIM1.ccmr_input(0).modify(|w| {
            w.set_icf(0, FilterValue::FCK_INT_N8);
            w.set_icf(1, FilterValue::FCK_INT_N8);
        });

        Self { left, right }
    }
}

impl QuadratureCounters for Counters {
    fn read_raw(&mut self) -> [u16; MEASURING_WHEELS] {
        [self.left.count(), self.right.count()]
    }
}
