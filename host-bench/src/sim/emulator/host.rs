//! The host's side of a session, as the emulator runs it: the same frames a real host sends
//! over a serial port (hello, set-pose, follow-target, heartbeats), and a reader that checks
//! every frame the master sends back.

use std::cell::RefCell;
use std::rc::Rc;

use embassy_futures::join::join;
use embassy_time::{Duration, Instant, Timer};
use embedded_io_async::{Read, Write};
use protocol::serial::{self, FrameDecoder, HostToMaster, MasterToHost, MovingTarget, Telemetry};
use protocol::{BinaryAngle, Point, Pose, PROTOCOL_VERSION};

use super::Scenario;

/// What the host saw during the session.
#[derive(Debug, Default)]
pub struct HostLog {
    pub frames_received: u64,
    pub frames_rejected: u64,
    pub frames_sent: u64,
    pub fingerprint_match: Option<bool>,
    pub last_telemetry: Option<Telemetry>,
    /// Virtual time (s) the follow-target command was sent.
    pub follow_sent_at: Option<f64>,
    /// Why the session failed, if it did.
    pub problem: Option<String>,
}

/// How often the host says it is still there (well inside the master's host timeout).
const HEARTBEAT: Duration = Duration::from_millis(100);

/// Run a host session for `scenario` over a serial link.
pub async fn session(
    rx: impl Read,
    mut tx: impl Write,
    scenario: Scenario,
    algorithm: protocol::spi::OdometryAlgorithm,
    log: Rc<RefCell<HostLog>>,
) {
    let reader = read_loop(rx, log.clone());
    let writer = async {
        send(
            &mut tx,
            &log,
            &HostToMaster::Hello {
                protocol_version: PROTOCOL_VERSION,
            },
        )
        .await;
        // Wait for the hello reply before commanding anything.
        let deadline = Instant::now() + Duration::from_secs(1);
        while log.borrow().fingerprint_match.is_none() && log.borrow().problem.is_none() {
            if Instant::now() > deadline {
                log.borrow_mut().problem = Some("no hello reply within 1 s".into());
                return;
            }
            Timer::after_millis(1).await;
        }
        if log.borrow().problem.is_some() {
            return;
        }
        let (x, y, th) = scenario.start;
        send(
            &mut tx,
            &log,
            &HostToMaster::SetPose(Pose::from_si(x, y, th)),
        )
        .await;
        send(&mut tx, &log, &HostToMaster::SetOdometry(algorithm)).await;
        // Give the master a few polls to get both commands to the slave and acknowledged.
        Timer::after_millis(20).await;
        let follow = HostToMaster::FollowTarget(MovingTarget {
            from: Point::from_metres(scenario.target_from.0, scenario.target_from.1),
            to: Point::from_metres(scenario.target_to.0, scenario.target_to.1),
            target_speed_um_s: (scenario.target_speed * 1e6).round() as u32,
            robot_speed_um_s: (scenario.robot_speed * 1e6).round() as u32,
            heading: BinaryAngle::from_radians(scenario.heading),
        });
        send(&mut tx, &log, &follow).await;
        log.borrow_mut().follow_sent_at = Some(Instant::now().as_micros() as f64 * 1e-6);
        loop {
            Timer::after(HEARTBEAT).await;
            send(&mut tx, &log, &HostToMaster::Heartbeat).await;
        }
    };
    join(reader, writer).await;
}

async fn send(tx: &mut impl Write, log: &RefCell<HostLog>, msg: &HostToMaster) {
    let mut buf = [0u8; serial::MAX_FRAME];
    match serial::encode(msg, &mut buf) {
        Ok(frame) => {
            if tx.write_all(frame).await.is_ok() {
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
                        MasterToHost::HelloReply(protocol::serial::BoardInfo {
                            protocol_version,
                            schema_fingerprint,
                            ..
                        }) => {
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
                        MasterToHost::Telemetry(t) => l.last_telemetry = Some(t),
                        MasterToHost::Rejected(r) => {
                            l.problem = Some(format!("master rejected a command: {r:?}"))
                        }
                        // This session neither plays nor records.
                        MasterToHost::Reports(_)
                        | MasterToHost::EventsAck(_)
                        | MasterToHost::SimTruth { .. } => {}
                    }
                }
            }
        }
    }
}
