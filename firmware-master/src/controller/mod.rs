//! The master's decisions as a sans-IO state machine: messages and frames in, commands and
//! duties out, time passed explicitly. Unit-tested without any executor.

use core::mem::MaybeUninit;

use crate::MasterConfig;
use embassy_time::{Duration, Instant};
use protocol::serial::{
    status, BoardInfo, HostToMaster, LinkCounters, MasterToHost, MovingTarget, RejectReason,
    Telemetry,
};
use protocol::spi::{SlaveCommand, SlaveFrame};

mod goal;
mod slave_link;

use crate::baud::BaudLink;
use crate::drive_setup::DriveSetup;
use crate::relay::Relay;
use goal::Goal;
use protocol::{Pose, PROTOCOL_VERSION};
use robot_math::pid::SpeedPid;
use robot_math::pursuit::{euler_step, field_to_body, pursue, SegmentTarget};
use robot_math::se2::wrap_angle;
use robot_math::tracking::PointTracker;
use robot_math::{Pose2, Twist};

/// Slave commands waiting for the slave, oldest first: room for a whole robot upload (two
/// parts per encoder and the commit) plus a source and a pose.
pub const COMMAND_QUEUE: usize = 2 * protocol::spi::ENCODER_SLOTS + 4;
type CommandQueue = heapless::Deque<SlaveCommand, COMMAND_QUEUE>;

/// What the control step wants done with the motors.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Drive {
    Stop,
    Duty([i16; 3]),
}

pub struct Controller {
    cfg: MasterConfig,
    drive: DriveSetup,
    goal: Option<Goal>,
    /// Seed 002's law and its memory; the tracked point's position at the last control step,
    /// for the velocity it measured since.
    tracker: PointTracker,
    last_point: Option<((f64, f64), Instant)>,
    /// Arrived at a stopped target: the motors are off until the robot is pushed past
    /// [`MasterConfig::hold_release`] or a new target comes.
    holding: bool,
    /// Where the tracked point and the heading last moved to (by a quarter of the arrival
    /// bands) and when: a robot that stands still near a stopped goal for
    /// [`MasterConfig::hold_settle_us`] holds.
    still: Option<((f64, f64, f64), Instant)>,
    /// With seed 004's Euler pursuit: the field velocity taken at the period's start, and when
    /// the period ends.
    euler: Option<((f64, f64), Instant)>,
    status: u16,
    last_host_rx: Option<Instant>,
    /// The serial link's rate, as negotiated with the host.
    baud: BaudLink,
    // Slave link.
    spi_seq: u16,
    /// Sequence number of the command at the front of the queue (or of the last one acked).
    command_seq: u8,
    /// Commands for the slave, oldest first; the front one is sent until acknowledged.
    commands: CommandQueue,
    /// Latest usable slave frame and when (master clock) the slave sampled it.
    slave: Option<(SlaveFrame, Instant)>,
    /// When the previous SPI transaction ended, if it was good: the slave surely saw it, so
    /// it armed the next frame right then. After a failed one the master cannot tell (a frame
    /// lost whole left the slave's armed frame as it was).
    prev_good_exchange_end: Option<Instant>,
    /// Master clock minus slave clock (low 32 bits of microseconds, wrapping), learned at
    /// each exchange whose arming instant is known: it dates a frame's pose on the master's
    /// clock after a lost transaction too.
    slave_clock_offset: Option<u32>,
    last_fresh_slave: Option<Instant>,
    /// The drive motors' encoders: the last counts read and when, and the rim speeds they
    /// showed since the reading before (m/s).
    motor_counts: Option<([u16; 3], Instant)>,
    motor_speeds: Option<[f64; 3]>,
    /// One speed loop per motor, and when they last ran.
    speed_pids: [SpeedPid; 3],
    last_pid_at: Option<Instant>,
    // Outputs.
    cmd_twist: Twist,
    wheel_cmd: [f64; 3],
    duty: [i16; 3],
    counters: LinkCounters,
    /// Play and record streams between the host and the slave.
    relay: Relay,
    /// The newest valid slave frame, whatever commands are pending (for the board info).
    slave_latest: Option<SlaveFrame>,
    /// When a play/record stream last moved, and whether that was under 100 ms ago.
    last_stream_at: Option<Instant>,
    stream_recent: bool,
}

fn secs(t: Instant) -> f64 {
    t.as_micros() as f64 * 1e-6
}

fn us_since(now: Instant, then: Option<Instant>) -> u64 {
    then.map_or(u64::MAX, |t| now.saturating_duration_since(t).as_micros())
}

impl Controller {
    /// `None` when the configured drive is impossible ([`DriveSetup::from_geometry`]).
    pub fn new(cfg: MasterConfig) -> Option<Self> {
        let mut slot = MaybeUninit::uninit();
        Controller::init(&mut slot, cfg)?;
        // SAFETY: `init` returned `Some`: it wrote the whole controller.
        Some(unsafe { slot.assume_init() })
    }

    /// [`new`](Self::new), built in place in `slot` (the board's static cell): the
    /// controller is 3.7 KB, and built on the stack and moved into its cell it was most of
    /// the master's stack. `None` (the slot untouched) for a drive geometry it cannot run.
    pub fn init(slot: &mut MaybeUninit<Controller>, cfg: MasterConfig) -> Option<&mut Controller> {
        let drive = DriveSetup::from_geometry(&cfg.drive)?;
        // Field by field: a struct literal this size is built on the stack and copied
        // (2.4 KB of the master's stack, measured).
        Some(robot_math::init_in_place!(
            slot,
            Controller {
                drive: drive,
                cfg: cfg,
                goal: None,
                tracker: PointTracker::new(drive.gains),
                last_point: None,
                holding: false,
                still: None,
                euler: None,
                status: 0,
                last_host_rx: None,
                baud: BaudLink::new(cfg.baud),
                spi_seq: 0,
                command_seq: 0,
                commands: CommandQueue::new(),
                slave_latest: None,
                last_stream_at: None,
                stream_recent: false,
                slave: None,
                prev_good_exchange_end: None,
                slave_clock_offset: None,
                last_fresh_slave: None,
                motor_counts: None,
                motor_speeds: None,
                speed_pids: [SpeedPid::new(drive.speed_pid); 3],
                last_pid_at: None,
                cmd_twist: Twist::default(),
                wheel_cmd: [0.0; 3],
                duty: [0; 3],
                counters: LinkCounters::default(),
            } in_place {
                relay: Relay::init(),
            }
        ))
    }

    /// A valid host message arrived. Returns an immediate reply, if one is due.
    pub fn on_host_message(&mut self, now: Instant, msg: HostToMaster) -> Option<MasterToHost> {
        self.counters.serial_ok = self.counters.serial_ok.wrapping_add(1);
        self.last_host_rx = Some(now);
        self.baud.on_good_frame(now);
        self.status &= !status::HOST_LOST;
        match msg {
            HostToMaster::Hello { protocol_version } if protocol_version != PROTOCOL_VERSION => {
                Some(self.reject(RejectReason::ProtocolVersion {
                    master: PROTOCOL_VERSION,
                    host: protocol_version,
                }))
            }
            HostToMaster::Hello { .. } => {
                self.relay.reset_host();
                Some(MasterToHost::HelloReply(self.board_info()))
            }
            HostToMaster::Info => Some(MasterToHost::HelloReply(self.board_info())),
            HostToMaster::Slave(c) => self.queue_for_slave(c),
            HostToMaster::Events(f) => {
                self.relay.on_host_events(&f);
                None
            }
            HostToMaster::ReportsAck(a) => {
                self.relay.on_host_ack(a, now.as_micros());
                None
            }
            HostToMaster::SetPose(p) => self.queue_for_slave(SlaveCommand::SetPose(p)),
            HostToMaster::SetOdometry(a) => self.queue_for_slave(SlaveCommand::SetAlgorithm(a)),
            HostToMaster::FollowTarget(t) => match self.validate(now, &t) {
                Some(goal) => {
                    self.set_goal(goal);
                    None
                }
                None => Some(self.reject(RejectReason::InvalidTarget)),
            },
            HostToMaster::Track(sample) => {
                let speed = robot_math::se2::norm(
                    sample.velocity_um_s[0] as f64,
                    sample.velocity_um_s[1] as f64,
                ) * 1e-6;
                if speed > self.drive.kinematics.max_speed() {
                    return Some(self.reject(RejectReason::InvalidTarget));
                }
                if !matches!(self.goal, Some(Goal::Track { .. })) {
                    // A new path: no memory of another motion's commands or positions.
                    self.tracker.reset();
                    self.last_point = None;
                }
                self.set_goal(Goal::Track { sample, at: now });
                None
            }
            HostToMaster::SetDrive(g) => match DriveSetup::from_geometry(&g) {
                Some(drive) => {
                    self.stop_following(0);
                    self.drive = drive;
                    self.tracker = PointTracker::new(drive.gains);
                    self.speed_pids = [SpeedPid::new(drive.speed_pid); 3];
                    None
                }
                None => Some(self.reject(RejectReason::InvalidDrive)),
            },
            HostToMaster::Stop => {
                self.stop_following(0);
                None
            }
            HostToMaster::Heartbeat => None,
            // Answered at the old rate; the host-tx task switches once the answer is out.
            HostToMaster::SetBaud { baud } if BaudLink::accepts(baud) => {
                Some(MasterToHost::BaudSet { baud })
            }
            HostToMaster::SetBaud { .. } => Some(self.reject(RejectReason::InvalidBaud)),
        }
    }

    /// The serial port runs at `baud` from now on (the host-tx task switched it).
    pub fn baud_switched(&mut self, now: Instant, baud: u32) {
        self.baud.switched(now, baud);
    }

    /// The power-on rate, when the port must go back to it ([`BaudLink::fallback_due`]).
    pub fn baud_fallback_due(&self, now: Instant) -> Option<u32> {
        self.baud.fallback_due(now)
    }

    /// A serial frame was dropped (COBS, CRC, decode or overflow).
    pub fn on_host_frame_error(&mut self) {
        self.counters.serial_rejected = self.counters.serial_rejected.wrapping_add(1);
    }

    /// Take a new goal. The same standing goal again (a host that refreshes its target, or
    /// keeps sending a path's last sample) keeps a hold; anything else starts over.
    fn set_goal(&mut self, goal: Goal) {
        if self.status & status::SLAVE_RESET != 0 {
            return; // the slave's pose is not where the robot is (status::SLAVE_RESET)
        }
        let holds = self.drive.kinematics.holds_heading();
        let same = matches!(
            (self.goal.and_then(|g| g.standing_at(holds)), goal.standing_at(holds)),
            (Some(a), Some(b)) if a == b
        );
        self.goal = Some(goal);
        if same {
            return;
        }
        self.holding = false;
        // Standing still counts towards settling only on the goal it stands for.
        self.still = None;
        self.euler = None;
        self.status &= !(status::ARRIVED | status::COMMAND_REJECTED);
        self.status |= status::FOLLOWING;
    }

    fn validate(&self, now: Instant, t: &MovingTarget) -> Option<Goal> {
        let robot_speed = t.robot_speed_um_s as f64 * 1e-6;
        let target_speed = t.target_speed_um_s as f64 * 1e-6;
        let max = self.drive.kinematics.max_speed();
        if !(robot_speed > 0.0 && robot_speed <= max) || target_speed > max {
            return None;
        }
        Some(Goal::Pursue {
            target: SegmentTarget {
                from: t.from.to_metres(),
                to: t.to.to_metres(),
                speed: target_speed,
                t0: secs(now),
            },
            robot_speed,
            heading: t.heading.to_radians(),
        })
    }

    /// Queue a command for the slave; refused (and the motors stopped) if the queue is full,
    /// which only a host flooding commands faster than the slave applies them can cause.
    fn queue_for_slave(&mut self, c: SlaveCommand) -> Option<MasterToHost> {
        if matches!(c, SlaveCommand::SetPose(_) | SlaveCommand::SetSource { .. }) {
            // The host knows where the robot is again (a source starts from the pose it
            // carries: `play` and `record` set one); the pose is used once applied.
            self.status &= !status::SLAVE_RESET;
        }
        let was_empty = self.commands.is_empty();
        if self.commands.push_back(c).is_err() {
            return Some(self.reject(RejectReason::Busy));
        }
        if was_empty {
            self.command_seq = self.command_seq.wrapping_add(1);
        }
        None
    }

    fn reject(&mut self, reason: RejectReason) -> MasterToHost {
        self.stop_following(status::COMMAND_REJECTED);
        MasterToHost::Rejected(reason)
    }

    fn stop_following(&mut self, why: u16) {
        self.goal = None;
        self.holding = false;
        self.still = None;
        self.euler = None;
        self.status &= !(status::FOLLOWING | status::ARRIVED);
        self.status |= why;
    }

    /// The master's pose estimate: the slave's last pose propagated with the commanded motion
    /// since the slave sampled it.
    pub fn estimate(&self, now: Instant) -> Option<Pose2> {
        let (f, at) = self.slave?;
        let (x, y, theta) = f.pose.to_si();
        let dt = now.saturating_duration_since(at).as_micros() as f64 * 1e-6;
        Some(Pose2::new(x, y, theta).integrate(self.cmd_twist, dt))
    }

    /// The drive motors' encoder counts, read just before a control step (free-running 16-bit
    /// counters: only differences matter, and they wrap).
    pub fn on_motor_counts(&mut self, now: Instant, counts: [u16; 3]) {
        let Some(per_count) = self.drive.metres_per_motor_count else {
            return;
        };
        if let Some((before, at)) = self.motor_counts {
            let dt = now.saturating_duration_since(at).as_micros() as f64 * 1e-6;
            self.motor_speeds = (dt > 0.0)
                .then(|| robot_math::sensors::speeds_from_counts(before, counts, per_count, dt));
        }
        self.motor_counts = Some((counts, now));
    }

    /// One control step: watchdogs, pursuit, inverse kinematics, speed loops, duties.
    pub fn control(&mut self, now: Instant) -> Drive {
        let slave_ok = us_since(now, self.last_fresh_slave) <= self.cfg.slave_timeout_us as u64;
        if slave_ok {
            self.status &= !status::SLAVE_LOST;
        } else {
            self.status |= status::SLAVE_LOST;
        }
        if self.goal.is_some() {
            if us_since(now, self.last_host_rx) > self.cfg.host_timeout_us as u64 {
                self.stop_following(status::HOST_LOST);
            } else if !slave_ok {
                self.stop_following(status::SLAVE_LOST);
            }
        }
        // No goal, no estimate: propagating the slave's pose is soft-float sines and cosines,
        // 13 % of the idle board's work when it ran every period regardless.
        let Some(goal) = self.goal else {
            return self.halt();
        };
        let Some(est) = self.estimate(now) else {
            return self.halt();
        };

        let r = goal.reference(now, self.drive.kinematics.holds_heading());
        // Seed 002's A; an omni robot's reference point.
        let point = est.transform_point(self.drive.kinematics.tracked_point());
        let target = r.point.position;
        let off = robot_math::se2::norm(target.0 - point.0, target.1 - point.1);
        let turned = r
            .heading
            .map_or(0.0, |h| libm::fabs(wrap_angle(h - est.theta)));
        let settled = match self.still {
            Some((p, since))
                if robot_math::se2::norm(point.0 - p.0, point.1 - p.1)
                    < self.cfg.arrive_tolerance / 4.0
                    && libm::fabs(wrap_angle(est.theta - p.2))
                        < self.cfg.arrive_heading_tolerance / 4.0 =>
            {
                us_since(now, Some(since)) >= self.cfg.hold_settle_us as u64
            }
            _ => {
                self.still = Some(((point.0, point.1, est.theta), now));
                false
            }
        };
        let arrived = off < self.cfg.arrive_tolerance && turned < self.cfg.arrive_heading_tolerance;
        let stalled =
            settled && off < self.cfg.hold_release && turned < self.cfg.hold_heading_release;
        if r.standing && (arrived || stalled) {
            self.holding = true;
        }
        // Holding still at the goal, without chasing the sensors' last count: the motors stay
        // off until the robot is pushed out of the release band (or the target moves on).
        if self.holding
            && r.standing
            && off < self.cfg.hold_release
            && turned < self.cfg.hold_heading_release
        {
            self.status |= status::ARRIVED;
            // A pursuit period in progress ends here: pushed out, the robot heads anew.
            self.euler = None;
            return self.halt();
        }
        self.holding = false;
        self.status &= !status::ARRIVED;
        let (forward, left, omega) = match goal {
            Goal::Pursue {
                robot_speed,
                heading,
                ..
            } => self.pursuit_command(now, point, est.theta, target, heading, robot_speed),
            Goal::Track { .. } => {
                let measured = self.point_velocity_since_last(now, point, est.theta);
                let (f, l) = self.tracker.command(&r.point, point, est.theta, measured);
                // The heading hold (a chassis that cannot choose its heading ignores it).
                let p = &self.cfg.pursuit;
                let hold = r.heading.map_or(0.0, |h| wrap_angle(h - est.theta));
                let omega = (r.omega + p.heading_gain * hold)
                    .max(-p.max_spin)
                    .min(p.max_spin);
                (f, l, omega)
            }
        };
        let (wheels, twist) = self.drive.kinematics.command(forward, left, omega);
        // The damping term compares with what was sent, after saturation.
        self.tracker
            .sent(self.drive.kinematics.point_velocity(twist));
        self.cmd_twist = twist;
        self.wheel_cmd = wheels;
        let dt = self.last_pid_at.map_or(0.0, |t| {
            now.saturating_duration_since(t).as_micros() as f64 * 1e-6
        });
        self.last_pid_at = Some(now);
        let duty: [f64; 3] = match self.motor_speeds {
            // Closed loop on the motor encoders.
            Some(measured) if self.drive.metres_per_motor_count.is_some() => {
                core::array::from_fn(|i| self.speed_pids[i].update(wheels[i], measured[i], dt))
            }
            // No motor encoders (or no reading yet): the motor constant alone.
            _ => wheels.map(|w| (w * self.drive.speed_pid.ff).clamp(-1.0, 1.0)),
        };
        self.duty = duty.map(|d| libm::round(d * 1000.0) as i16);
        self.status |= status::MOTORS_ON;
        Drive::Duty(self.duty)
    }

    /// The tracked point's robot-frame velocity since the last control step (zero at first).
    fn point_velocity_since_last(
        &mut self,
        now: Instant,
        point: (f64, f64),
        heading: f64,
    ) -> (f64, f64) {
        let last = self.last_point.replace((point, now));
        let Some((p0, t0)) = last else {
            return (0.0, 0.0);
        };
        let dt = now.saturating_duration_since(t0).as_micros() as f64 * 1e-6;
        if dt <= 0.0 {
            return (0.0, 0.0);
        }
        field_to_body((point.0 - p0.0) / dt, (point.1 - p0.1) / dt, heading)
    }

    /// Seed 004's pursuit, as a robot-frame velocity of the tracked point and a spin.
    fn pursuit_command(
        &mut self,
        now: Instant,
        point: (f64, f64),
        theta: f64,
        target: (f64, f64),
        heading: f64,
        robot_speed: f64,
    ) -> (f64, f64, f64) {
        let (mut vx, mut vy, omega) = pursue(
            point,
            theta,
            target,
            heading,
            robot_speed,
            &self.cfg.pursuit,
        );
        let period = self.cfg.pursuit.period_s;
        if period > 0.0 {
            // Seed 004: the direction is taken once per period and held, at full speed.
            (vx, vy) = match self.euler {
                Some((v, until)) if now < until => v,
                _ => {
                    let v = euler_step(point, target, robot_speed);
                    // Periods beyond an hour are a configuration error; saturate, never panic.
                    let hold = Duration::from_micros((period.min(3600.0) * 1e6) as u64);
                    let until = now.checked_add(hold).unwrap_or(Instant::MAX);
                    self.euler = Some((v, until));
                    v
                }
            };
        }
        let (f, l) = field_to_body(vx, vy, theta);
        (f, l, omega)
    }

    fn halt(&mut self) -> Drive {
        self.last_point = None;
        // Motors off: nothing for the speed loops to carry into the next start.
        self.speed_pids.iter_mut().for_each(SpeedPid::reset);
        self.last_pid_at = None;
        self.tracker.reset();
        self.cmd_twist = Twist::default();
        self.wheel_cmd = [0.0; 3];
        self.duty = [0; 3];
        self.status &= !status::MOTORS_ON;
        Drive::Stop
    }

    pub fn telemetry(&self, now: Instant) -> Telemetry {
        let (slave_pose, slave_time_us) = self
            .slave
            .map_or((Pose::default(), 0), |(f, _)| (f.pose, f.time_us));
        let master_pose = self
            .estimate(now)
            .map_or(Pose::default(), |p| Pose::from_si(p.x, p.y, p.theta));
        let slave_fault = self
            .slave
            .is_some_and(|(f, _)| f.status & !protocol::spi::slave_status::RUNNING != 0);
        Telemetry {
            time_us: now.as_micros(),
            slave_time_us,
            slave_pose,
            master_pose,
            wheel_cmd_um_s: self.wheel_cmd.map(protocol::metres_to_um),
            duty_permille: self.duty,
            status: self.status | if slave_fault { status::SLAVE_FAULT } else { 0 },
            counters: self.counters,
            slave_algorithm: self.slave.map_or(Default::default(), |(f, _)| f.algorithm),
        }
    }

    /// The next play/record frame for the host, if one is due.
    pub fn poll_host_stream(&mut self, now: Instant) -> Option<MasterToHost> {
        self.relay.poll_host(now.as_micros())
    }

    /// Whether play/record streams are moving (poll the slave faster).
    /// True while a stream moved in the last 100 ms (momentary pauses in a recording included).
    /// Not after a slave reset, which ends the streams: the line is the telemetry's again, and
    /// tells the host.
    pub fn streaming(&self) -> bool {
        (self.relay.busy() || self.stream_recent) && self.status & status::SLAVE_RESET == 0
    }

    /// What the hello reply says.
    pub fn board_info(&self) -> BoardInfo {
        let slave = self.slave_latest;
        BoardInfo {
            protocol_version: PROTOCOL_VERSION,
            schema_fingerprint: protocol::SCHEMA_FINGERPRINT,
            firmware_version: crate::FIRMWARE_VERSION,
            master_uid: self.cfg.uid,
            // A frame armed before the slave's first update carries no settings yet.
            slave_seen: slave.is_some_and(|f| f.status & protocol::spi::slave_status::RUNNING != 0),
            robot: slave.map_or(0, |f| f.robot),
            source: slave.map_or(Default::default(), |f| f.source),
            period_us: slave.map_or(0, |f| f.period_us),
            algorithm: slave.map_or(Default::default(), |f| f.algorithm),
            baud: self.baud.current(),
        }
    }

    /// The newest valid frame from the slave: what the master knows of its pose.
    pub fn slave_latest(&self) -> Option<SlaveFrame> {
        self.slave_latest
    }

    pub fn status(&self) -> u16 {
        self.status
    }

    pub fn counters(&self) -> LinkCounters {
        self.counters
    }
}

#[cfg(test)]
mod link_tests;
#[cfg(test)]
mod tests;
