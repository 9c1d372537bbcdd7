//! The master's decisions as a sans-IO state machine: messages and frames in, commands and
//! duties out, time passed explicitly. Unit-tested without any executor.

use crate::MasterConfig;
use embassy_time::Instant;
use protocol::serial::{
    status, BoardInfo, HostToMaster, LinkCounters, MasterToHost, MovingTarget, RejectReason,
    Telemetry,
};
use protocol::spi::{MasterFrame, SlaveCommand, SlaveFrame, SpiFrameError};

use crate::relay::Relay;
use protocol::{Pose, PROTOCOL_VERSION};
use robot_math::omni3::Omni3;
use robot_math::pursuit::{field_to_body, pursue, SegmentTarget};
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

#[derive(Clone, Copy, Debug)]
struct Goal {
    target: SegmentTarget,
    robot_speed: f64,
    heading: f64,
}

pub struct Controller {
    cfg: MasterConfig,
    omni: Omni3,
    goal: Option<Goal>,
    status: u16,
    last_host_rx: Option<Instant>,
    // Slave link.
    spi_seq: u16,
    /// Sequence number of the command at the front of the queue (or of the last one acked).
    command_seq: u8,
    /// Commands for the slave, oldest first; the front one is sent until acknowledged.
    commands: CommandQueue,
    /// Latest usable slave frame and when (master clock) the slave sampled it.
    slave: Option<(SlaveFrame, Instant)>,
    /// When the previous SPI transaction ended: the slave armed the next frame right then.
    prev_exchange_end: Option<Instant>,
    last_fresh_slave: Option<Instant>,
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
    /// `None` when the configured geometry is impossible (d or v_max not positive).
    pub fn new(cfg: MasterConfig) -> Option<Self> {
        Some(Controller {
            omni: Omni3::new(cfg.wheel_distance, cfg.v_max)?,
            cfg,
            goal: None,
            status: 0,
            last_host_rx: None,
            spi_seq: 0,
            command_seq: 0,
            commands: CommandQueue::new(),
            relay: Relay::new(),
            slave_latest: None,
            last_stream_at: None,
            stream_recent: false,
            slave: None,
            prev_exchange_end: None,
            last_fresh_slave: None,
            cmd_twist: Twist::default(),
            wheel_cmd: [0.0; 3],
            duty: [0; 3],
            counters: LinkCounters::default(),
        })
    }

    /// A valid host message arrived. Returns an immediate reply, if one is due.
    pub fn on_host_message(&mut self, now: Instant, msg: HostToMaster) -> Option<MasterToHost> {
        self.counters.serial_ok = self.counters.serial_ok.wrapping_add(1);
        self.last_host_rx = Some(now);
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
                    self.goal = Some(goal);
                    self.status &= !(status::ARRIVED | status::COMMAND_REJECTED);
                    self.status |= status::FOLLOWING;
                    None
                }
                None => Some(self.reject(RejectReason::InvalidTarget)),
            },
            HostToMaster::Stop => {
                self.stop_following(0);
                None
            }
            HostToMaster::Heartbeat => None,
        }
    }

    /// A serial frame was dropped (COBS, CRC, decode or overflow).
    pub fn on_host_frame_error(&mut self) {
        self.counters.serial_rejected = self.counters.serial_rejected.wrapping_add(1);
    }

    fn validate(&self, now: Instant, t: &MovingTarget) -> Option<Goal> {
        let robot_speed = t.robot_speed_um_s as f64 * 1e-6;
        let target_speed = t.target_speed_um_s as f64 * 1e-6;
        if !(robot_speed > 0.0 && robot_speed <= self.cfg.max_robot_speed()) {
            return None;
        }
        if target_speed > self.cfg.max_robot_speed() {
            return None;
        }
        Some(Goal {
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
        self.status &= !(status::FOLLOWING | status::ARRIVED);
        self.status |= why;
    }

    /// The frame to send on the next SPI poll. A command is repeated until acknowledged.
    pub fn next_slave_frame(&mut self) -> MasterFrame {
        self.spi_seq = self.spi_seq.wrapping_add(1);
        MasterFrame {
            seq: self.spi_seq,
            command_seq: self.command_seq,
            command: self.commands.front().cloned().unwrap_or(SlaveCommand::None),
            events: self.relay.events_chunk(self.commands.is_empty()),
            reports_next: self.relay.reports_next(),
        }
    }

    /// The outcome of an SPI poll.
    pub fn on_slave_frame(&mut self, now: Instant, frame: Result<SlaveFrame, SpiFrameError>) {
        let armed_at = self.prev_exchange_end.replace(now);
        let Ok(f) = frame else {
            self.counters.spi_rejected = self.counters.spi_rejected.wrapping_add(1);
            return;
        };
        self.counters.spi_ok = self.counters.spi_ok.wrapping_add(1);
        self.slave_latest = Some(f);
        self.counters.slave_rx_rejected = f.rx_rejected as u32;
        if f.command_ack == self.command_seq {
            if let Some(done) = self.commands.pop_front() {
                if matches!(done, SlaveCommand::SetSource { .. }) {
                    // The slave restarted both SPI streams when it applied this.
                    self.relay.reset_slave();
                }
                if !self.commands.is_empty() {
                    // The next queued command goes out under a new number.
                    self.command_seq = self.command_seq.wrapping_add(1);
                }
            }
        }
        // A recording's reports come and go; stay in streaming mode across short pauses.
        if !f.reports.bytes.is_empty() || self.relay.busy() {
            self.last_stream_at = Some(now);
        }
        self.stream_recent = us_since(now, self.last_stream_at) < 100_000;
        self.relay.on_slave_frame(&f);
        // A frame whose seq did not move means the slave's odometry loop is stuck: the SPI
        // peripheral still answers, but with stale data. Only moving frames count as alive.
        let fresh = self.slave.is_none_or(|(prev, _)| prev.seq != f.seq);
        if fresh {
            self.last_fresh_slave = Some(now);
        }
        // Until the slave has applied every queued command (a set-pose among them), its poses
        // may be from before them.
        if self.commands.is_empty() {
            let sampled = Self::sample_time(armed_at, now, &f);
            self.slave = Some((f, sampled));
        }
    }

    /// When, on the master's clock, the slave sampled the pose in frame `f` that arrived at
    /// `now`.
    ///
    /// A frame can be up to a poll period plus an odometry period old, over a millimetre at
    /// 0.6 m/s. The clocks are not synchronised, but the slave arms each frame right after the
    /// previous transaction ends (an instant the master knows on its own clock) and stamps
    /// both that moment and the pose's sampling time on its clock; their difference is the
    /// pose's age at arming. Ages that make no sense (first frame, a slave reboot, a missed
    /// transaction) fall back to the arrival time.
    fn sample_time(armed_at: Option<Instant>, now: Instant, f: &SlaveFrame) -> Instant {
        const MAX_AGE_US: u64 = 20_000;
        let Some(armed_at) = armed_at else {
            return now;
        };
        let age_at_arming = f.armed_us.wrapping_sub(f.time_us) as i32;
        if age_at_arming < 0 {
            return now;
        }
        let sampled = armed_at.as_micros().saturating_sub(age_at_arming as u64);
        if now.as_micros().saturating_sub(sampled) > MAX_AGE_US {
            return now;
        }
        Instant::from_micros(sampled)
    }

    /// A bus error on the SPI side.
    pub fn on_slave_bus_error(&mut self, now: Instant) {
        self.prev_exchange_end = Some(now);
        self.counters.spi_rejected = self.counters.spi_rejected.wrapping_add(1);
    }

    /// The master's pose estimate: the slave's last pose propagated with the commanded motion
    /// since the slave sampled it.
    pub fn estimate(&self, now: Instant) -> Option<Pose2> {
        let (f, at) = self.slave?;
        let (x, y, theta) = f.pose.to_si();
        let dt = now.saturating_duration_since(at).as_micros() as f64 * 1e-6;
        Some(Pose2::new(x, y, theta).integrate(self.cmd_twist, dt))
    }

    /// One control step: watchdogs, pursuit, inverse kinematics, duties.
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
        let (Some(goal), Some(est)) = (self.goal, self.estimate(now)) else {
            return self.halt();
        };

        let (target, stopped) = goal.target.position(secs(now));
        let (vx, vy, omega) = pursue(
            (est.x, est.y),
            est.theta,
            target,
            goal.heading,
            goal.robot_speed,
            &self.cfg.pursuit,
        );
        if stopped && libm::hypot(target.0 - est.x, target.1 - est.y) < self.cfg.arrive_tolerance {
            self.status |= status::ARRIVED;
        }
        let (bx, by) = field_to_body(vx, vy, est.theta);
        let (wheels, _) = self.omni.wheel_speeds_saturated(Twist::new(bx, by, omega));
        self.cmd_twist = self.omni.twist(wheels);
        self.wheel_cmd = wheels;
        self.duty = wheels.map(|w| {
            let d = libm::round(w / self.cfg.speed_at_full_duty * 1000.0);
            d.clamp(-1000.0, 1000.0) as i16
        });
        self.status |= status::MOTORS_ON;
        Drive::Duty(self.duty)
    }

    fn halt(&mut self) -> Drive {
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
    pub fn streaming(&self) -> bool {
        self.relay.busy() || self.stream_recent
    }

    /// What the hello reply says.
    pub fn board_info(&self) -> BoardInfo {
        let slave = self.slave_latest;
        BoardInfo {
            protocol_version: PROTOCOL_VERSION,
            schema_fingerprint: protocol::schema_fingerprint(),
            firmware_version: crate::FIRMWARE_VERSION,
            master_uid: self.cfg.uid,
            // A frame armed before the slave's first update carries no settings yet.
            slave_seen: slave.is_some_and(|f| f.status & protocol::spi::slave_status::RUNNING != 0),
            robot: slave.map_or(0, |f| f.robot),
            source: slave.map_or(Default::default(), |f| f.source),
            period_us: slave.map_or(0, |f| f.period_us),
            algorithm: slave.map_or(Default::default(), |f| f.algorithm),
            baud: self.cfg.baud,
        }
    }

    pub fn status(&self) -> u16 {
        self.status
    }

    pub fn counters(&self) -> LinkCounters {
        self.counters
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use protocol::{BinaryAngle, Point};

    fn t(ms: u64) -> Instant {
        Instant::from_millis(ms)
    }

    fn slave_frame(seq: u16, ack: u8, x_um: i32) -> SlaveFrame {
        SlaveFrame {
            seq,
            command_ack: ack,
            pose: Pose {
                x_um,
                y_um: 0,
                heading: BinaryAngle(0),
            },
            status: protocol::spi::slave_status::RUNNING,
            ..Default::default()
        }
    }

    fn follow(speed_um_s: u32) -> HostToMaster {
        HostToMaster::FollowTarget(MovingTarget {
            from: Point {
                x_um: 1_000_000,
                y_um: 0,
            },
            to: Point {
                x_um: 1_000_000,
                y_um: 0,
            },
            target_speed_um_s: 0,
            robot_speed_um_s: speed_um_s,
            heading: BinaryAngle(0),
        })
    }

    fn ctl() -> Controller {
        Controller::new(MasterConfig::DEFAULT).unwrap()
    }

    #[test]
    fn drives_towards_the_target_and_stops_when_the_slave_goes_quiet() {
        let mut c = ctl();
        c.on_host_message(t(0), follow(500_000));
        c.on_slave_frame(t(1), Ok(slave_frame(1, 0, 0)));
        let Drive::Duty(d) = c.control(t(2)) else {
            panic!("should drive")
        };
        // Straight ahead along +x: wheel 1 (rolling along +y) idle, wheels 2 and 3 opposite.
        assert_eq!(d[0], 0);
        assert!(d[1] < 0 && d[2] > 0, "{d:?}");
        // No fresh frame for longer than the timeout: motors stop and the goal is dropped.
        c.on_host_message(t(60), HostToMaster::Heartbeat);
        assert_eq!(c.control(t(2 + 51)), Drive::Stop);
        assert_ne!(c.status() & status::SLAVE_LOST, 0);
        assert_eq!(c.status() & status::FOLLOWING, 0);
    }

    #[test]
    fn a_stuck_slave_counts_as_lost() {
        let mut c = ctl();
        c.on_host_message(t(0), follow(500_000));
        for ms in 1..100 {
            // Valid CRC, but the same seq: odometry is not running.
            c.on_slave_frame(t(ms), Ok(slave_frame(7, 0, 0)));
            c.on_host_message(t(ms), HostToMaster::Heartbeat);
        }
        assert_eq!(c.control(t(100)), Drive::Stop);
    }

    #[test]
    fn host_silence_stops_the_motors() {
        let mut c = ctl();
        c.on_host_message(t(0), follow(500_000));
        for ms in 1..=600 {
            c.on_slave_frame(t(ms), Ok(slave_frame(ms as u16, 0, 0)));
        }
        assert!(matches!(c.control(t(400)), Drive::Duty(_)));
        assert_eq!(c.control(t(600)), Drive::Stop);
        assert_ne!(c.status() & status::HOST_LOST, 0);
    }

    #[test]
    fn invalid_target_is_rejected_and_stops() {
        let mut c = ctl();
        c.on_host_message(t(0), follow(500_000));
        let reply = c.on_host_message(t(1), follow(5_000_000));
        assert_eq!(
            reply,
            Some(MasterToHost::Rejected(RejectReason::InvalidTarget))
        );
        c.on_slave_frame(t(2), Ok(slave_frame(1, 0, 0)));
        assert_eq!(c.control(t(3)), Drive::Stop);
        assert_ne!(c.status() & status::COMMAND_REJECTED, 0);
    }

    #[test]
    fn wrong_protocol_version_is_refused() {
        let mut c = ctl();
        let reply = c.on_host_message(
            t(0),
            HostToMaster::Hello {
                protocol_version: 99,
            },
        );
        assert_eq!(
            reply,
            Some(MasterToHost::Rejected(RejectReason::ProtocolVersion {
                master: PROTOCOL_VERSION,
                host: 99
            }))
        );
        let ok = c.on_host_message(
            t(0),
            HostToMaster::Hello {
                protocol_version: PROTOCOL_VERSION,
            },
        );
        let Some(MasterToHost::HelloReply(info)) = ok else {
            panic!("hello must be answered with the board info, got {ok:?}")
        };
        assert_eq!(info.protocol_version, PROTOCOL_VERSION);
        assert_eq!(info.schema_fingerprint, protocol::schema_fingerprint());
        assert!(!info.slave_seen, "no slave frame yet");
    }

    #[test]
    fn set_pose_is_repeated_until_acknowledged_and_old_poses_are_ignored() {
        let mut c = ctl();
        let p = Pose {
            x_um: 5,
            y_um: 6,
            heading: BinaryAngle(7),
        };
        c.on_host_message(t(0), HostToMaster::SetPose(p));
        for _ in 0..3 {
            let f = c.next_slave_frame();
            assert_eq!((f.command_seq, f.command), (1, SlaveCommand::SetPose(p)));
            // Slave has not applied it yet: its pose is from before and must not be used.
            c.on_slave_frame(t(1), Ok(slave_frame(1, 0, 999)));
            assert!(c.estimate(t(1)).is_none());
        }
        c.on_slave_frame(t(2), Ok(slave_frame(2, 1, 5)));
        assert_eq!(c.next_slave_frame().command, SlaveCommand::None);
        assert!((c.estimate(t(2)).unwrap().x - 5e-6).abs() < 1e-12);
    }

    #[test]
    fn frame_age_comes_from_the_slave_clock() {
        let mut c = ctl();
        // The slave's clock runs 1 s behind the master's. Polls end at 2.000 s and 2.002 s
        // (master clock); the slave armed its frame right after the first, holding a pose it
        // sampled 700 µs before that.
        c.on_slave_frame(t(2_000), Err(SpiFrameError::Crc));
        let mut f = slave_frame(1, 0, 0);
        f.armed_us = 1_000_000;
        f.time_us = 1_000_000 - 700;
        c.on_slave_frame(t(2_002), Ok(f));
        assert_eq!(c.slave.unwrap().1.as_micros(), 2_000_000 - 700);
        // A slave reboot (its clock back near zero) must not produce an absurd age.
        let mut f = slave_frame(2, 0, 0);
        f.time_us = 5;
        f.armed_us = 3;
        c.on_slave_frame(t(2_004), Ok(f));
        assert_eq!(c.slave.unwrap().1.as_micros(), 2_004_000);
    }

    #[test]
    fn queued_commands_go_out_one_by_one_each_until_acknowledged() {
        use protocol::spi::OdometryAlgorithm;
        let mut c = ctl();
        let p = Pose {
            x_um: 1,
            y_um: 2,
            heading: BinaryAngle(3),
        };
        c.on_host_message(t(0), HostToMaster::SetPose(p));
        c.on_host_message(t(0), HostToMaster::SetOdometry(OdometryAlgorithm::Arc));
        let f = c.next_slave_frame();
        assert_eq!((f.command_seq, f.command), (1, SlaveCommand::SetPose(p)));
        // Not acknowledged yet: the same command again.
        c.on_slave_frame(t(1), Ok(slave_frame(1, 0, 0)));
        assert_eq!(c.next_slave_frame().command, SlaveCommand::SetPose(p));
        // Acked: the next one, under the next number.
        c.on_slave_frame(t(2), Ok(slave_frame(2, 1, 0)));
        let f = c.next_slave_frame();
        assert_eq!(
            (f.command_seq, f.command),
            (2, SlaveCommand::SetAlgorithm(OdometryAlgorithm::Arc))
        );
        assert!(
            c.estimate(t(2)).is_none(),
            "poses wait until every command is applied"
        );
        c.on_slave_frame(t(3), Ok(slave_frame(3, 2, 0)));
        let f = c.next_slave_frame();
        assert_eq!((f.command_seq, f.command), (2, SlaveCommand::None));
        assert!(c.estimate(t(3)).is_some());
        // A flood beyond the queue is refused and stops the robot.
        for _ in 0..COMMAND_QUEUE {
            assert_eq!(c.on_host_message(t(4), HostToMaster::SetPose(p)), None);
        }
        assert_eq!(
            c.on_host_message(t(4), HostToMaster::SetPose(p)),
            Some(MasterToHost::Rejected(RejectReason::Busy))
        );
    }

    fn events(seq: u16, bytes: &[u8]) -> HostToMaster {
        HostToMaster::Events(protocol::link::DataFrame {
            seq,
            bytes: heapless::Vec::from_slice(bytes).unwrap(),
        })
    }

    /// The master's ack of the host's event stream, which it sends next.
    fn events_ack(c: &mut Controller, now: Instant) -> protocol::link::Ack {
        match c.poll_host_stream(now) {
            Some(MasterToHost::EventsAck(a)) => a,
            other => panic!("expected an events ack, got {other:?}"),
        }
    }

    #[test]
    fn info_answers_without_restarting_the_streams_and_hello_restarts_them() {
        let mut c = ctl();
        let hello = HostToMaster::Hello {
            protocol_version: PROTOCOL_VERSION,
        };
        assert!(c.on_host_message(t(0), hello.clone()).is_some());
        c.on_slave_frame(
            t(0),
            Ok(SlaveFrame {
                robot: 0xabcd,
                period_us: 2_000,
                ..slave_frame(1, 0, 0)
            }),
        );
        c.on_host_message(t(1), events(0, &[1, 2, 3, 4]));
        assert_eq!(events_ack(&mut c, t(1)).next, 4);

        let reply = c.on_host_message(t(2), HostToMaster::Info);
        let Some(MasterToHost::HelloReply(info)) = reply else {
            panic!("info must be answered with the board info, got {reply:?}")
        };
        assert!(info.slave_seen);
        assert_eq!((info.robot, info.period_us), (0xabcd, 2_000));
        // The event stream goes on where it was.
        c.on_host_message(t(3), events(4, &[5, 6]));
        let ack = events_ack(&mut c, t(3));
        assert_eq!((ack.next, ack.gap), (6, false));

        // A hello starts a new session: the same continuation is now beyond the stream's start.
        assert!(c.on_host_message(t(4), hello).is_some());
        c.on_host_message(t(5), events(6, &[7]));
        let ack = events_ack(&mut c, t(5));
        assert_eq!((ack.next, ack.gap), (0, true));
    }

    #[test]
    fn slave_commands_are_forwarded_in_order_each_until_acknowledged() {
        use protocol::robot::{ExactPart, RobotHeader, WheelPart};
        use protocol::spi::{Reports, SensorSource};
        let mut c = ctl();
        let sent = [
            SlaveCommand::RobotWheel(WheelPart {
                index: 0,
                metres_per_count: 1e-4,
                ..Default::default()
            }),
            SlaveCommand::RobotExact(ExactPart {
                index: 0,
                kx: 5,
                ky: 6,
                kth: 7,
            }),
            SlaveCommand::RobotCommit(RobotHeader {
                encoders: 1,
                fingerprint: 42,
                ..Default::default()
            }),
            SlaveCommand::SetSource {
                source: SensorSource::PlayedTicks,
                reports: Reports::Poses,
                start: Pose::default(),
            },
        ];
        for cmd in sent {
            assert_eq!(c.on_host_message(t(0), HostToMaster::Slave(cmd)), None);
        }
        let mut ack = 0;
        for (i, cmd) in sent.iter().enumerate() {
            let f = c.next_slave_frame();
            assert_eq!(
                (f.command_seq, &f.command),
                (i as u8 + 1, cmd),
                "command {i}"
            );
            // Not acknowledged: repeated, same number.
            c.on_slave_frame(t(1), Ok(slave_frame(2 * i as u16, ack, 0)));
            let again = c.next_slave_frame();
            assert_eq!((again.command_seq, &again.command), (f.command_seq, cmd));
            ack = f.command_seq;
            c.on_slave_frame(t(1), Ok(slave_frame(2 * i as u16 + 1, ack, 0)));
        }
        assert_eq!(c.next_slave_frame().command, SlaveCommand::None);
    }

    #[test]
    fn played_events_wait_for_the_pending_commands() {
        use protocol::spi::{Reports, SensorSource};
        let mut c = ctl();
        let source = SlaveCommand::SetSource {
            source: SensorSource::PlayedTicks,
            reports: Reports::Poses,
            start: Pose::default(),
        };
        c.on_host_message(t(0), HostToMaster::Slave(source));
        c.on_host_message(t(0), events(0, &[1, 2, 3]));
        // The slave has not switched to played sensors yet: the events are held.
        for seq in 1..4 {
            let f = c.next_slave_frame();
            assert_eq!(f.command, source);
            assert!(f.events.bytes.is_empty(), "frame {seq} carried events");
            c.on_slave_frame(t(1), Ok(slave_frame(seq, 0, 0)));
        }
        // Applied: the events go out from the start of the slave's new stream.
        c.on_slave_frame(t(2), Ok(slave_frame(4, 1, 0)));
        let f = c.next_slave_frame();
        assert_eq!(f.command, SlaveCommand::None);
        assert_eq!(
            (f.events.offset, f.events.bytes.as_slice()),
            (0, &[1, 2, 3][..])
        );
    }

    #[test]
    fn crc_failures_are_counted_not_used() {
        let mut c = ctl();
        c.on_slave_frame(t(1), Err(SpiFrameError::Crc));
        c.on_host_frame_error();
        assert_eq!(c.counters().spi_rejected, 1);
        assert_eq!(c.counters().serial_rejected, 1);
        assert!(c.estimate(t(1)).is_none());
    }

    #[test]
    fn default_config_is_valid() {
        assert!(Controller::new(MasterConfig::DEFAULT).is_some());
        let mut bad = MasterConfig::DEFAULT;
        bad.wheel_distance = 0.0;
        assert!(Controller::new(bad).is_none());
    }
}
