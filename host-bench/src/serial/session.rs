//! A session with the boards over the serial link: the handshake (refusing another protocol
//! or schema, and saying which), loading a robot into the slave, choosing the odometry method
//! and the sensor source — each confirmed by what the board then reports, never assumed.

use std::time::Duration;

use anyhow::{bail, Result};
use protocol::serial::{BoardInfo, DriveGeometry, HostToMaster, MasterToHost, RejectReason};
use protocol::spi::{OdometryAlgorithm, Reports, SensorSource, SlaveCommand};
use protocol::PROTOCOL_VERSION;
use robot_math::odometry::{Layout, Method};

use super::link::Link;
use crate::serial::clock::{self, Instant};

/// How long the board may take to answer the handshake or apply a setting.
const ANSWER_TIMEOUT: Duration = Duration::from_secs(3);

/// Say hello until the master answers (a new session: both streams restart); refuse another
/// protocol version or schema.
/// Then switch the link to the rate asked for, once ([`Link::switch_baud`]).
pub fn hello(link: &mut Link) -> Result<BoardInfo> {
    let info = ask(
        link,
        &HostToMaster::Hello {
            protocol_version: PROTOCOL_VERSION,
        },
    )?;
    link.switch_baud(info.baud)?;
    Ok(BoardInfo {
        baud: link.baud(),
        ..info
    })
}

/// The board info now, without restarting the session's streams.
pub fn info(link: &mut Link) -> Result<BoardInfo> {
    ask(link, &HostToMaster::Info)
}

fn ask(link: &mut Link, question: &HostToMaster) -> Result<BoardInfo> {
    let deadline = Instant::now() + link.wait(ANSWER_TIMEOUT);
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
        link.wait(ANSWER_TIMEOUT).as_secs(),
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
    // Checked before any arithmetic with it (the played stream's updates, the recording's
    // clock): a slave image updates at one of the rates it can be built for.
    let rates = firmware_slave::board_rate::BOARD_RATES_HZ;
    if !rates
        .iter()
        .any(|&hz| firmware_slave::board_rate::period_us(hz) == Some(info.period_us))
    {
        bail!(
            "the master reports the slave's update period BoardInfo.period_us = {} us, which \
             is none of the rates a slave image is built for ({rates:?} Hz): not a board this \
             host-bench can trust",
            info.period_us
        );
    }
    Ok(info)
}

/// Send `commands` for the slave, then ask for the board info until `done` holds, or fail
/// with `what`. Commands travel in plain frames, which a noisy line can lose: while the board
/// does not show them applied, they are sent again every [`RESEND_AFTER`] (each one applied
/// twice is applied once: a robot part overwrites its slot, a setting sets it again).
fn send_until(
    link: &mut Link,
    commands: &[SlaveCommand],
    what: &str,
    mut done: impl FnMut(&BoardInfo) -> bool,
) -> Result<BoardInfo> {
    let deadline = Instant::now() + link.wait(ANSWER_TIMEOUT);
    loop {
        for c in commands {
            link.send(&HostToMaster::Slave(*c))?;
        }
        let resend_at = Instant::now() + link.wait(RESEND_AFTER);
        loop {
            clock::sleep(Duration::from_millis(20));
            let info = info(link)?;
            if done(&info) {
                return Ok(info);
            }
            if Instant::now() > deadline {
                bail!("{what} (the board reports: {info:?})");
            }
            if Instant::now() > resend_at {
                break;
            }
        }
    }
}

/// How long a command may take to show before it is taken for lost and sent again: a few
/// slave polls (2 ms each) and a serial round trip, with room for a busy host.
const RESEND_AFTER: Duration = Duration::from_millis(400);

/// Load `layout` into the slave; returns its fingerprint once the slave reports running it.
pub fn load_robot(link: &mut Link, layout: &Layout) -> Result<u32> {
    let (commands, fp) = firmware_slave::robot_wire::upload_commands(layout);
    let commands: Vec<SlaveCommand> = commands.collect();
    send_until(
        link,
        &commands,
        &format!("the slave did not take the robot (fingerprint {fp:08x})"),
        |i| i.robot == fp,
    )?;
    Ok(fp)
}

/// Send the robot's drive to the master (wheel layout, limits, tracking gains): one master
/// image drives every robot. The protocol has no echo of it, so the master's telemetry tells:
/// sent while nothing else is on its way, it arrived when the master's count of accepted host
/// frames rose and its count of refused ones did not; otherwise it goes again. A drive the
/// master refuses is an error.
pub fn set_drive(link: &mut Link, drive: &DriveGeometry) -> Result<()> {
    for _ in 0..5 {
        let before = next_counters(link, Instant::now())?;
        link.send(&HostToMaster::SetDrive(*drive))?;
        // Telemetry made once the frame has surely landed (a few ms at 115200 baud).
        let after = next_counters(link, Instant::now() + link.wait(Duration::from_millis(60)))?;
        if after.0 != before.0 && after.1 == before.1 {
            return Ok(());
        }
    }
    bail!(
        "the master on {} did not take the robot's drive (sent 5 times; its frame counters \
         did not show it arrived whole)",
        link.name()
    )
}

/// The master's `(accepted, refused)` host-frame counts in the first telemetry received at
/// `after` or later; a refused drive is an error.
fn next_counters(link: &mut Link, after: Instant) -> Result<(u32, u32)> {
    let deadline = after + link.wait(ANSWER_TIMEOUT);
    while Instant::now() < deadline {
        match link.recv(Duration::from_millis(20))? {
            Some(MasterToHost::Telemetry(t)) if Instant::now() >= after => {
                return Ok((t.counters.serial_ok, t.counters.serial_rejected))
            }
            Some(MasterToHost::Rejected(RejectReason::InvalidDrive)) => bail!(
                "the master refused the robot's drive (InvalidDrive: wheels not apart, the \
                 tracked point on the axle, or a limit or gain not positive)"
            ),
            _ => {}
        }
    }
    bail!(
        "no telemetry from the master on {} within {} s",
        link.name(),
        link.wait(ANSWER_TIMEOUT).as_secs()
    )
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
///
/// The board shows only which source it reads, not which command set it: a board already
/// reading `source` (left so by a play that was interrupted) would look switched before it
/// had even received the command, its old streams still running. So it is switched to another
/// source first (one of its own sensors, with nothing reported): then
/// seeing `source` means this command was applied.
pub fn set_method_and_source(
    link: &mut Link,
    method: Method,
    source: SensorSource,
    reports: Reports,
    start: protocol::Pose,
) -> Result<BoardInfo> {
    if info(link)?.source == source {
        let other = if source == SensorSource::Ticks {
            SensorSource::Counts
        } else {
            SensorSource::Ticks
        };
        let away = SlaveCommand::SetSource {
            source: other,
            reports: Reports::Off,
            start,
        };
        send_until(
            link,
            &[away],
            &format!("the slave did not switch away from {source:?}"),
            |i| i.source == other,
        )?;
    }
    let alg = wire_algorithm(method);
    let commands = [
        SlaveCommand::SetAlgorithm(alg),
        SlaveCommand::SetSource {
            source,
            reports,
            start,
        },
    ];
    send_until(
        link,
        &commands,
        &format!(
            "the slave did not switch to `{}` reading {source:?} (a method this slave cannot run \
             on this robot is refused: `host-bench replay` says why){}",
            method.name(),
            if method == Method::Exact {
                ""
            } else {
                "; and a slave image built without the float baselines refuses `arc`, `lut` and \
                 `timing` on any robot: build it with them, `cargo build --release --target \
                 thumbv7m-none-eabi -p firmware-slave --features baselines`, then `host-bench \
                 flash`"
            }
        ),
        |i| i.source == source && i.algorithm == alg,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn info(period_us: u32) -> BoardInfo {
        BoardInfo {
            protocol_version: PROTOCOL_VERSION,
            schema_fingerprint: protocol::schema_fingerprint(),
            firmware_version: [0, 1, 0],
            master_uid: [0; 12],
            slave_seen: true,
            robot: 0,
            source: SensorSource::Ticks,
            period_us,
            algorithm: OdometryAlgorithm::Exact,
            baud: 115_200,
        }
    }

    /// The board's own numbers are checked before anything is computed with them: an update
    /// period no slave image has (0, 999, 2^32 - 1 µs) is refused at the handshake.
    #[test]
    fn an_update_period_no_slave_image_has_is_refused_naming_the_field() {
        for good in [1000, 500, 200, 100] {
            assert!(check(info(good)).is_ok(), "{good}");
        }
        for bad in [0, 999, u32::MAX] {
            let e = check(info(bad)).unwrap_err().to_string();
            assert!(
                e.contains("BoardInfo.period_us") && e.contains(&bad.to_string()),
                "{e}"
            );
        }
        // A master that has not heard from its slave reports period 0: the wiring is named.
        let e = check(BoardInfo {
            slave_seen: false,
            ..info(0)
        })
        .unwrap_err()
        .to_string();
        assert!(e.contains("SPI wiring"), "{e}");
    }
}
