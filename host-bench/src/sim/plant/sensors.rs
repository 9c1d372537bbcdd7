//! What the slave's measuring encoders are on the simulated robot, and whether the slave
//! board can read a robot's.

use robot_math::carriage::CarriageGeometry;
use robot_math::odometry::{AbsLayout, Layout};
use robot_math::wheel::Wheel;

/// What the slave's two quadrature encoders (and its eight absolute-encoder pins) measure.
#[derive(Clone, Copy, Debug)]
pub enum MeasuringSensors {
    /// A trailing swivel carriage (seed 004): its two wheels, and the swivel angle on the
    /// absolute encoder, whose pins show the code in `abs`'s output format.
    Carriage {
        geometry: CarriageGeometry,
        abs: AbsLayout,
    },
    /// Two measuring wheels fixed to the body; the absolute-encoder pins read nothing.
    Wheels {
        wheels: [Wheel; 2],
        metres_per_count: [f64; 2],
    },
}

/// Whether the slave board has inputs for a robot's sensors: its timers' two quadrature
/// inputs and eight absolute-encoder lines (what `record` and the virtual board need; `play`
/// feeds any layout).
pub fn slave_board_reads(layout: &Layout) -> Result<(), String> {
    if layout.encoders() != 2 {
        return Err(format!(
            "the slave board reads 2 quadrature encoders, this robot has {} (play its streams \
             instead: play feeds any layout)",
            layout.encoders()
        ));
    }
    if let Some(abs) = layout.abs().filter(|a| a.bits > 8) {
        return Err(format!(
            "the slave board has 8 absolute-encoder pins, the robot's absolute encoder has {} \
             bits",
            abs.bits
        ));
    }
    Ok(())
}

impl MeasuringSensors {
    /// Seed 004's carriage and its E6CP-AG5C.
    pub const SEED_004: MeasuringSensors = MeasuringSensors::Carriage {
        geometry: CarriageGeometry::SEED_004,
        abs: AbsLayout::E6CP_AG5C,
    };

    /// The sensors a robot's odometry layout describes, if the slave board can read them: two
    /// quadrature encoders, and an absolute encoder of at most 8 bits (its 8 input pins).
    pub fn from_layout(layout: &Layout) -> Result<Self, String> {
        slave_board_reads(layout)?;
        let [w0, w1, ..] = *layout.wheels();
        let [k0, k1, ..] = *layout.metres_per_count();
        match (layout.carriage_geometry(), layout.abs()) {
            (Some(geometry), Some(abs)) => {
                let on_axle = |w: Wheel| w.x.abs() < 1e-12 && (w.ux - 1.0).abs() < 1e-12;
                if !(on_axle(w0) && on_axle(w1) && (w0.y + w1.y).abs() < 1e-12 && w0.y > 0.0) {
                    return Err(
                        "a simulated carriage has its wheels left and right on the axle \
                                through the carriage origin, rolling along +x"
                            .into(),
                    );
                }
                Ok(MeasuringSensors::Carriage { geometry, abs })
            }
            (Some(_), None) => Err("a carriage needs its swivel encoder".into()),
            (None, _) => Ok(MeasuringSensors::Wheels {
                wheels: [w0, w1],
                metres_per_count: [k0, k1],
            }),
        }
    }

    /// Travel per count of the two encoders, metres.
    pub fn metres_per_count(&self) -> [f64; 2] {
        match *self {
            MeasuringSensors::Carriage { geometry, .. } => geometry.metres_per_count,
            MeasuringSensors::Wheels {
                metres_per_count, ..
            } => metres_per_count,
        }
    }
}
