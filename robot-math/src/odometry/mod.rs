//! One odometry layer: every method over every sensor layout, for the slave firmware and the
//! host alike (so both compute bit-identical poses from the same inputs).
//!
//! * [`Layout`]: the sensors as plain data (N ≤ 4 measuring wheels, optionally seed 004's
//!   swivel carriage and an absolute encoder), built once by [`Layout::from_geometry`];
//! * [`Method`]: `exact` (ours, integer-only), `arc` (seed 004), `lut` (seed 001), `timing`
//!   (seed 000);
//! * [`SensorKind`]: whole counts sampled at a fixed rate, or every tick time-stamped;
//! * [`Odometry`]: one estimator over a layout, fed ticks or counts and the absolute encoder,
//!   updated at a fixed rate, switchable at run time without a jump in the pose.
//!
//! `lut` on layouts other than a differential drive needs seed 001's 360-entry tables per
//! wheel (11.5 KiB, [`crate::lut::LutN`]): that is behind the `lut-n` feature, which the host
//! enables and the slave (20 KiB of RAM) does not; without it such layouts are
//! [`Unsupported::LutTablesNotBuilt`].

mod estimator;
mod layout;
#[cfg(test)]
mod tests;

pub use estimator::Odometry;
pub use layout::{AbsLayout, CarriageLayout, Layout, LayoutError, MAX_TRAIL_Q40};

use core::fmt;

/// An odometry method.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Method {
    /// Ours: the exact constant-twist arc per update, fixed point (SPEC §3.4).
    Exact,
    /// Seed 004's arc algorithm: accumulated heading, step along the heading after the step.
    Arc,
    /// Seed 001's table method: per tick, whole-degree tables.
    Lut,
    /// Seed 000's timing method: wheel speeds from tick times, Euler integration.
    Timing,
}

/// What arithmetic a method needs on its update path (the slave has no FPU).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Arithmetic {
    /// Integers only, on every update (proven by `scripts/check-no-float.py`).
    Integer,
    /// Integers per tick; the pose is converted with floats when read out.
    IntegerPerTick,
    /// Floating point on every update (soft floats on the slave: slow).
    Float,
}

impl Method {
    /// Every method, in report order.
    pub const ALL: [Method; 4] = [Method::Arc, Method::Lut, Method::Timing, Method::Exact];

    pub fn name(self) -> &'static str {
        match self {
            Method::Exact => "exact",
            Method::Arc => "arc",
            Method::Lut => "lut",
            Method::Timing => "timing",
        }
    }

    /// The method called `name` ([`name`](Self::name)'s inverse), `None` for anything else.
    pub fn from_name(name: &str) -> Option<Method> {
        Self::ALL.into_iter().find(|m| m.name() == name)
    }

    /// The accepted names, for error messages: "arc, lut, timing, exact".
    pub const NAMES: &'static str = "arc, lut, timing, exact";

    pub fn arithmetic(self) -> Arithmetic {
        match self {
            Method::Exact => Arithmetic::Integer,
            Method::Lut => Arithmetic::IntegerPerTick,
            Method::Arc | Method::Timing => Arithmetic::Float,
        }
    }
}

impl fmt::Display for Method {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// How the estimator sees the incremental encoders.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SensorKind {
    /// Cumulative whole counts, sampled at a fixed rate ([`Odometry::set_counts`]).
    Counts,
    /// Every tick with its time stamp ([`Odometry::tick`]); `exact` interpolates each wheel
    /// to the update instant and `timing` becomes available.
    Ticks,
}

/// Why an [`Odometry`] cannot run a method on a layout.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Unsupported {
    /// `timing` needs every tick's time stamp ([`SensorKind::Ticks`]).
    TimingNeedsTicks,
    /// `lut` needs a differential drive, or wheels that all turn the body by the same angle
    /// per tick (seed 001's heading is a count of one step).
    LutLayout(crate::lut::LutNError),
    /// `lut` on this layout needs seed 001's per-wheel tables, which this build leaves out
    /// (feature `lut-n`: too big for the slave's RAM).
    LutTablesNotBuilt,
    /// The wheels cannot determine the motion (a layout rebuilt from inconsistent parts).
    Geometry(crate::wheelset::GeometryError),
    /// `arc`, `lut` and `timing` are left out of this build (robot-math feature
    /// `float-methods`; on the slave, its `baselines` feature).
    FloatMethodsNotBuilt,
}

/// Whether this build has the float methods (`arc`, `lut`, `timing`): without them an
/// [`Odometry`] refuses every switch away from `exact`, so it can only be running `exact`.
pub const FLOAT_METHODS: bool = cfg!(any(test, feature = "float-methods"));

impl fmt::Display for Unsupported {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Unsupported::TimingNeedsTicks => f.write_str(
                "`timing` (the tick-timing paper) needs every tick's time stamp; it cannot run on \
                 sampled counts",
            ),
            Unsupported::LutLayout(e) => write!(
                f,
                "`lut` (Batbayar and Zoljargal 2013) needs a differential drive, or wheels that \
                 all turn the body by the same angle per tick ({e:?})"
            ),
            Unsupported::LutTablesNotBuilt => f.write_str(
                "`lut` (Batbayar and Zoljargal 2013) on this layout needs per-wheel tables, left \
                 out of this build (robot-math feature `lut-n`)",
            ),
            Unsupported::Geometry(e) => {
                write!(f, "the encoders cannot determine the body's motion: {e:?}")
            }
            Unsupported::FloatMethodsNotBuilt => f.write_str(
                "the float baselines (`arc`, `lut`, `timing`) are left out of this build (a slave \
                 image without its `baselines` feature)",
            ),
        }
    }
}
