//! Runs you can look at: every command that makes a run hands its messages to a [`View`],
//! which writes them to an MCAP file (`--mcap`, [`mcap_file`]) and serves them live over the
//! Foxglove WebSocket protocol with a bench page for a browser (`--live`, [`live`]).
//!
//! ```text
//!  emulate / virtual-board / play / record / replay
//!        │ View::pose, View::json  (the run's own time, ns)
//!        ├──► McapFile   ─► run.mcap            Foxglove, Lichtblick, PlotJuggler, Rerun
//!        └──► LiveServer ─► ws://127.0.0.1:8765  the same viewers, live
//!                         └► http://127.0.0.1:8765/  the bench page
//! ```
//! Every message is JSON, with a JSON schema: poses in the viewers' well-known
//! `foxglove.PoseInFrame` and `foxglove.FrameTransform` (so the 3D panel draws them), the rest
//! in schemas of ours ([`schemas`]). One encoding for the file, the socket and the page.

pub mod live;
pub mod mcap_file;
mod outputs;
pub mod schemas;
pub mod topics;

pub use outputs::{Outputs, Pacer, ViewArgs, LIVE_SPEEDS};

use anyhow::Result;
use serde::Serialize;

/// One channel: a topic and what its messages are.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Channel {
    pub topic: String,
    /// The schema's name: a Foxglove well-known one (`foxglove.PoseInFrame`) or ours.
    pub schema_name: &'static str,
    /// The JSON schema (encoding `jsonschema`), as text.
    pub schema: &'static str,
}

impl Channel {
    /// A pose channel (`foxglove.PoseInFrame`, frame [`FRAME`]).
    pub fn pose(topic: &str) -> Self {
        Channel {
            topic: topic.into(),
            schema_name: "foxglove.PoseInFrame",
            schema: schemas::POSE_IN_FRAME,
        }
    }

    /// The true pose as a transform [`FRAME`] → `robot`, so the 3D panel can follow it.
    pub fn transform(topic: &str) -> Self {
        Channel {
            topic: topic.into(),
            schema_name: "foxglove.FrameTransform",
            schema: schemas::FRAME_TRANSFORM,
        }
    }

    /// A channel of our own messages, `schema_name` from [`schemas`].
    pub fn json(topic: &str, schema_name: &'static str, schema: &'static str) -> Self {
        Channel {
            topic: topic.into(),
            schema_name,
            schema,
        }
    }
}

/// The world frame every pose is in: the odometry's, where the run started.
pub const FRAME: &str = "odom";

/// Where a run's messages go. Implemented by the MCAP file and the live server.
pub trait Sink {
    /// Before any message: the run's channels, their ids their index in `channels`.
    fn start(&mut self, channels: &[Channel]) -> Result<()>;
    /// One message on channel `id`, logged at `t_ns` of the run's own time.
    fn message(&mut self, id: usize, t_ns: u64, data: &[u8]) -> Result<()>;
}

/// The channels of one run and the sinks they go to. With no sink (neither `--mcap` nor
/// `--live`) every call returns at once and nothing is encoded.
pub struct View {
    channels: Vec<Channel>,
    sinks: Vec<Box<dyn Sink>>,
    started: bool,
    /// The last log time handed on: log times only go forward.
    last_ns: u64,
    buf: Vec<u8>,
}

impl View {
    pub fn new(channels: Vec<Channel>) -> Self {
        View {
            channels,
            sinks: Vec::new(),
            started: false,
            last_ns: 0,
            buf: Vec::new(),
        }
    }

    pub fn add(&mut self, sink: Box<dyn Sink>) {
        self.sinks.push(sink);
    }

    pub fn is_on(&self) -> bool {
        !self.sinks.is_empty()
    }

    /// The channel of `topic`'s id. Topics are the command's own: one not declared is a bug.
    pub fn id(&self, topic: &str) -> usize {
        self.channels
            .iter()
            .position(|c| c.topic == topic)
            .unwrap_or_else(|| panic!("topic {topic} was not declared"))
    }

    /// A pose `(x m, y m, heading rad)` on a [`Channel::pose`] channel at `t_s` seconds.
    pub fn pose(&mut self, topic: &str, t_s: f64, pose: (f64, f64, f64)) -> Result<()> {
        if !self.is_on() {
            return Ok(());
        }
        self.json(topic, t_s, &PoseInFrame::new(t_s, pose))
    }

    /// A pose as the transform [`FRAME`] → `child` on a [`Channel::transform`] channel.
    pub fn transform(
        &mut self,
        topic: &str,
        child: &str,
        t_s: f64,
        pose: (f64, f64, f64),
    ) -> Result<()> {
        if !self.is_on() {
            return Ok(());
        }
        self.json(topic, t_s, &FrameTransform::new(t_s, child, pose))
    }

    /// Any message of ours, as JSON.
    pub fn json<T: Serialize>(&mut self, topic: &str, t_s: f64, msg: &T) -> Result<()> {
        if !self.is_on() {
            return Ok(());
        }
        let id = self.id(topic);
        if !self.started {
            for s in &mut self.sinks {
                s.start(&self.channels)?;
            }
            self.started = true;
        }
        self.buf.clear();
        serde_json::to_writer(&mut self.buf, msg)?;
        // A run's clock never runs back; a message stamped before the last one (two sources
        // of one run) is logged at the last time, so every reader sees time go forward.
        let t_ns = secs_to_ns(t_s).max(self.last_ns);
        self.last_ns = t_ns;
        for s in &mut self.sinks {
            s.message(id, t_ns, &self.buf)?;
        }
        Ok(())
    }

    /// The sinks, to finish them: the MCAP file is put in place by its owner.
    pub fn into_sinks(self) -> Vec<Box<dyn Sink>> {
        self.sinks
    }
}

fn secs_to_ns(t_s: f64) -> u64 {
    (t_s.max(0.0) * 1e9).round() as u64
}

#[derive(Serialize)]
struct Time {
    sec: u32,
    nsec: u32,
}

impl Time {
    fn of(t_s: f64) -> Self {
        let ns = secs_to_ns(t_s);
        Time {
            sec: (ns / 1_000_000_000) as u32,
            nsec: (ns % 1_000_000_000) as u32,
        }
    }
}

#[derive(Serialize)]
struct Vector3 {
    x: f64,
    y: f64,
    z: f64,
}

#[derive(Serialize)]
struct Quaternion {
    x: f64,
    y: f64,
    z: f64,
    w: f64,
}

/// A heading about z as a unit quaternion.
fn yaw(theta: f64) -> Quaternion {
    let (s, c) = (theta / 2.0).sin_cos();
    Quaternion {
        x: 0.0,
        y: 0.0,
        z: s,
        w: c,
    }
}

#[derive(Serialize)]
struct Pose {
    position: Vector3,
    orientation: Quaternion,
}

/// `foxglove.PoseInFrame`.
#[derive(Serialize)]
struct PoseInFrame {
    timestamp: Time,
    frame_id: &'static str,
    pose: Pose,
}

impl PoseInFrame {
    fn new(t_s: f64, (x, y, theta): (f64, f64, f64)) -> Self {
        PoseInFrame {
            timestamp: Time::of(t_s),
            frame_id: FRAME,
            pose: Pose {
                position: Vector3 { x, y, z: 0.0 },
                orientation: yaw(theta),
            },
        }
    }
}

/// `foxglove.FrameTransform`.
#[derive(Serialize)]
struct FrameTransform<'a> {
    timestamp: Time,
    parent_frame_id: &'static str,
    child_frame_id: &'a str,
    translation: Vector3,
    rotation: Quaternion,
}

impl<'a> FrameTransform<'a> {
    fn new(t_s: f64, child: &'a str, (x, y, theta): (f64, f64, f64)) -> Self {
        FrameTransform {
            timestamp: Time::of(t_s),
            parent_frame_id: FRAME,
            child_frame_id: child,
            translation: Vector3 { x, y, z: 0.0 },
            rotation: yaw(theta),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_pose_is_foxglove_pose_in_frame() {
        let v = serde_json::to_value(PoseInFrame::new(1.25, (1.0, -2.0, std::f64::consts::PI)))
            .unwrap();
        assert_eq!(v["timestamp"]["sec"], 1);
        assert_eq!(v["timestamp"]["nsec"], 250_000_000);
        assert_eq!(v["frame_id"], "odom");
        assert_eq!(v["pose"]["position"]["y"], -2.0);
        // Half a turn: (0, 0, 1, 0) within rounding.
        assert!((v["pose"]["orientation"]["z"].as_f64().unwrap() - 1.0).abs() < 1e-12);
        assert!(v["pose"]["orientation"]["w"].as_f64().unwrap().abs() < 1e-12);
    }

    /// What a sink was given: (channel id, log time ns, message).
    struct Recorded(std::rc::Rc<std::cell::RefCell<Vec<(usize, u64, serde_json::Value)>>>);

    impl Sink for Recorded {
        fn start(&mut self, _: &[Channel]) -> Result<()> {
            Ok(())
        }
        fn message(&mut self, id: usize, t_ns: u64, data: &[u8]) -> Result<()> {
            let v = serde_json::from_slice(data)?;
            self.0.borrow_mut().push((id, t_ns, v));
            Ok(())
        }
    }

    #[test]
    fn a_message_stamped_before_the_last_is_logged_at_the_last_time() {
        let got = std::rc::Rc::default();
        let mut view = View::new(vec![Channel::pose("/a"), Channel::pose("/b")]);
        view.add(Box::new(Recorded(std::rc::Rc::clone(&got))));
        view.pose("/a", 2.0, (0.0, 0.0, 0.0)).unwrap();
        view.pose("/b", 1.5, (1.0, 0.0, 0.0)).unwrap();
        view.pose("/a", 2.5, (2.0, 0.0, 0.0)).unwrap();
        let got = got.borrow();
        let log: Vec<(usize, u64)> = got.iter().map(|(id, t, _)| (*id, *t)).collect();
        assert_eq!(
            log,
            [(0, 2_000_000_000), (1, 2_000_000_000), (0, 2_500_000_000)]
        );
        // The message keeps its own time stamp; only the log time is held.
        assert_eq!(got[1].2["timestamp"]["nsec"], 500_000_000);
        assert_eq!(got[1].2["timestamp"]["sec"], 1);
    }
}
