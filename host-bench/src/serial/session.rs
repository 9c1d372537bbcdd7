//! A session with the boards over the serial link: the handshake (refusing another protocol
//! or schema, and saying which), loading a robot into the slave, choosing the odometry method
//! and the sensor source — each confirmed by what the board then reports, never assumed.

use std::time::{Duration, Instant};

use anyhow::{bail, Result};
use protocol::serial::{BoardInfo, HostToMaster, MasterToHost, RejectReason};
use protocol::spi::{OdometryAlgorithm, Reports, SensorSource, SlaveCommand};
use protocol::PROTOCOL_VERSION;
use robot_math::odometry::{Layout, Method};

use super::link::Link;

/// How long the board may take to answer the handshake or apply a setting.
const ANSWER_TIMEOUT: Duration = Duration::from_secs(3);

/// Say hello until the master answers (a new session: both streams restart); refuse another
/// protocol version or schema.
pub fn hello(link: &mut Link) -> Result<BoardInfo> {
    ask(
        link,
        &HostToMaster::Hello {
            protocol_version: PROTOCOL_VERSION,
        },
    )
}

/// The board info now, without restarting the session's streams.
pub fn info(link: &mut Link) -> Result<BoardInfo> {
    ask(link, &HostToMaster::Info)
}

fn ask(link: &mut Link, question: &HostToMaster) -> Result<BoardInfo> {
    let deadline = Instant::now() + ANSWER_TIMEOUT;
    while Instant::now() < deadline {
        link.send(question)?;
        let wait_until = Instant::now() + Duration::from_millis(300);
        while Instant::now() < wait_until {
            match link.recv(Duration::from_millis(20))? {
                // A master that just started may not have heard from its slave yet.
                Some(MasterToHost::HelloReply(info))
                    if !info.slave_seen
                        && Instant::now() + Duration::from_millis(300) < deadline => {}
                Some(MasterToHost::HelloReply(info)) => return check(info),
                Some(MasterToHost::Rejected(RejectReason::ProtocolVersion { master, host })) => {
                    bail!(
                        "the master on {} speaks protocol v{master}, this host-bench v{host}: \
                         flash the firmware built from this checkout (`host-bench flash`)",
                        link.name()
                    )
                }
                _ => {}
            }
        }
    }
    bail!(
        "no answer from a master on {} within {} s ({} bytes received, {} frames rejected): \
         is the master powered and flashed, and is the baud rate right?",
        link.name(),
        ANSWER_TIMEOUT.as_secs(),
        link.stats.bytes_received,
        link.stats.frames_rejected
    )
}

fn check(info: BoardInfo) -> Result<BoardInfo> {
    let ours = protocol::schema_fingerprint();
    if info.protocol_version != PROTOCOL_VERSION || info.schema_fingerprint != ours {
        bail!(
            "the master speaks protocol v{} with schema {:08x}; this host-bench speaks v{} with \
             schema {:08x}: the message types differ, so nothing it says can be trusted. Flash \
             both boards built from this checkout (`host-bench flash`)",
            info.protocol_version,
            info.schema_fingerprint,
            PROTOCOL_VERSION,
            ours
        );
    }
    if !info.slave_seen {
        bail!(
            "the master answers but has no valid frame from the slave: check the SPI wiring \
             (docs/pinmap.md) and that the slave is powered and flashed"
        );
    }
    Ok(info)
}

/// Ask for the board info again until `done` holds, or fail with `what`.
fn confirm(
    link: &mut Link,
    what: &str,
    mut done: impl FnMut(&BoardInfo) -> bool,
) -> Result<BoardInfo> {
    let deadline = Instant::now() + ANSWER_TIMEOUT;
    loop {
        std::thread::sleep(Duration::from_millis(20));
        let info = info(link)?;
        if done(&info) {
            return Ok(info);
        }
        if Instant::now() > deadline {
            bail!("{what} (the board reports: {info:?})");
        }
    }
}

fn to_slave(link: &mut Link, c: SlaveCommand) -> Result<()> {
    link.send(&HostToMaster::Slave(c))
}

/// Load `layout` into the slave; returns its fingerprint once the slave reports running it.
pub fn load_robot(link: &mut Link, layout: &Layout) -> Result<u32> {
    let (commands, fp) = firmware_slave::robot_wire::upload_commands(layout);
    for c in commands {
        to_slave(link, c)?;
    }
    confirm(
        link,
        &format!("the slave did not take the robot (fingerprint {fp:08x})"),
        |i| i.robot == fp,
    )?;
    Ok(fp)
}

pub fn wire_algorithm(m: Method) -> OdometryAlgorithm {
    match m {
        Method::Exact => OdometryAlgorithm::Exact,
        Method::Arc => OdometryAlgorithm::Arc,
        Method::Lut => OdometryAlgorithm::Lut,
        Method::Timing => OdometryAlgorithm::Timing,
    }
}

/// The method a board reports running ([`wire_algorithm`] the other way).
pub fn method_of(a: OdometryAlgorithm) -> Method {
    match a {
        OdometryAlgorithm::Exact => Method::Exact,
        OdometryAlgorithm::Arc => Method::Arc,
        OdometryAlgorithm::Lut => Method::Lut,
        OdometryAlgorithm::Timing => Method::Timing,
    }
}

/// Switch the slave's odometry method and its sensor source (which restarts odometry at the
/// origin and both streams at zero), confirmed by the board.
pub fn set_method_and_source(
    link: &mut Link,
    method: Method,
    source: SensorSource,
    reports: Reports,
    start: protocol::Pose,
) -> Result<BoardInfo> {
    to_slave(link, SlaveCommand::SetAlgorithm(wire_algorithm(method)))?;
    to_slave(
        link,
        SlaveCommand::SetSource {
            source,
            reports,
            start,
        },
    )?;
    let alg = wire_algorithm(method);
    confirm(
        link,
        &format!(
            "the slave did not switch to `{}` reading {source:?} (a method this slave cannot run \
             on this robot is refused: `host-bench replay` says why)",
            method.name()
        ),
        |i| i.source == source && i.algorithm == alg,
    )
}
