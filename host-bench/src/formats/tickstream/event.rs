//! One row of a tick stream.

/// One row of a tick stream.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Event {
    /// An incremental encoder moved by one count; `step` is +1 (the wheel rolled along its
    /// rolling direction) or -1. `encoder` indexes the robot's `[[encoders]]`.
    Tick { t_ns: u64, encoder: u16, step: i8 },
    /// An absolute encoder read `code` (raw, as the sensor outputs it). `encoder` indexes the
    /// robot's `[[absolute_encoders]]`.
    Abs { t_ns: u64, encoder: u16, code: u32 },
    /// The true pose of the body reference point in the field frame (metres, radians CCW).
    Truth {
        t_ns: u64,
        x_m: f64,
        y_m: f64,
        theta_rad: f64,
    },
}

impl Event {
    /// When the event happened, nanoseconds from the start of the stream.
    pub fn t_ns(&self) -> u64 {
        match *self {
            Event::Tick { t_ns, .. } | Event::Abs { t_ns, .. } | Event::Truth { t_ns, .. } => t_ns,
        }
    }

    /// A truth row's time and pose; `None` for the other rows.
    pub fn truth(&self) -> Option<(u64, robot_math::Pose2)> {
        match *self {
            Event::Truth {
                t_ns,
                x_m,
                y_m,
                theta_rad,
            } => Some((t_ns, robot_math::Pose2::new(x_m, y_m, theta_rad))),
            _ => None,
        }
    }
}
