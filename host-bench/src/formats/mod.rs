//! The bench's files: robot descriptions (`docs/robot-format.md`), scenarios
//! (`docs/scenario-format.md`) and tick streams
//! (`docs/tick-stream.md`), each read strictly (every error names its line) and written
//! atomically.

pub mod atomic;
pub mod bounded_file;
pub mod drive_geometry;
pub mod odometry_layout;
pub mod robot;
pub mod run_robot;
pub mod scenario;
pub mod tickstream;
pub mod toml_file;
