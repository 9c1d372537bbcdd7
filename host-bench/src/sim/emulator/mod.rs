//! `host-bench emulate`: both boards' portable firmware in one process, on virtual time,
//! against the simulated robot, with the host speaking the real serial protocol.
//!
//! ```text
//!  host task ── UartLine x2 (115200 8N1) ──► firmware_master::tasks ── SpiWire ──► firmware_slave::run
//!                                              │ EmuMotors                        ▲ EmuCounters, EmuAbsEncoder
//!                                              ▼                                  │
//!                                            Plant (omni drive + measuring carriage = ground truth)
//! ```
//! The loop steps the plant on a fixed grid ([`physics_grid`]) and lets the firmware run up
//! to each step's end; every sensor read falls on a step's end, so it sees the plant exactly
//! at the time it happens.

mod fault_check;
pub mod host;
pub mod hw;
mod options;
pub mod reference;
mod scenario;
mod summary;

pub use fault_check::{fault_check, FaultCheck};
pub use options::{
    check_options, Faults, Options, MAX_DURATION_S, RESET_SEEN_AFTER_S, RESET_SEEN_WITHIN_S,
};
pub use scenario::{Motion, RobotModel, Scenario, POWER_ON_ROBOT};
pub use summary::{nothing_scored, LogRow, SlaveResetSeen, Summary};

use std::cell::RefCell;
use std::rc::Rc;
use std::time::Instant as WallInstant;

use anyhow::{bail, Context as _, Result};
use embassy_time::{Duration, Instant};
use firmware_master::drive_setup::DriveSetup;
use firmware_master::MasterShared;
use firmware_slave::{SlaveConfig, SlaveShared};
use rand::{Rng, SeedableRng};
use robot_math::se2::wrap_angle;
use robot_math::Pose2;
use virtual_time::Simulation;

use crate::sim::generate::EdgeMap;
use crate::sim::master_tasks::{spawn_master, MasterPorts};
use crate::sim::plant::{MeasuringSensors, Plant, PlantConfig};
use crate::sim::serial_noise::{Receiver, SerialFaults, SerialNoise};
use hw::*;

pub struct Run {
    pub summary: Summary,
    pub log: Vec<LogRow>,
}

/// Emulate `scenario` to the end; the log rows are kept in [`Run::log`] if
/// [`Options::keep_log`].
pub fn run(scenario: &Scenario, opts: &Options) -> Result<Run> {
    let mut log = Vec::new();
    let summary = if opts.keep_log {
        run_logged(
            scenario,
            opts,
            Some(&mut |row| {
                log.push(row);
                Ok(())
            }),
        )?
    } else {
        run_logged(scenario, opts, None)?
    };
    Ok(Run { summary, log })
}

/// Emulate `scenario` to the end, handing each log row (every [`Options::log_period`]) to
/// `log` as it is made: a sink that writes them out keeps memory flat however long the run.
pub fn run_logged(
    scenario: &Scenario,
    opts: &Options,
    mut log: Option<&mut dyn FnMut(LogRow) -> Result<()>>,
) -> Result<Summary> {
    check_options(opts)?;
    let wall = WallInstant::now();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(opts.seed);
    // The simulated robot: as the boards are told, or as it really is.
    let truly = scenario.true_robot.as_ref();
    let sensors = MeasuringSensors::from_layout(truly.map_or(&opts.robot_layout, |t| &t.layout))
        .map_err(|e| anyhow::anyhow!("the robot's encoders cannot be emulated: {e}"))?;
    // One slave image serves every robot: the host uploads this run's, unless the slave
    // powered on with it.
    let fingerprint = firmware_slave::robot_wire::layout_fingerprint;
    let upload = (fingerprint(&opts.robot_layout) != fingerprint(opts.slave.layout()))
        .then_some(opts.robot_layout);
    let drive = DriveSetup::from_geometry(truly.map_or(&scenario.drive, |t| &t.drive))
        .context("the scenario's drive geometry is impossible")?;
    let plant_cfg = PlantConfig {
        drive: drive.kinematics,
        motor: truly.map_or(scenario.motor, |t| t.motor),
        motor_metres_per_count: drive.metres_per_motor_count,
        sensors,
    };
    let (x, y, th) = scenario.start;
    let encoder_phase = opts
        .encoder_phase
        .unwrap_or_else(|| [rng.random::<f64>(), rng.random::<f64>()]);
    if !encoder_phase.iter().all(|p| (0.0..1.0).contains(p)) {
        bail!("encoder phases are fractions of a count, in [0, 1): got {encoder_phase:?}");
    }
    // The host's clock is not the master's: a path starts anywhere within the master's control
    // period, and where a velocity step falls inside it moves a corner's peak error by
    // millimetres. Drawn after the phases, so a seed keeps them.
    let control_period_s = opts.master.control_period_us as f64 * 1e-6;
    let path_start_delay_s = rng.random::<f64>() * control_period_s;
    let per_count = plant_cfg.sensors.metres_per_count();
    let mut plant = Plant::new(
        plant_cfg,
        Pose2::new(x, y, th),
        scenario.start_swivel,
        encoder_phase,
    );
    if !opts.edges.is_ideal() {
        plant = plant.with_edges(core::array::from_fn(|j| {
            EdgeMap::draw(&opts.edges, opts.seed, j, per_count[j])
        }));
    }
    let counts_at_start = plant.encoder_counts();
    let plant: SharedPlant = Rc::new(RefCell::new(plant));

    let slave_shared = SlaveShared::new();
    let master_shared = MasterShared::new();

    let wire = Rc::new(RefCell::new(SpiWire::new(opts.faults.spi, opts.seed)));
    let to_master: SharedLine = Rc::default();
    let to_host: SharedLine = Rc::default();
    let host_log = Rc::new(RefCell::new(host::HostLog::default()));
    let byte_time = byte_time(opts.baud);
    // The emulated host never asks for another rate: one rate for both ends.
    let rate: SharedRate = Rc::new(core::cell::Cell::new(opts.baud));

    // Serial noise each way, from streams of their own (a clean run draws nothing).
    let noisy = opts.faults.serial != SerialFaults::default();
    let noise = |salt: u64, to: Receiver| {
        noisy.then(|| {
            Rc::new(RefCell::new(SerialNoise::new(
                opts.faults.serial,
                opts.seed ^ salt,
                to,
            )))
        })
    };
    let (noise_to_master, noise_to_host) = (
        noise(0x5e1a, Receiver::Master),
        noise(0x5e1b, Receiver::Host),
    );
    let slave_off = opts.faults.slave_off_at.map(secs_to_instant);
    let slave_reset = opts.faults.slave_reset_at.map(secs_to_instant);
    let mut sim = Simulation::new()?;
    sim.spawn(slave_board(
        &plant,
        &wire,
        &slave_shared,
        &opts.slave,
        slave_reset,
        slave_off,
    ));
    spawn_master(
        &mut sim,
        MasterPorts {
            bus: EmuMasterBus {
                wire: wire.clone(),
                transfer_time: spi_transfer_time(opts.spi_clock_hz),
            },
            serial_rx: UartRx(to_master.clone()),
            serial_tx: UartTx {
                line: to_host.clone(),
                rate: rate.clone(),
                noise: noise_to_host.clone(),
            },
            motors: EmuMotors {
                plant: plant.clone(),
                source: opts.duties.clone(),
                steps: 0,
            },
            encoders: EmuMotorEncoders(plant.clone()),
            shared: &master_shared,
            config: &opts.master,
        },
    );
    sim.spawn(until(
        opts.faults.host_silent_after.map(secs_to_instant),
        host::session(
            UartRx(to_host.clone()),
            UartTx {
                line: to_master.clone(),
                rate: rate.clone(),
                noise: noise_to_master.clone(),
            },
            byte_time,
            host::Plan {
                scenario: scenario.clone(),
                path_start_delay_s,
                upload,
                algorithm: opts.algorithm,
                confirm: noisy,
            },
            host_log.clone(),
        ),
    ));

    let end = Instant::from_micros((opts.duration * 1e6).round() as u64);
    let log_every = Duration::from_micros(((opts.log_period * 1e6).round() as u64).max(1));
    let mut next_log = Instant::from_ticks(0);
    let mut last_seq = None;
    let (mut max_error, mut slave_updates) = (0.0f64, 0u64);
    // The motors' switch-ons and driven time when the master first said it arrived.
    let mut at_arrival: Option<(u64, f64)> = None;
    let reference = reference::ReferencePath::new(&scenario.motion)?;
    let motion_s = reference.duration();
    let tracking = matches!(scenario.motion, Motion::Track { .. });
    let tracked = drive.kinematics.tracked_point();
    let grid = physics_grid(opts, tracking);
    // Tracking error of the true tracked point against the reference at every physics step
    // (≤ 0.1 ms: a corner's peak lasts a few ms and a 10 ms sampling misses most of it), from
    // a second after the path started: (∫e² dt, steps, max, seconds scored).
    let mut tracking_error = (0.0f64, 0u64, 0.0f64, 0.0f64);
    // The slave counts the master frames it rejected in a wrapping u16 (its frame's field):
    // added up here as they go, so a long noisy run does not wrap.
    let mut slave_rejects = (0u16, 0u64);
    let mut reset_told = None;
    let mut reset_seen = opts.faults.slave_reset_at.map(|at_s| SlaveResetSeen {
        at_s,
        ..SlaveResetSeen::default()
    });
    // The instant the slave resets, as the board task has it: compared as instants, since
    // `1_100_000 µs · 1e-6 < 1.1` (a float comparison scored the reset pose for many times).
    let reset_at = slave_reset;

    sim.run_until_idle();
    loop {
        let now = sim.now();
        if now >= end {
            break;
        }
        // The physics steps on a fixed grid, never split at a firmware event: how the SPI
        // traffic falls must not change the robot's motion by a rounding (a lost frame once
        // moved an encoder edge across a microsecond). Every firmware access to the plant (the
        // slave's updates, the control steps) is on the grid; other events in a step (SPI,
        // UART) see the plant at the step's end, which they do not read.
        let step = grid.as_ticks();
        let next = Instant::from_ticks((now.as_ticks() / step + 1) * step).min(end);
        let dt = (next - now).as_micros() as f64 * 1e-6;
        plant
            .borrow_mut()
            .advance_us(now.as_micros(), next.as_micros(), dt);
        sim.run_until(next);

        // Score the slave at every update, at the very instant it sampled its sensors, once
        // the motion has started (the host's set-pose has been applied by then).
        let frame = slave_shared.frame();
        // A reset starts the slave's count again from 0: what it counts since is new.
        let restarted = reset_at.is_some_and(|r| next >= r) && frame.rx_rejected < slave_rejects.0;
        slave_rejects.1 += if restarted {
            frame.rx_rejected as u64
        } else {
            frame.rx_rejected.wrapping_sub(slave_rejects.0) as u64
        };
        slave_rejects.0 = frame.rx_rejected;
        if last_seq != Some(frame.seq) {
            last_seq = Some(frame.seq);
            slave_updates += 1;
            let reset = reset_at.is_some_and(|r| next >= r);
            if host_log.borrow().follow_sent_at.is_some() && !reset {
                let err = slave_shared.pose().distance_to(plant.borrow().body());
                max_error = max_error.max(err);
            }
        }
        if tracking {
            let t0 = host_log.borrow().follow_sent_at;
            let t_s = next.as_micros() as f64 * 1e-6;
            if let Some(t0) = t0.filter(|t0| t_s - t0 >= TRACKING_SCORED_AFTER_S) {
                let r = reference.at(t_s - t0).position;
                let p = plant.borrow().body().transform_point(tracked);
                let e = (p.0 - r.0).hypot(p.1 - r.1);
                let dt = (next - now).as_micros() as f64 * 1e-6;
                tracking_error.0 += e * e * dt;
                tracking_error.1 += 1;
                tracking_error.2 = tracking_error.2.max(e);
                tracking_error.3 += dt;
            }
        }
        // Arrival at the end: a path may stop (and the master hold) on its way.
        let motion_over = || {
            host_log
                .borrow()
                .follow_sent_at
                .is_some_and(|t0| next.as_micros() as f64 * 1e-6 - t0 >= motion_s)
        };
        if at_arrival.is_none()
            && motion_over()
            && master_shared.with(|c| c.status()).unwrap_or(0) & protocol::serial::status::ARRIVED
                != 0
        {
            let p = plant.borrow();
            at_arrival = Some((p.motor_switch_ons(), p.motor_driven_s()));
        }
        if reset_told.is_none()
            && master_shared.with(|c| c.status()).unwrap_or(0)
                & protocol::serial::status::SLAVE_RESET
                != 0
        {
            reset_told = Some(next.as_micros() as f64 * 1e-6);
        }
        if let Some(r) = reset_seen
            .as_mut()
            .filter(|_| reset_at.is_some_and(|r| next >= r))
        {
            let t_s = next.as_micros() as f64 * 1e-6;
            if plant.borrow().duty() == [0; 3] {
                r.motors_stopped_s.get_or_insert(t_s);
            }
        }
        if let Some(sink) = log.as_mut().filter(|_| next >= next_log) {
            next_log = next + log_every;
            let t_s = next.as_micros() as f64 / 1e6;
            let goal_t0 = host_log.borrow().follow_sent_at;
            let wanted = goal_t0.map(|t0| reference.at(t_s - t0).position);
            sink(log_row(
                t_s,
                &plant.borrow(),
                &slave_shared,
                &master_shared,
                next,
                wanted,
            ))?;
        }
    }

    let plant = plant.borrow();
    let truth = plant.body();
    let slave = slave_shared.pose();
    let counters = master_shared.with(|c| c.counters()).unwrap_or_default();
    let master_view = master_shared.with(|c| c.slave_latest()).flatten();
    let h = host_log.borrow();
    let slave_rx_rejected = slave_rejects.1;
    let end_point = truth.transform_point(tracked);
    let goal = reference.at(motion_s).position;
    let distance_to_goal = (end_point.0 - goal.0).hypot(end_point.1 - goal.1);
    let status = master_shared.with(|c| c.status()).unwrap_or(0);
    // What each way's noise injected and the copy of its receiver's decoder refused (none on
    // a quiet line).
    let noise_counts = |n: &Option<Rc<RefCell<SerialNoise>>>| {
        n.as_ref()
            .map(|n| (n.borrow().injected, n.borrow().rejected))
            .unwrap_or_default()
    };
    let (to_master_noise, to_host_noise) =
        (noise_counts(&noise_to_master), noise_counts(&noise_to_host));
    let slave_frame = slave_shared.frame();
    if slave_frame.status & protocol::spi::slave_status::ALGORITHM_UNSUPPORTED != 0 {
        bail!(
            "the slave cannot run {:?} reading hardware counters only (it needs every tick's time \
             stamp: --sensor timestamps); it kept running {:?}",
            opts.algorithm,
            slave_frame.algorithm
        );
    }
    let wall_seconds = wall.elapsed().as_secs_f64();
    let summary = Summary {
        scenario: scenario.name.clone(),
        robot: scenario.robot.clone(),
        robot_fingerprint: fingerprint(&opts.robot_layout),
        true_robot: scenario.true_robot.as_ref().map(|t| t.name.clone()),
        algorithm: format!("{:?}", slave_frame.algorithm).to_lowercase(),
        seed: opts.seed,
        encoder_phase,
        encoder_edges: opts.edges.to_string(),
        sim_seconds: sim.now().as_micros() as f64 / 1e6,
        wall_seconds,
        speed_x: sim.now().as_micros() as f64 / 1e6 / wall_seconds.max(1e-9),
        path_length_m: plant.path_length(),
        final_error_m: slave.distance_to(truth),
        max_error_m: max_error,
        final_heading_error_rad: wrap_angle(slave.theta - truth.theta),
        final_estimate_m: (slave.x, slave.y),
        final_estimate_heading_rad: slave.theta,
        final_position_m: (truth.x, truth.y),
        final_heading_rad: truth.theta,
        start_pose: scenario.start,
        measuring_counts: {
            let end = plant.encoder_counts();
            [end[0] - counts_at_start[0], end[1] - counts_at_start[1]]
        },
        distance_to_goal_m: distance_to_goal,
        tracking_rms_m: (tracking_error.3 > 0.0)
            .then(|| (tracking_error.0 / tracking_error.3).sqrt()),
        tracking_max_m: (tracking_error.1 > 0).then_some(tracking_error.2),
        tracking_samples: tracking_error.1,
        tracking_seconds: tracking_error.3,
        arrived: status & protocol::serial::status::ARRIVED != 0,
        motor_switch_ons: plant.motor_switch_ons(),
        motor_switch_ons_after_arrival: at_arrival.map(|(on, _)| plant.motor_switch_ons() - on),
        motor_driven_s_after_arrival: at_arrival.map(|(_, s)| plant.motor_driven_s() - s),
        spi_frames: wire.borrow().transactions,
        spi_frames_rejected: counters.spi_rejected as u64 + slave_rx_rejected,
        spi_rejected_by_master: counters.spi_rejected as u64,
        spi_rejected_by_slave: slave_rx_rejected,
        spi_injected: wire.borrow().injected,
        spi_rejected_kinds_master: wire.borrow().rejected_by_master,
        spi_rejected_kinds_slave: wire.borrow().rejected_by_slave,
        serial_injected_to_master: to_master_noise.0,
        serial_injected_to_host: to_host_noise.0,
        serial_rejected_kinds_master: to_master_noise.1,
        serial_rejected_kinds_host: to_host_noise.1,
        master_view_of_slave_m: master_view.map(|f| {
            let (x, y) = protocol::Point {
                x_um: f.pose.x_um,
                y_um: f.pose.y_um,
            }
            .to_metres();
            (x, y)
        }),
        // Only meaningful with the robot standing: while it moves the slave's pose changes
        // between one poll and the next.
        master_view_matches_slave: (status & protocol::serial::status::ARRIVED != 0)
            .then(|| master_view.is_some_and(|f| f.pose == slave_shared.frame().pose)),
        serial_frames: counters.serial_ok as u64 + h.frames_received,
        serial_frames_rejected: counters.serial_rejected as u64 + h.frames_rejected,
        protocol_version: protocol::PROTOCOL_VERSION,
        schema_fingerprint_match: h.fingerprint_match == Some(true),
        robot_uploaded: h.robot_uploaded,
        serial_drive_sends: (h.drive_sends > 0).then_some(h.drive_sends),
        slave_updates,
        firmware_polls: sim.polls(),
        slave_reset_told_s: reset_told,
        slave_reset: reset_seen.map(|r| SlaveResetSeen {
            host_told_s: h.slave_reset_told_at,
            ..r
        }),
        fault_check: None,
    };
    if let Some(problem) = &h.problem {
        bail!("the emulated master refused the session: {problem}");
    }
    if let Some(t) = opts
        .faults
        .host_silent_after
        .filter(|_| h.fingerprint_match.is_none())
    {
        bail!(
            "the host fell silent at {t} s (--fault-host-silent-after) before the master \
             answered its hello: nothing was run to score"
        );
    }
    if h.fingerprint_match.is_none() {
        bail!(
            "the run ended after {:?} s, before the master answered the host's hello: nothing \
             was run to score (--duration of 0.1 s at least)",
            opts.duration
        );
    }
    Ok(summary)
}

/// The tracking error is scored from this long after the path starts (the robot may start
/// off it), seconds.
pub const TRACKING_SCORED_AFTER_S: f64 = 1.0;

/// How long a reset slave takes to run again: the F103's reset, its clock start-up (the
/// crystal and PLL) and embassy's init, about 5 ms.
pub const SLAVE_BOOT_S: f64 = 0.005;

fn secs_to_instant(s: f64) -> Instant {
    Instant::from_micros((s.max(0.0) * 1e6).round() as u64)
}

/// Run `f` until it ends or the virtual time `at` comes, whichever is first.
/// The physics step: the longest, up to `plant_step`, that every firmware read of the plant
/// falls on the end of (the slave's updates, the master's control steps, both timed from
/// power-on). The physics never steps at other instants, so how SPI and serial traffic falls
/// cannot change the robot's motion by a rounding. Tracked paths are scored at every step and
/// a corner's peak lasts a few milliseconds, so they step at most 0.1 ms.
///
/// At 1 ms the default run takes a third of the time it took at 0.1 ms, its final error
/// moving by 5 nm: the motors' response inside a step is exact, and RK4's error on the
/// carriage's 0.1 s swing is of order (1 ms / 0.1 s)^5.
pub fn physics_grid(opts: &Options, tracking: bool) -> Duration {
    fn gcd(a: u64, b: u64) -> u64 {
        if b == 0 {
            a
        } else {
            gcd(b, a % b)
        }
    }
    let mut longest = ((opts.plant_step * 1e6).round() as u64).max(1);
    if tracking {
        longest = longest.min(100);
    }
    let slave = opts.slave.update_period_us.max(1) as u64;
    let control = opts.master.control_period_us.max(1) as u64;
    Duration::from_micros(gcd(gcd(longest, slave), control))
}

/// The slave board: its firmware on the emulated parts, reset at `reset` (running again
/// [`SLAVE_BOOT_S`] later) and losing power at `off`, if they come.
pub(crate) async fn slave_board(
    plant: &SharedPlant,
    wire: &Rc<RefCell<SpiWire>>,
    shared: &SlaveShared,
    config: &SlaveConfig,
    reset: Option<Instant>,
    off: Option<Instant>,
) {
    let slave = || {
        firmware_slave::run(
            EmuCounters(plant.clone()),
            EmuEdges::new(plant.clone()),
            EmuAbsEncoder(plant.clone()),
            EmuSlaveSpi(wire.clone()),
            firmware_slave::ports::NoCycles,
            shared,
            config,
        )
    };
    // A reset before any power loss: the CPU stops, RAM and the shift register are gone, and
    // after its boot time the firmware starts again from power-on.
    if let Some(reset) = reset.filter(|r| off.is_none_or(|off| *r < off)) {
        until(Some(reset), slave()).await;
        wire.borrow_mut().power_off();
        shared.restart();
        embassy_time::Timer::at(reset + Duration::from_micros((SLAVE_BOOT_S * 1e6) as u64)).await;
        wire.borrow_mut().power_on();
    }
    // Power loss: the firmware future is dropped mid-flight, like a CPU that stops.
    until(off, slave()).await;
    wire.borrow_mut().power_off();
}

async fn until(at: Option<Instant>, f: impl std::future::Future) {
    match at {
        Some(at) => {
            embassy_futures::select::select(f, embassy_time::Timer::at(at)).await;
        }
        None => {
            f.await;
        }
    }
}

pub(crate) fn log_row(
    t_s: f64,
    plant: &Plant,
    slave: &SlaveShared,
    master: &MasterShared,
    now: Instant,
    target: Option<(f64, f64)>,
) -> LogRow {
    let truth = plant.body();
    let s = slave.pose();
    let (est, tel) = master
        .with(|c| (c.estimate(now), c.telemetry(now)))
        .unwrap_or((None, Default::default()));
    let w = tel.wheel_cmd_um_s.map(|v| v as f64 / 1e6);
    LogRow {
        t_s,
        true_x_m: truth.x,
        true_y_m: truth.y,
        true_theta_rad: wrap_angle(truth.theta),
        slave_x_m: s.x,
        slave_y_m: s.y,
        slave_theta_rad: wrap_angle(s.theta),
        master_x_m: est.map(|p| p.x),
        master_y_m: est.map(|p| p.y),
        master_theta_rad: est.map(|p| wrap_angle(p.theta)),
        target_x_m: target.map(|p| p.0),
        target_y_m: target.map(|p| p.1),
        wheel_cmd_1_m_s: w[0],
        wheel_cmd_2_m_s: w[1],
        wheel_cmd_3_m_s: w[2],
        duty_1_permille: tel.duty_permille[0],
        duty_2_permille: tel.duty_permille[1],
        duty_3_permille: tel.duty_permille[2],
        status: tel.status,
        encoder_counts: plant.encoder_counts(),
        link: master.with(|c| c.counters()).unwrap_or_default(),
    }
}
