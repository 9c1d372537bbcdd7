//! Robot math shared by the firmware, the emulator and the analysis tools.
//!
//! `no_std`, no allocation. Conventions used everywhere in omnibench:
//! * field frame: x, y in metres, heading θ counter-clockwise from +x, radians;
//! * body frame: x forward, y to the left; a twist is (v_x, v_y, ω) in the body frame;
//! * a wheel `i` at r_i = (x_i, y_i) rolling along the unit vector u_i has rolling speed
//!   s_i' = u_ix·v_x + u_iy·v_y + ω·(x_i·u_iy − y_i·u_ix)   (SPEC §2, the general wheel model).
//!
//! Floats (f64) are fine on the host and in the reference (oracle) implementations; the
//! slave's default path ([`exact`], [`carriage::CarriageExact`], [`fixed`], [`ticks`]) is
//! integer-only on every update.
#![cfg_attr(not(test), no_std)]

pub mod arc;
pub mod carriage;
pub mod drive;
pub mod exact;
pub mod fixed;
pub mod in_place;
pub mod lut;
pub mod motor;
pub mod odometry;
pub mod offset_diff;
pub mod omni3;
pub mod pid;
pub mod pursuit;
pub mod se2;
pub mod sensors;
pub mod ticks;
pub mod timing;
pub mod tracking;
pub mod trig;
pub mod wheel;
pub mod wheelset;

pub use se2::{Pose2, Twist};
