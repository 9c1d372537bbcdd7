//! The drive motors' shaft encoders.
//!
//! The F103C8 has four timers and the master already spends two: TIM2 on the motors' PWM and
//! TIM4 on embassy's time driver. So two encoders count in hardware and the third by edge
//! interrupts:
//! - motor 1: TIM3 in encoder mode on PB4 / PB5 (partial remap; JTAG is off, SWD stays),
//! - motor 2: TIM1 in encoder mode on PA8 / PA9 (which is why USART1 moved to PB6 / PB7),
//! - motor 3: EXTI lines 8 and 9 on PB8 / PB9, both edges, decoded x4 by
//!   `robot_math::sensors::QuadratureDecoder` into a 16-bit count (the same wrapping counter
//!   the timers give). At 1.2 m/s a 1440-count wheel turn makes ~9 200 edges/s: about 1 % of
//!   the CPU at ~80 cycles an edge.
//!
//! Seed 002's robot drives motors 1 and 2 only, both counted in hardware.

use core::sync::atomic::{AtomicU16, Ordering};

use embassy_stm32::gpio::{AfioRemap, Input, Pull};
use embassy_stm32::interrupt::{self as irq, InterruptExt, Priority};
use embassy_stm32::pac::{self, interrupt};
use embassy_stm32::peripherals::{PA8, PA9, PB4, PB5, PB8, PB9, TIM1, TIM3};
use embassy_stm32::timer::qei::Qei;
use embassy_stm32::timer::{Ch1, Ch2};
use embassy_stm32::Peri;
use firmware_master::ports::{MotorEncoders, DRIVE_WHEELS};
use robot_math::sensors::{Quadrature, QuadratureDecoder};

/// EXTI lines 8 (A) and 9 (B) of motor 3.
const MOTOR3_LINES: u32 = 0b11 << 8;

static MOTOR3_COUNT: AtomicU16 = AtomicU16::new(0);
/// Only the EXTI9_5 handler touches the decoder (a critical section makes that explicit).
static MOTOR3_DECODER: critical_section::Mutex<core::cell::Cell<QuadratureDecoder>> =
    critical_section::Mutex::new(core::cell::Cell::new(QuadratureDecoder::new(0)));

pub struct Encoders {
    motor1: Qei<'static, TIM3>,
    motor2: Qei<'static, TIM1>,
    /// Holds PB8 / PB9 as pulled-up inputs for the EXTI lines.
    _motor3: [Input<'static>; 2],
}

impl Encoders {
    #[allow(clippy::too_many_arguments)] // one argument per owned resource, as embassy does
    pub fn new(
        tim3: Peri<'static, TIM3>,
        pb4: Peri<'static, PB4>,
        pb5: Peri<'static, PB5>,
        tim1: Peri<'static, TIM1>,
        pa8: Peri<'static, PA8>,
        pa9: Peri<'static, PA9>,
        pb8: Peri<'static, PB8>,
        pb9: Peri<'static, PB9>,
    ) -> Self {
        // TIM3 partial remap (2): CH1/CH2 on PB4/PB5. TIM1 reset mapping (0): PA8/PA9.
        let motor1 = Qei::new::<Ch1, Ch2, AfioRemap<2>>(tim3, pb4, pb5, bluepill::ENCODER_QEI);
        let motor2 = Qei::new::<Ch1, Ch2, AfioRemap<0>>(tim1, pa8, pa9, bluepill::ENCODER_QEI);
        bluepill::filter_encoder_inputs(pac::TIM3.ccmr_input(0));
        bluepill::filter_encoder_inputs(pac::TIM1.ccmr_input(0));

        let motor3 = [Input::new(pb8, Pull::Up), Input::new(pb9, Pull::Up)];
        critical_section::with(|cs| {
            MOTOR3_DECODER
                .borrow(cs)
                .set(QuadratureDecoder::new(motor3_levels()));
            // Port B (1) for lines 8 and 9 (EXTICR3), both edges.
            pac::AFIO.exticr(2).modify(|w| {
                w.set_exti(0, 1);
                w.set_exti(1, 1);
            });
            let exti = pac::EXTI;
            exti.rtsr(0).modify(|w| w.0 |= MOTOR3_LINES);
            exti.ftsr(0).modify(|w| w.0 |= MOTOR3_LINES);
            exti.pr(0).write(|w| w.0 = MOTOR3_LINES);
            exti.imr(0).modify(|w| w.0 |= MOTOR3_LINES);
        });
        irq::EXTI9_5.set_priority(Priority::P0);
        // SAFETY: EXTI9_5 is handled below, touching only lines 8 and 9 and atomics /
        // critical-section state.
        unsafe { irq::EXTI9_5.enable() };

        Self {
            motor1,
            motor2,
            _motor3: motor3,
        }
    }
}

fn motor3_levels() -> u8 {
    // One read of the port: A and B at the same instant (bit 0 = A = PB8, bit 1 = B = PB9).
    ((pac::GPIOB.idr().read().0 >> 8) & 0b11) as u8
}

#[interrupt]
fn EXTI9_5() {
    // Clear first: an edge arriving while this runs pends again instead of being lost.
    pac::EXTI.pr(0).write(|w| w.0 = MOTOR3_LINES);
    let levels = motor3_levels();
    let step = critical_section::with(|cs| {
        let cell = MOTOR3_DECODER.borrow(cs);
        let mut decoder = cell.get();
        let q = decoder.edge(levels);
        cell.set(decoder);
        q
    });
    // A missed edge (both levels changed) cannot be attributed: no step is guessed; the speed
    // loop sees one count less for one period.
    if let Quadrature::Step(s) = step {
        let delta = s as i16 as u16;
        MOTOR3_COUNT.fetch_add(delta, Ordering::Relaxed);
    }
}

impl MotorEncoders for Encoders {
    fn counts(&mut self) -> [u16; DRIVE_WHEELS] {
        [
            self.motor1.count(),
            self.motor2.count(),
            MOTOR3_COUNT.load(Ordering::Relaxed),
        ]
    }
}
