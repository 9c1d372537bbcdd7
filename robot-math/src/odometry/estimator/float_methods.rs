//! The float baselines' state inside [`Odometry`]: seed 002's `arc`, seed 001's `lut` and
//! seed 000's `timing`. Compiled for the host always and for a slave image only with its
//! `baselines` feature (robot-math's `float-methods`): the slave's own method, `exact`, needs
//! none of this, and without it the image has no soft-float code at all.

use super::{Odometry, State};
use crate::arc::ArcOdometry;
use crate::exact::{FixedPose, MAX_ENCODERS};
use crate::lut::LutOdometry;
use crate::odometry::{SensorKind, Unsupported};
use crate::ticks::counts_as_ticks;
use crate::timing::TimingOdometry;
use crate::Pose2;

/// A float method's state.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug)]
pub(super) enum FloatState {
    Arc(ArcOdometry),
    Lut(Lut),
    Timing(TimingOdometry),
}

/// Seed 001's method and the counts it has seen (its input is ticks).
#[derive(Clone, Debug)]
pub(super) struct Lut {
    tables: LutTables,
    applied: [i64; MAX_ENCODERS],
}

// Unboxed (no heap): only host builds have the big variant, and they have the memory.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug)]
enum LutTables {
    /// The paper's own method, for its differential drive (two 90-entry tables).
    Differential(LutOdometry),
    /// Its generalisation: 360-entry tables per wheel (host builds only).
    #[cfg(feature = "lut-n")]
    Wheels(crate::lut::LutN),
}

impl LutTables {
    fn tick(&mut self, encoder: usize, step: i8) {
        match self {
            // Wheel 0 is the left wheel in both conventions.
            LutTables::Differential(l) => l.tick(encoder as u8, step),
            #[cfg(feature = "lut-n")]
            LutTables::Wheels(l) => l.tick(encoder, step),
        }
    }

    fn pose(&self) -> Pose2 {
        match self {
            LutTables::Differential(l) => l.pose(),
            #[cfg(feature = "lut-n")]
            LutTables::Wheels(l) => l.pose(),
        }
    }
}

impl FloatState {
    /// A tick already counted by [`Odometry::tick`], for the methods whose input is ticks.
    pub(super) fn tick(&mut self, t_ns: u64, encoder: usize, step: i8) {
        match self {
            FloatState::Lut(l) => {
                l.tables.tick(encoder, step);
                if let Some(a) = l.applied.get_mut(encoder) {
                    *a += step as i64;
                }
            }
            FloatState::Timing(t) => t.tick(t_ns, encoder, step),
            FloatState::Arc(_) => {}
        }
    }
}

/// A float baseline to start.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum FloatMethod {
    Arc,
    Lut,
    Timing,
}

impl Odometry {
    /// Run `method` from `body` with the current readings at `t_ns`; on `Err` the running
    /// state is kept: whatever can refuse the method is checked before the state is touched.
    /// The state is then written where it lives, never returned by value: each 0.5 to 0.9 KB
    /// pass of a float state through a builder would be a copy on a board's stack (the slave
    /// with its baselines). Each method's writer is out of line, so a board's stack holds one
    /// method's temporaries at a time.
    pub(super) fn start_float(
        &mut self,
        method: FloatMethod,
        body: FixedPose,
        t_ns: u64,
    ) -> Result<(), Unsupported> {
        if method == FloatMethod::Timing && self.sensors != SensorKind::Ticks {
            return Err(Unsupported::TimingNeedsTicks);
        }
        self.check_solver()?;
        let start = self.float_start(body);
        match method {
            FloatMethod::Arc => self.start_arc(start)?,
            FloatMethod::Lut => self.start_lut(start)?,
            FloatMethod::Timing => self.start_timing(start, t_ns)?,
        }
        self.state_changed();
        Ok(())
    }

    /// Whether the float methods' wheel solver takes this layout (a solver built and
    /// dropped: out of line, its temporaries are gone before a state is written).
    #[inline(never)]
    fn check_solver(&self) -> Result<(), Unsupported> {
        self.layout
            .solver()
            .map(|_| ())
            .map_err(Unsupported::Geometry)
    }

    /// Seed 002's `arc`, from `start` at the current counts.
    #[inline(never)]
    fn start_arc(&mut self, start: Pose2) -> Result<(), Unsupported> {
        let n = self.layout.encoders();
        let counts = self.counts.map(|c| c as f64);
        let layout = &self.layout;
        self.state = State::Float(FloatState::Arc(ArcOdometry::EMPTY));
        let State::Float(FloatState::Arc(arc)) = &mut self.state else {
            return Err(Unsupported::FloatMethodsNotBuilt);
        };
        arc.init_from_wheels(
            &layout.wheels()[..n],
            &layout.metres_per_count()[..n],
            start,
            &counts[..n],
        )
        .map_err(Unsupported::Geometry)
    }

    /// Seed 001's `lut`: its own tables on a differential drive, per-wheel tables elsewhere.
    #[inline(never)]
    fn start_lut(&mut self, start: Pose2) -> Result<(), Unsupported> {
        let Some((step, track)) = self.layout.differential_drive() else {
            let tables = self.lut_wheels(start)?;
            self.state = State::Float(FloatState::Lut(Lut {
                tables,
                applied: self.counts,
            }));
            return Ok(());
        };
        self.state = State::Float(FloatState::Lut(Lut {
            tables: LutTables::Differential(LutOdometry::EMPTY),
            applied: [0; MAX_ENCODERS],
        }));
        let State::Float(FloatState::Lut(Lut {
            tables: LutTables::Differential(tables),
            applied,
        })) = &mut self.state
        else {
            return Err(Unsupported::FloatMethodsNotBuilt);
        };
        *applied = self.counts;
        tables.init(step, track, start, self.lut_origin);
        Ok(())
    }

    /// Seed 000's `timing` (it needs every tick's time stamp); its integration starts at
    /// `t_ns`, every wheel taken to sit on an edge then.
    #[inline(never)]
    fn start_timing(&mut self, start: Pose2, t_ns: u64) -> Result<(), Unsupported> {
        let n = self.layout.encoders();
        let layout = &self.layout;
        self.state = State::Float(FloatState::Timing(TimingOdometry::EMPTY));
        let State::Float(FloatState::Timing(timing)) = &mut self.state else {
            return Err(Unsupported::FloatMethodsNotBuilt);
        };
        timing
            .init_from_wheels(
                &layout.wheels()[..n],
                &layout.metres_per_count()[..n],
                start,
            )
            .map_err(Unsupported::Geometry)?;
        timing.update(t_ns);
        Ok(())
    }

    /// A float method's update: its frame's pose (the carriage's with a carriage), then the
    /// body's.
    pub(super) fn update_float(&mut self, t_ns: u64) -> FixedPose {
        let n = self.layout.encoders();
        let counts = self.counts;
        let State::Float(state) = &mut self.state else {
            return self.pose;
        };
        let frame = match state {
            // Whole counts, in either sensor mode (seed 004 samples counters).
            FloatState::Arc(a) => a.update(&counts.map(|c| c as f64)[..n]),
            // With counts: each sample's changes as ticks, the wheels interleaved. With ticks
            // every tick is in already and this does nothing.
            FloatState::Lut(l) => {
                let tables = &mut l.tables;
                counts_as_ticks(&mut l.applied[..n], &counts[..n], |j, s| tables.tick(j, s));
                tables.pose()
            }
            FloatState::Timing(t) => t.update(t_ns),
        };
        let body = match self.layout.carriage_geometry() {
            Some(g) => g.body_pose(frame, g.swivel_angle(self.abs)),
            None => frame,
        };
        self.pose = FixedPose::from_pose2(body);
        self.pose
    }

    /// The float methods' start pose: they integrate the carriage frame with a carriage,
    /// the body otherwise.
    fn float_start(&self, body: FixedPose) -> Pose2 {
        match self.layout.carriage_geometry() {
            Some(g) => g.carriage_pose(body.to_pose2(), g.swivel_angle(self.abs)),
            None => body.to_pose2(),
        }
    }

    /// Per-wheel tables (host builds: 360 entries a wheel), built by value.
    #[cfg(feature = "lut-n")]
    fn lut_wheels(&self, start: Pose2) -> Result<LutTables, Unsupported> {
        let solver = self.layout.solver().map_err(Unsupported::Geometry)?;
        let k = &self.layout.metres_per_count()[..self.layout.encoders()];
        crate::lut::LutN::new(&solver, k, start, self.lut_origin)
            .map(LutTables::Wheels)
            .map_err(Unsupported::LutLayout)
    }

    #[cfg(not(feature = "lut-n"))]
    fn lut_wheels(&self, _start: Pose2) -> Result<LutTables, Unsupported> {
        Err(Unsupported::LutTablesNotBuilt)
    }
}
