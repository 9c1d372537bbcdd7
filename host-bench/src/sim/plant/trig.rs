//! The sines and cosines of a step's headings: worked out in full now and then, and turned by
//! the step's small angle in between.

use super::{MeasuringSensors, PlantConfig, State};

/// A step's end angles are turned from its start's ([`Trig::turned`]), and worked out with
/// `sin_cos` every this many steps: each turn is exact but for the last bit of its
/// products, so between two full ones the sines drift by a few 10^-16 at most.
pub(super) const FULL_TRIG_EVERY: u32 = 16;

/// `sin_cos` of the body heading θ and of the carriage heading φ (φ's only with a carriage:
/// the derivative of body-fixed wheels does not use it).
#[derive(Clone, Copy, Debug)]
pub(super) struct Trig {
    pub(super) theta: (f64, f64),
    pub(super) phi: (f64, f64),
}

impl Trig {
    pub(super) fn of(cfg: &PlantConfig, y: &State) -> Trig {
        Trig {
            theta: y.body.theta.sin_cos(),
            phi: match cfg.sensors {
                MeasuringSensors::Carriage { .. } => y.phi.sin_cos(),
                MeasuringSensors::Wheels { .. } => (0.0, 1.0),
            },
        }
    }

    /// The angles of `y`, a state inside the step that starts at `y0` (whose angles `self`
    /// has), or at its end: each turned by the small angle between them, where that angle is
    /// small enough for a short series to be exact to the last bit of the terms (the step's
    /// end is computed in full every [`FULL_TRIG_EVERY`] steps, [`Trig::of`], so the turns'
    /// last bits cannot add up). `sin_cos` was 6 % of an emulation.
    pub(super) fn turned(&self, cfg: &PlantConfig, y0: &State, y: &State) -> Trig {
        let turn = |(s, c): (f64, f64), from: f64, to: f64| {
            let d = to - from;
            if d.abs() > 1e-3 {
                return to.sin_cos();
            }
            // |d| ≤ 10^-3: the first terms left out are below 10^-24. The series' divisions
            // as products with the reciprocals (a division's latency is five products'; the
            // terms differ in their last bit at most, 10^-26 of the sine).
            let d2 = d * d;
            let sd = d * (1.0 - d2 * (1.0 / 6.0) * (1.0 - d2 * (1.0 / 20.0)));
            let cd = 1.0 - d2 * 0.5 * (1.0 - d2 * (1.0 / 12.0) * (1.0 - d2 * (1.0 / 30.0)));
            (s * cd + c * sd, c * cd - s * sd)
        };
        Trig {
            theta: turn(self.theta, y0.body.theta, y.body.theta),
            phi: match cfg.sensors {
                MeasuringSensors::Carriage { .. } => turn(self.phi, y0.phi, y.phi),
                MeasuringSensors::Wheels { .. } => (0.0, 1.0),
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::plant::tests::cfg;
    use robot_math::Pose2;

    #[test]
    fn angles_turned_inside_a_step_are_the_sines_and_cosines_to_an_ulp() {
        // Body and carriage headings anywhere, turned by up to 2·10^-3 rad (the series'
        // range and past it, where `sin_cos` is called): within 2·10^-16 of `sin_cos`.
        let cfg = cfg();
        let state = |theta: f64, phi: f64| State {
            body: Pose2::new(0.0, 0.0, theta),
            phi,
            rolled: [0.0; 2],
            driven: [0.0; 3],
        };
        let mut worst = 0.0f64;
        for i in 0..2000 {
            let (theta, phi) = (i as f64 * 0.0137 - 13.0, 7.0 - i as f64 * 0.0091);
            let turn = (i as f64 * 0.618).fract() * 4e-3 - 2e-3;
            let (y0, y) = (state(theta, phi), state(theta + turn, phi - 0.7 * turn));
            let (turned, full) = (
                Trig::of(&cfg, &y0).turned(&cfg, &y0, &y),
                Trig::of(&cfg, &y),
            );
            for (a, b) in [
                (turned.theta.0, full.theta.0),
                (turned.theta.1, full.theta.1),
                (turned.phi.0, full.phi.0),
                (turned.phi.1, full.phi.1),
            ] {
                worst = worst.max((a - b).abs());
            }
        }
        assert!(worst < 2.5e-16, "{worst}");
    }
}
