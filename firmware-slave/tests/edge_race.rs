//! Tick-timestamp mode's cross-check of decoded edges against the hardware counters must not
//! be fooled by an edge that arrives between reading the sensors and draining the edge queue.
//!
//! The fake board here makes an encoder edge arrive right after *every* sensor read (the
//! counters and the absolute encoder): exactly the window where the slave used to read the
//! timers in one step and drain the queue in another, so the decoded count ran one ahead of
//! the timers and the slave flagged `EDGES_LOST` with nothing lost. The edge port's drain
//! now hands over the counters read together with the edges (as the board's critical section
//! does): no false alarm. The control run hands over counters read before that edge (the old
//! two-step read) and must raise the flag, so the check is shown to be live.

use std::cell::RefCell;
use std::rc::Rc;

use embassy_time::{Duration, Instant};
use firmware_slave::ports::{
    AbsoluteEncoderPins, EdgeBatch, EncoderEdge, EncoderEdges, QuadratureCounters, MEASURING_WHEELS,
};
use firmware_slave::{odometry_task, SlaveConfig, SlaveShared};
use protocol::spi::slave_status;
use robot_math::sensors::{binary_to_gray, QuadratureDecoder};
use virtual_time::Simulation;

#[derive(Default)]
struct Board {
    /// What the timers have counted.
    count: [i64; MEASURING_WHEELS],
    /// Edges recorded and not yet drained.
    queue: Vec<EncoderEdge>,
    /// The counters as the last sensor read saw them (before the edge that followed it).
    seen_before_edge: [i64; MEASURING_WHEELS],
    /// Control: the drain reports `seen_before_edge` instead of the counters it cut at.
    stale_counters: bool,
}

impl Board {
    /// Wheel 0 moves one count forward now.
    fn edge(&mut self) {
        self.seen_before_edge = self.count;
        self.count[0] += 1;
        self.queue.push(EncoderEdge {
            t_us: Instant::now().as_micros(),
            encoder: 0,
            levels: QuadratureDecoder::levels_at(self.count[0]),
        });
    }
}

type Shared = Rc<RefCell<Board>>;

struct Counters(Shared);
struct Edges(Shared);
struct Abs(Shared);

impl QuadratureCounters for Counters {
    fn read_raw(&mut self) -> [u16; MEASURING_WHEELS] {
        let mut b = self.0.borrow_mut();
        let raw = b.count.map(|c| c as u16);
        b.edge();
        raw
    }
}

impl AbsoluteEncoderPins for Abs {
    fn read_levels(&mut self) -> u8 {
        self.0.borrow_mut().edge();
        // Swivel at position 0: inverted Gray code of 0.
        !(binary_to_gray(0) as u8)
    }
}

impl EncoderEdges for Edges {
    fn levels(&mut self) -> [u8; MEASURING_WHEELS] {
        self.0.borrow().count.map(QuadratureDecoder::levels_at)
    }

    fn drain(&mut self, mut f: impl FnMut(EncoderEdge)) -> EdgeBatch {
        let (edges, counters) = {
            let mut b = self.0.borrow_mut();
            let counters = if b.stale_counters {
                b.seen_before_edge
            } else {
                b.count
            };
            (std::mem::take(&mut b.queue), counters.map(|c| c as u16))
        };
        for e in edges {
            f(e);
        }
        EdgeBatch {
            complete: true,
            counters: Some(counters),
        }
    }
}

/// Counts of wheel 0 the slave's pose stands for. Only the left wheel of seed 004's carriage
/// moves and the swivel stays at 0, so the body turns clockwise by one count's travel over the
/// wheel base per count (exact interpolates to the update instant: not always a whole count).
fn counts_in_pose(config: &SlaveConfig, heading_rad: f64) -> f64 {
    let geometry = config
        .layout()
        .carriage_geometry()
        .expect("the board runs seed 004's carriage");
    -heading_rad * geometry.wheel_base / geometry.metres_per_count[0]
}

/// Run the odometry task for 50 updates; the OR of every frame's status, and the count of
/// wheel 0 the slave's pose stands for with the board's count.
fn run(stale_counters: bool) -> (u16, f64, i64) {
    let board: Shared = Rc::new(RefCell::new(Board {
        stale_counters,
        ..Board::default()
    }));
    let shared = SlaveShared::new();
    let config = SlaveConfig::DEFAULT;
    assert_eq!(config.sensor, firmware_slave::SensorMode::TickTimestamps);
    let mut sim = Simulation::new().expect("one simulation per thread");
    let task = odometry_task(
        Counters(board.clone()),
        Edges(board.clone()),
        Abs(board.clone()),
        &shared,
        &config,
        firmware_slave::FrameClock::start(),
        firmware_slave::ports::NoCycles,
    );
    sim.spawn(async move {
        task.await;
    });
    let mut status = 0;
    for _ in 0..50 {
        sim.run_for(Duration::from_millis(1));
        status |= shared.frame().status;
    }
    let counted = counts_in_pose(&config, shared.pose().theta);
    let count = board.borrow().count[0];
    drop(sim);
    (status, counted, count)
}

#[test]
fn an_edge_between_sensor_reads_and_the_drain_is_not_a_lost_edge() {
    let (status, pose_count, board_count) = run(false);
    assert_ne!(status & slave_status::RUNNING, 0);
    assert_eq!(status & slave_status::EDGES_LOST, 0, "status {status:#x}");
    // Edges kept arriving (one per read): the slave counted them.
    assert!(pose_count >= 50.0, "{pose_count}");
    assert!(
        (board_count as f64 - pose_count).abs() <= 2.0,
        "{board_count} vs {pose_count}"
    );
}

#[test]
fn counters_read_apart_from_the_edges_would_raise_the_flag() {
    let (status, _, _) = run(true);
    assert_ne!(status & slave_status::EDGES_LOST, 0, "status {status:#x}");
}
