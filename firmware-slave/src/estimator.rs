//! The slave's odometry as a function of its inputs: decoded edges, sampled counters, the
//! absolute encoder and the master's commands in; the pose and status bits out.
//!
//! [`SlaveEstimator`] wraps robot-math's one odometry layer ([`Odometry`]) with what the slave
//! adds around it: quadrature decoding of the edges, the cross-check of the decoded counts
//! against the hardware counters, the wire's algorithm codes and the sticky
//! "unsupported algorithm" flag. The odometry task feeds it from the board's ports; any other
//! sensor source (e.g. played-back events) can feed the same path.

use core::mem::MaybeUninit;

use protocol::spi::{slave_status, OdometryAlgorithm, SlaveCommand, ENCODER_SLOTS};
use robot_math::exact::{FixedPose, MAX_ENCODERS};
use robot_math::odometry::{Layout, Method, Odometry, SensorKind, Unsupported};
use robot_math::sensors::{Quadrature, QuadratureDecoder};

use crate::ports::EncoderEdge;
use crate::SensorMode;

/// The wire's algorithm code for a method (1:1).
pub fn algorithm_of(method: Method) -> OdometryAlgorithm {
    match method {
        Method::Exact => OdometryAlgorithm::Exact,
        Method::Arc => OdometryAlgorithm::Arc,
        Method::Lut => OdometryAlgorithm::Lut,
        Method::Timing => OdometryAlgorithm::Timing,
    }
}

/// The method a wire algorithm code asks for (1:1).
pub fn method_of(algorithm: OdometryAlgorithm) -> Method {
    match algorithm {
        OdometryAlgorithm::Exact => Method::Exact,
        OdometryAlgorithm::Arc => Method::Arc,
        OdometryAlgorithm::Lut => Method::Lut,
        OdometryAlgorithm::Timing => Method::Timing,
    }
}

/// What one fixed-rate update produced.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Update {
    pub pose: FixedPose,
    /// [`slave_status`] bits the estimator is responsible for (`EDGES_LOST`,
    /// `ALGORITHM_UNSUPPORTED`); the caller adds its own (running, overrun, counter jumps).
    pub status: u16,
    pub algorithm: OdometryAlgorithm,
}

/// The slave's odometry over up to [`ENCODER_SLOTS`] encoders.
pub struct SlaveEstimator {
    odometry: Odometry,
    decoders: [QuadratureDecoder; ENCODER_SLOTS],
    /// Status bits gathered since the last update.
    pending: u16,
    /// Sticky until the next successful switch: the host asked for something this slave lacks.
    unsupported: bool,
}

fn slots<T: Copy + Default>(values: &[T]) -> [T; MAX_ENCODERS] {
    let mut out = [T::default(); MAX_ENCODERS];
    for (o, v) in out.iter_mut().zip(values) {
        *o = *v;
    }
    out
}

impl SlaveEstimator {
    /// `exact` at the origin at `t_ns`, the encoders at `counts`, their A/B channels at
    /// `edge_levels` (where edge decoding starts), the absolute encoder's pins at
    /// `abs_levels`. Uses floats once (the layout's float methods are not started).
    ///
    /// By value, for the host; the board builds its estimator in place
    /// ([`init`](Self::init) and [`restart`](Self::restart)).
    pub fn new(
        layout: &Layout,
        sensor: SensorMode,
        t_ns: u64,
        counts: &[i64],
        edge_levels: &[u8],
        abs_levels: u16,
    ) -> Result<Self, Unsupported> {
        let mut slot = MaybeUninit::uninit();
        SlaveEstimator::init(&mut slot, layout).restart(
            layout,
            sensor,
            t_ns,
            counts,
            edge_levels,
            abs_levels,
        )?;
        // SAFETY: `init` wrote every field.
        Ok(unsafe { slot.assume_init() })
    }

    /// Build an estimator in place in `slot` (the board's static cell): `exact` over `layout`
    /// at rest, a start for [`restart`](Self::restart). Cannot fail.
    pub fn init<'a>(slot: &'a mut MaybeUninit<Self>, layout: &Layout) -> &'a mut Self {
        robot_math::init_in_place!(
            slot,
            SlaveEstimator {
                decoders: [QuadratureDecoder::new(0); ENCODER_SLOTS],
                pending: 0,
                unsupported: false,
            } in_place {
                odometry: Odometry::init(layout),
            }
        )
    }

    /// Start again in place, as [`new`](Self::new) would have started. On `Err` the
    /// estimator runs `exact` over `layout` from the origin ([`Odometry::restart`]); `exact`
    /// runs every layout [`Layout`]'s checks let through.
    pub fn restart(
        &mut self,
        layout: &Layout,
        sensor: SensorMode,
        t_ns: u64,
        counts: &[i64],
        edge_levels: &[u8],
        abs_levels: u16,
    ) -> Result<(), Unsupported> {
        let kind = match sensor {
            SensorMode::Counts => SensorKind::Counts,
            SensorMode::TickTimestamps => SensorKind::Ticks,
        };
        for (j, d) in self.decoders.iter_mut().enumerate() {
            *d = QuadratureDecoder::new(edge_levels.get(j).copied().unwrap_or(0));
        }
        self.pending = 0;
        self.unsupported = false;
        self.odometry.restart(
            layout,
            Method::Exact,
            kind,
            FixedPose::default(),
            t_ns,
            &slots(counts),
            Some(abs_levels),
        )
    }

    /// One recorded encoder edge (tick-timestamp mode), in time order; returns the count step
    /// it decoded to, if any (for recording).
    pub fn on_edge(&mut self, e: EncoderEdge) -> Option<i8> {
        let w = e.encoder as usize;
        let decoder = self.decoders.get_mut(w)?;
        match decoder.edge(e.levels) {
            Quadrature::Step(step) => {
                self.odometry.tick(e.t_us * 1000, w, step);
                Some(step)
            }
            Quadrature::Missed => {
                self.pending |= slave_status::EDGES_LOST;
                None
            }
            Quadrature::None => None,
        }
    }

    /// The edge source says edges were lost (a full queue).
    pub fn edges_lost(&mut self) {
        self.pending |= slave_status::EDGES_LOST;
    }

    /// One fixed-rate update at `t_ns`.
    ///
    /// * `counters`: the hardware counters' totals. In counts mode they are the input; in
    ///   tick-timestamp mode, when `counters_match_edges` (read together with the edges
    ///   handed over so far, no edge in between), they are checked against the decoded
    ///   counts: a difference means an edge was lost (or invented) on the interrupt path.
    /// * `abs_levels`: the absolute encoder's pins.
    /// * `command`: the master's command, applied after the readings, before the update.
    pub fn sample(
        &mut self,
        t_ns: u64,
        counters: &[i64],
        counters_match_edges: bool,
        abs_levels: u16,
        command: Option<SlaveCommand>,
    ) -> Update {
        let mut status = core::mem::take(&mut self.pending);
        match self.odometry.sensors() {
            SensorKind::Counts => self.odometry.set_counts(counters),
            SensorKind::Ticks => {
                if counters_match_edges && !self.odometry.counts_are(counters) {
                    status |= slave_status::EDGES_LOST;
                }
            }
        }
        self.odometry.set_abs(abs_levels);
        match command {
            Some(SlaveCommand::SetPose(p)) => {
                let pose = FixedPose::from_micrometres(p.x_um, p.y_um, p.heading.0);
                self.odometry.set_pose(pose, t_ns);
            }
            Some(SlaveCommand::SetAlgorithm(a)) => {
                self.unsupported = self.odometry.switch(method_of(a), t_ns).is_err();
            }
            // The odometry task handles robot uploads and sensor sources itself.
            Some(_) | None => {}
        }
        let pose = self.odometry.update(t_ns);
        if self.unsupported {
            status |= slave_status::ALGORITHM_UNSUPPORTED;
        }
        Update {
            pose,
            status,
            algorithm: algorithm_of(self.odometry.method()),
        }
    }

    /// The running method's wire code.
    pub fn algorithm(&self) -> OdometryAlgorithm {
        algorithm_of(self.odometry.method())
    }

    /// The decoded (tick mode) or sampled (counts mode) whole counts.
    pub fn counts(&self) -> [i64; MAX_ENCODERS] {
        self.odometry.counts()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use robot_math::sensors::binary_to_gray;

    fn abs_levels(position: u16) -> u16 {
        !binary_to_gray(position) & 0xFF
    }

    /// Seed 004's sensors read as counters, at rest at the origin with the swivel at 0.
    fn seed_004_reading_counters() -> SlaveEstimator {
        SlaveEstimator::new(
            &Layout::SEED_004,
            SensorMode::Counts,
            0,
            &[0, 0],
            &[0, 0],
            abs_levels(0),
        )
        .unwrap()
    }

    #[test]
    fn algorithm_codes_map_one_to_one() {
        for m in Method::ALL {
            assert_eq!(method_of(algorithm_of(m)), m);
        }
    }

    #[test]
    #[cfg(feature = "baselines")]
    fn timing_on_counts_is_flagged_until_a_supported_switch() {
        let layout = Layout::SEED_004;
        let mut est = seed_004_reading_counters();
        let timing = Some(SlaveCommand::SetAlgorithm(OdometryAlgorithm::Timing));
        let u = est.sample(1_000_000, &[5, 5], false, abs_levels(0), timing);
        assert_eq!(u.algorithm, OdometryAlgorithm::Exact);
        assert_ne!(u.status & slave_status::ALGORITHM_UNSUPPORTED, 0);
        let u = est.sample(2_000_000, &[6, 6], false, abs_levels(0), None);
        assert_ne!(u.status & slave_status::ALGORITHM_UNSUPPORTED, 0, "sticky");
        let arc = Some(SlaveCommand::SetAlgorithm(OdometryAlgorithm::Arc));
        let u = est.sample(3_000_000, &[7, 7], false, abs_levels(0), arc);
        assert_eq!(u.algorithm, OdometryAlgorithm::Arc);
        assert_eq!(u.status & slave_status::ALGORITHM_UNSUPPORTED, 0);
        // Straight ahead along the carriage (swivel 0): x grows by 7 counts' travel.
        let x = u.pose.to_pose2().x;
        let k = layout.metres_per_count()[0];
        assert!((x - 7.0 * k).abs() < 1e-9, "{x}");
    }

    /// The default image (no `baselines`): every float method is refused, `exact` keeps
    /// running and integrating, and the refusal is flagged until a switch that works.
    /// `cargo test -p firmware-slave` runs it (`.ci/run` does); the workspace's `cargo test`
    /// builds the slave with host-bench's `baselines`.
    #[test]
    #[cfg(not(feature = "baselines"))]
    fn an_image_without_the_baselines_refuses_them_and_keeps_exact() {
        let layout = Layout::SEED_004;
        let mut est = seed_004_reading_counters();
        for (k, alg) in [
            OdometryAlgorithm::Arc,
            OdometryAlgorithm::Lut,
            OdometryAlgorithm::Timing,
        ]
        .into_iter()
        .enumerate()
        {
            let t = (k as u64 + 1) * 1_000_000;
            let c = 5 * (k as i64 + 1);
            let u = est.sample(
                t,
                &[c, c],
                false,
                abs_levels(0),
                Some(SlaveCommand::SetAlgorithm(alg)),
            );
            assert_eq!(u.algorithm, OdometryAlgorithm::Exact, "{alg:?}");
            assert_ne!(u.status & slave_status::ALGORITHM_UNSUPPORTED, 0, "{alg:?}");
            let x = u.pose.to_pose2().x;
            let travel = c as f64 * layout.metres_per_count()[0];
            assert!((x - travel).abs() < 1e-9, "{alg:?}: {x} vs {travel}");
        }
        let exact = Some(SlaveCommand::SetAlgorithm(OdometryAlgorithm::Exact));
        let u = est.sample(9_000_000, &[20, 20], false, abs_levels(0), exact);
        assert_eq!(u.status & slave_status::ALGORITHM_UNSUPPORTED, 0);
    }

    #[test]
    fn decoded_edges_are_checked_against_matching_counters() {
        let layout = Layout::SEED_004;
        let levels = [QuadratureDecoder::levels_at(0); 2];
        let mut est = SlaveEstimator::new(
            &layout,
            SensorMode::TickTimestamps,
            0,
            &[0, 0],
            &levels,
            abs_levels(0),
        )
        .unwrap();
        for (k, t) in [(1i64, 100u64), (2, 200), (3, 300)] {
            est.on_edge(EncoderEdge {
                t_us: t,
                encoder: 0,
                levels: QuadratureDecoder::levels_at(k),
            });
        }
        let u = est.sample(1_000_000, &[3, 0], true, abs_levels(0), None);
        assert_eq!(u.status & slave_status::EDGES_LOST, 0);
        assert_eq!(est.counts()[..2], [3, 0]);
        // Counters ahead of the decoded edges: an edge went missing on the interrupt path.
        let u = est.sample(2_000_000, &[4, 0], true, abs_levels(0), None);
        assert_ne!(u.status & slave_status::EDGES_LOST, 0);
        // Not read together with the edges: no verdict.
        let u = est.sample(3_000_000, &[4, 0], false, abs_levels(0), None);
        assert_eq!(u.status & slave_status::EDGES_LOST, 0);
    }
}
