//! Three driven omni wheels 120° apart (seed 003).
//!
//! Wheel speeds `[v1 v2 v3] = M · [v_x v_y ω]` with rows (0, 1, d), (−sin 60°, −cos 60°, d),
//! (sin 60°, −cos 60°, d): wheel 1 sits at (d, 0) rolling along +y, wheels 2 and 3 at 120° and
//! 240° around the centre. These are exactly the rows of the general wheel model for those
//! positions and directions, so `M` is built from [`Wheel`]s rather than typed in.

use crate::wheel::{invert3, mul3, Mat3, Wheel};
use crate::Twist;
use core::f64::consts::PI;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Omni3 {
    /// Distance from the centre to each wheel's contact point, metres.
    pub d: f64,
    /// Highest wheel rolling speed, m/s.
    pub v_max: f64,
    m: Mat3,
    m_inv: Mat3,
}

impl Omni3 {
    /// Seed 003's layout. Returns `None` for `d <= 0` or `v_max <= 0`.
    pub fn new(d: f64, v_max: f64) -> Option<Self> {
        if !(d > 0.0 && v_max > 0.0) {
            return None;
        }
        let wheels = Self::wheels(d);
        let m = [wheels[0].row(), wheels[1].row(), wheels[2].row()];
        let m_inv = invert3(&m, 1e-12)?;
        Some(Omni3 { d, v_max, m, m_inv })
    }

    /// The three wheels: at angles 0°, 120°, 240° around the centre, each rolling
    /// tangentially (counter-clockwise).
    pub fn wheels(d: f64) -> [Wheel; 3] {
        core::array::from_fn(|i| {
            let a = i as f64 * 2.0 * PI / 3.0;
            Wheel::at(
                d * crate::trig::cos(a),
                d * crate::trig::sin(a),
                a + PI / 2.0,
            )
        })
    }

    /// Inverse kinematics: wheel speeds for a body twist (no saturation).
    pub fn wheel_speeds(&self, t: Twist) -> [f64; 3] {
        mul3(&self.m, [t.vx, t.vy, t.omega])
    }

    /// Forward kinematics: the body twist that the three wheel speeds produce (`M⁻¹`).
    pub fn twist(&self, w: [f64; 3]) -> Twist {
        let v = mul3(&self.m_inv, w);
        Twist::new(v[0], v[1], v[2])
    }

    /// Inverse kinematics with direction-keeping saturation: when any wheel would exceed
    /// `v_max`, the whole command is scaled down by the same factor, so the robot still moves
    /// in the commanded direction with the commanded ratio of spin to translation.
    /// Returns the wheel speeds and the scale applied (1 when nothing saturated).
    pub fn wheel_speeds_saturated(&self, t: Twist) -> ([f64; 3], f64) {
        let w = self.wheel_speeds(t);
        let peak = w.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        if peak <= self.v_max {
            return (w, 1.0);
        }
        let k = self.v_max / peak;
        (w.map(|v| v * k), k)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn omni() -> Omni3 {
        Omni3::new(0.22, 1.0).unwrap()
    }

    #[test]
    fn rows_are_seed_003s_matrix() {
        let o = omni();
        let s60 = (PI / 3.0).sin();
        let c60 = (PI / 3.0).cos();
        let expect = [[0.0, 1.0, 0.22], [-s60, -c60, 0.22], [s60, -c60, 0.22]];
        for (r, e) in o.m.iter().zip(expect.iter()) {
            for (a, b) in r.iter().zip(e.iter()) {
                assert!((a - b).abs() < 1e-12, "{:?} vs {:?}", o.m, expect);
            }
        }
    }

    #[test]
    fn spin_rate_is_mean_wheel_speed_over_d() {
        let o = omni();
        let t = o.twist([0.3, -0.1, 0.5]);
        assert!((t.omega - (0.3 - 0.1 + 0.5) / (3.0 * 0.22)).abs() < 1e-12);
    }

    #[test]
    fn forward_inverts_inverse() {
        let o = omni();
        let t = Twist::new(0.4, -0.2, 1.3);
        let back = o.twist(o.wheel_speeds(t));
        assert!(
            (back.vx - t.vx).abs() < 1e-12
                && (back.vy - t.vy).abs() < 1e-12
                && (back.omega - t.omega).abs() < 1e-12
        );
    }

    #[test]
    fn pure_translation_tops_out_at_2_vmax_over_sqrt3() {
        // Along a wheel axis direction the best case is 2·v_max/√3 (seed 003).
        let o = omni();
        let best = (0..3600)
            .map(|i| {
                let a = i as f64 * 2.0 * PI / 3600.0;
                let (w, k) =
                    o.wheel_speeds_saturated(Twist::new(10.0 * a.cos(), 10.0 * a.sin(), 0.0));
                assert!(w.iter().all(|v| v.abs() <= o.v_max + 1e-12));
                10.0 * k
            })
            .fold(0.0f64, f64::max);
        assert!((best - 2.0 / 3f64.sqrt()).abs() < 1e-6, "{best}");
    }

    #[test]
    fn saturation_keeps_direction() {
        let o = omni();
        let t = Twist::new(3.0, 1.0, 2.0);
        let (w, k) = o.wheel_speeds_saturated(t);
        assert!(k < 1.0);
        let back = o.twist(w);
        assert!((back.vx / back.vy - 3.0).abs() < 1e-9);
        assert!((back.omega / back.vx - 2.0 / 3.0).abs() < 1e-9);
    }
}
