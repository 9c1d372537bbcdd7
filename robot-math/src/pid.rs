//! A wheel-speed PID, one per motor on the master.
//!
//! `duty = ff·v_ref + kp·e + ∫ki·e dt − kd·dv/dt`, clamped to ±1:
//! - feed-forward from the motor constant (`1 / speed at full duty`), so the loop only
//!   corrects what the motor model misses (friction, load, supply sag);
//! - derivative on the *measurement*, so a step in the reference kicks nothing;
//! - anti-windup by conditional integration: the integrator only moves when the output is not
//!   pinned at the clamp in the direction it would push, and its own share is clamped to ±1.

/// Gains in duty per unit: `kp` per m/s, `ki` per m (per m/s·s), `kd` per m/s².
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PidGains {
    pub kp: f64,
    pub ki: f64,
    pub kd: f64,
    /// Duty per m/s of reference: 1 / (rim speed at full duty).
    pub ff: f64,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpeedPid {
    pub gains: PidGains,
    integral: f64,
    last_measured: Option<f64>,
}

impl SpeedPid {
    pub const fn new(gains: PidGains) -> Self {
        SpeedPid {
            gains,
            integral: 0.0,
            last_measured: None,
        }
    }

    /// Forget the integral and the last measurement (motors off: nothing to carry over).
    pub fn reset(&mut self) {
        self.integral = 0.0;
        self.last_measured = None;
    }

    /// The duty in [-1, 1] for a reference and a measured speed (m/s), `dt` seconds after
    /// the last call.
    pub fn update(&mut self, reference: f64, measured: f64, dt: f64) -> f64 {
        let g = self.gains;
        let error = reference - measured;
        let derivative = match self.last_measured {
            Some(last) if dt > 0.0 => (measured - last) / dt,
            _ => 0.0,
        };
        self.last_measured = Some(measured);
        let without_i = g.ff * reference + g.kp * error - g.kd * derivative;
        let pinned = |u: f64| (u >= 1.0 && error > 0.0) || (u <= -1.0 && error < 0.0);
        if !pinned(without_i + self.integral) && dt > 0.0 {
            self.integral = (self.integral + g.ki * error * dt).clamp(-1.0, 1.0);
        }
        (without_i + self.integral).clamp(-1.0, 1.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::motor::DcMotor;

    const MOTOR: DcMotor = DcMotor::SEED_004;

    fn gains() -> PidGains {
        PidGains {
            kp: 1.0,
            ki: 8.0,
            kd: 0.0,
            ff: 1.0 / MOTOR.steady_speed(1.0),
        }
    }

    /// Run the loop at 100 Hz on the motor for `steps`, returning the speed.
    fn run(pid: &mut SpeedPid, v: &mut f64, reference: f64, steps: usize) -> f64 {
        for _ in 0..steps {
            let duty = pid.update(reference, *v, 0.01);
            *v = MOTOR.speed_after(*v, duty, 0.01);
        }
        *v
    }

    #[test]
    fn reaches_a_slow_speed_that_friction_alone_would_miss() {
        // Feed-forward alone at 0.05 m/s lands in the dead band / friction: the robot would
        // stand still. The integrator finds the duty.
        let r = 0.05;
        assert!(MOTOR.steady_speed(gains().ff * r) < 0.5 * r);
        let (mut pid, mut v) = (SpeedPid::new(gains()), 0.0);
        let v = run(&mut pid, &mut v, r, 300);
        assert!((v - r).abs() < 0.002, "{v}");
    }

    #[test]
    fn a_saturated_loop_does_not_wind_up() {
        // Ask for more than the motor can do for 5 s, then for 0.3 m/s: it must come down as
        // a loop that never saturated would, not after unwinding 5 s of error.
        let (mut pid, mut v) = (SpeedPid::new(gains()), 0.0);
        run(&mut pid, &mut v, 5.0, 500);
        assert!(pid.integral.abs() <= 1.0);
        let (mut fresh, mut v_fresh) = (SpeedPid::new(gains()), v);
        let v = run(&mut pid, &mut v, 0.3, 50);
        let v_fresh = run(&mut fresh, &mut v_fresh, 0.3, 50);
        assert!(
            (v - 0.3).abs() < 0.02 && (v - v_fresh).abs() < 0.005,
            "{v} {v_fresh}"
        );
    }

    #[test]
    fn the_derivative_acts_on_the_measurement_only() {
        let mut pid = SpeedPid::new(PidGains { kd: 0.5, ..gains() });
        pid.update(0.0, 0.0, 0.01);
        // A reference step with the measurement unchanged: no derivative kick.
        let u = pid.update(0.4, 0.0, 0.01);
        let expected = gains().ff * 0.4 + gains().kp * 0.4 + gains().ki * 0.4 * 0.01;
        assert!((u - expected).abs() < 1e-12, "{u} {expected}");
    }
}
