//! The one function that turns a robot file into the odometry layout, the integer constants
//! included, that the slave needs: [`Robot::odometry_layout`].

use anyhow::{anyhow, Result};
use robot_math::odometry::{AbsLayout, Layout};

use super::robot::{AbsMeasures, Robot};

impl Robot {
    /// The robot's odometry sensors as robot-math's [`Layout`]: its encoders' measuring
    /// wheels (in the carriage frame with a carriage), the carriage's trail and its swivel
    /// encoder. An absolute encoder that measures the body heading is not part of it (no
    /// method uses one yet). Errors name the robot and the reason.
    pub fn odometry_layout(&self) -> Result<Layout> {
        let wheels: Vec<_> = self
            .encoders
            .iter()
            .map(|e| (e.wheel, e.metres_per_count))
            .collect();
        let abs = match self.carriage {
            Some(_) => self
                .absolute_encoder(AbsMeasures::CarriageSwivel)
                .map(|a| AbsLayout {
                    bits: a.bits,
                    gray: a.gray,
                    inverted: a.inverted,
                }),
            None => None,
        };
        Layout::from_geometry(&wheels, self.carriage.map(|c| c.trail_m), abs).map_err(|e| {
            anyhow!(
                "robot {}: key `encoders`: {e} (what the odometry in replay, play, record \
                     and the slave takes; generate takes any layout: docs/robot-format.md)",
                self.name
            )
        })
    }

    /// Index (in `absolute_encoders`) of the encoder the layout's absolute encoder is.
    pub fn odometry_abs_index(&self) -> Option<usize> {
        self.carriage?;
        self.absolute_encoders
            .iter()
            .position(|a| a.measures == AbsMeasures::CarriageSwivel)
    }
}
