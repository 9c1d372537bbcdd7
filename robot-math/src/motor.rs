//! A brushed DC gear motor driving one wheel, as the emulator's plant runs it.
//!
//! Per wheel, at the wheel shaft (ω rad/s):
//!
//! ```text
//! u = duty · V_supply           (0 inside the driver's dead band)
//! i = (u − k·N·ω) / R            (winding: back-EMF k·N·ω; inductance neglected, L/R ≈ 1 ms)
//! J·dω/dt = N·k·i − b·ω − τc·sgn ω   (τc: Coulomb friction, which also holds a stopped wheel)
//! ```
//!
//! With the duty held, that is linear in ω between stops, so a step follows its exact
//! exponential (no integration error), and a wheel that reaches zero stays there unless the
//! drive torque beats the friction. Each wheel carries its share of the robot's mass in `J`:
//! the wheels are treated as independent, which holds when the drive is symmetric and the
//! motion smooth; it is not a rigid-body model of the chassis.

/// One motor, its gearbox, its wheel and its driver.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DcMotor {
    /// Supply voltage at full duty, V.
    pub supply_v: f64,
    /// Winding resistance, ohm.
    pub resistance_ohm: f64,
    /// Torque constant = back-EMF constant, N·m/A = V·s/rad (motor side).
    pub torque_constant: f64,
    /// Motor turns per wheel turn.
    pub gear_ratio: f64,
    pub wheel_radius_m: f64,
    /// Inertia at the wheel shaft: rotor·N² + wheel + this wheel's share of the robot, kg·m².
    pub inertia_kg_m2: f64,
    /// Viscous friction at the wheel shaft, N·m·s/rad.
    pub viscous_nm_s: f64,
    /// Coulomb (dry) friction at the wheel shaft, N·m.
    pub coulomb_nm: f64,
    /// The driver outputs nothing below this duty (a fraction of full), e.g. its minimum pulse.
    pub dead_band: f64,
}

impl DcMotor {
    /// The drive motors of the seed robots (robots/seed00{2,3,4}.toml `[motor]`). The seeds
    /// name none, so these are ours, in the range of a 12 V, 30:1, 37 mm gear motor's data
    /// sheet (stall ~5 A and ~1.4 N·m at the shaft, no-load ~350 rpm): R = 2.4 Ω,
    /// k = 0.0095 V·s/rad, a 60 mm wheel, J = 0.002 kg·m² (rotor·N² ~0.0009 plus a third of a
    /// 3.5 kg robot at r²), gearbox friction 0.08 N·m (the wheel breaks away at ~6 % duty) and a
    /// driver dead band of 4 %. That gives 1.18 m/s at full duty and a 58 ms time constant.
    pub const SEED_004: DcMotor = DcMotor {
        supply_v: 12.0,
        resistance_ohm: 2.4,
        torque_constant: 0.0095,
        gear_ratio: 30.0,
        wheel_radius_m: 0.03,
        inertia_kg_m2: 0.002,
        viscous_nm_s: 0.0005,
        coulomb_nm: 0.08,
        dead_band: 0.04,
    };

    /// The same motor without friction or dead band: speed exactly proportional to duty, for
    /// tests and benches that drive open loop and score something else (the sensors).
    pub const fn frictionless(self) -> DcMotor {
        DcMotor {
            coulomb_nm: 0.0,
            dead_band: 0.0,
            ..self
        }
    }

    /// Voltage the driver applies for a duty in [-1, 1].
    pub fn voltage(&self, duty: f64) -> f64 {
        let duty = duty.clamp(-1.0, 1.0);
        if libm::fabs(duty) <= self.dead_band {
            0.0
        } else {
            duty * self.supply_v
        }
    }

    /// Damping of the wheel speed: viscous plus the back-EMF's electrical braking, N·m·s/rad.
    fn damping(&self) -> f64 {
        let kn = self.torque_constant * self.gear_ratio;
        self.viscous_nm_s + kn * kn / self.resistance_ohm
    }

    /// Mechanical time constant J / damping, seconds.
    pub fn time_constant_s(&self) -> f64 {
        self.inertia_kg_m2 / self.damping()
    }

    /// Torque at the wheel from the applied voltage alone (the motor at a standstill).
    fn drive_torque(&self, duty: f64) -> f64 {
        self.torque_constant * self.gear_ratio * self.voltage(duty) / self.resistance_ohm
    }

    /// Steady rim speed at a duty (m/s), friction included: what "speed at full duty" means.
    pub fn steady_speed(&self, duty: f64) -> f64 {
        let drive = self.drive_torque(duty);
        if libm::fabs(drive) <= self.coulomb_nm {
            return 0.0;
        }
        let net = drive - self.coulomb_nm * drive.signum();
        net / self.damping() * self.wheel_radius_m
    }

    /// The factor by which a speed's distance from its steady value shrinks in `h` seconds:
    /// what [`speed_after_decay`](Self::speed_after_decay) takes, so a simulation stepping on
    /// a fixed step pays for the exponential once, not per wheel and stage.
    pub fn decay(&self, h: f64) -> f64 {
        libm::exp(-h / self.time_constant_s())
    }

    /// Rim speed after `h` seconds at `duty`, from rim speed `v0` (m/s): the exact solution,
    /// stopping (and sticking) where the speed would cross zero.
    pub fn speed_after(&self, v0: f64, duty: f64, h: f64) -> f64 {
        self.speed_after_decay(v0, duty, self.decay(h))
    }

    /// [`speed_after`](Self::speed_after) for a step whose [`decay`](Self::decay) is known.
    pub fn speed_after_decay(&self, v0: f64, duty: f64, decay: f64) -> f64 {
        self.speeds_after_decays(v0, duty, [decay])[0]
    }

    /// [`speed_after_decay`](Self::speed_after_decay) for several decays from one start (the
    /// instants inside a step that an integrator looks at): the drive, the friction's sign
    /// and the steady speed are worked out once, each speed exactly as alone.
    pub fn speeds_after_decays<const N: usize>(
        &self,
        v0: f64,
        duty: f64,
        decays: [f64; N],
    ) -> [f64; N] {
        self.driven_speeds_after_decays(v0, &self.held(duty), decays)
    }

    /// What a duty makes of this motor while it is held: its drive torque and the steady
    /// speeds either way, worked out once. A plant that steps many times at one duty pays
    /// for the divisions in them once (three a wheel and step otherwise).
    pub fn held(&self, duty: f64) -> HeldDuty {
        let drive = self.drive_torque(duty);
        let damping = self.damping();
        // The friction opposes the motion (or at rest the drive): ±coulomb, each exact.
        HeldDuty {
            drive,
            steady_w: [
                (drive - self.coulomb_nm) / damping,
                (drive + self.coulomb_nm) / damping,
            ],
        }
    }

    /// Whether a wheel at rim speed `v0` stays at rest through a step at `held`: standing, with
    /// a drive the stiction holds. [`driven_speeds_after_decays`](Self::driven_speeds_after_decays)
    /// is then all zeros, whatever the decays.
    pub fn held_still(&self, v0: f64, held: &HeldDuty) -> bool {
        v0 / self.wheel_radius_m == 0.0 && libm::fabs(held.drive) <= self.coulomb_nm
    }

    /// [`speeds_after_decays`](Self::speeds_after_decays) at a duty [`held`](Self::held):
    /// the same arithmetic, so the same speeds to the bit.
    pub fn driven_speeds_after_decays<const N: usize>(
        &self,
        v0: f64,
        held: &HeldDuty,
        decays: [f64; N],
    ) -> [f64; N] {
        let r = self.wheel_radius_m;
        let drive = held.drive;
        let w0 = v0 / r;
        // The sign the friction opposes: the motion, or at rest the drive.
        let forward = if w0 != 0.0 { w0 > 0.0 } else { drive >= 0.0 };
        if self.held_still(v0, held) {
            return [0.0; N];
        }
        let w_ss = held.steady_w[usize::from(!forward)];
        decays.map(|decay| {
            let w = w_ss + (w0 - w_ss) * decay;
            // Friction cannot reverse a wheel: crossing zero, it stops (until the next step,
            // which starts from rest and asks whether the drive beats the friction).
            if w0 != 0.0 && w * w0 < 0.0 {
                0.0
            } else {
                w * r
            }
        })
    }
}

/// A duty as a [`DcMotor`] holds it ([`DcMotor::held`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HeldDuty {
    drive: f64,
    /// The steady shaft speed (rad/s) moving forward, and backward.
    steady_w: [f64; 2],
}

#[cfg(test)]
mod tests {
    use super::*;

    const M: DcMotor = DcMotor::SEED_004;

    proptest::proptest! {
        /// A held duty gives the speeds the friction's sign worked out as `signum` of the
        /// motion (or at rest of the drive) gives, to the bit: from rest, either way, across
        /// the dead band and the stiction, and for a motor without friction.
        #[test]
        fn a_held_duty_moves_the_wheel_as_the_duty_itself(
            v0 in proptest::prop_oneof![proptest::strategy::Just(0.0), -3.0f64..3.0],
            duty in -1.2f64..1.2,
            decay in 0.0f64..1.0,
            frictionless in proptest::bool::ANY,
        ) {
            let m = if frictionless { M.frictionless() } else { M };
            let by_signum = {
                let (r, drive) = (m.wheel_radius_m, m.drive_torque(duty));
                let w0 = v0 / r;
                let moving = if w0 != 0.0 { w0.signum() } else { drive.signum() };
                if w0 == 0.0 && libm::fabs(drive) <= m.coulomb_nm {
                    0.0
                } else {
                    let w_ss = (drive - m.coulomb_nm * moving) / m.damping();
                    let w = w_ss + (w0 - w_ss) * decay;
                    if w0 != 0.0 && w * w0 < 0.0 { 0.0 } else { w * r }
                }
            };
            let held = m.driven_speeds_after_decays(v0, &m.held(duty), [decay])[0];
            proptest::prop_assert_eq!(held.to_bits(), by_signum.to_bits());
        }
    }

    #[test]
    fn settles_on_its_steady_speed_and_inside_the_dead_band_does_nothing() {
        let mut v = 0.0;
        for _ in 0..20_000 {
            v = M.speed_after(v, 0.6, 1e-4);
        }
        assert!((v - M.steady_speed(0.6)).abs() < 1e-9, "{v}");
        assert!(M.steady_speed(0.6) > 0.0 && M.steady_speed(-0.6) == -M.steady_speed(0.6));
        assert_eq!(M.speed_after(0.0, M.dead_band, 1.0), 0.0);
        assert_eq!(M.steady_speed(0.0), 0.0);
    }

    #[test]
    fn friction_stops_a_wheel_and_holds_it() {
        let mut v = M.steady_speed(1.0);
        let mut t = 0.0;
        while v != 0.0 {
            v = M.speed_after(v, 0.0, 1e-3);
            t += 1e-3;
            assert!(t < 2.0, "never stops");
        }
        // Stopped for good, and a duty just above the dead band cannot break it free.
        let weak = M.dead_band + 0.001;
        assert!(M.drive_torque(weak) < M.coulomb_nm);
        assert_eq!(M.speed_after(0.0, weak, 1.0), 0.0);
    }

    #[test]
    fn steps_compose_exactly() {
        // One 10 ms step equals a hundred 0.1 ms steps (the solution is exact).
        let one = M.speed_after(0.1, 0.8, 0.01);
        let mut many = 0.1;
        for _ in 0..100 {
            many = M.speed_after(many, 0.8, 1e-4);
        }
        assert!((one - many).abs() < 1e-12, "{one} {many}");
    }
}
