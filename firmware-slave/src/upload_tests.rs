//! A robot upload through the odometry task, as the master delivers it: a good one is
//! installed and reported by its fingerprint; a lost part or a changed constant is refused
//! with `ROBOT_REJECTED`, the robot that ran before keeps running, and the next good upload
//! clears the flag.

use embassy_time::Duration;
use protocol::robot::ExactPart;
use protocol::spi::{slave_status, MasterFrame, SlaveCommand};
use robot_math::carriage::CarriageGeometry;
use robot_math::odometry::{AbsLayout, Layout};
use robot_math::sensors::binary_to_gray;
use virtual_time::Simulation;

use crate::ports::{AbsoluteEncoderPins, NoCycles, NoEdges, QuadratureCounters};
use crate::robot_wire::{layout_fingerprint, upload_commands};
use crate::{odometry_task, FrameClock, SlaveConfig, SlaveShared};

struct Still;

impl QuadratureCounters for Still {
    fn read_raw(&mut self) -> [u16; 2] {
        [0; 2]
    }
}

impl AbsoluteEncoderPins for Still {
    fn read_levels(&mut self) -> u8 {
        !(binary_to_gray(0) as u8)
    }
}

struct Master<'a> {
    shared: &'a SlaveShared,
    command_seq: u8,
}

impl Master<'_> {
    /// Send `command` until the slave acknowledges it (one odometry update applies it).
    fn send(&mut self, sim: &mut Simulation, command: SlaveCommand) {
        self.command_seq = self.command_seq.wrapping_add(1);
        let frame = MasterFrame {
            command_seq: self.command_seq,
            command,
            ..MasterFrame::default()
        };
        for _ in 0..10 {
            self.shared.receive(&frame);
            sim.run_for(Duration::from_millis(1));
            if self.shared.frame().command_ack == self.command_seq {
                return;
            }
        }
        panic!("command {command:?} never acknowledged");
    }

    /// The whole upload of `layout`, the commit's header passed through `edit`.
    fn upload(
        &mut self,
        sim: &mut Simulation,
        layout: &Layout,
        mut edit: impl FnMut(SlaveCommand) -> Option<SlaveCommand>,
    ) {
        for command in upload_commands(layout).0 {
            if let Some(c) = edit(command) {
                self.send(sim, c);
            }
        }
    }
}

fn other_carriage() -> Layout {
    let geometry = CarriageGeometry {
        trail: 0.085,
        wheel_base: 0.23,
        ..CarriageGeometry::SEED_004
    };
    Layout::from_carriage(&geometry, AbsLayout::E6CP_AG5C).unwrap()
}

#[test]
fn an_upload_is_installed_whole_or_refused_keeping_the_robot_that_ran() {
    let shared = SlaveShared::new();
    let config = SlaveConfig::DEFAULT;
    let mut sim = Simulation::new().expect("one simulation per thread");
    let task = odometry_task(
        Still,
        NoEdges,
        Still,
        &shared,
        &config,
        FrameClock::start(),
        NoCycles,
    );
    sim.spawn(async move {
        task.await;
    });
    sim.run_for(Duration::from_millis(3));
    let rejected = |shared: &SlaveShared| shared.frame().status & slave_status::ROBOT_REJECTED != 0;
    let power_on = layout_fingerprint(config.layout());
    assert_eq!(shared.frame().robot, power_on);
    assert!(!rejected(&shared));

    let mut master = Master {
        shared: &shared,
        command_seq: 0,
    };
    let other = other_carriage();
    assert_ne!(layout_fingerprint(&other), power_on);

    // A changed constant: the parts no longer hash to the header's fingerprint.
    master.upload(&mut sim, &other, |c| match c {
        SlaveCommand::RobotExact(e) if e.index == 1 => {
            Some(SlaveCommand::RobotExact(ExactPart { kx: e.kx + 1, ..e }))
        }
        c => Some(c),
    });
    assert!(rejected(&shared));
    assert_eq!(shared.frame().robot, power_on);

    // The good upload is installed and clears the flag.
    master.upload(&mut sim, &other, Some);
    assert!(!rejected(&shared));
    assert_eq!(shared.frame().robot, layout_fingerprint(&other));

    // A part lost (the commit finds encoder 1's wheel missing): refused, `other` keeps running.
    master.upload(&mut sim, config.layout(), |c| match c {
        SlaveCommand::RobotWheel(w) if w.index == 1 => None,
        c => Some(c),
    });
    assert!(rejected(&shared));
    assert_eq!(shared.frame().robot, layout_fingerprint(&other));

    // And the power-on robot again, whole.
    master.upload(&mut sim, config.layout(), Some);
    assert!(!rejected(&shared));
    assert_eq!(shared.frame().robot, power_on);
    drop(sim);
}
