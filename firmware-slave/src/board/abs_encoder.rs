//! The absolute encoder's 8 parallel outputs on PB8..PB15.

use embassy_stm32::gpio::{Input, Pull};
use embassy_stm32::pac;
use embassy_stm32::peripherals::{PB10, PB11, PB12, PB13, PB14, PB15, PB8, PB9};
use embassy_stm32::Peri;
use firmware_slave::ports::AbsoluteEncoderPins;

/// Bit i of the encoder on PB(8 + i), inputs with pull-up.
pub struct AbsoluteEncoder {
    // Held only to own (and keep configured) the pins; reads go through the port register.
    _pins: [Input<'static>; 8],
}

impl AbsoluteEncoder {
    #[allow(clippy::too_many_arguments)] // one argument per encoder bit
    pub fn new(
        b0: Peri<'static, PB8>,
        b1: Peri<'static, PB9>,
        b2: Peri<'static, PB10>,
        b3: Peri<'static, PB11>,
        b4: Peri<'static, PB12>,
        b5: Peri<'static, PB13>,
        b6: Peri<'static, PB14>,
        b7: Peri<'static, PB15>,
    ) -> Self {
        // The encoder's outputs are open collector: the internal pull-ups (~40 kOhm) supply the
        // high level. PB8..PB15 are 5 V tolerant, so a 5 V encoder with its own pull-ups works too.
        Self {
            _pins: [
                Input::new(b0, Pull::Up),
                Input::new(b1, Pull::Up),
                Input::new(b2, Pull::Up),
                Input::new(b3, Pull::Up),
                Input::new(b4, Pull::Up),
                Input::new(b5, Pull::Up),
                Input::new(b6, Pull::Up),
                Input::new(b7, Pull::Up),
            ],
        }
    }
}

impl AbsoluteEncoderPins for AbsoluteEncoder {
    fn read_levels(&mut self) -> u8 {
        // One read of GPIOB's input data register samples all 8 bits at the same instant, so a
        // code change between two pin reads can never produce a torn (mixed old/new) word.
        // Truncating to u8 after the shift keeps exactly PB8..PB15.
        (pac::GPIOB.idr().read().0 >> 8) as u8
    }
}
