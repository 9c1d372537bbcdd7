//! Simulation: the robot (plant), the seed trajectories, the exact tick generator, and the
//! emulator that runs both boards' firmware against the plant on virtual time.

pub mod adapter;
pub mod emulator;
pub mod generate;
pub mod master_tasks;
pub mod misbehaving;
pub mod plant;
pub mod serial_noise;
pub mod trajectory;
pub mod virtual_board;
