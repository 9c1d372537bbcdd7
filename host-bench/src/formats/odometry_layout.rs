//! The one function that turns a robot file into the odometry layout, the integer constants
//! included, that the slave needs: [`Robot::odometry_layout`].

use anyhow::{anyhow, bail, Result};
use robot_math::odometry::{AbsLayout, Layout};

use super::robot::{AbsMeasures, Robot};
use super::tickstream::Event;

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

    /// What an `abs` row of a tick stream is to the odometry: `Some(code)` for the absolute
    /// encoder it reads (the swivel), `None` for another (read by nothing); refused if the robot
    /// has no absolute encoder `encoder` or `code` does not fit its bits. `replay` and `play`
    /// both ask here, so a row one of them refuses the other refuses too.
    pub fn abs_reading(&self, encoder: u16, code: u32, t_ns: u64) -> Result<Option<u16>> {
        let Some(a) = self.absolute_encoders.get(encoder as usize) else {
            bail!(
                "abs reading of absolute encoder {encoder} at t = {t_ns} ns, but robot {} has {} \
                 absolute encoders",
                self.name,
                self.absolute_encoders.len()
            );
        };
        if u64::from(code) >> a.bits != 0 {
            bail!(
                "abs reading {code} of absolute encoder {encoder} ({}) at t = {t_ns} ns does not \
                 fit its {} bits",
                a.name,
                a.bits
            );
        }
        // At most 16 bits (the robot file's range), so the code fits a u16.
        Ok((Some(encoder as usize) == self.odometry_abs_index()).then_some(code as u16))
    }

    /// Where the odometry's absolute encoder stands at the start: the first reading of it at
    /// the first row's instant (its row index and code), if the stream has one there.
    pub fn start_reading(&self, rows: &[Event]) -> Option<(usize, u16)> {
        let index = self.odometry_abs_index()?;
        let t0 = rows.first()?.t_ns();
        rows.iter()
            .take_while(|e| e.t_ns() == t0)
            .enumerate()
            .find_map(|(i, e)| match *e {
                Event::Abs { encoder, code, .. } if encoder as usize == index => {
                    Some((i, code as u16))
                }
                _ => None,
            })
    }
}
