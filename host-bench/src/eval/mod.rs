//! Evaluation: odometry replayed over tick streams and scored against truth, the side-by-side
//! accuracy suite over every seed case, and the reports and plots.

pub mod accuracy;
pub mod arc_vs_line;
pub mod board_poses;
pub mod envelope;
pub mod png;
pub mod pursuit_sweep;
pub mod replay;
pub mod replay_checks;
pub mod report;

/// A path in the field, metres (for plots).
pub type FieldPath = Vec<(f64, f64)>;
