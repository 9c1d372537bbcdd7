//! Checking a robot file's values and geometry, and building the [`Robot`].

use std::collections::HashMap;
use std::f64::consts::PI;

use robot_math::wheel::{invert3, Mat3, Wheel};
use toml::Spanned;

use super::super::toml_file::{short, Res, TomlFile};
use super::raw::{RawCarriage, RawCode, RawRobot};
use super::{AbsMeasures, AbsoluteEncoder, Carriage, DriveWheel, Encoder, Robot};

/// Largest distance of any sensor or wheel from the body origin, and largest wheel diameter
/// and trail, metres: a robot, not a field. The fixed-point per-count constants stay far
/// inside their range below this.
pub const MAX_PLACE_M: f64 = 10.0;

/// Shortest and longest count, metres. 0.1 um is finer than any odometry encoder (a 1 m/s
/// wheel then ticks at 10 MHz); 1/16 m is what exact's fixed point takes per count.
pub const COUNT_M: (f64, f64) = (1e-7, 0.0625);

/// Fastest drive wheel, m/s.
pub const MAX_WHEEL_SPEED_M_S: f64 = 100.0;

impl TomlFile<'_> {
    /// A position on the robot, metres, within [`MAX_PLACE_M`] of the body origin.
    fn place(&self, v: &Spanned<f64>, key: &str) -> Res<f64> {
        self.within(v, key, -MAX_PLACE_M, MAX_PLACE_M, "m")
    }

    /// A rolling direction, degrees, within one turn either way.
    fn direction(&self, v: &Spanned<f64>, key: &str) -> Res<f64> {
        self.within(v, key, -360.0, 360.0, "deg")
    }

    /// A count's length in metres (`m`, read at `span`), in [`COUNT_M`].
    fn count_length(&self, span: std::ops::Range<usize>, key: &str, m: f64) -> Res<f64> {
        let (lo, hi) = COUNT_M;
        if m.is_finite() && (lo..=hi).contains(&m) {
            Ok(m)
        } else {
            Err(self.at(
                span,
                key,
                format!(
                    "a count must be {} to {} m of wheel travel, got {} m",
                    short(lo),
                    short(hi),
                    short(m)
                ),
            ))
        }
    }

    pub(super) fn check_robot(&self, raw: RawRobot) -> Res<Robot> {
        let name = self.name(&raw.name, "name")?;

        let mut encoders = Vec::with_capacity(raw.encoders.len());
        let mut names: HashMap<String, usize> = HashMap::new();
        for (i, e) in raw.encoders.iter().enumerate() {
            let k = |f: &str| format!("encoders[{i}].{f}");
            let span = e.span();
            let e = e.get_ref();
            let ename = self.name(&e.name, &k("name"))?;
            if let Some(j) = names.insert(ename.clone(), i) {
                return Err(self.at(
                    e.name.span(),
                    &k("name"),
                    format!("\"{ename}\" is already the name of encoders[{j}]"),
                ));
            }
            let x = self.place(&e.x_m, &k("x_m"))?;
            let y = self.place(&e.y_m, &k("y_m"))?;
            let dir = self.direction(&e.direction_deg, &k("direction_deg"))?;
            let metres_per_count =
                match (&e.metres_per_count, &e.counts_per_rev, &e.wheel_diameter_m) {
                    (Some(m), None, None) => {
                        let v = self.finite(m, &k("metres_per_count"))?;
                        self.count_length(m.span(), &k("metres_per_count"), v)?
                    }
                    (Some(m), _, _) => return Err(self.at(
                        m.span(),
                        &k("metres_per_count"),
                        "give either metres_per_count, or counts_per_rev with wheel_diameter_m, \
                         not both",
                    )),
                    (None, Some(c), Some(d)) => {
                        let counts = *c.get_ref();
                        if !(1..=i64::from(u32::MAX)).contains(&counts) {
                            return Err(self.at(
                                c.span(),
                                &k("counts_per_rev"),
                                format!("must be a whole number of counts > 0, got {counts}"),
                            ));
                        }
                        let d = self.within(d, &k("wheel_diameter_m"), 1e-4, MAX_PLACE_M, "m")?;
                        let m = PI * d / counts as f64;
                        self.count_length(c.span(), &k("counts_per_rev"), m)?
                    }
                    (None, Some(c), None) => {
                        return Err(self.at(
                            c.span(),
                            &k("wheel_diameter_m"),
                            "missing: counts_per_rev needs wheel_diameter_m",
                        ))
                    }
                    (None, None, Some(d)) => {
                        return Err(self.at(
                            d.span(),
                            &k("counts_per_rev"),
                            "missing: wheel_diameter_m needs counts_per_rev",
                        ))
                    }
                    (None, None, None) => return Err(self.at(
                        span,
                        &k("metres_per_count"),
                        "missing: give metres_per_count, or counts_per_rev and wheel_diameter_m",
                    )),
                };
            encoders.push(Encoder {
                name: ename,
                wheel: Wheel::at(x, y, dir.to_radians()),
                metres_per_count,
            });
        }

        let mut absolute_encoders = Vec::with_capacity(raw.absolute_encoders.len());
        let mut abs_names: HashMap<String, usize> = HashMap::new();
        let mut kinds: HashMap<AbsMeasures, usize> = HashMap::new();
        for (i, a) in raw.absolute_encoders.iter().enumerate() {
            let k = |f: &str| format!("absolute_encoders[{i}].{f}");
            let a = a.get_ref();
            let aname = self.name(&a.name, &k("name"))?;
            if let Some(j) = abs_names.insert(aname.clone(), i) {
                return Err(self.at(
                    a.name.span(),
                    &k("name"),
                    format!("\"{aname}\" is already the name of absolute_encoders[{j}]"),
                ));
            }
            let bits = *a.bits.get_ref();
            if !(1..=16).contains(&bits) {
                return Err(self.at(
                    a.bits.span(),
                    &k("bits"),
                    format!("must be 1 to 16, got {bits}"),
                ));
            }
            let measures = *a.measures.get_ref();
            if let Some(j) = kinds.insert(measures, i) {
                return Err(self.at(
                    a.measures.span(),
                    &k("measures"),
                    format!(
                        "absolute_encoders[{j}] already measures {}: at most one of each kind",
                        measures.as_str()
                    ),
                ));
            }
            absolute_encoders.push(AbsoluteEncoder {
                name: aname,
                bits: bits as u8,
                gray: a.code == RawCode::Gray,
                inverted: a.inverted,
                measures,
            });
        }

        let mut drive_wheels = Vec::with_capacity(raw.drive_wheels.len());
        for (i, w) in raw.drive_wheels.iter().enumerate() {
            let k = |f: &str| format!("drive_wheels[{i}].{f}");
            let w = w.get_ref();
            let x = self.place(&w.x_m, &k("x_m"))?;
            let y = self.place(&w.y_m, &k("y_m"))?;
            let dir = self.direction(&w.direction_deg, &k("direction_deg"))?;
            let v_max_m_s = self.within(
                &w.v_max_m_s,
                &k("v_max_m_s"),
                1e-3,
                MAX_WHEEL_SPEED_M_S,
                "m/s",
            )?;
            drive_wheels.push(DriveWheel {
                wheel: Wheel::at(x, y, dir.to_radians()),
                v_max_m_s,
            });
        }

        let carriage =
            match &raw.carriage {
                Some(c) => Some(self.check_carriage(c, &raw, &encoders)?),
                None => {
                    if let Some(a) = raw.absolute_encoders.iter().position(|a| {
                        *a.get_ref().measures.get_ref() == AbsMeasures::CarriageSwivel
                    }) {
                        return Err(self.at(
                            raw.absolute_encoders[a].get_ref().measures.span(),
                            &format!("absolute_encoders[{a}].measures"),
                            "carriage_swivel needs a [carriage] table (there is no carriage)",
                        ));
                    }
                    self.check_encoder_geometry(&raw, &encoders)?;
                    None
                }
            };

        let tracked_point_x_m = match &raw.tracked_point {
            Some(t) => {
                let x = self.place(&t.get_ref().x_m, "tracked_point.x_m")?;
                if x == 0.0 {
                    return Err(self.at(
                        t.get_ref().x_m.span(),
                        "tracked_point.x_m",
                        "must not be 0: a point on the axle cannot move sideways (the tracking \
                         of Dehghan Banadaki, Nili Ahmadabadi and Moaveni Sabet 2005 needs \
                         l != 0)",
                    ));
                }
                Some(x)
            }
            None => None,
        };

        let motor = match &raw.motor {
            Some(m) => Some(self.check_motor(m)?),
            None => None,
        };

        Ok(Robot {
            name,
            description: raw.description.trim().to_string(),
            encoders,
            absolute_encoders,
            carriage,
            drive_wheels,
            tracked_point_x_m,
            motor,
        })
    }

    fn check_motor(&self, m: &Spanned<super::raw::RawMotor>) -> Res<super::Motor> {
        let r = m.get_ref();
        let k = |f: &str| format!("motor.{f}");
        let dead_band = self.non_negative(&r.dead_band, &k("dead_band"))?;
        if dead_band >= 1.0 {
            return Err(self.at(
                r.dead_band.span(),
                &k("dead_band"),
                format!("a fraction of full duty, under 1: got {dead_band}"),
            ));
        }
        let model = robot_math::motor::DcMotor {
            supply_v: self.within(&r.supply_v, &k("supply_v"), 0.1, 1000.0, "V")?,
            resistance_ohm: self.within(
                &r.resistance_ohm,
                &k("resistance_ohm"),
                1e-4,
                1e4,
                "ohm",
            )?,
            torque_constant: self.within(
                &r.torque_constant_nm_per_a,
                &k("torque_constant_nm_per_a"),
                1e-5,
                100.0,
                "N m/A",
            )?,
            gear_ratio: self.within(&r.gear_ratio, &k("gear_ratio"), 0.01, 1e4, "")?,
            wheel_radius_m: self.within(
                &r.wheel_diameter_m,
                &k("wheel_diameter_m"),
                1e-3,
                10.0,
                "m",
            )? / 2.0,
            inertia_kg_m2: self.within(
                &r.inertia_kg_m2,
                &k("inertia_kg_m2"),
                1e-12,
                1e3,
                "kg m^2",
            )?,
            viscous_nm_s: self.within(&r.viscous_nm_s, &k("viscous_nm_s"), 0.0, 1e3, "N m s")?,
            coulomb_nm: self.within(&r.coulomb_nm, &k("coulomb_nm"), 0.0, 1e3, "N m")?,
            dead_band,
        };
        if model.steady_speed(1.0) <= 0.0 {
            return Err(self.at(
                m.span(),
                "motor",
                "at full duty this motor cannot overcome its own friction",
            ));
        }
        Ok(super::Motor {
            model,
            encoder_counts_per_motor_rev: *r.encoder_counts_per_motor_rev.get_ref(),
        })
    }

    fn check_carriage(
        &self,
        c: &Spanned<RawCarriage>,
        raw: &RawRobot,
        encoders: &[Encoder],
    ) -> Res<Carriage> {
        let trail_m = self.within(
            &c.get_ref().trail_m,
            "carriage.trail_m",
            1e-3,
            MAX_PLACE_M,
            "m",
        )?;
        if encoders.len() != 2 {
            return Err(self.at(
                c.span(),
                "carriage",
                format!(
                    "a carriage carries exactly two encoders (left, then right), this file has {}",
                    encoders.len()
                ),
            ));
        }
        if !raw
            .absolute_encoders
            .iter()
            .any(|a| *a.get_ref().measures.get_ref() == AbsMeasures::CarriageSwivel)
        {
            return Err(self.at(
                c.span(),
                "carriage",
                "a carriage needs an absolute encoder with measures = \"carriage_swivel\" \
                 (the body heading is the carriage heading minus the swivel angle)",
            ));
        }
        for (i, e) in raw.encoders.iter().enumerate() {
            let e = e.get_ref();
            let dir = e.direction_deg.get_ref().rem_euclid(360.0);
            if dir.min(360.0 - dir) > 1e-9 {
                return Err(self.at(
                    e.direction_deg.span(),
                    &format!("encoders[{i}].direction_deg"),
                    format!(
                        "must be 0 on a carriage (both measuring wheels roll along the carriage's \
                         +x), got {}",
                        e.direction_deg.get_ref()
                    ),
                ));
            }
            if e.x_m.get_ref().abs() > 1e-9 {
                return Err(self.at(
                    e.x_m.span(),
                    &format!("encoders[{i}].x_m"),
                    format!(
                        "must be 0 on a carriage (the carriage frame's origin is the axle \
                         midpoint), got {}",
                        e.x_m.get_ref()
                    ),
                ));
            }
        }
        let (left, right) = (
            &raw.encoders[0].get_ref().y_m,
            &raw.encoders[1].get_ref().y_m,
        );
        let (yl, yr) = (*left.get_ref(), *right.get_ref());
        if yl <= 0.0 {
            return Err(self.at(
                left.span(),
                "encoders[0].y_m",
                format!("must be > 0 on a carriage (encoder 0 is the left wheel), got {yl}"),
            ));
        }
        if (yl + yr).abs() > 1e-9 {
            return Err(self.at(
                right.span(),
                "encoders[1].y_m",
                format!(
                    "must be -{yl} on a carriage (the right wheel, opposite the left one about \
                     the axle midpoint), got {yr}"
                ),
            ));
        }
        Ok(Carriage { trail_m })
    }

    /// Can the encoders (body frame, no carriage) determine the body's motion?
    fn check_encoder_geometry(&self, raw: &RawRobot, encoders: &[Encoder]) -> Res<()> {
        let Some(first) = raw.encoders.first() else {
            return Ok(()); // no odometry sensors: a description of drive wheels only
        };
        let fail = |message: &str| Err(self.at(first.span(), "encoders", message));
        match encoders {
            [_] => fail(
                "one encoder cannot determine the body's motion: give two on one axle, or three \
                 or more",
            ),
            [a, b] => {
                let (a, b) = (a.wheel, b.wheel);
                let cross = a.ux * b.uy - a.uy * b.ux;
                let dot = a.ux * b.ux + a.uy * b.uy;
                let (dx, dy) = (b.x - a.x, b.y - a.y);
                let lateral = -dx * a.uy + dy * a.ux;
                let along = dx * a.ux + dy * a.uy;
                if cross.abs() > 1e-9 || dot <= 0.0 || lateral.abs() < 1e-9 || along.abs() > 1e-9 {
                    fail(
                        "two encoders must be on one axle: the same direction_deg, side by side \
                         (the line between them perpendicular to the rolling direction)",
                    )
                } else {
                    Ok(())
                }
            }
            _ => {
                let mut jtj: Mat3 = [[0.0; 3]; 3];
                for e in encoders {
                    let r = e.wheel.row();
                    for (i, row) in jtj.iter_mut().enumerate() {
                        for (j, v) in row.iter_mut().enumerate() {
                            *v += r[i] * r[j];
                        }
                    }
                }
                let scale = (jtj[0][0] + jtj[1][1] + jtj[2][2]) / 3.0;
                if scale > 0.0 && invert3(&jtj, 1e-9 * scale * scale * scale).is_some() {
                    Ok(())
                } else {
                    fail(
                        "these encoders cannot determine the body's motion (their kinematic \
                         matrix has rank < 3: e.g. all rolling the same way, or all rolling \
                         lines through one point)",
                    )
                }
            }
        }
    }
}
