//! Where each incremental encoder stands inside its count when the robot powers on: taking every
//! encoder to start on an edge biased the odometry by up to a count per wheel (docs/odometry.md,
//! "Where a wheel starts inside its count").
//!
//! A real encoder powers on anywhere inside a count, not on its edge. Encoder `i` starts with
//! the rolled distance `φ_i · step_i`, φ_i in `[0, 1)`, and counts from there: its count at time
//! t is `floor((φ_i · step_i + s_i(t)) / step_i)`, 0 at power-on. So its first forward tick comes
//! after `(1 − φ_i) · step_i` of travel and its first backward tick after `φ_i · step_i`. With
//! φ = 0 every encoder sits exactly on an edge (a wheel that creeps back by a nanometre
//! ticks −1 at once), the special case the generator used to produce every time.

use std::fmt;

use anyhow::bail;

use crate::formats::robot::Robot;

/// How the power-on phases of a robot's incremental encoders are chosen.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PowerOnPhase {
    /// Independent, uniform in `[0, 1)` for each encoder, reproducible from the seed: encoder
    /// i's phase is the (i+1)-th output of a SplitMix64 generator started at `seed` (its top 53
    /// bits over 2^53), so adding an encoder does not move the others.
    Random { seed: u64 },
    /// Every encoder exactly on the edge of a count (φ = 0).
    Zero,
    /// Every encoder at this fraction of a count; must be in `[0, 1)`.
    Fraction(f64),
}

impl Default for PowerOnPhase {
    fn default() -> Self {
        PowerOnPhase::Random { seed: 0 }
    }
}

impl fmt::Display for PowerOnPhase {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PowerOnPhase::Random { seed } => write!(f, "random seed {seed}"),
            PowerOnPhase::Zero => write!(f, "zero (every encoder on the edge of a count)"),
            PowerOnPhase::Fraction(x) => write!(f, "fraction {x} of a count"),
        }
    }
}

/// Each incremental encoder's power-on phase, in the robot file's order, each in `[0, 1)`.
/// Refuses a [`PowerOnPhase::Fraction`] outside `[0, 1)`.
pub fn phases(robot: &Robot, phase: PowerOnPhase) -> anyhow::Result<Vec<f64>> {
    let n = robot.encoders.len();
    Ok(match phase {
        PowerOnPhase::Zero => vec![0.0; n],
        PowerOnPhase::Fraction(x) => {
            if !(0.0..1.0).contains(&x) {
                bail!(
                    "the power-on phase is a fraction of a count in [0, 1) (0 = on an edge), \
                     got {x}"
                );
            }
            vec![x; n]
        }
        PowerOnPhase::Random { seed } => (0..n as u64)
            .map(|i| unit(splitmix64(seed.wrapping_add((i + 1).wrapping_mul(GOLDEN)))))
            .collect(),
    })
}

/// SplitMix64's increment (2^64 / φ, odd).
pub(super) const GOLDEN: u64 = 0x9E37_79B9_7F4A_7C15;

/// SplitMix64's output function (Steele, Lea and Flood 2014), applied to the generator's
/// state after its increment.
pub(super) fn splitmix64(state: u64) -> u64 {
    let mut z = state;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The top 53 bits as a float in `[0, 1)`: every value is exact and 1 is never reached.
pub(super) fn unit(x: u64) -> f64 {
    (x >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn splitmix64_matches_the_reference_outputs() {
        // The first outputs of SplitMix64 seeded with 1234567 (the reference implementation's
        // test vector), so a stream's phases can be recomputed from its seed elsewhere.
        let expected = [
            6457827717110365317u64,
            3203168211198807973,
            9817491932198370423,
        ];
        for (i, e) in expected.iter().enumerate() {
            let state = 1234567u64.wrapping_add((i as u64 + 1).wrapping_mul(GOLDEN));
            assert_eq!(splitmix64(state), *e, "output {i}");
        }
    }

    #[test]
    fn unit_stays_below_one() {
        assert_eq!(unit(0), 0.0);
        assert!(unit(u64::MAX) < 1.0);
        assert_eq!(unit(1 << 63), 0.5);
    }
}
