//! Three motor drivers with a PWM + direction interface and a shared enable/standby line.

use embassy_stm32::gpio::{AfioRemap, Level, Output, OutputType, Speed};
use embassy_stm32::peripherals::{PA0, PA1, PA2, PB12, PB13, PB14, PB15, TIM2};
use embassy_stm32::time::Hertz;
use embassy_stm32::timer::low_level::CountingMode;
use embassy_stm32::timer::simple_pwm::{PwmPin, SimplePwm, SimplePwmChannel};
use embassy_stm32::Peri;
use firmware_master::ports::{MotorDrivers, DRIVE_WHEELS, DUTY_FULL};

/// PWM frequency: above hearing, and low enough for the drivers' switching losses.
const PWM_HZ: u32 = 20_000;

/// TIM2 CH1..CH3 (PA0..PA2) PWM for motors 1..3, PB12..PB14 their direction (high = positive
/// duty), PB15 the drivers' enable/standby (high = enabled).
pub struct Motors {
    pwm: [SimplePwmChannel<'static, TIM2>; DRIVE_WHEELS],
    direction: [Output<'static>; DRIVE_WHEELS],
    enable: Output<'static>,
    /// Compare value for 100 % duty (the timer period in ticks).
    max_duty: u32,
}

impl Motors {
    #[allow(clippy::too_many_arguments)] // one argument per owned resource, as embassy does
    pub fn new(
        tim2: Peri<'static, TIM2>,
        pwm1: Peri<'static, PA0>,
        pwm2: Peri<'static, PA1>,
        pwm3: Peri<'static, PA2>,
        dir1: Peri<'static, PB12>,
        dir2: Peri<'static, PB13>,
        dir3: Peri<'static, PB14>,
        enable: Peri<'static, PB15>,
    ) -> Self {
        // Drivers off before any PWM pin becomes an output.
        let enable = Output::new(enable, Level::Low, Speed::Low);
        let direction = [
            Output::new(dir1, Level::High, Speed::Low),
            Output::new(dir2, Level::High, Speed::Low),
            Output::new(dir3, Level::High, Speed::Low),
        ];

        // On the F1 a pin can reach a timer channel through several AFIO remaps, so the remap is
        // named explicitly: 0 = the reset mapping, TIM2 CH1..CH3 on PA0..PA2.
        let pwm = SimplePwm::new::<AfioRemap<0>>(
            tim2,
            Some(PwmPin::new(pwm1, OutputType::PushPull)),
            Some(PwmPin::new(pwm2, OutputType::PushPull)),
            Some(PwmPin::new(pwm3, OutputType::PushPull)),
            None,
            Hertz(PWM_HZ),
            CountingMode::EdgeAlignedUp,
        );
        let max_duty = pwm.max_duty_cycle();
        let channels = pwm.split();
        let mut pwm = [channels.ch1, channels.ch2, channels.ch3];
        for channel in &mut pwm {
            channel.set_duty_cycle(0);
            channel.enable();
        }

        Self {
            pwm,
            direction,
            enable,
            max_duty,
        }
    }
}

impl MotorDrivers for Motors {
    fn set_duty(&mut self, duty_permille: [i16; DRIVE_WHEELS]) {
        let full = DUTY_FULL.unsigned_abs();
        for ((duty, pwm), direction) in duty_permille
            .into_iter()
            .zip(&mut self.pwm)
            .zip(&mut self.direction)
        {
            let duty = duty.clamp(-DUTY_FULL, DUTY_FULL);
            // Zero keeps the previous direction: no needless toggling of the driver input.
            if duty != 0 {
                direction.set_level(Level::from(duty > 0));
            }
            // Integer scaling (no FPU): |duty| <= 1000 and max_duty <= 65 536, so no overflow,
            // and the result never exceeds max_duty.
            let magnitude = u32::from(duty.unsigned_abs());
            pwm.set_duty_cycle(self.max_duty * magnitude / u32::from(full));
        }
        self.enable.set_high();
    }

    fn stop(&mut self) {
        for pwm in &mut self.pwm {
            pwm.set_duty_cycle(0);
        }
        self.enable.set_low();
    }
}
