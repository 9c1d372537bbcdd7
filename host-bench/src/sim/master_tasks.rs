//! The master firmware's tasks on the emulation's executor, as the board spawns them
//! (firmware-master's `main.rs`): [`tasks::start`], then each of the four a task of its own,
//! so a wake-up polls only the task it is for, on the board and here alike.

use embedded_io_async::{Read, Write};
use firmware_master::ports::{MotorDrivers, MotorEncoders, SerialRate, SlaveBus};
use firmware_master::{tasks, MasterConfig, MasterShared};
use virtual_time::Simulation;

/// The master's ports and state, as its tasks take them.
pub struct MasterPorts<'a, B, R, T, M, E> {
    pub bus: B,
    pub serial_rx: R,
    pub serial_tx: T,
    pub motors: M,
    pub encoders: E,
    pub shared: &'a MasterShared,
    pub config: &'a MasterConfig,
}

/// Start the master and spawn its four tasks on `sim`. A drive geometry the controller cannot
/// run starts no task (the motors stopped), as on the board.
pub fn spawn_master<'a, B, R, T, M, E>(
    sim: &mut Simulation<'a>,
    ports: MasterPorts<'a, B, R, T, M, E>,
) where
    B: SlaveBus + 'a,
    R: Read + 'a,
    T: Write + SerialRate + 'a,
    M: MotorDrivers + 'a,
    E: MotorEncoders + 'a,
{
    let MasterPorts {
        bus,
        serial_rx,
        serial_tx,
        mut motors,
        encoders,
        shared,
        config,
    } = ports;
    if !tasks::start(&mut motors, shared, config) {
        return;
    }
    sim.spawn(async move {
        tasks::host_rx_task(serial_rx, shared).await;
    });
    sim.spawn(async move {
        tasks::host_tx_task(serial_tx, shared, config).await;
    });
    sim.spawn(async move {
        tasks::slave_poll_task(bus, shared, config).await;
    });
    sim.spawn(async move {
        tasks::control_task(motors, encoders, shared, config).await;
    });
}
