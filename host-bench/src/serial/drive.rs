//! Driving the robot along a path through the master, over the serial link: the path's
//! reference sent as `Track` samples every [`SAMPLE_PERIOD`], as `emulate`'s host sends them
//! on virtual time, here on the host's clock (the wall's, or a board model's: `--clock`). The master tracks them with the robot's own law
//! (seed 002's point A ahead of a differential drive's axle; an omni robot's reference
//! point), steered by the slave's odometry: a robot driven so goes where its odometry says
//! the path is, which is what UMBmark asks.

use std::time::Duration;

use anyhow::{bail, Result};
use protocol::serial::{status, HostToMaster, MasterToHost};
use robot_math::Pose2;

use super::link::Link;
use super::record::Mover;
use crate::serial::clock::Instant;
use crate::sim::emulator::host::track_point;
use crate::sim::emulator::reference::{ReferencePath, Sample};
use crate::sim::trajectory::{AheadOf, Trajectory};

/// How often a reference sample goes to the master (the master extrapolates between them
/// with the sample's velocity; its host timeout is 500 ms).
pub const SAMPLE_PERIOD: Duration = Duration::from_millis(20);

/// How long the robot holds the path's end before the recording stops: the master's
/// tracking error decays, and the wheels come to rest.
pub const SETTLE: Duration = Duration::from_millis(1500);

/// A body path driven through the master from wherever the recording starts.
pub struct PathDriver {
    reference: ReferencePath,
    duration: Duration,
    /// The field pose of the path's origin: the pose the recording starts at.
    frame: Pose2,
    /// How long a sample's frame takes on the wire (the master takes a sample as "now" when
    /// its last byte lands).
    on_the_wire: Duration,
    started: Option<Instant>,
    next_sample: Instant,
}

impl PathDriver {
    /// `body_path` is the body's reference point's, from the origin facing +x; `ahead_m` is
    /// how far ahead of it the master's tracked point is (seed 002's A; 0 for an omni robot).
    pub fn new(body_path: Box<dyn Trajectory>, ahead_m: f64, baud: u32) -> PathDriver {
        let duration = Duration::from_secs_f64(body_path.duration());
        let path: Box<dyn Trajectory> = if ahead_m != 0.0 {
            Box::new(AheadOf::new(body_path, ahead_m))
        } else {
            body_path
        };
        // A track frame is about 30 bytes of 10 bits.
        let on_the_wire = Duration::from_secs_f64(300.0 / baud.max(1) as f64);
        PathDriver {
            reference: ReferencePath::Path(path),
            duration,
            frame: Pose2::default(),
            on_the_wire,
            started: None,
            next_sample: Instant::now(),
        }
    }

    /// The reference `t` seconds in, in the field frame.
    fn sample(&self, t: f64) -> Sample {
        let s = self.reference.at(t);
        let f = self.frame;
        let (sin, cos) = f.theta.sin_cos();
        let rotate = |(x, y): (f64, f64)| (cos * x - sin * y, sin * x + cos * y);
        let p = rotate(s.position);
        Sample {
            position: (f.x + p.0, f.y + p.1),
            velocity: rotate(s.velocity),
            heading: s.heading + f.theta,
            omega: s.omega,
        }
    }
}

impl Mover for PathDriver {
    fn start(&mut self, _link: &mut Link, start: protocol::Pose) -> Result<()> {
        let (x, y, theta) = start.to_si();
        self.frame = Pose2::new(x, y, theta);
        let now = Instant::now();
        self.started = Some(now);
        self.next_sample = now;
        Ok(())
    }

    fn step(&mut self, link: &mut Link, msg: Option<&MasterToHost>) -> Result<bool> {
        match msg {
            Some(MasterToHost::Rejected(why)) => {
                link.send(&HostToMaster::Stop)?;
                bail!("the master refused the path ({why:?}) and stopped the motors")
            }
            Some(MasterToHost::Telemetry(t)) => {
                for (bit, what) in [
                    (
                        status::HOST_LOST,
                        "heard nothing from this host for too long",
                    ),
                    (status::SLAVE_LOST, "lost its slave"),
                    (status::SLAVE_FAULT, "was told of a fault by its slave"),
                    (status::COMMAND_REJECTED, "refused a command"),
                ] {
                    if t.status & bit != 0 {
                        link.send(&HostToMaster::Stop)?;
                        bail!("the master {what} and stopped the motors mid-path")
                    }
                }
            }
            _ => {}
        }
        let Some(t0) = self.started else {
            return Ok(false);
        };
        let now = Instant::now();
        if now >= t0 + self.duration + SETTLE {
            link.send(&HostToMaster::Stop)?;
            return Ok(true);
        }
        if now >= self.next_sample {
            let t = (now + self.on_the_wire - t0).as_secs_f64();
            link.send(&HostToMaster::Track(track_point(self.sample(t))))?;
            self.next_sample += SAMPLE_PERIOD;
            // A host that fell behind sends the reference for now, not a backlog.
            if self.next_sample < now {
                self.next_sample = now + SAMPLE_PERIOD;
            }
        }
        Ok(false)
    }
}
