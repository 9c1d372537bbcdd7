//! Each command's channels, and its records turned into messages. The topics a viewer shows,
//! by command (README, "Looking at runs"):
//!
//! | topic | schema | emulate / virtual-board | play | record | replay |
//! |---|---|---|---|---|---|
//! | `/tf` (odom → robot) | foxglove.FrameTransform | truth | truth rows | truth (virtual board) | truth rows |
//! | `/truth/pose` | foxglove.PoseInFrame | ✓ | truth rows | truth (virtual board) | truth rows |
//! | `/slave/pose`, `/slave/error` | PoseInFrame, PoseError | ✓ | | | |
//! | `/master/estimate`, `/master/error`, `/master/target` | PoseInFrame, PoseError | ✓ | | | |
//! | `/master/wheels`, `/master/status`, `/master/link` | Wheels, Status, Link | ✓ | | | |
//! | `/board/pose`, `/board/error` | PoseInFrame, PoseError | | the slave's reported poses | ✓ | |
//! | `/host/pose` | PoseInFrame | | the host's own computation | | |
//! | `/odometry/METHOD/pose`, `/odometry/METHOD/error` | PoseInFrame, PoseError | | | | each method |
//! | `/encoders` | Encoders | ✓ | | ✓ | |
//! | `/link` (the serial port's) | Link | virtual-board | ✓ | ✓ | |

use anyhow::Result;
use robot_math::se2::wrap_angle;
use robot_math::Pose2;

use super::{schemas, Channel, View};
use crate::sim::emulator::LogRow;

/// The names of the master's status flags set in `flags` (protocol::serial::status).
pub fn status_names(flags: u16) -> Vec<&'static str> {
    use protocol::serial::status::*;
    [
        (FOLLOWING, "following"),
        (ARRIVED, "arrived"),
        (MOTORS_ON, "motors on"),
        (SLAVE_LOST, "slave lost"),
        (HOST_LOST, "host lost"),
        (COMMAND_REJECTED, "command rejected"),
        (SLAVE_FAULT, "slave fault"),
        (SLAVE_RESET, "slave reset"),
    ]
    .iter()
    .filter(|(bit, _)| flags & bit != 0)
    .map(|(_, name)| *name)
    .collect()
}

fn error_channel(topic: &str) -> Channel {
    Channel::json(topic, schemas::POSE_ERROR.0, schemas::POSE_ERROR.1)
}

/// An estimate's error against the truth, as `omnibench.PoseError`.
pub fn pose_error(est: (f64, f64, f64), truth: (f64, f64, f64)) -> serde_json::Value {
    serde_json::json!({
        "position_mm": (est.0 - truth.0).hypot(est.1 - truth.1) * 1e3,
        "heading_deg": wrap_angle(est.2 - truth.2).to_degrees(),
    })
}

/// `emulate`'s (and `virtual-board`'s) channels.
pub fn emulate_channels(with_serial_port: bool) -> Vec<Channel> {
    let mut c = vec![
        Channel::transform("/tf"),
        Channel::pose("/truth/pose"),
        Channel::pose("/slave/pose"),
        error_channel("/slave/error"),
        Channel::pose("/master/estimate"),
        error_channel("/master/error"),
        Channel::pose("/master/target"),
        Channel::json("/master/wheels", schemas::WHEELS.0, schemas::WHEELS.1),
        Channel::json("/master/status", schemas::STATUS.0, schemas::STATUS.1),
        Channel::json("/encoders", schemas::ENCODERS.0, schemas::ENCODERS.1),
        Channel::json("/master/link", schemas::LINK.0, schemas::LINK.1),
    ];
    if with_serial_port {
        c.push(Channel::json("/link", schemas::LINK.0, schemas::LINK.1));
    }
    c
}

/// One emulation log row as its messages.
pub fn emulate_row(view: &mut View, r: &LogRow) -> Result<()> {
    if !view.is_on() {
        return Ok(());
    }
    let t = r.t_s;
    let truth = (r.true_x_m, r.true_y_m, r.true_theta_rad);
    let slave = (r.slave_x_m, r.slave_y_m, r.slave_theta_rad);
    view.transform("/tf", "robot", t, truth)?;
    view.pose("/truth/pose", t, truth)?;
    view.pose("/slave/pose", t, slave)?;
    view.json("/slave/error", t, &pose_error(slave, truth))?;
    if let (Some(x), Some(y), Some(th)) = (r.master_x_m, r.master_y_m, r.master_theta_rad) {
        view.pose("/master/estimate", t, (x, y, th))?;
        view.json("/master/error", t, &pose_error((x, y, th), truth))?;
    }
    if let (Some(x), Some(y)) = (r.target_x_m, r.target_y_m) {
        view.pose("/master/target", t, (x, y, 0.0))?;
    }
    view.json(
        "/master/wheels",
        t,
        &serde_json::json!({
            "cmd_m_s": [r.wheel_cmd_1_m_s, r.wheel_cmd_2_m_s, r.wheel_cmd_3_m_s],
            "duty_permille": [r.duty_1_permille, r.duty_2_permille, r.duty_3_permille],
        }),
    )?;
    view.json(
        "/master/status",
        t,
        &serde_json::json!({"flags": r.status, "set": status_names(r.status)}),
    )?;
    view.json(
        "/encoders",
        t,
        &serde_json::json!({"counts": r.encoder_counts}),
    )?;
    let l = &r.link;
    view.json(
        "/master/link",
        t,
        &serde_json::json!({
            "spi_frames_ok": l.spi_ok,
            "spi_frames_rejected": l.spi_rejected,
            "slave_rx_rejected": l.slave_rx_rejected,
            "serial_frames_ok": l.serial_ok,
            "serial_frames_rejected": l.serial_rejected,
        }),
    )
}

/// `replay`'s channels: the truth and each method's pose and error.
pub fn replay_channels(methods: &[&str]) -> Vec<Channel> {
    let mut c = vec![Channel::transform("/tf"), Channel::pose("/truth/pose")];
    for m in methods {
        c.push(Channel::pose(&format!("/odometry/{m}/pose")));
        c.push(error_channel(&format!("/odometry/{m}/error")));
    }
    c
}

/// A method's scored truth rows: (t s, estimate, truth).
pub type Track = Vec<(f64, Pose2, Pose2)>;

/// Each method's scored track `(t s, estimate, truth)` as messages, row by row across the
/// methods so the log times go forward; the truth from the first method's rows.
pub fn replay_tracks(view: &mut View, tracks: &[(String, Track)]) -> Result<()> {
    if !view.is_on() {
        return Ok(());
    }
    let si = |p: &Pose2| (p.x, p.y, p.theta);
    let topics: Vec<(String, String)> = tracks
        .iter()
        .map(|(m, _)| {
            (
                format!("/odometry/{m}/pose"),
                format!("/odometry/{m}/error"),
            )
        })
        .collect();
    let rows = tracks.iter().map(|(_, t)| t.len()).max().unwrap_or(0);
    for i in 0..rows {
        if let Some((t, _, truth)) = tracks[0].1.get(i) {
            view.transform("/tf", "robot", *t, si(truth))?;
            view.pose("/truth/pose", *t, si(truth))?;
        }
        for ((_, track), (pose, error)) in tracks.iter().zip(&topics) {
            if let Some((t, est, truth)) = track.get(i) {
                view.pose(pose, *t, si(est))?;
                view.json(error, *t, &pose_error(si(est), si(truth)))?;
            }
        }
    }
    Ok(())
}

/// `play`'s and `record`'s channels.
pub fn serial_channels(play: bool) -> Vec<Channel> {
    let mut c = vec![
        Channel::transform("/tf"),
        Channel::pose("/truth/pose"),
        Channel::pose("/board/pose"),
        Channel::json("/link", schemas::LINK.0, schemas::LINK.1),
    ];
    if play {
        c.extend([error_channel("/board/error"), Channel::pose("/host/pose")]);
    } else {
        c.push(Channel::json(
            "/encoders",
            schemas::ENCODERS.0,
            schemas::ENCODERS.1,
        ));
    }
    c
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flags_are_named() {
        use protocol::serial::status::*;
        assert_eq!(
            status_names(MOTORS_ON | SLAVE_RESET),
            ["motors on", "slave reset"]
        );
        assert!(status_names(0).is_empty());
    }

    #[test]
    fn errors_are_in_mm_and_degrees() {
        let e = pose_error((0.003, 0.004, 0.1), (0.0, 0.0, 0.1 - 1f64.to_radians()));
        assert!((e["position_mm"].as_f64().unwrap() - 5.0).abs() < 1e-9);
        assert!((e["heading_deg"].as_f64().unwrap() - 1.0).abs() < 1e-9);
    }
}
