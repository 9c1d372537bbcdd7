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
    /// Seed 002's `arc`, from `body` at the current counts.
    pub(super) fn arc(odo: &Odometry, body: FixedPose) -> Result<FloatState, Unsupported> {
        let n = odo.layout.encoders();
        let (solver, start) = odo.float_start(body)?;
        let counts_f64 = odo.counts.map(|c| c as f64);
        let k = &odo.layout.metres_per_count()[..n];
        Ok(FloatState::Arc(ArcOdometry::new(
            solver,
            k,
            start,
            &counts_f64[..n],
        )))
    }

    /// Seed 001's `lut`: its own tables on a differential drive, per-wheel tables elsewhere.
    pub(super) fn lut(odo: &Odometry, body: FixedPose) -> Result<FloatState, Unsupported> {
        let (solver, start) = odo.float_start(body)?;
        let tables = match odo.layout.differential_drive() {
            Some((step, track)) => LutTables::Differential(LutOdometry::with_origin_offset(
                step,
                track,
                start,
                odo.lut_origin,
            )),
            None => odo.lut_wheels(&solver, start)?,
        };
        Ok(FloatState::Lut(Lut {
            tables,
            applied: odo.counts,
        }))
    }

    /// Seed 000's `timing` (it needs every tick's time stamp); its integration starts at
    /// [`started`](Self::started).
    pub(super) fn timing(odo: &Odometry, body: FixedPose) -> Result<FloatState, Unsupported> {
        if odo.sensors != SensorKind::Ticks {
            return Err(Unsupported::TimingNeedsTicks);
        }
        let n = odo.layout.encoders();
        let (_, start) = odo.float_start(body)?;
        let k = &odo.layout.metres_per_count()[..n];
        TimingOdometry::from_wheels(&odo.layout.wheels()[..n], k, start)
            .map(FloatState::Timing)
            .map_err(Unsupported::Geometry)
    }

    /// In place, once started at `t_ns`: `timing`'s integration starts here, every wheel
    /// taken to sit on an edge now.
    fn started(&mut self, t_ns: u64) {
        if let FloatState::Timing(t) = self {
            t.update(t_ns);
        }
    }

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

impl Odometry {
    /// Run the float method `build` makes; on `Err` the running state is kept. Out of line,
    /// and one copy per method: a board with the baselines holds one method's temporaries at
    /// a time on its stack.
    #[inline(never)]
    pub(super) fn start_float(
        &mut self,
        t_ns: u64,
        build: impl FnOnce(&Odometry) -> Result<FloatState, Unsupported>,
    ) -> Result<(), Unsupported> {
        self.state = State::Float(build(self)?);
        if let State::Float(f) = &mut self.state {
            f.started(t_ns);
        }
        self.state_changed();
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

    /// The float methods' solver and start pose: they integrate the carriage frame with a
    /// carriage, the body otherwise.
    fn float_start(
        &self,
        body: FixedPose,
    ) -> Result<(crate::wheelset::WheelSolver, Pose2), Unsupported> {
        let solver = self.layout.solver().map_err(Unsupported::Geometry)?;
        let start = match self.layout.carriage_geometry() {
            Some(g) => g.carriage_pose(body.to_pose2(), g.swivel_angle(self.abs)),
            None => body.to_pose2(),
        };
        Ok((solver, start))
    }

    #[cfg(feature = "lut-n")]
    fn lut_wheels(
        &self,
        solver: &crate::wheelset::WheelSolver,
        start: Pose2,
    ) -> Result<LutTables, Unsupported> {
        let k = &self.layout.metres_per_count()[..self.layout.encoders()];
        crate::lut::LutN::new(solver, k, start, self.lut_origin)
            .map(LutTables::Wheels)
            .map_err(Unsupported::LutLayout)
    }

    #[cfg(not(feature = "lut-n"))]
    fn lut_wheels(
        &self,
        _solver: &crate::wheelset::WheelSolver,
        _start: Pose2,
    ) -> Result<LutTables, Unsupported> {
        Err(Unsupported::LutTablesNotBuilt)
    }
}
