//! [`Layout`]: a robot's odometry sensors as plain data.
//!
//! Everything an estimator needs and nothing it can recompute cheaply: the float geometry the
//! float baselines use, and the integer constants of `exact`, which are derived with floats
//! **once**, by [`Layout::from_geometry`] (on the host, or at the board's boot for its
//! compiled-in default). Every field is an integer or an f64 that can be shipped as its exact
//! bits and rebuilt with [`Layout::from_parts`], so host and board hold the same bits and
//! compute the same poses. No tables: it lives in the slave's RAM.

use core::fmt;

use crate::carriage::CarriageGeometry;
use crate::exact::{ExactParams, ExactParamsError, MAX_ENCODERS};
use crate::sensors::gray_to_binary;
use crate::wheel::Wheel;
use crate::wheelset::{GeometryError, WheelSolver};

/// Seed 004's measuring carriage: encoders 0 and 1 are its left and right wheels (in the
/// carriage frame: x along the carriage's heading, origin on the axle), and the layout's
/// absolute encoder reads the swivel angle β (carriage heading minus body heading). The
/// pivot, the body's reference point, sits `trail_m` ahead of the carriage frame's origin.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CarriageLayout {
    pub trail_m: f64,
    /// `trail_m` in Q40 metres (the integer path's unit), rounded once by the host.
    pub trail_q40: i64,
}

/// How an absolute encoder's raw output becomes a position `0..2^bits` (position k stands for
/// k/2^bits of a turn).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AbsLayout {
    /// 1..=16.
    pub bits: u8,
    /// Gray code on the outputs (else plain binary).
    pub gray: bool,
    /// Active-low outputs (open collector): undo before decoding.
    pub inverted: bool,
}

impl AbsLayout {
    /// Seed 004's Omron E6CP-AG5C: 8 bits, Gray code, open collector.
    pub const E6CP_AG5C: AbsLayout = AbsLayout {
        bits: 8,
        gray: true,
        inverted: true,
    };

    /// The position a raw output stands for: keep `bits` bits, undo the inversion, then the
    /// Gray code. Integer-only. (With `bits` outside 1..=16, which [`Layout`] refuses, the
    /// mask is clamped rather than overflowing.)
    pub fn decode(&self, raw: u16) -> u16 {
        let mask = ((1u32 << self.bits.clamp(1, 16)) - 1) as u16;
        let mut v = raw & mask;
        if self.inverted {
            v = !v & mask;
        }
        if self.gray {
            v = gray_to_binary(v) & mask;
        }
        v
    }
}

/// Why a sensor layout cannot be used for odometry.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LayoutError {
    /// Not 2..=[`MAX_ENCODERS`] incremental encoders (fewer cannot see the motion; more do
    /// not fit the fixed-point integrator).
    EncoderCount(usize),
    /// Travel per count of encoder `encoder` is not a finite positive number.
    MetresPerCount { encoder: usize },
    /// A wheel position or direction is not finite.
    NotFinite { encoder: usize },
    /// The wheels cannot determine the body's motion (the wheel solver's reason).
    Degenerate(GeometryError),
    /// A per-count constant does not fit the fixed-point format (absurd sizes).
    OutOfFixedPointRange,
    /// A carriage carries exactly two encoders (left, right), this layout has this many.
    CarriageEncoders(usize),
    /// A carriage needs an absolute encoder for its swivel angle.
    CarriageNeedsAbsoluteEncoder,
    /// The carriage's trail is not finite or out of the fixed-point range (itself, or the
    /// pivot's sideways travel per count it gives the fixed-point carriage).
    CarriageTrail,
    /// Absolute encoder resolution not in 1..=16 bits.
    AbsBits(u8),
    /// [`Layout::from_parts`]: the integer constants are for this many encoders, not the
    /// layout's.
    ConstantsMismatch(usize),
}

impl fmt::Display for LayoutError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            LayoutError::EncoderCount(n) => write!(
                f,
                "odometry takes 2 to {MAX_ENCODERS} incremental encoders, the layout has {n}"
            ),
            LayoutError::MetresPerCount { encoder } => write!(
                f,
                "encoder {encoder}: travel per count must be a finite number > 0"
            ),
            LayoutError::NotFinite { encoder } => {
                write!(
                    f,
                    "encoder {encoder}: wheel position or direction is not finite"
                )
            }
            LayoutError::Degenerate(e) => {
                write!(f, "the encoders cannot determine the body's motion: {e:?}")
            }
            LayoutError::OutOfFixedPointRange => write!(
                f,
                "a count moves the body too far for exact's fixed point (at most 1/16 m and a \
                 quarter turn per count)"
            ),
            LayoutError::CarriageEncoders(n) => write!(
                f,
                "a carriage carries exactly 2 encoders (left, right), the layout has {n}"
            ),
            LayoutError::CarriageNeedsAbsoluteEncoder => {
                write!(
                    f,
                    "a carriage needs an absolute encoder for its swivel angle"
                )
            }
            LayoutError::CarriageTrail => {
                write!(
                    f,
                    "the carriage trail is not finite, not under 128 m, or so long that the \
                     pivot moves 1/16 m or more sideways per count of the measuring wheels"
                )
            }
            LayoutError::AbsBits(b) => {
                write!(f, "absolute encoder: {b} bits, expected 1 to 16")
            }
            LayoutError::ConstantsMismatch(n) => write!(
                f,
                "the integer constants are for {n} encoders, not the layout's"
            ),
        }
    }
}

/// A robot's odometry sensors: incremental encoders on measuring wheels (body frame, or the
/// carriage frame with a carriage), optionally a swivel carriage and an absolute encoder.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Layout {
    encoders: u8,
    /// Unused slots: all zero.
    wheels: [Wheel; MAX_ENCODERS],
    metres_per_count: [f64; MAX_ENCODERS],
    exact: ExactParams,
    carriage: Option<CarriageLayout>,
    abs: Option<AbsLayout>,
}

/// A carriage trail must be under 2^47 Q40 units, 128 m (robot files allow 10 m): the
/// fixed-point carriage moves its constants to the pivot with 128-bit products of it.
pub const MAX_TRAIL_Q40: i64 = 1 << 47;

const NO_WHEEL: Wheel = Wheel {
    x: 0.0,
    y: 0.0,
    ux: 0.0,
    uy: 0.0,
};

impl Layout {
    /// THE function that turns a geometry into the integers the slave needs. `wheels`: each
    /// encoder's measuring wheel and travel per count (metres); `carriage`: the trail (metres)
    /// of seed 004's swivel carriage, whose two wheels `wheels` then are, in the carriage
    /// frame; `abs`: the absolute encoder (the swivel's, with a carriage).
    pub fn from_geometry(
        wheels: &[(Wheel, f64)],
        carriage_trail_m: Option<f64>,
        abs: Option<AbsLayout>,
    ) -> Result<Layout, LayoutError> {
        let n = wheels.len();
        if !(2..=MAX_ENCODERS).contains(&n) {
            return Err(LayoutError::EncoderCount(n));
        }
        let mut ws = [NO_WHEEL; MAX_ENCODERS];
        let mut k = [0.0; MAX_ENCODERS];
        for (j, &(w, m)) in wheels.iter().enumerate() {
            ws[j] = w;
            k[j] = m;
        }
        let solver = WheelSolver::new(&ws[..n]).map_err(LayoutError::Degenerate)?;
        let exact = ExactParams::new(&solver, &k[..n]).map_err(|e| match e {
            ExactParamsError::TooManyEncoders => LayoutError::EncoderCount(n),
            ExactParamsError::OutOfRange => LayoutError::OutOfFixedPointRange,
        })?;
        let carriage = match carriage_trail_m {
            None => None,
            Some(trail_m) => {
                let q40 = trail_m * crate::exact::FixedPose::METRE as f64;
                if !q40.is_finite() || libm::fabs(q40) >= MAX_TRAIL_Q40 as f64 {
                    return Err(LayoutError::CarriageTrail);
                }
                Some(CarriageLayout {
                    trail_m,
                    trail_q40: libm::round(q40) as i64,
                })
            }
        };
        Self::from_parts(n as u8, ws, k, exact, carriage, abs)
    }

    /// Rebuild a layout from its parts (as the accessors give them, e.g. shipped over a
    /// wire). Checks that the parts fit together; derives nothing, so the same parts give
    /// the same layout, bit for bit. The wheel geometry is not re-solved here: a degenerate
    /// one makes the float methods [`Unsupported`](super::Unsupported) when started.
    pub fn from_parts(
        encoders: u8,
        wheels: [Wheel; MAX_ENCODERS],
        metres_per_count: [f64; MAX_ENCODERS],
        exact: ExactParams,
        carriage: Option<CarriageLayout>,
        abs: Option<AbsLayout>,
    ) -> Result<Layout, LayoutError> {
        check_parts(encoders, &wheels, &metres_per_count, &exact, carriage, abs)?;
        Ok(Layout {
            encoders,
            wheels,
            metres_per_count,
            exact,
            carriage,
            abs,
        })
    }

    /// [`from_parts`](Self::from_parts) written over this layout, which stays as it was on
    /// `Err`: on a board the layout is rebuilt where it is kept, not in a value returned and
    /// copied (the slave's robot upload: 1.3 KB of stack, and flash).
    pub fn set_parts(
        &mut self,
        encoders: u8,
        wheels: [Wheel; MAX_ENCODERS],
        metres_per_count: [f64; MAX_ENCODERS],
        exact: ExactParams,
        carriage: Option<CarriageLayout>,
        abs: Option<AbsLayout>,
    ) -> Result<(), LayoutError> {
        check_parts(encoders, &wheels, &metres_per_count, &exact, carriage, abs)?;
        self.encoders = encoders;
        self.wheels = wheels;
        self.metres_per_count = metres_per_count;
        self.exact = exact;
        self.carriage = carriage;
        self.abs = abs;
        Ok(())
    }

    /// A carriage layout from robot-math's [`CarriageGeometry`] (its wheels left then right
    /// on the axle through the carriage origin) and the swivel encoder's output format.
    pub fn from_carriage(geom: &CarriageGeometry, abs: AbsLayout) -> Result<Layout, LayoutError> {
        if geom.abs_bits != abs.bits {
            return Err(LayoutError::AbsBits(geom.abs_bits));
        }
        let (left, right) = geom.wheels();
        let mut layout = Self::from_geometry(
            &[
                (left, geom.metres_per_count[0]),
                (right, geom.metres_per_count[1]),
            ],
            Some(geom.trail),
            Some(abs),
        )?;
        // The same rounding as `CarriageExact::new`, so the two agree bit for bit.
        if let Some(c) = layout.carriage.as_mut() {
            c.trail_q40 = geom.trail_q40();
        }
        Ok(layout)
    }

    /// Seed 004's sensors ([`CarriageGeometry::SEED_004`] and the E6CP-AG5C, 8-bit Gray,
    /// active-low): the slave's compiled-in power-on default. The integer constants are what
    /// [`Layout::from_carriage`] derives for it (a test pins that they are), written out so
    /// the layout is a `const` and the board derives nothing at boot.
    pub const SEED_004: Layout = {
        const G: CarriageGeometry = CarriageGeometry::SEED_004;
        const HALF: f64 = G.wheel_base / 2.0;
        let exact = match ExactParams::from_raw(
            2,
            [287_851_471, 287_851_471, 0, 0],
            [0; MAX_ENCODERS],
            [-7_330_077_519, 7_330_077_519, 0, 0],
        ) {
            Ok(p) => p,
            // Evaluated at compile time: a broken constant fails the build, not the board.
            Err(_) => panic!("seed 004's exact constants are out of range"),
        };
        // On the axle through the carriage origin, rolling along +x (`Wheel::at(0, ±L/2, 0)`).
        const LEFT: Wheel = Wheel {
            x: 0.0,
            y: HALF,
            ux: 1.0,
            uy: 0.0,
        };
        const RIGHT: Wheel = Wheel { y: -HALF, ..LEFT };
        Layout {
            encoders: 2,
            wheels: [LEFT, RIGHT, NO_WHEEL, NO_WHEEL],
            metres_per_count: [G.metres_per_count[0], G.metres_per_count[1], 0.0, 0.0],
            exact,
            carriage: Some(CarriageLayout {
                trail_m: G.trail,
                trail_q40: 65_970_697_667,
            }),
            abs: Some(AbsLayout::E6CP_AG5C),
        }
    };

    /// [`Layout::SEED_004`].
    pub fn seed_004() -> Layout {
        Self::SEED_004
    }

    /// Number of incremental encoders (2..=4).
    pub fn encoders(&self) -> usize {
        self.encoders as usize
    }

    /// Each encoder's measuring wheel (zero past [`encoders`](Self::encoders)).
    pub fn wheels(&self) -> &[Wheel; MAX_ENCODERS] {
        &self.wheels
    }

    /// Each encoder's travel per count, metres (zero past the encoders).
    pub fn metres_per_count(&self) -> &[f64; MAX_ENCODERS] {
        &self.metres_per_count
    }

    /// `exact`'s integer constants.
    pub fn exact(&self) -> &ExactParams {
        &self.exact
    }

    pub fn carriage(&self) -> Option<CarriageLayout> {
        self.carriage
    }

    pub fn abs(&self) -> Option<AbsLayout> {
        self.abs
    }

    /// The wheel solver of the float methods (floats: at start or switch only).
    #[cfg(any(test, feature = "float-methods"))]
    pub(crate) fn solver(&self) -> Result<WheelSolver, GeometryError> {
        WheelSolver::new(&self.wheels[..self.encoders()])
    }

    /// With a carriage: its float geometry (for the float methods' body pose).
    pub fn carriage_geometry(&self) -> Option<CarriageGeometry> {
        let c = self.carriage?;
        Some(CarriageGeometry {
            wheel_base: self.wheels[0].y - self.wheels[1].y,
            trail: c.trail_m,
            metres_per_count: [self.metres_per_count[0], self.metres_per_count[1]],
            abs_bits: self.abs?.bits,
        })
    }

    /// Seed 001's differential drive: two encoders on one axle through the frame's origin,
    /// left (+y) then right (−y), both rolling forward, with the same travel per count.
    /// Returns (travel per count, track).
    pub fn differential_drive(&self) -> Option<(f64, f64)> {
        if self.encoders != 2 {
            return None;
        }
        let (l, r) = (self.wheels[0], self.wheels[1]);
        let forward = |w: Wheel| {
            libm::fabs(w.ux - 1.0) < 1e-9 && libm::fabs(w.uy) < 1e-9 && libm::fabs(w.x) < 1e-9
        };
        let (kl, kr) = (self.metres_per_count[0], self.metres_per_count[1]);
        let same = libm::fabs(kl - kr) <= 1e-12 * kl;
        (forward(l) && forward(r) && same && l.y > 0.0 && libm::fabs(l.y + r.y) < 1e-9)
            .then_some((kl, l.y - r.y))
    }
}

/// What [`Layout::from_parts`] checks: that the parts fit together.
fn check_parts(
    encoders: u8,
    wheels: &[Wheel; MAX_ENCODERS],
    metres_per_count: &[f64; MAX_ENCODERS],
    exact: &ExactParams,
    carriage: Option<CarriageLayout>,
    abs: Option<AbsLayout>,
) -> Result<(), LayoutError> {
    let n = encoders as usize;
    if !(2..=MAX_ENCODERS).contains(&n) {
        return Err(LayoutError::EncoderCount(n));
    }
    if exact.encoders() != n {
        return Err(LayoutError::ConstantsMismatch(exact.encoders()));
    }
    for j in 0..MAX_ENCODERS {
        let (w, m) = (wheels[j], metres_per_count[j]);
        let finite = [w.x, w.y, w.ux, w.uy].iter().all(|v| v.is_finite());
        if j >= n {
            // An unused slot is all zero bits, as `NO_WHEEL` (compared as bits: an f64
            // equality was the slave's last soft-float routine, 68 B of its flash).
            if [w.x, w.y, w.ux, w.uy, m].iter().any(|v| v.to_bits() != 0) {
                return Err(LayoutError::EncoderCount(j + 1));
            }
        } else if !finite {
            return Err(LayoutError::NotFinite { encoder: j });
        } else if !(m.is_finite() && m > 0.0) {
            return Err(LayoutError::MetresPerCount { encoder: j });
        }
    }
    if let Some(a) = abs {
        if !(1..=16).contains(&a.bits) {
            return Err(LayoutError::AbsBits(a.bits));
        }
    }
    if let Some(c) = carriage {
        if n != 2 {
            return Err(LayoutError::CarriageEncoders(n));
        }
        if abs.is_none() {
            return Err(LayoutError::CarriageNeedsAbsoluteEncoder);
        }
        // The pivot's constants (what the fixed-point carriage integrates) must fit too.
        if !c.trail_m.is_finite()
            || c.trail_q40.unsigned_abs() >= MAX_TRAIL_Q40 as u64
            || crate::carriage::pivot_params(*exact, c.trail_q40).is_none()
        {
            return Err(LayoutError::CarriageTrail);
        }
    }
    Ok(())
}
