//! The simulated robot: seed 004's platform. Three driven omni wheels (seed 003 layout), each
//! on a DC gear motor (`robot_math::motor::DcMotor`: back-EMF, friction, the driver's dead
//! band) with an encoder on its shaft, and the slave's two measuring encoders: on seed 004's trailing
//! carriage (two wheels and a swivel angle), or on two wheels fixed to the body (a robot
//! file's differential axle). Either way they produce exactly the counts and codes the real
//! encoders would.
//!
//! The state is integrated with classic RK4 on small steps; the motor speeds inside a step
//! follow their exact exponential, so the only approximation is RK4's (nanometres here).
//! Ground truth is the body pose at every instant.

mod edges;
mod sensors;
mod trig;

pub use sensors::{slave_board_reads, MeasuringSensors};

use trig::{Trig, FULL_TRIG_EVERY};

use crate::sim::generate::EdgeMap;

use robot_math::drive::DriveKinematics;
use robot_math::motor::{DcMotor, HeldDuty};
use robot_math::se2::wrap_angle;
use robot_math::sensors::binary_to_gray;
use robot_math::{Pose2, Twist};

/// Physical parameters of the simulated robot.
#[derive(Clone, Copy, Debug)]
pub struct PlantConfig {
    /// Drive wheels (their `v_max` is unused by the plant: physics does not saturate).
    pub drive: DriveKinematics,
    /// Every drive wheel's motor (the same model on each).
    pub motor: DcMotor,
    /// Rim travel per count of the motor-shaft encoders, m (None: no motor encoders).
    pub motor_metres_per_count: Option<f64>,
    pub sensors: MeasuringSensors,
}

/// Continuous state of the robot.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct State {
    body: Pose2,
    /// Carriage heading φ (with body-fixed wheels: the body heading plus a constant).
    phi: f64,
    /// Rolling distance of each measuring wheel since the start, metres.
    rolled: [f64; 2],
    /// Rim travel of each drive wheel since the start, metres (its motor encoder's count).
    driven: [f64; 3],
}

pub struct Plant {
    cfg: PlantConfig,
    t: f64,
    state: State,
    /// Actual drive wheel speeds, m/s.
    wheel_speed: [f64; 3],
    /// Duty the motors are driven with, per mille.
    duty: [i16; 3],
    /// Times the motors went from standing (every duty zero, or stopped) to driven, and the
    /// time they spent driven, seconds.
    switch_ons: u64,
    driven_s: f64,
    /// Each encoder's position within its first count at the start, in counts, [0, 1): a real
    /// encoder is not aligned to a count edge when the robot is switched on.
    encoder_phase: [f64; 2],
    path_length: f64,
    /// Encoder edges since the last `take_edges`: (time s, encoder, count after the edge).
    edges: Vec<edges::Edge>,
    /// The motors' decay over the last step length and its half, `(h, half, full)`: the steps
    /// are all the same length, so the exponentials are paid for once.
    decay: (f64, f64, f64),
    /// The motors at their duties (changed by [`set_duty`](Self::set_duty) only): their drive
    /// and steady speeds, worked out when a duty is set rather than every step.
    held: [HeldDuty; 3],
    /// The measuring encoders' travel per count and their power-on phase's whole counts:
    /// constants of every position, taken out of the per-step path.
    per_count: [f64; 2],
    phase_floor: [f64; 2],
    /// The encoders' positions and the sines and cosines of the headings at `state`: each
    /// step computes them for its end, and the next step starts from that state (the values
    /// are the same computations on the same inputs, so the results are bit for bit those
    /// of computing them again).
    positions: [f64; 2],
    trig: Trig,
    /// Steps until the end angles are computed in full again ([`FULL_TRIG_EVERY`]).
    full_trig_in: u32,
    /// The first encoder's edges of a step while they are merged with the second's.
    merge_scratch: Vec<edges::Edge>,
    /// Real encoders' edges ([`with_edges`](Self::with_edges)): where each puts them, and
    /// its last time stamp. None: ideal edges, whole counts.
    edge_maps: Option<Box<MappedEdges>>,
}

/// The measuring encoders' uneven edges.
#[derive(Clone, Debug)]
struct MappedEdges {
    maps: [EdgeMap; 2],
    last_stamp: [f64; 2],
}

impl Plant {
    /// A robot at rest at `body`, carriage swivelled by `swivel` (carriage minus body heading).
    pub fn new(cfg: PlantConfig, body: Pose2, swivel: f64, encoder_phase: [f64; 2]) -> Self {
        // Any -0.0 made +0.0 (`x + 0.0`): the integrator's sums never make a -0.0 of their own
        // (`x + -x` is +0.0), so the state never holds one, and a parked step, which skips
        // adding zeros ([`step_at_rest`](Self::step_at_rest)), leaves what adding them would.
        let body = Pose2::new(body.x + 0.0, body.y + 0.0, body.theta + 0.0);
        let state = State {
            body,
            phi: body.theta + swivel + 0.0,
            rolled: [0.0; 2],
            driven: [0.0; 3],
        };
        let per_count = cfg.sensors.metres_per_count();
        let phase_floor = encoder_phase.map(f64::floor);
        Plant {
            cfg,
            t: 0.0,
            state,
            wheel_speed: [0.0; 3],
            duty: [0; 3],
            switch_ons: 0,
            driven_s: 0.0,
            encoder_phase,
            path_length: 0.0,
            edges: Vec::new(),
            decay: (f64::NAN, 0.0, 0.0),
            held: held_duties(&cfg.motor, [0; 3]),
            per_count,
            phase_floor,
            positions: encoder_positions(per_count, encoder_phase, phase_floor, &state),
            trig: Trig::of(&cfg, &state),
            full_trig_in: FULL_TRIG_EVERY,
            merge_scratch: Vec::new(),
            edge_maps: None,
        }
    }

    /// The measuring encoders' edges where `maps` puts them (a real encoder's: uneven, and
    /// stamped late by up to its capture latency) instead of one count apart. Each encoder
    /// powers on at its phase between its map's first two edges. Call before the first step.
    pub fn with_edges(mut self, maps: [EdgeMap; 2]) -> Self {
        for (j, map) in maps.iter().enumerate() {
            let (e0, e1) = (map.edge(0), map.edge(1));
            let phase = self.encoder_phase[j] - self.phase_floor[j];
            self.encoder_phase[j] = e0 + phase * (e1 - e0);
            self.phase_floor[j] = 0.0;
        }
        self.edge_maps = Some(Box::new(MappedEdges {
            maps,
            last_stamp: [0.0; 2],
        }));
        self.positions = self.encoder_positions(&self.state);
        self
    }

    pub fn time(&self) -> f64 {
        self.t
    }

    /// Ground truth: the body's pose now.
    pub fn body(&self) -> Pose2 {
        self.state.body
    }

    pub fn path_length(&self) -> f64 {
        self.path_length
    }

    pub fn set_duty(&mut self, duty: [i16; 3]) {
        let driven = |d: [i16; 3]| d != [0; 3];
        if driven(duty) && !driven(self.duty) {
            self.switch_ons += 1;
        }
        self.duty = duty;
        self.held = held_duties(&self.cfg.motor, duty);
    }

    /// Times the motors went from standing (every duty zero) to driven since the start: what
    /// a controller that dithers at rest shows, one switch-on per kick.
    pub fn motor_switch_ons(&self) -> u64 {
        self.switch_ons
    }

    /// Seconds the motors spent driven (some duty non-zero) since the start.
    pub fn motor_driven_s(&self) -> f64 {
        self.driven_s
    }

    pub fn duty(&self) -> [i16; 3] {
        self.duty
    }

    pub fn wheel_speeds(&self) -> [f64; 3] {
        self.wheel_speed
    }

    /// Quadrature counts each measuring-wheel encoder shows now (x4 decoding).
    pub fn encoder_counts(&self) -> [i64; 2] {
        match &self.edge_maps {
            None => self.positions.map(edges::whole_counts),
            Some(m) => core::array::from_fn(|j| m.maps[j].count_at(self.positions[j])),
        }
    }

    /// The motor encoders' counts now, as the master's free-running 16-bit counters show
    /// them (zero at power-on; all zero without motor encoders).
    pub fn motor_counts(&self) -> [u16; 3] {
        let Some(per_count) = self.cfg.motor_metres_per_count else {
            return [0; 3];
        };
        self.state
            .driven
            .map(|d| (d / per_count).floor() as i64 as u16)
    }

    fn encoder_positions(&self, s: &State) -> [f64; 2] {
        encoder_positions(self.per_count, self.encoder_phase, self.phase_floor, s)
    }

    /// Every encoder edge since the last call: (time s, encoder, count after the edge),
    /// oldest first. The instants are interpolated within each physics step.
    pub fn take_edges(&mut self) -> Vec<(f64, usize, i64)> {
        std::mem::take(&mut self.edges)
    }

    /// [`take_edges`](Self::take_edges) into `out` (emptied first), whose allocation the plant
    /// keeps for the next ones: a caller that drains every millisecond allocates nothing.
    pub fn swap_edges(&mut self, out: &mut Vec<(f64, usize, i64)>) {
        out.clear();
        std::mem::swap(out, &mut self.edges);
    }

    /// Swivel angle β = φ − θ, wrapped.
    pub fn swivel(&self) -> f64 {
        wrap_angle(self.state.phi - self.state.body.theta)
    }

    /// The absolute encoder's code now (0 without one).
    pub fn abs_code(&self) -> u16 {
        match self.cfg.sensors {
            MeasuringSensors::Carriage { geometry, .. } => geometry.abs_code(self.swivel()),
            MeasuringSensors::Wheels { .. } => 0,
        }
    }

    /// The levels on the slave's eight absolute-encoder pins now: the code in the encoder's
    /// output format (Gray, active-low, as the layout says).
    pub fn abs_pins(&self) -> u8 {
        let mut raw = self.abs_code();
        if let MeasuringSensors::Carriage { abs, .. } = self.cfg.sensors {
            if abs.gray {
                raw = binary_to_gray(raw);
            }
            if abs.inverted {
                raw = !raw;
            }
        }
        raw as u8
    }

    /// Advance the physics by `dt` seconds, sub-stepping so no step exceeds `max_step`.
    pub fn advance(&mut self, dt: f64, max_step: f64) {
        if dt <= 0.0 {
            return;
        }
        if self.duty != [0; 3] {
            self.driven_s += dt;
        }
        let n = (dt / max_step).ceil().max(1.0) as usize;
        let h = dt / n as f64;
        for _ in 0..n {
            self.step(h);
        }
    }

    /// [`advance`](Self::advance) from `from_us` to `to_us` microseconds of the firmware's
    /// clock, the plant's clock then set to `to_us` itself: steps added up drift off whole
    /// microseconds (by half of one after 78 min of 1 ms steps, when `scripts/long-run` ran a
    /// build with debug assertions on), and every firmware read must find the plant at its own
    /// instant (`emulator::hw`). The steps are the same as `advance`'s.
    pub fn advance_us(&mut self, from_us: u64, to_us: u64, max_step: f64) {
        if to_us <= from_us {
            return;
        }
        self.advance((to_us - from_us) as f64 * 1e-6, max_step);
        self.t = to_us as f64 * 1e-6;
    }

    fn step(&mut self, h: f64) {
        if self.held_still() {
            self.step_at_rest(h);
        } else {
            self.step_moving(h);
        }
    }

    /// One RK4 step of `h` seconds.
    fn step_moving(&mut self, h: f64) {
        let w0 = self.wheel_speed;
        let motor = self.cfg.motor;
        if self.decay.0 != h {
            self.decay = (h, motor.decay(h / 2.0), motor.decay(h));
        }
        // The motors' exact response inside the step (the duty is held through it), at the
        // three instants RK4 looks at.
        let speeds: [[f64; 3]; 3] = core::array::from_fn(|i| {
            motor.driven_speeds_after_decays(
                w0[i],
                &self.held[i],
                [1.0, self.decay.1, self.decay.2],
            )
        });
        let (start, half, end) = (
            speeds.map(|s| s[0]),
            speeds.map(|s| s[1]),
            speeds.map(|s| s[2]),
        );
        // Each wheel-speed triple's twist once (k2 and k3 share the half step's, k4 and the
        // edges' end speed the end's).
        let drive = &self.cfg.drive;
        let (twist_half, twist_end) = (drive.twist(half), drive.twist(end));
        let cfg = &self.cfg;
        let f = |wheels: [f64; 3], twist: Twist, trig: &Trig| State {
            driven: wheels,
            ..derivative(cfg, twist, trig)
        };
        let y0 = self.state;
        let k1 = f(start, drive.twist(start), &self.trig);
        let y1 = add(&y0, &k1, h / 2.0);
        let k2 = f(half, twist_half, &self.trig.turned(cfg, &y0, &y1));
        let y2 = add(&y0, &k2, h / 2.0);
        let k3 = f(half, twist_half, &self.trig.turned(cfg, &y0, &y2));
        let y3 = add(&y0, &k3, h);
        let k4 = f(end, twist_end, &self.trig.turned(cfg, &y0, &y3));
        let mut y = y0;
        y = add(&y, &k1, h / 6.0);
        y = add(&y, &k2, h / 3.0);
        y = add(&y, &k3, h / 3.0);
        y = add(&y, &k4, h / 6.0);
        // The end state's angles: the edges' end speed uses them, and the next step's k1.
        // Turned from the start's by the step's small angle, as the stages' are, and in full
        // every [`FULL_TRIG_EVERY`] steps, so the rounding of the turns cannot add up.
        self.full_trig_in -= 1;
        let trig_end = if self.full_trig_in == 0 {
            self.full_trig_in = FULL_TRIG_EVERY;
            Trig::of(cfg, &y)
        } else {
            self.trig.turned(cfg, &y0, &y)
        };
        // Edges crossed in this step, at the instant each encoder's position crosses a whole
        // count: found on the cubic through both ends' positions and speeds (RK4's own order
        // of accuracy), not on a straight line. A straight line misplaced the edges of a
        // wheel starting from rest by tens of microseconds, and with them the slave's
        // placing of its wheels from their first ticks; it also made the edges depend on how
        // the steps fell.
        let (p0, p1) = (self.positions, self.encoder_positions(&y));
        let first_new = self.edges.len();
        let mut second_encoder = first_new;
        let mut end_speed = None;
        for j in 0..2 {
            second_encoder = self.edges.len();
            let (a, b) = (p0[j], p1[j]);
            let map = self.edge_maps.as_deref().map(|m| &m.maps[j]);
            let same = match map {
                None => edges::whole_counts(a) == edges::whole_counts(b),
                Some(m) => m.count_at(a) == m.count_at(b),
            };
            if same {
                continue;
            }
            let per_count = self.per_count[j];
            let k_end = *end_speed.get_or_insert_with(|| f(end, twist_end, &trig_end));
            let (v0, v1) = (
                k1.rolled[j] / per_count * h,
                k_end.rolled[j] / per_count * h,
            );
            match map {
                None => edges::push_crossings(&mut self.edges, j, self.t, h, (a, b), (v0, v1)),
                Some(m) => {
                    let from = self.edges.len();
                    edges::push_mapped_crossings(
                        &mut self.edges,
                        j,
                        self.t,
                        h,
                        (a, b),
                        (v0, v1),
                        m,
                    );
                    if let Some(m) = self.edge_maps.as_deref_mut() {
                        m.stamp_late(j, &mut self.edges[from..]);
                    }
                }
            }
        }
        // Each encoder's edges are in time order: merged, the two are in the order the edge
        // interrupts would come (the first encoder's first on a tie).
        edges::merge_by_time(
            &mut self.edges[first_new..],
            second_encoder - first_new,
            &mut self.merge_scratch,
        );
        self.path_length += y.body.distance_to(y0.body);
        self.state = y;
        self.positions = p1;
        self.trig = trig_end;
        self.wheel_speed = end;
        self.t += h;
    }
}

impl MappedEdges {
    /// Encoder `j`'s new `edges`, stamped late by its capture latency (uniform in [0, the
    /// map's latency]), never before its previous stamp.
    fn stamp_late(&mut self, j: usize, edges: &mut [edges::Edge]) {
        if self.maps[j].capture_jitter_ns == 0 {
            return;
        }
        for (t, _, _) in edges {
            let late = self.maps[j].latency_ns();
            *t = (*t + late as f64 * 1e-9).max(self.last_stamp[j]);
            self.last_stamp[j] = *t;
        }
    }
}

impl Plant {
    /// Whether every wheel stands and its motor's drive cannot overcome the stiction: then
    /// nothing moves through a step (a robot parked between runs, or at the end of one).
    fn held_still(&self) -> bool {
        let motor = &self.cfg.motor;
        (0..3).all(|i| motor.held_still(self.wheel_speed[i], &self.held[i]))
    }

    /// [`step`](Self::step) for a robot [`held_still`](Self::held_still): every derivative is
    /// zero, so RK4 would hand back the state, the angles and the positions it started from,
    /// with no edge and no path. Only the clock moves, and the angles are computed in full
    /// when a moving step would compute them, so a robot setting off again steps exactly as
    /// it would have (8 % of the plant's time in the default run, which stands for 3 444 of
    /// its 12 000 steps). The same bits because the state holds no -0.0 ([`Plant::new`]):
    /// adding a zero then changes nothing.
    fn step_at_rest(&mut self, h: f64) {
        self.full_trig_in -= 1;
        if self.full_trig_in == 0 {
            self.full_trig_in = FULL_TRIG_EVERY;
            self.trig = Trig::of(&self.cfg, &self.state);
        }
        self.wheel_speed = [0.0; 3];
        self.t += h;
    }
}

/// The motors at `duty` (‰ of the supply).
fn held_duties(motor: &DcMotor, duty: [i16; 3]) -> [HeldDuty; 3] {
    duty.map(|d| motor.held(d as f64 / 1000.0))
}

/// Each encoder's position in counts (fractional), relative to its power-on count.
fn encoder_positions(
    per_count: [f64; 2],
    phase: [f64; 2],
    phase_floor: [f64; 2],
    s: &State,
) -> [f64; 2] {
    core::array::from_fn(|i| s.rolled[i] / per_count[i] + phase[i] - phase_floor[i])
}

/// Time derivative of the state for a body twist, at the state whose angles `trig` has
/// (nothing else of the state enters it).
fn derivative(cfg: &PlantConfig, twist: Twist, trig: &Trig) -> State {
    let (s, c) = trig.theta;
    // Velocity of the body reference point (the swivel pivot) in the field frame.
    let vx = c * twist.vx - s * twist.vy;
    let vy = s * twist.vx + c * twist.vy;
    let g = match cfg.sensors {
        MeasuringSensors::Carriage { geometry, .. } => geometry,
        MeasuringSensors::Wheels { wheels, .. } => {
            return State {
                body: Pose2::new(vx, vy, twist.omega),
                phi: twist.omega,
                rolled: wheels.map(|w| w.rolling_speed(twist)),
                driven: [0.0; 3],
            };
        }
    };
    let (sp, cp) = trig.phi;
    // The axle trails the pivot and cannot slide sideways: it swings to follow. Times the
    // trail's reciprocal, which waits for nothing, rather than over the trail: the carriage
    // angle is the integrator's longest chain, each of its four stages through this line, and
    // a division's latency is several products' (3 % of the plant's time). The angle moves in
    // its last bits, and with it the measuring wheels' travel: edge times by about 10^-15 s,
    // none across the slave's microsecond in the runs checked. The body's pose not at all.
    let phi_dot = (-sp * vx + cp * vy) * (1.0 / g.trail);
    let forward = cp * vx + sp * vy;
    State {
        body: Pose2::new(vx, vy, twist.omega),
        phi: phi_dot,
        rolled: [
            forward - phi_dot * g.wheel_base / 2.0,
            forward + phi_dot * g.wheel_base / 2.0,
        ],
        driven: [0.0; 3],
    }
}

fn add(y: &State, k: &State, h: f64) -> State {
    State {
        body: Pose2::new(
            y.body.x + h * k.body.x,
            y.body.y + h * k.body.y,
            y.body.theta + h * k.body.theta,
        ),
        phi: y.phi + h * k.phi,
        rolled: [y.rolled[0] + h * k.rolled[0], y.rolled[1] + h * k.rolled[1]],
        driven: core::array::from_fn(|i| y.driven[i] + h * k.driven[i]),
    }
}

#[cfg(test)]
pub(super) mod tests;
