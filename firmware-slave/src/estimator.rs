//! The slave's odometry, switchable between methods at run time (SPEC §3: users compare them on
//! the same robot). `Exact` is the default and integer-only; `Arc` is seed 004's algorithm in
//! floats (slow without an FPU, but it is the paper's baseline); `Lut` is seed 001's table
//! method on the carriage (itself a differential drive), fed each sample's count changes as
//! ticks. `Timing` needs every tick's time stamp, which hardware quadrature counting does not
//! give, so this build refuses it. A switch continues from the current pose, so the robot
//! does not jump.

use protocol::spi::OdometryAlgorithm;
use robot_math::arc::CarriageArc;
use robot_math::carriage::{CarriageExact, CarriageGeometry};
use robot_math::exact::FixedPose;
use robot_math::lut::LutOdometry;
use robot_math::ticks::counts_as_ticks;
use robot_math::Pose2;

// One instance lives in the odometry task's future (no heap on the board); the size gap
// between the float and the integer method costs 400 bytes of RAM once, not per update.
#[allow(clippy::large_enum_variant)]
enum Method {
    Exact(CarriageExact),
    Arc(CarriageArc),
    Lut(CarriageLut),
}

/// Seed 001's method on the carriage's two wheels; the body follows through the swivel.
struct CarriageLut {
    odo: LutOdometry,
    applied: [i64; 2],
}

impl CarriageLut {
    fn new(geom: &CarriageGeometry, body: Pose2, totals: [i64; 2], code: u16) -> Self {
        let carriage = geom.carriage_pose(body, geom.swivel_angle(code));
        CarriageLut {
            odo: LutOdometry::new(geom.metres_per_count[0], geom.wheel_base, carriage),
            applied: totals,
        }
    }

    fn update(&mut self, geom: &CarriageGeometry, totals: [i64; 2], code: u16) -> Pose2 {
        // The count changes since the last sample, as ticks, the two wheels interleaved.
        // Wheel 0 is the left wheel in both conventions.
        counts_as_ticks(&mut self.applied, &totals, |wheel, step| {
            self.odo.tick(wheel as u8, step)
        });
        geom.body_pose(self.odo.pose(), geom.swivel_angle(code))
    }
}

pub(crate) struct SlaveOdometry {
    geom: CarriageGeometry,
    method: Method,
    pose: FixedPose,
}

impl SlaveOdometry {
    /// `Exact`, at the origin. `None` for an impossible geometry.
    pub fn new(geom: CarriageGeometry, totals: [i64; 2], code: u16) -> Option<Self> {
        let exact = CarriageExact::new(&geom, robot_math::Pose2::default(), totals, code)?;
        Some(SlaveOdometry {
            geom,
            pose: exact.body(),
            method: Method::Exact(exact),
        })
    }

    pub fn algorithm(&self) -> OdometryAlgorithm {
        match self.method {
            Method::Exact(_) => OdometryAlgorithm::Exact,
            Method::Arc(_) => OdometryAlgorithm::Arc,
            Method::Lut(_) => OdometryAlgorithm::Lut,
        }
    }

    /// One fixed-rate update. On the default (`Exact`) path this is integer-only.
    pub fn update(&mut self, totals: [i64; 2], code: u16) -> FixedPose {
        self.pose = match &mut self.method {
            Method::Exact(e) => e.update(totals, code),
            Method::Arc(a) => FixedPose::from_pose2(a.update(totals.map(|c| c as f64), code)),
            Method::Lut(l) => FixedPose::from_pose2(l.update(&self.geom, totals, code)),
        };
        self.pose
    }

    /// Restart from `pose` at the current sensor readings.
    pub fn set_pose(&mut self, pose: FixedPose, totals: [i64; 2], code: u16) {
        match &mut self.method {
            Method::Exact(e) => {
                // Take in the counts up to now first, so they are not applied after the reset.
                e.update(totals, code);
                e.set_body(pose, code);
            }
            Method::Arc(a) => {
                if let Some(fresh) =
                    CarriageArc::new(self.geom, pose.to_pose2(), totals.map(|c| c as f64), code)
                {
                    *a = fresh;
                }
            }
            Method::Lut(l) => *l = CarriageLut::new(&self.geom, pose.to_pose2(), totals, code),
        }
        self.pose = pose;
    }

    /// Switch method, continuing from the current pose. False if this build cannot run it
    /// (`Timing` needs tick time stamps).
    pub fn switch(&mut self, algorithm: OdometryAlgorithm, totals: [i64; 2], code: u16) -> bool {
        if algorithm == self.algorithm() {
            return true;
        }
        let here = self.update(totals, code).to_pose2();
        let next = match algorithm {
            OdometryAlgorithm::Exact => {
                CarriageExact::new(&self.geom, here, totals, code).map(Method::Exact)
            }
            OdometryAlgorithm::Arc => {
                CarriageArc::new(self.geom, here, totals.map(|c| c as f64), code).map(Method::Arc)
            }
            OdometryAlgorithm::Lut => Some(Method::Lut(CarriageLut::new(
                &self.geom, here, totals, code,
            ))),
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
