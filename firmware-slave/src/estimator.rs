//! The slave's odometry, switchable between methods at run time (SPEC §3: users compare them on
//! the same robot). A switch continues from the current pose, so the robot does not jump.
//!
//! * `Exact` (default): integer-only. With tick time stamps it is fed every wheel's position
//!   interpolated to the sample instant; with counters only, whole counts.
//! * `Arc` (seed 004) and `Lut` (seed 001, on the carriage, itself a differential drive): whole
//!   counts each sample, in floats (slow without an FPU, but they are the papers' baselines).
//! * `Timing` (seed 000): every tick with its time, so only in tick-timestamp mode.

use protocol::spi::OdometryAlgorithm;
use robot_math::arc::CarriageArc;
use robot_math::carriage::{CarriageExact, CarriageGeometry};
use robot_math::exact::FixedPose;
use robot_math::lut::LutOdometry;
use robot_math::ticks::counts_as_ticks;
use robot_math::timing::TimingOdometry;
use robot_math::wheel::Wheel;
use robot_math::Pose2;

/// What the sensors say at one fixed-rate update.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Sample {
    /// Cumulative whole counts of the two measuring wheels.
    pub counts: [i64; 2],
    /// The wheels' positions in Q16 counts: interpolated between ticks in tick-timestamp
    /// mode, the whole counts otherwise.
    pub q16: [i64; 2],
    /// Slave clock, nanoseconds.
    pub t_ns: u64,
    /// Absolute encoder code.
    pub code: u16,
}

// One instance lives in the odometry task's future (no heap on the board); the size gap
// between the float and the integer methods costs RAM once, not per update.
#[allow(clippy::large_enum_variant)]
enum Method {
    Exact(CarriageExact),
    Arc(CarriageArc),
    Lut(CarriageLut),
    Timing(CarriageTiming),
}

/// Seed 001's method on the carriage's two wheels; the body follows through the swivel.
struct CarriageLut {
    odo: LutOdometry,
    applied: [i64; 2],
}

impl CarriageLut {
    fn new(geom: &CarriageGeometry, body: Pose2, s: &Sample) -> Self {
        let carriage = geom.carriage_pose(body, geom.swivel_angle(s.code));
        CarriageLut {
            odo: LutOdometry::new(geom.metres_per_count[0], geom.wheel_base, carriage),
            applied: s.counts,
        }
    }

    fn update(&mut self, geom: &CarriageGeometry, s: &Sample) -> Pose2 {
        // The count changes since the last sample, as ticks, the two wheels interleaved.
        // Wheel 0 is the left wheel in both conventions.
        counts_as_ticks(&mut self.applied, &s.counts, |wheel, step| {
            self.odo.tick(wheel as u8, step)
        });
        geom.body_pose(self.odo.pose(), geom.swivel_angle(s.code))
    }
}

/// Seed 000's method on the carriage's two wheels (the axle solver; wheel A is the left one).
struct CarriageTiming {
    odo: TimingOdometry,
}

impl CarriageTiming {
    fn new(geom: &CarriageGeometry, body: Pose2, s: &Sample) -> Option<Self> {
        let half = geom.wheel_base / 2.0;
        let wheels = [Wheel::at(0.0, half, 0.0), Wheel::at(0.0, -half, 0.0)];
        let carriage = geom.carriage_pose(body, geom.swivel_angle(s.code));
        let mut odo =
            TimingOdometry::from_wheels(&wheels, &geom.metres_per_count, carriage).ok()?;
        // The switch instant is where its integration starts.
        odo.update(s.t_ns);
        Some(CarriageTiming { odo })
    }
}

pub(crate) struct SlaveOdometry {
    geom: CarriageGeometry,
    method: Method,
    pose: FixedPose,
    /// Whether tick time stamps are available (`Timing` needs them).
    timestamps: bool,
}

impl SlaveOdometry {
    /// `Exact`, at the origin. `None` for an impossible geometry.
    pub fn new(geom: CarriageGeometry, s: &Sample, timestamps: bool) -> Option<Self> {
        let exact = CarriageExact::new(&geom, Pose2::default(), s.counts, s.code)?;
        Some(SlaveOdometry {
            geom,
            pose: exact.body(),
            method: Method::Exact(exact),
            timestamps,
        })
    }

    pub fn algorithm(&self) -> OdometryAlgorithm {
        match self.method {
            Method::Exact(_) => OdometryAlgorithm::Exact,
            Method::Arc(_) => OdometryAlgorithm::Arc,
            Method::Lut(_) => OdometryAlgorithm::Lut,
            Method::Timing(_) => OdometryAlgorithm::Timing,
        }
    }

    /// A decoded tick, as it happened (only `Timing` uses individual ticks).
    pub fn on_tick(&mut self, t_ns: u64, wheel: usize, step: i8) {
        if let Method::Timing(t) = &mut self.method {
            t.odo.tick(t_ns, wheel, step);
        }
    }

    /// One fixed-rate update. On the default (`Exact`) path this is integer-only.
    pub fn update(&mut self, s: &Sample) -> FixedPose {
        let geom = &self.geom;
        self.pose = match &mut self.method {
            Method::Exact(e) => e.update_q16(s.q16, s.code),
            Method::Arc(a) => FixedPose::from_pose2(a.update(s.counts.map(|c| c as f64), s.code)),
            Method::Lut(l) => FixedPose::from_pose2(l.update(geom, s)),
            Method::Timing(t) => {
                let c = t.odo.update(s.t_ns);
                FixedPose::from_pose2(geom.body_pose(c, geom.swivel_angle(s.code)))
            }
        };
        self.pose
    }

    /// Restart from `pose` at the current sensor readings.
    pub fn set_pose(&mut self, pose: FixedPose, s: &Sample) {
        let body = pose.to_pose2();
        match &mut self.method {
            Method::Exact(e) => {
                // Take in the counts up to now first, so they are not applied after the reset.
                e.update_q16(s.q16, s.code);
                e.set_body(pose, s.code);
            }
            Method::Arc(a) => {
                if let Some(fresh) =
                    CarriageArc::new(self.geom, body, s.counts.map(|c| c as f64), s.code)
                {
                    *a = fresh;
                }
            }
            Method::Lut(l) => *l = CarriageLut::new(&self.geom, body, s),
            Method::Timing(t) => {
                if let Some(fresh) = CarriageTiming::new(&self.geom, body, s) {
                    *t = fresh;
                }
            }
        }
        self.pose = pose;
    }

    /// Switch method, continuing from the current pose. False if this slave cannot run it
    /// (`Timing` without tick time stamps).
    pub fn switch(&mut self, algorithm: OdometryAlgorithm, s: &Sample) -> bool {
        if algorithm == self.algorithm() {
            return true;
        }
        let here = self.update(s).to_pose2();
        let next = match algorithm {
            OdometryAlgorithm::Exact => {
                CarriageExact::new(&self.geom, here, s.counts, s.code).map(|mut e| {
                    // Start from the interpolated positions, not the whole counts.
                    e.update_q16(s.q16, s.code);
                    e.set_body(FixedPose::from_pose2(here), s.code);
                    Method::Exact(e)
                })
            }
            OdometryAlgorithm::Arc => {
                CarriageArc::new(self.geom, here, s.counts.map(|c| c as f64), s.code)
                    .map(Method::Arc)
            }
            OdometryAlgorithm::Lut => Some(Method::Lut(CarriageLut::new(&self.geom, here, s))),
            OdometryAlgorithm::Timing if self.timestamps => {
                CarriageTiming::new(&self.geom, here, s).map(Method::Timing)
            }
            OdometryAlgorithm::Timing => None,
        };
        match next {
            Some(m) => {
                self.method = m;
                true
            }
            None => false,
        }
    }
}
