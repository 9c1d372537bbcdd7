//! The host's side of a session, as the emulator runs it: the same frames a real host sends
//! over a serial port (hello, set-pose, follow-target, heartbeats), and a reader that checks
//! every frame the master sends back.

use std::cell::RefCell;
use std::rc::Rc;

use embassy_futures::join::join;
use embassy_time::{Duration, Instant, Timer};
use embedded_io_async::{Read, Write};
use protocol::serial::{
    self, FrameDecoder, HostToMaster, MasterToHost, MovingTarget, Telemetry, TrackPoint,
};
use protocol::{BinaryAngle, Point, Pose, PROTOCOL_VERSION};

use super::reference::{ReferencePath, Sample};
use super::{Motion, Scenario};

/// What the host saw during the session.
#[derive(Debug, Default)]
pub struct HostLog {
    pub frames_received: u64,
    pub frames_rejected: u64,
    pub frames_sent: u64,
    pub fingerprint_match: Option<bool>,
    /// The master's last board info (hello or info reply).
    pub board: Option<protocol::serial::BoardInfo>,
    /// The robot uploaded to the slave, once the slave reported running it.
    pub robot_uploaded: Option<u32>,
    pub last_telemetry: Option<Telemetry>,
    /// Virtual time (s) the master's telemetry first said the slave had restarted.
    pub slave_reset_told_at: Option<f64>,
    /// Virtual time (s) the motion started: the follow-target command was sent, or the
    /// tracked path's first sample.
    pub follow_sent_at: Option<f64>,
    /// How often the drive geometry went to the master before it showed as taken (on a
    /// noisy line; 0 on a quiet one, where it goes once unconfirmed).
    pub drive_sends: u32,
    /// Why the session failed, if it did.
    pub problem: Option<String>,
}

/// How often the host says it is still there (well inside the master's host timeout).
const HEARTBEAT: Duration = Duration::from_millis(100);

/// What the host does in a session.
pub struct Plan {
    pub scenario: Scenario,
    /// How long after the setup a path starts, seconds (the host's clock against the
    /// master's control period).
    pub path_start_delay_s: f64,
    /// The robot's encoders, when the slave did not power on with them.
    pub upload: Option<robot_math::odometry::Layout>,
    pub algorithm: protocol::spi::OdometryAlgorithm,
    /// The line may lose or spoil frames (`--fault-serial-*`): send each setting again until
    /// the master's telemetry shows it, as `play` and `record` do. On a quiet line each goes
    /// once, so a clean run's timing is what it always was.
    pub confirm: bool,
}

/// How long a setting or goal may take to show in the telemetry (20 ms apart) before it is
/// sent again, on a noisy line.
const CONFIRM_WITHIN: Duration = Duration::from_millis(60);

/// Whether the master's latest telemetry satisfies `f`.
fn telemetry_shows(log: &RefCell<HostLog>, f: impl Fn(&Telemetry) -> bool) -> bool {
    log.borrow().last_telemetry.as_ref().is_some_and(f)
}

/// Run a host session for `plan` over a serial link whose bytes take `byte_time` each.
pub async fn session(
    rx: impl Read,
    tx: impl Write,
    byte_time: Duration,
    plan: Plan,
    log: Rc<RefCell<HostLog>>,
) {
    let Plan {
        scenario,
        path_start_delay_s,
        upload,
        algorithm,
        confirm,
    } = plan;
    let reader = read_loop(rx, log.clone());
    let mut tx = HostTx {
        line: tx,
        flush: confirm,
    };
    let writer = async {
        let hello = HostToMaster::Hello {
            protocol_version: PROTOCOL_VERSION,
        };
        send(&mut tx, &log, &hello).await;
        // Wait for the hello reply before commanding anything (asking again if it is lost).
        let deadline = Instant::now() + Duration::from_secs(1);
        let mut ask_again = Instant::now() + CONFIRM_WITHIN;
        while log.borrow().fingerprint_match.is_none() && log.borrow().problem.is_none() {
            if Instant::now() > deadline {
                log.borrow_mut().problem = Some("no hello reply within 1 s".into());
                return;
            }
            if confirm && Instant::now() > ask_again {
                send(&mut tx, &log, &hello).await;
                ask_again = Instant::now() + CONFIRM_WITHIN;
            }
            Timer::after_millis(1).await;
        }
        if log.borrow().problem.is_some() {
            return;
        }
        // One image serves every robot: this run's drive first, then its encoders.
        let lands_within = byte_time * serial::MAX_FRAME as u32 + Duration::from_millis(1);
        if let Err(e) = set_drive(&mut tx, &log, &scenario.drive, confirm, lands_within).await {
            log.borrow_mut().problem = Some(e);
            return;
        }
        if let Some(layout) = upload {
            if let Err(e) = upload_robot(&mut tx, &log, &layout, confirm).await {
                log.borrow_mut().problem = Some(e);
                return;
            }
        }
        let (x, y, th) = scenario.start;
        let start = Pose::from_si(x, y, th);
        send(&mut tx, &log, &HostToMaster::SetPose(start)).await;
        send(&mut tx, &log, &HostToMaster::SetOdometry(algorithm)).await;
        // Give the master a few polls to get both commands to the slave and acknowledged.
        Timer::after_millis(20).await;
        if confirm {
            // Until the slave's pose and method show in the telemetry (the robot stands still
            // meanwhile, so its pose is the one set).
            let deadline = Instant::now() + Duration::from_secs(2);
            loop {
                Timer::after(CONFIRM_WITHIN).await;
                if telemetry_shows(&log, |t| {
                    t.slave_pose == start && t.slave_algorithm == algorithm
                }) {
                    break;
                }
                if Instant::now() > deadline {
                    log.borrow_mut().problem =
                        Some("the slave did not show the start pose and method within 2 s".into());
                    return;
                }
                send(&mut tx, &log, &HostToMaster::SetPose(start)).await;
                send(&mut tx, &log, &HostToMaster::SetOdometry(algorithm)).await;
            }
        }
        match scenario.motion {
            Motion::Pursue {
                target_from,
                target_to,
                target_speed,
                robot_speed,
                heading,
            } => {
                let follow = HostToMaster::FollowTarget(MovingTarget {
                    from: Point::from_metres(target_from.0, target_from.1),
                    to: Point::from_metres(target_to.0, target_to.1),
                    target_speed_um_s: (target_speed * 1e6).round() as u32,
                    robot_speed_um_s: (robot_speed * 1e6).round() as u32,
                    heading: BinaryAngle::from_radians(heading),
                });
                send(&mut tx, &log, &follow).await;
                log.borrow_mut().follow_sent_at = Some(secs(Instant::now()));
                // On a noisy line, the goal again until the master says it follows one (each
                // time it takes it, it starts over: the motion is timed from the last one).
                let mut check_at = confirm.then(|| Instant::now() + CONFIRM_WITHIN);
                let mut heartbeat_at = Instant::now() + HEARTBEAT;
                loop {
                    Timer::at(check_at.map_or(heartbeat_at, |c| c.min(heartbeat_at))).await;
                    if let Some(c) = check_at.filter(|c| Instant::now() >= *c) {
                        let following = telemetry_shows(&log, |t| {
                            t.status & protocol::serial::status::FOLLOWING != 0
                        });
                        check_at = if following || log.borrow().problem.is_some() {
                            None
                        } else {
                            send(&mut tx, &log, &follow).await;
                            log.borrow_mut().follow_sent_at = Some(secs(Instant::now()));
                            Some(c + CONFIRM_WITHIN)
                        };
                    }
                    if Instant::now() >= heartbeat_at {
                        send(&mut tx, &log, &HostToMaster::Heartbeat).await;
                        heartbeat_at = Instant::now() + HEARTBEAT;
                    }
                }
            }
            Motion::Track {
                sample_period_s, ..
            } => {
                let reference = match ReferencePath::new(&scenario.motion) {
                    Ok(r) => r,
                    Err(e) => {
                        log.borrow_mut().problem = Some(e.to_string());
                        return;
                    }
                };
                Timer::after(Duration::from_micros(
                    (path_start_delay_s * 1e6).round() as u64
                ))
                .await;
                let t0 = Instant::now();
                log.borrow_mut().follow_sent_at = Some(secs(t0));
                let period = Duration::from_micros((sample_period_s * 1e6).round() as u64);
                let mut next = t0;
                loop {
                    // The master takes a sample as "now" when its last byte lands: send the
                    // reference for that instant.
                    let on_the_wire = byte_time * TRACK_FRAME_BYTES;
                    let t = secs(Instant::now() + on_the_wire) - secs(t0);
                    send(
                        &mut tx,
                        &log,
                        &HostToMaster::Track(track_point(reference.at(t))),
                    )
                    .await;
                    next += period;
                    Timer::at(next).await;
                }
            }
        }
    };
    join(reader, writer).await;
}

/// The robot's encoders to the slave, as `host-bench play` loads them on real boards
/// (`serial::session::load_robot`): the parts through the master, then board info until the
/// slave reports running them.
async fn upload_robot(
    tx: &mut HostTx<impl Write>,
    log: &RefCell<HostLog>,
    layout: &robot_math::odometry::Layout,
    confirm: bool,
) -> Result<(), String> {
    let (commands, fingerprint) = firmware_slave::robot_wire::upload_commands(layout);
    let commands: Vec<_> = commands.collect();
    for c in &commands {
        send(tx, log, &HostToMaster::Slave(*c)).await;
    }
    let within_s = if confirm { 3 } else { 1 };
    let deadline = Instant::now() + Duration::from_secs(within_s);
    // On a noisy line every part goes again while the slave does not show the robot (a part
    // applied twice overwrites its slot: the same robot).
    let mut resend_at = Instant::now() + Duration::from_millis(400);
    loop {
        if confirm && Instant::now() > resend_at {
            for c in &commands {
                send(tx, log, &HostToMaster::Slave(*c)).await;
            }
            resend_at = Instant::now() + Duration::from_millis(400);
        }
        send(tx, log, &HostToMaster::Info).await;
        Timer::after_millis(10).await;
        if log.borrow().board.is_some_and(|b| b.robot == fingerprint) {
            log.borrow_mut().robot_uploaded = Some(fingerprint);
            return Ok(());
        }
        if Instant::now() > deadline {
            return Err(format!(
                "the slave did not take the robot (fingerprint {:08x}) within {within_s} s: {:?}",
                fingerprint,
                log.borrow().board
            ));
        }
    }
}

/// The drive geometry to the master. Protocol v5 has no echo of it, so on a noisy line the
/// master's frame counters in its telemetry tell: sent while nothing else is on its way, it
/// arrived when the count of accepted frames rises and that of refused ones does not. (The
/// line holds a frame back only until one passes, and a spoilt geometry counts as refused.)
/// Sent again until then, as often as it takes within 2 s; applied twice it is the same drive.
async fn set_drive(
    tx: &mut HostTx<impl Write>,
    log: &RefCell<HostLog>,
    drive: &protocol::serial::DriveGeometry,
    confirm: bool,
    lands_within: Duration,
) -> Result<(), String> {
    let msg = HostToMaster::SetDrive(*drive);
    if !confirm {
        send(tx, log, &msg).await;
        return Ok(());
    }
    let deadline = Instant::now() + Duration::from_secs(2);
    loop {
        // What the master had counted once everything sent before had landed.
        let before = counts_after(log, Instant::now() + lands_within, deadline).await?;
        send(tx, log, &msg).await;
        let after = counts_after(log, Instant::now() + lands_within, deadline).await?;
        log.borrow_mut().drive_sends += 1;
        if after.0 != before.0 && after.1 == before.1 {
            return Ok(());
        }
    }
}

/// The master's `(accepted, refused)` host-frame counts in its first telemetry made at `at` or
/// later (the emulated host shares the boards' virtual clock).
async fn counts_after(
    log: &RefCell<HostLog>,
    at: Instant,
    deadline: Instant,
) -> Result<(u32, u32), String> {
    loop {
        let counts = log.borrow().last_telemetry.as_ref().and_then(|t| {
            (t.time_us >= at.as_micros())
                .then_some((t.counters.serial_ok, t.counters.serial_rejected))
        });
        if let Some(c) = counts {
            return Ok(c);
        }
        if Instant::now() > deadline {
            return Err("the master did not show the drive geometry taken within 2 s".into());
        }
        Timer::after_millis(1).await;
    }
}

/// A track sample's frame length on the wire, bytes (typical; a byte or two either way moves
/// the sample by under 0.2 ms at 115200 baud).
const TRACK_FRAME_BYTES: u32 = 30;

fn secs(t: Instant) -> f64 {
    t.as_micros() as f64 * 1e-6
}

/// A reference sample as the master takes it.
pub fn track_point(s: Sample) -> TrackPoint {
    let um = protocol::metres_to_um;
    TrackPoint {
        position: Point::from_metres(s.position.0, s.position.1),
        velocity_um_s: [um(s.velocity.0), um(s.velocity.1)],
        heading: BinaryAngle::from_radians(s.heading),
        omega_urad_s: um(s.omega),
    }
}

/// The host's end of the line. On a noisy one a delimiter follows each frame's own (as `play`
/// and `record` always send): should the line tear the frame, its piece is closed off as one
/// bad frame of its own instead of running into the next (a heartbeat's, 100 ms later: two
/// lost for one tear, and the master's 500 ms host timeout within reach). The master takes it
/// for an empty frame. A quiet line has nothing to flush, and its runs keep their timing to
/// the bit.
struct HostTx<W> {
    line: W,
    flush: bool,
}

async fn send(tx: &mut HostTx<impl Write>, log: &RefCell<HostLog>, msg: &HostToMaster) {
    let mut buf = [0u8; serial::MAX_FRAME];
    match serial::encode(msg, &mut buf) {
        Ok(frame) => {
            let sent = tx.line.write_all(frame).await.is_ok()
                && (!tx.flush || tx.line.write_all(&[0]).await.is_ok());
            if sent {
                log.borrow_mut().frames_sent += 1;
            }
        }
        Err(e) => log.borrow_mut().problem = Some(format!("cannot encode {msg:?}: {e:?}")),
    }
}

async fn read_loop(mut rx: impl Read, log: Rc<RefCell<HostLog>>) {
    let mut decoder = FrameDecoder::new();
    let mut buf = [0u8; 256];
    loop {
        let n = match rx.read(&mut buf).await {
            Ok(0) | Err(_) => return,
            Ok(n) => n,
        };
        for &b in &buf[..n] {
            let Some(result) = decoder.push::<MasterToHost>(b) else {
                continue;
            };
            let mut l = log.borrow_mut();
            match result {
                Err(_) => l.frames_rejected += 1,
                Ok(msg) => {
                    l.frames_received += 1;
                    match msg {
                        MasterToHost::HelloReply(info) => {
                            l.board = Some(info);
                            let protocol::serial::BoardInfo {
                                protocol_version,
                                schema_fingerprint,
                                ..
                            } = info;
                            let ok = protocol_version == PROTOCOL_VERSION
                                && schema_fingerprint == protocol::schema_fingerprint();
                            l.fingerprint_match = Some(ok);
                            if !ok {
                                l.problem = Some(format!(
                                    "master speaks protocol v{protocol_version} with schema {schema_fingerprint:08x}, \
                                     host v{PROTOCOL_VERSION} with {:08x}",
                                    protocol::schema_fingerprint()
                                ));
                            }
                        }
                        MasterToHost::Telemetry(t) => {
                            if t.status & protocol::serial::status::SLAVE_RESET != 0 {
                                l.slave_reset_told_at.get_or_insert(
                                    embassy_time::Instant::now().as_micros() as f64 * 1e-6,
                                );
                            }
                            l.last_telemetry = Some(t);
                        }
                        MasterToHost::Rejected(r) => {
                            l.problem = Some(format!("master rejected a command: {r:?}"))
                        }
                        // This session neither plays nor records, nor asks for another rate.
                        MasterToHost::BaudSet { .. }
                        | MasterToHost::Reports(_)
                        | MasterToHost::EventsAck(_)
                        | MasterToHost::SimTruth { .. } => {}
                    }
                }
            }
        }
    }
}
