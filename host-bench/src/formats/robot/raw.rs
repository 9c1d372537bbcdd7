//! The robot file as written (before checking). Every value keeps its span for error messages.

use serde::Deserialize;
use toml::Spanned;

use super::AbsMeasures;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawRobot {
    // Checked before these structs are deserialized; kept so that it is a known key.
    #[allow(dead_code)]
    pub(super) format: Spanned<String>,
    pub(super) name: Spanned<String>,
    #[serde(default)]
    pub(super) description: String,
    #[serde(default)]
    pub(super) encoders: Vec<Spanned<RawEncoder>>,
    #[serde(default)]
    pub(super) absolute_encoders: Vec<Spanned<RawAbsolute>>,
    pub(super) carriage: Option<Spanned<RawCarriage>>,
    #[serde(default)]
    pub(super) drive_wheels: Vec<Spanned<RawDriveWheel>>,
    pub(super) tracked_point: Option<Spanned<RawTrackedPoint>>,
    pub(super) motor: Option<Spanned<RawMotor>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawMotor {
    pub(super) supply_v: Spanned<f64>,
    pub(super) resistance_ohm: Spanned<f64>,
    pub(super) torque_constant_nm_per_a: Spanned<f64>,
    pub(super) gear_ratio: Spanned<f64>,
    pub(super) wheel_diameter_m: Spanned<f64>,
    pub(super) inertia_kg_m2: Spanned<f64>,
    pub(super) viscous_nm_s: Spanned<f64>,
    pub(super) coulomb_nm: Spanned<f64>,
    pub(super) dead_band: Spanned<f64>,
    pub(super) encoder_counts_per_motor_rev: Spanned<u32>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawTrackedPoint {
    pub(super) x_m: Spanned<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawEncoder {
    pub(super) name: Spanned<String>,
    pub(super) x_m: Spanned<f64>,
    pub(super) y_m: Spanned<f64>,
    pub(super) direction_deg: Spanned<f64>,
    pub(super) metres_per_count: Option<Spanned<f64>>,
    pub(super) counts_per_rev: Option<Spanned<i64>>,
    pub(super) wheel_diameter_m: Option<Spanned<f64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawAbsolute {
    pub(super) name: Spanned<String>,
    pub(super) bits: Spanned<i64>,
    pub(super) code: RawCode,
    #[serde(default)]
    pub(super) inverted: bool,
    pub(super) measures: Spanned<AbsMeasures>,
}

#[derive(Deserialize, Clone, Copy, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub(super) enum RawCode {
    Gray,
    Binary,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawCarriage {
    pub(super) trail_m: Spanned<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawDriveWheel {
    pub(super) x_m: Spanned<f64>,
    pub(super) y_m: Spanned<f64>,
    pub(super) direction_deg: Spanned<f64>,
    pub(super) v_max_m_s: Spanned<f64>,
}
