//! `host-bench virtual-board`: both boards' firmware, emulated as `emulate` does, behind a
//! pseudo-terminal, in real time, so `play` and `record` talk to it exactly as to real boards
//! (or faster or slower, [`Options::time_scale`], with the host on its clock file).
//!
//! ```text
//!  play/record ── /dev/pts/N ══ pty ══ bridge ── UartLine x2 (115200 8N1) ──► firmware_master::tasks ── SpiWire ──► firmware_slave::run
//!                                        │ (SimTruth every 10 ms)                                               ▲ encoders, absolute encoder
//!                                        └────────────── Plant (the slave's robot, driven round a square) ──────┘
//! ```
//! The simulated robot is driven round a 1 m square course by the virtual board itself, as if
//! pushed by hand (the master gets no goal, and its motor outputs go nowhere), so `record`
//! has something to record. Or, with [`Options::master_drives`], it stands still until the
//! host drives it through the master, whose motor outputs then turn its wheels, as on a
//! robot on the floor (`calibrate --port` drives its squares so). Only a simulated board can
//! send the truth; it does, as [`MasterToHost::SimTruth`] frames between the master's own.
//!
//! The robot is the slave's layout (`Options::slave.layout()`): seed 004's carriage by default,
//! as a freshly flashed slave; or a robot file's two encoders, as a slave that was sent that
//! robot. A robot whose measuring wheels share an axle is driven like a differential drive
//! (its axle never slides sideways), so its encoders see what real ones would.

use std::cell::RefCell;
use std::io::{ErrorKind, Read, Write};
use std::rc::Rc;
use std::time::{Duration as WallDuration, Instant as WallInstant};

use anyhow::{Context, Result};
use embassy_time::{Duration, Instant};
use firmware_master::drive_setup::DriveSetup;
use firmware_master::ports::{MotorDrivers, MotorEncoders};
use firmware_master::{MasterConfig, MasterShared};
use firmware_slave::{SlaveConfig, SlaveShared};
use protocol::serial::{self, FrameDecoder, MasterToHost};
use rand::{Rng, SeedableRng};
use robot_math::drive::DriveKinematics;
use robot_math::odometry::Layout;
use robot_math::omni3::Omni3;
use robot_math::pursuit::field_to_body;
use robot_math::se2::wrap_angle;
use robot_math::{Pose2, Twist};
use serialport::TTYPort;
use virtual_time::Simulation;

use super::adapter::Adapter;
use super::emulator::hw::*;
use super::master_tasks::{spawn_master, MasterPorts};
use super::plant::{MeasuringSensors, Plant, PlantConfig};
use super::serial_noise::{Receiver, SerialFaults, SerialNoise};
use crate::serial::clock::ClockFile;
use robot_math::motor::DcMotor;

/// Fault knobs of the virtual board (for tests of the host's checks and of the links).
#[derive(Clone, Debug, Default)]
pub struct Faults {
    /// Report this schema fingerprint in the hello reply instead of the real one.
    pub schema: Option<u32>,
    /// Serial noise, per frame, each direction on its own: a bit flipped, the frame lost,
    /// sent twice, or held back behind the next.
    pub serial: SerialFaults,
    /// Bit errors and lost transactions on the SPI wire between the boards.
    pub spi: SpiFaults,
    /// Reset the slave this many seconds after the board started (it runs again from
    /// power-on 5 ms later).
    pub slave_reset_at: Option<f64>,
    /// One deliberate failure on the line to the host (stall, flood, ...), once that many
    /// report frames have reached it.
    pub misbehave: Option<super::misbehaving::Misbehaviour>,
}

#[derive(Clone, Debug)]
pub struct Options {
    pub seed: u64,
    pub slave: SlaveConfig,
    pub master: MasterConfig,
    pub faults: Faults,
    /// Course: side of the square, metres, and speed, m/s.
    pub course_side: f64,
    pub course_speed: f64,
    /// Where the measuring encoders put their edges (ideal, or a datasheet's errors, each
    /// encoder's drawn from `seed`).
    pub edges: crate::sim::generate::EdgeErrors,
    /// The robot's measuring sensors as they really are, when they are not as the slave is
    /// told (`--true-robot`): the simulated wheels follow these. None: the slave's own.
    pub true_layout: Option<Layout>,
    /// The robot's drive and motors, when the master drives it (`--master-drives`): the
    /// wheels follow the master's duties, and the host must send this drive (`SetDrive`)
    /// first, as to real boards. None: the board's own course pushes it round.
    pub master_drives: Option<Drivetrain>,
    /// Whether the board sends the host its truth (`SimTruth`); without it, it is as a real
    /// board, and a recording has no truth rows.
    pub send_truth: bool,
    /// The USB-serial adapter between the pseudo-terminal and the master: its top rate and
    /// latency timer.
    pub adapter: super::adapter::AdapterSpec,
    /// Simulated seconds per wall second: 1 is real time. Off 1, the host must take the
    /// board's time from its clock file (`serve`'s `clock`), or every wait of its is off by
    /// this factor.
    pub time_scale: f64,
}

/// The most simulated time [`serve`] runs between two looks at the line.
const MOST_PER_PASS: Duration = Duration::from_millis(10);

/// A robot's driven wheels and their motors, as they really are.
#[derive(Clone, Copy, Debug)]
pub struct Drivetrain {
    pub drive: protocol::serial::DriveGeometry,
    pub motor: DcMotor,
}

impl Default for Options {
    fn default() -> Self {
        Options::for_robot(Layout::SEED_004)
    }
}

impl Options {
    /// A virtual board whose slave holds `layout`, driven at [`course_speed_for`] it.
    pub fn for_robot(layout: Layout) -> Options {
        let course_speed = course_speed_for(&layout);
        Options {
            seed: 1,
            slave: SlaveConfig::DEFAULT.with_layout(layout),
            master: MasterConfig::DEFAULT,
            faults: Faults::default(),
            course_side: 1.0,
            course_speed,
            edges: crate::sim::generate::EdgeErrors::IDEAL,
            true_layout: None,
            master_drives: None,
            send_truth: true,
            adapter: super::adapter::AdapterSpec::default(),
            time_scale: 1.0,
        }
    }
}

/// A course speed at which a 115200-baud link carries every time-stamped edge a recording
/// sends (2 bytes each): seed 004's 0.05 m/s with its 32.7 µm counts, about 3 000 edges/s,
/// scaled to the finer of the robot's two encoders (0.01 to 0.5 m/s).
pub fn course_speed_for(layout: &Layout) -> f64 {
    let finest = |l: &Layout| {
        l.metres_per_count()[..2]
            .iter()
            .copied()
            .fold(f64::MAX, f64::min)
    };
    (0.05 * finest(layout) / finest(&Layout::SEED_004)).clamp(0.01, 0.5)
}

/// The master's motor outputs on the virtual board: kept, applied to nothing.
struct Unconnected;

impl MotorDrivers for Unconnected {
    fn set_duty(&mut self, _duty: [i16; 3]) {}
    fn stop(&mut self) {}
}

impl MotorEncoders for Unconnected {
    fn counts(&mut self) -> [u16; 3] {
        [0; 3]
    }
}

/// How the course steers the body.
enum Steering {
    /// Any twist (a carriage follows whatever the body does): slide to each corner, holding
    /// heading 0.
    Holonomic,
    /// Measuring wheels on one axle, rolling along `u` (body frame), its midpoint at `mid`:
    /// that point only moves along `u`, like a differential drive's. Turn towards each corner,
    /// then roll to it.
    Axle { mid: (f64, f64), u: (f64, f64) },
}

impl Steering {
    fn for_sensors(sensors: &MeasuringSensors) -> Steering {
        match *sensors {
            MeasuringSensors::Carriage { .. } => Steering::Holonomic,
            MeasuringSensors::Wheels { wheels: [a, b], .. } => Steering::Axle {
                mid: ((a.x + b.x) / 2.0, (a.y + b.y) / 2.0),
                u: (a.ux, a.uy),
            },
        }
    }
}

/// Drives the plant round a square with seed 003's inverse kinematics.
struct Course {
    corners: [(f64, f64); 4],
    next: usize,
    speed: f64,
    steering: Steering,
    drive: Omni3,
    speed_at_full_duty: f64,
}

impl Course {
    /// The body twist that heads for the next corner.
    fn twist(&mut self, body: Pose2) -> Twist {
        // The point that goes round the square: the body origin, or the axle's midpoint.
        let (fx, fy) = body.transform_point(match self.steering {
            Steering::Holonomic => (0.0, 0.0),
            Steering::Axle { mid, .. } => mid,
        });
        let (cx, cy) = self.corners[self.next];
        let (dx, dy) = (cx - fx, cy - fy);
        let dist = dx.hypot(dy);
        if dist < 0.01 {
            self.next = (self.next + 1) % self.corners.len();
        }
        let v = self.speed.min(dist * 4.0).max(0.01);
        match self.steering {
            Steering::Holonomic => {
                let (vx, vy) = (v * dx / dist.max(1e-9), v * dy / dist.max(1e-9));
                let (bx, by) = field_to_body(vx, vy, body.theta);
                Twist::new(bx, by, -2.0 * wrap_angle(body.theta))
            }
            Steering::Axle { mid, u } => {
                let heading = body.theta + u.1.atan2(u.0);
                let err = wrap_angle(dy.atan2(dx) - heading);
                let omega = (3.0 * err).clamp(-1.0, 1.0);
                // Facing away: turn on the spot first.
                let v = v * err.cos().max(0.0);
                // The origin's velocity from the midpoint's: v·u − ω × mid.
                Twist::new(v * u.0 + omega * mid.1, v * u.1 - omega * mid.0, omega)
            }
        }
    }

    fn duty(&mut self, body: Pose2) -> [i16; 3] {
        let twist = self.twist(body);
        let (w, _) = self.drive.wheel_speeds_saturated(twist);
        w.map(|s| {
            ((s / self.speed_at_full_duty) * 1000.0)
                .round()
                .clamp(-1000.0, 1000.0) as i16
        })
    }
}

/// The virtual board's robot: the master's power-on drive, which must be omni wheels (the
/// course steers the body's twist freely), and its wheel speed at full duty.
/// The motors the course drives open loop: without friction its duties move the robot where it
/// steers (what this board is for is the slave's sensors, not the motors).
const COURSE_MOTOR: DcMotor = DcMotor::SEED_004.frictionless();

fn omni_drive(master: &MasterConfig) -> Result<Omni3> {
    match DriveSetup::from_geometry(&master.drive) {
        Some(DriveSetup {
            kinematics: DriveKinematics::Omni3(omni),
            ..
        }) => Ok(omni),
        Some(_) => anyhow::bail!("the virtual board drives omni wheels only"),
        None => anyhow::bail!("the master's drive geometry is impossible"),
    }
}

/// Open the pseudo-terminal pair; the returned name is what `play --port` opens.
pub fn open_pty() -> Result<(TTYPort, TTYPort, String)> {
    let (mut master, slave) = TTYPort::pair().context("cannot open a pseudo-terminal pair")?;
    let name = serialport::SerialPort::name(&slave).context("the pseudo-terminal has no name")?;
    // Short timeouts: the bridge polls, and a host that is not reading must not stall it.
    serialport::SerialPort::set_timeout(&mut master, WallDuration::from_millis(1))?;
    Ok((master, slave, name))
}

/// Serves `pty` until `stop()` says so (forever for the CLI). `view` (`--mcap`, `--live`) is
/// shown the run every 10 ms of its time: the channels of
/// [`crate::viewer::topics::emulate_channels`] with `/link`. `clock`, if any, is given the
/// boards' time before each pass hands the host its bytes (`--clock` takes the file): at
/// `opts.time_scale` other than 1 the host must take it.
pub fn serve(
    mut pty: TTYPort,
    opts: &Options,
    stop: &dyn Fn() -> bool,
    view: Option<&RefCell<crate::viewer::View>>,
    clock: Option<&ClockFile>,
) -> Result<()> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(opts.seed);
    let sensors =
        MeasuringSensors::from_layout(opts.true_layout.as_ref().unwrap_or(opts.slave.layout()))
            .map_err(|e| anyhow::anyhow!("the virtual board cannot simulate this robot: {e}"))?;
    // Pushed round the course open loop (no speed loops, no motor encoders), or driven by the
    // master through the robot's own drive and motors.
    let (plant_cfg, course) = match &opts.master_drives {
        Some(d) => {
            let setup = DriveSetup::from_geometry(&d.drive)
                .context("the robot's drive geometry is impossible")?;
            let cfg = PlantConfig {
                drive: setup.kinematics,
                motor: d.motor,
                motor_metres_per_count: setup.metres_per_motor_count,
                sensors,
            };
            (cfg, None)
        }
        None => {
            let drive = omni_drive(&opts.master)?;
            let side = opts.course_side;
            let course = Course {
                corners: [(0.0, side), (side, side), (side, 0.0), (0.0, 0.0)],
                next: 0,
                speed: opts.course_speed,
                steering: Steering::for_sensors(&sensors),
                drive,
                speed_at_full_duty: COURSE_MOTOR.steady_speed(1.0),
            };
            let cfg = PlantConfig {
                drive: DriveKinematics::Omni3(drive),
                motor: COURSE_MOTOR,
                motor_metres_per_count: None,
                sensors,
            };
            (cfg, Some(course))
        }
    };
    let per_count = plant_cfg.sensors.metres_per_count();
    let mut plant = Plant::new(
        plant_cfg,
        Pose2::new(0.0, 0.0, 0.0),
        std::f64::consts::FRAC_PI_2,
        [rng.random::<f64>(), rng.random::<f64>()],
    );
    if !opts.edges.is_ideal() {
        plant = plant.with_edges(core::array::from_fn(|j| {
            crate::sim::generate::EdgeMap::draw(&opts.edges, opts.seed, j, per_count[j])
        }));
    }
    let plant: SharedPlant = Rc::new(RefCell::new(plant));
    let mut course = course;
    let slave_shared = SlaveShared::new();
    let master_shared = MasterShared::new();
    let wire = Rc::new(RefCell::new(SpiWire::new(opts.faults.spi, opts.seed)));
    let f = &opts.faults;
    let mut noise_to_master = SerialNoise::new(f.serial, opts.seed ^ 0x5e1a, Receiver::Master);
    let mut noise_to_host = SerialNoise::new(f.serial, opts.seed ^ 0x5e1b, Receiver::Host);
    let mut misbehaving = f.misbehave.map(super::misbehaving::MisbehavingLine::new);
    let to_master: SharedLine = Rc::default();
    let to_host: SharedLine = Rc::new(RefCell::new(UartLine::with_rates()));
    // The master's USART rate (it changes when the host negotiates), and the adapter.
    let master_rate: SharedRate = Rc::new(core::cell::Cell::new(opts.master.baud));
    let mut adapter = Adapter::new(opts.adapter);
    let mut sim = Simulation::new()?;
    sim.spawn(super::emulator::slave_board(
        &plant,
        &wire,
        &slave_shared,
        &opts.slave,
        opts.faults
            .slave_reset_at
            .map(|s| Instant::from_micros((s * 1e6) as u64)),
        None,
    ));
    let bus = || EmuMasterBus {
        wire: wire.clone(),
        transfer_time: spi_transfer_time(protocol::spi::SPI_CLOCK_HZ),
    };
    let uart_tx = || UartTx {
        line: to_host.clone(),
        rate: master_rate.clone(),
        noise: None,
    };
    // A macro, not a closure: the two calls give different motor types.
    macro_rules! master_ports {
        ($motors:expr, $encoders:expr) => {
            MasterPorts {
                bus: bus(),
                serial_rx: UartRx(to_master.clone()),
                serial_tx: uart_tx(),
                motors: $motors,
                encoders: $encoders,
                shared: &master_shared,
                config: &opts.master,
            }
        };
    }
    // The master's motor outputs: to the wheels, or nowhere (the course pushes the robot).
    if opts.master_drives.is_some() {
        let motors = EmuMotors {
            plant: plant.clone(),
            source: DutySource::Master,
            steps: 0,
        };
        let encoders = EmuMotorEncoders(plant.clone());
        spawn_master(&mut sim, master_ports!(motors, encoders));
    } else {
        spawn_master(&mut sim, master_ports!(Unconnected, Unconnected));
    }

    let wall = WallInstant::now();
    // Where the boards' time is due by the wall's.
    let due =
        || Instant::from_micros((wall.elapsed().as_secs_f64() * opts.time_scale * 1e6) as u64);
    let plant_step = Duration::from_micros(100);
    let course_every = Duration::from_millis(10);
    // Never, when the master drives.
    let mut next_course = if course.is_some() {
        Instant::from_ticks(0)
    } else {
        Instant::MAX
    };
    let mut next_truth = Instant::from_ticks(0);
    let mut next_view = Instant::from_ticks(0);
    let (mut bytes_from_host, mut bytes_to_host) = (0u64, 0u64);
    let mut rewrite = FrameDecoder::new();
    let mut buf = [0u8; 4096];
    sim.run_until_idle();
    while !stop() {
        // Catch the virtual clock up with the wall clock (times the time scale), by at most
        // `MOST_PER_PASS` a pass: an emulation slower than the scale asked for then runs as
        // fast as it can and still serves the line between, on its own clock.
        let due_now = due();
        let target = due_now.min(sim.now() + MOST_PER_PASS);
        let behind = due_now > target;
        while sim.now() < target {
            let now = sim.now();
            if let Some(course) = course.as_mut().filter(|_| now >= next_course) {
                let body = plant.borrow().body();
                let d = course.duty(body);
                plant.borrow_mut().set_duty(d);
                next_course = now + course_every;
            }
            let mut next = (now + plant_step).min(target).min(next_course);
            if let Some(d) = sim.next_deadline() {
                next = next.min(d.max(now));
            }
            plant
                .borrow_mut()
                .advance_us(now.as_micros(), next.as_micros(), 100e-6);
            sim.run_until(next);
        }
        // The time, before the step's bytes reach the host: what it reads is never ahead of it.
        if let Some(clock) = clock {
            clock.set(sim.now().as_micros() * 1_000)?;
        }
        // The rate the host set on its end of the line, and the master's.
        let host_rate = serialport::SerialPort::baud_rate(&pty).unwrap_or(0);
        let rate = master_rate.get();
        let now = sim.now();
        // Host -> master: whatever the pty has, through the adapter at the line's pace. Read
        // only what is there: a read that waits for bytes would cap the speed.
        let waiting = serialport::SerialPort::bytes_to_read(&pty).unwrap_or(1);
        match if waiting > 0 {
            pty.read(&mut buf)
        } else {
            Ok(0)
        } {
            Ok(n) if n > 0 => {
                bytes_from_host += n as u64;
                adapter.from_host(&buf[..n])
            }
            Ok(_) => {}
            Err(e) if matches!(e.kind(), ErrorKind::TimedOut | ErrorKind::WouldBlock) => {}
            Err(e) if e.kind() == ErrorKind::Interrupted => {}
            Err(e) => return Err(e).context("reading the pseudo-terminal"),
        }
        let arrived = adapter.to_master(now, host_rate, rate);
        if !arrived.is_empty() {
            to_master
                .borrow_mut()
                .deliver(&noise_to_master.pass(&arrived));
        }
        // Master -> host, and the truth every 10 ms.
        // Each run as sent, at the rate the master's USART ran at then.
        for (sent_at, mut out) in to_host.borrow_mut().take_runs(rate) {
            if let Some(fp) = opts.faults.schema {
                out = with_schema(&mut rewrite, &out, fp);
            }
            adapter.from_master(now, &out, host_rate, sent_at);
        }
        let mut out = Vec::new();
        if opts.send_truth && sim.now() >= next_truth {
            next_truth = sim.now() + Duration::from_millis(10);
            let b = plant.borrow().body();
            let msg = MasterToHost::SimTruth {
                t_us: sim.now().as_micros(),
                pose: protocol::Pose::from_si(b.x, b.y, b.theta),
            };
            let mut f = [0u8; serial::MAX_FRAME];
            if let Ok(frame) = serial::encode(&msg, &mut f) {
                out.extend_from_slice(frame);
            }
        }
        adapter.from_board(now, &out);
        let mut out = noise_to_host.pass(&adapter.to_host(now));
        if let Some(line) = &mut misbehaving {
            out = line.pass(&out);
            if line.hung_up() {
                return Ok(()); // the port closes with `pty`
            }
        }
        if !out.is_empty() {
            bytes_to_host += out.len() as u64;
            // Nobody reading: the bytes are lost, as on a UART with nothing attached.
            let _ = pty.write_all(&out);
        }
        if let Some(v) = view.filter(|_| sim.now() >= next_view) {
            next_view = sim.now() + Duration::from_millis(10);
            let t_s = sim.now().as_micros() as f64 * 1e-6;
            let row = super::emulator::log_row(
                t_s,
                &plant.borrow(),
                &slave_shared,
                &master_shared,
                sim.now(),
                None,
            );
            let mut v = v.borrow_mut();
            crate::viewer::topics::emulate_row(&mut v, &row)?;
            v.json(
                "/link",
                t_s,
                &serde_json::json!({
                    "baud": rate,
                    "bytes_from_host": bytes_from_host,
                    "bytes_to_host": bytes_to_host,
                }),
            )?;
        }
        // Caught up with the wall (times the time scale): wait a little. Behind it, on at once.
        if !behind {
            std::thread::sleep(WallDuration::from_micros(500));
        }
    }
    Ok(())
}

/// The master's frames with the hello reply's schema fingerprint replaced (fault knob).
fn with_schema(decoder: &mut FrameDecoder, bytes: &[u8], fp: u32) -> Vec<u8> {
    let mut out = Vec::with_capacity(bytes.len());
    for &b in bytes {
        if let Some(Ok(msg)) = decoder.push::<MasterToHost>(b) {
            let msg = match msg {
                MasterToHost::HelloReply(mut info) => {
                    info.schema_fingerprint = fp;
                    MasterToHost::HelloReply(info)
                }
                m => m,
            };
            let mut f = [0u8; serial::MAX_FRAME];
            if let Ok(frame) = serial::encode(&msg, &mut f) {
                out.extend_from_slice(frame);
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use robot_math::exact::{FixedPose, MAX_ENCODERS};
    use robot_math::odometry::{Method, Odometry, SensorKind};
    use robot_math::wheel::Wheel;

    /// Two body-fixed measuring wheels on an axle 3 cm ahead of the reference point and off
    /// its centre line, 1 µm counts (so quantisation does not hide a sliding axle).
    fn axle_layout() -> Layout {
        Layout::from_geometry(
            &[
                (Wheel::at(0.03, 0.12, 0.0), 1e-6),
                (Wheel::at(0.03, -0.17, 0.0), 1e-6),
            ],
            None,
            None,
        )
        .unwrap()
    }

    #[test]
    fn an_axle_robot_is_driven_round_the_square_without_sliding_sideways() {
        let layout = axle_layout();
        let sensors = MeasuringSensors::from_layout(&layout).unwrap();
        let drive = omni_drive(&MasterConfig::DEFAULT).unwrap();
        let cfg = PlantConfig {
            drive: DriveKinematics::Omni3(drive),
            motor: COURSE_MOTOR,
            motor_metres_per_count: None,
            sensors,
        };
        let mut plant = Plant::new(cfg, Pose2::default(), 0.0, [0.3, 0.8]);
        let mut course = Course {
            corners: [(0.0, 0.5), (0.5, 0.5), (0.5, 0.0), (0.0, 0.0)],
            next: 0,
            speed: 0.3,
            steering: Steering::for_sensors(&sensors),
            drive,
            speed_at_full_duty: COURSE_MOTOR.steady_speed(1.0),
        };
        let mut odo = Odometry::new(
            &layout,
            Method::Exact,
            SensorKind::Counts,
            FixedPose::default(),
            0,
            [0; MAX_ENCODERS],
            None,
        )
        .unwrap();
        let mut corners_passed = 0;
        for ms in 1..=12_000u64 {
            if ms % 10 == 0 {
                let before = course.next;
                let d = course.duty(plant.body());
                plant.set_duty(d);
                corners_passed += usize::from(course.next != before);
            }
            plant.advance(1e-3, 1e-4);
            let c = plant.encoder_counts();
            odo.set_counts(&[c[0], c[1]]);
            odo.update(ms * 1_000_000);
        }
        // Round the square at least once, turning at each corner.
        assert!(corners_passed >= 4, "{corners_passed} corners");
        assert!(plant.path_length() > 2.0, "{}", plant.path_length());
        // Two wheels on an axle see only motion without sideways sliding: had the course slid
        // the axle, odometry would be off by centimetres (a millimetre is the counts' own
        // quantisation over the 2+ m course).
        let (est, truth) = (odo.pose().to_pose2(), plant.body());
        assert!(est.distance_to(truth) < 1e-3, "{est:?} vs {truth:?}");
        assert!(wrap_angle(est.theta - truth.theta).abs() < 1e-3);
    }

    #[test]
    fn robots_the_slave_board_cannot_read_are_refused_with_the_reason() {
        let three = Layout::from_geometry(
            &[
                (Wheel::at(0.1, 0.0, 1.6), 1e-4),
                (Wheel::at(-0.05, 0.09, 3.7), 1e-4),
                (Wheel::at(-0.05, -0.09, 5.8), 1e-4),
            ],
            None,
            None,
        )
        .unwrap();
        let e = MeasuringSensors::from_layout(&three).unwrap_err();
        assert!(
            e.contains("2 quadrature encoders") && e.contains("has 3"),
            "{e}"
        );
        assert!(MeasuringSensors::from_layout(&Layout::SEED_004).is_ok());
        // Seed 004 at its own course speed; coarser counts drive faster.
        assert!((course_speed_for(&Layout::SEED_004) - 0.05).abs() < 1e-12);
        assert!(course_speed_for(&axle_layout()) == 0.01);
    }
}
