//! What an emulation run is asked to do ([`Options`], [`Faults`]) and the checks on it made
//! before anything runs or is written ([`check_options`]).

use anyhow::{bail, Result};
use firmware_master::MasterConfig;
use firmware_slave::SlaveConfig;
use robot_math::odometry::Layout;
use serde::Serialize;

use super::hw;
use super::Scenario;
use crate::sim::serial_noise::SerialFaults;

/// The longest run, simulated seconds (a week).
pub const MAX_DURATION_S: f64 = 7.0 * 86_400.0;

/// Knobs of an emulation run.
#[derive(Clone, Debug)]
pub struct Options {
    pub duration: f64,
    /// Seeds everything random (encoder phases at power-on).
    pub seed: u64,
    /// Longest physics step, seconds: the steps are as long as this allows with every
    /// firmware read of the plant on a step's end ([`physics_grid`](super::physics_grid)).
    pub plant_step: f64,
    /// Row interval of the log, seconds.
    pub log_period: f64,
    pub baud: u32,
    pub spi_clock_hz: u32,
    pub master: MasterConfig,
    /// The slave board as it powers on (its compiled-in robot: seed 004's carriage).
    pub slave: SlaveConfig,
    /// The robot's measuring encoders: what the plant has, and what the host uploads to the
    /// slave over the protocol (serial → master → SPI, as `play` does on real boards) when
    /// it is not the robot the slave powered on with.
    pub robot_layout: Layout,
    pub faults: Faults,
    /// The odometry algorithm the host asks the slave to run.
    pub algorithm: protocol::spi::OdometryAlgorithm,
    /// Where each measuring-wheel encoder stands within its count at power-on, in counts,
    /// [0, 1) (None: drawn from `seed`). The slave cannot know it ([`Summary::encoder_phase`](super::Summary::encoder_phase)).
    pub encoder_phase: Option<[f64; 2]>,
    /// Where the measuring encoders put their edges: ideal (one count apart), or a
    /// datasheet's errors, each encoder's drawn from `seed` (`EdgeErrors`).
    pub edges: crate::sim::generate::EdgeErrors,
    /// [`run`](super::run) keeps the run's log rows in [`Run::log`](super::Run::log) (about 59 MB per simulated hour). Off,
    /// the run keeps its summary only and its memory stays flat however long it runs;
    /// [`run_logged`](super::run_logged) streams the rows instead.
    pub keep_log: bool,
    /// Where the plant's motors take their duties from: the master (the closed loop), or a
    /// recorded run's ([`fault_check`](super::fault_check)).
    pub duties: hw::DutySource,
}

/// Faults to inject, each at a virtual time in seconds (None: never).
#[derive(Clone, Debug, Default, Serialize)]
pub struct Faults {
    /// The slave loses power: its firmware stops and it answers no more polls.
    pub slave_off_at: Option<f64>,
    /// The slave resets: its firmware stops and, [`SLAVE_BOOT_S`](super::SLAVE_BOOT_S) later, starts again from
    /// power-on (its RAM, clock and counters cleared).
    pub slave_reset_at: Option<f64>,
    /// The host stops sending anything (cable pulled, host program hung).
    pub host_silent_after: Option<f64>,
    /// Bit errors and lost transactions on the SPI wire, at rates per transaction.
    pub spi: hw::SpiFaults,
    /// Noise on the serial line between host and master, per frame, each way.
    #[serde(skip)]
    pub serial: SerialFaults,
}

impl Options {
    /// The scenario's own settings (duration, pursuit period, encoder phases, faults, the
    /// robot's sensors) on the boards' power-on defaults.
    pub fn new(scenario: &Scenario) -> Self {
        let mut master = MasterConfig::DEFAULT;
        if let Some(p) = scenario.pursuit_period_s {
            master.pursuit.period_s = p;
        }
        Options {
            duration: scenario.duration,
            seed: 1,
            plant_step: 1e-3,
            log_period: 0.01,
            baud: 115_200,
            spi_clock_hz: protocol::spi::SPI_CLOCK_HZ,
            master,
            slave: SlaveConfig::DEFAULT,
            robot_layout: scenario.layout,
            faults: scenario.faults.clone(),
            algorithm: protocol::spi::OdometryAlgorithm::Exact,
            encoder_phase: scenario.encoder_phase,
            edges: scenario.encoder_edges,
            keep_log: true,
            duties: hw::DutySource::Master,
        }
    }
}

/// A slave reset the master can tell: not before it has exchanged frames with the slave (it
/// learns the slave's clock from them), and not so late that the reboot and the polls after it
/// do not fit in the run.
pub const RESET_SEEN_AFTER_S: f64 = 0.05;
pub const RESET_SEEN_WITHIN_S: f64 = 0.1;

/// The options' own checks, made before anything runs (or is written).
pub fn check_options(opts: &Options) -> Result<()> {
    // The work is the simulated time: a week is far past any bench run, and keeps a typo from
    // running for ever.
    if !(opts.duration > 0.0 && opts.duration <= MAX_DURATION_S) {
        bail!(
            "--duration must be a number of seconds in (0, {MAX_DURATION_S}], got {:?}",
            opts.duration
        );
    }
    // Each names its flag and its scenario key: the value may come from either.
    for (name, at) in [
        (
            "--fault-slave-off-at (scenario: faults.slave_off_at_s)",
            opts.faults.slave_off_at,
        ),
        (
            "--fault-slave-reset-at (scenario: faults.slave_reset_at_s)",
            opts.faults.slave_reset_at,
        ),
        (
            "--fault-host-silent-after (scenario: faults.host_silent_after_s)",
            opts.faults.host_silent_after,
        ),
    ] {
        if let Some(t) = at.filter(|t| !(*t >= 0.0 && t.is_finite())) {
            bail!("{name} is a simulated time in seconds, >= 0: got {t:?}");
        }
        // A fault after the end would leave a clean run passing for a faulty one.
        if let Some(t) = at.filter(|t| *t >= opts.duration) {
            bail!(
                "{name}: {t:?} s is not within the run (--duration {:?} s): the fault would \
                 never happen",
                opts.duration
            );
        }
    }
    // A slave without power cannot reset: the reset would never be seen, and the run would
    // pass for one that tested it.
    if let (Some(off), Some(reset)) = (opts.faults.slave_off_at, opts.faults.slave_reset_at) {
        if reset >= off {
            bail!(
                "--fault-slave-reset-at {reset:?} s and --fault-slave-off-at {off:?} s \
                 (scenario: faults.slave_reset_at_s, faults.slave_off_at_s) contradict each \
                 other: the slave is off from {off:?} s, so a reset at {reset:?} s never \
                 happens. Reset it before it goes off, or test one fault per run"
            );
        }
    }
    if let Some(t) = opts.faults.slave_reset_at {
        // The master tells a reset by the slave's clock starting again: it must have learned
        // that clock first, and have a few polls after the reboot to see it.
        let (first, last) = (RESET_SEEN_AFTER_S, opts.duration - RESET_SEEN_WITHIN_S);
        if !(first..=last).contains(&t) {
            bail!(
                "--fault-slave-reset-at (scenario: faults.slave_reset_at_s) {t:?} s: a reset \
                 the master can tell falls between \
                 {first} s (before, it is a late power-on: the master has not learned the \
                 slave's clock) and {RESET_SEEN_WITHIN_S} s before the end of the run ({last} s \
                 here)"
            );
        }
    }
    for (name, rate) in [
        ("--fault-spi-corrupt", opts.faults.spi.corrupt),
        ("--fault-spi-drop", opts.faults.spi.drop),
        ("--fault-spi-torn", opts.faults.spi.torn),
        ("--fault-spi-duplicate", opts.faults.spi.duplicate),
        ("--fault-spi-late", opts.faults.spi.late),
        ("--fault-serial-corrupt", opts.faults.serial.corrupt),
        ("--fault-serial-drop", opts.faults.serial.drop),
        ("--fault-serial-duplicate", opts.faults.serial.duplicate),
        ("--fault-serial-delay", opts.faults.serial.delay),
        ("--fault-serial-torn", opts.faults.serial.torn),
    ] {
        if !(0.0..1.0).contains(&rate) {
            bail!("{name} is a probability per transaction or frame, in [0, 1): got {rate}");
        }
    }
    let f = opts.faults.serial;
    if f.total() >= 1.0 {
        bail!("the --fault-serial-* rates must add up to under 1");
    }
    Ok(())
}
