//! A recording shown as it goes (`record --mcap`, `--live`): what was collected since the last
//! look, as the view's messages, on the board's clock.

use std::cell::RefCell;
use std::collections::VecDeque;

use anyhow::Result;

use super::collect::Collected;
use crate::formats::tickstream::Event as Row;
use crate::serial::link::Link;
use crate::viewer::View;

/// How far the view has been told.
#[derive(Default)]
pub(super) struct Shown {
    rows: usize,
    board: usize,
    counts: Vec<i64>,
    /// The board's time of the last tick or pose shown.
    board_ns: u64,
    /// Truth rows (the virtual board's, over the serial link) not shown yet: they arrive ahead
    /// of the reports that carry the ticks and poses of the same time, and wait for them so
    /// every message is logged at its own time.
    truth: VecDeque<(u64, (f64, f64, f64))>,
}

/// Truth rows held back at most, should the reports stop.
const MAX_HELD: usize = 1000;

impl Shown {
    /// The rows and board poses collected since the last call, and the link's counters.
    pub fn show(&mut self, view: &RefCell<View>, c: &Collected, link: &Link) -> Result<()> {
        let mut view = view.borrow_mut();
        if !view.is_on() {
            return Ok(());
        }
        let mut ticked = false;
        for r in &c.rows[self.rows..] {
            match *r {
                Row::Tick {
                    t_ns,
                    encoder,
                    step,
                } => {
                    let e = encoder as usize;
                    if self.counts.len() <= e {
                        self.counts.resize(e + 1, 0);
                    }
                    self.counts[e] += i64::from(step);
                    self.board_ns = self.board_ns.max(t_ns);
                    ticked = true;
                }
                Row::Truth {
                    t_ns,
                    x_m,
                    y_m,
                    theta_rad,
                } => self.truth.push_back((t_ns, (x_m, y_m, theta_rad))),
                Row::Abs { .. } => {}
            }
        }
        self.rows = c.rows.len();
        let poses = &c.board[self.board..];
        let posed = !poses.is_empty();
        self.board = c.board.len();
        if let Some((t, _)) = poses.last() {
            self.board_ns = self.board_ns.max(*t);
        }
        // The poses and the truth rows up to the board's time, merged by time.
        let mut poses = poses.iter().peekable();
        loop {
            let due = |t: u64, held: usize| t <= self.board_ns || held > MAX_HELD;
            let truth_t = (self.truth.front())
                .map(|(t, _)| *t)
                .filter(|t| due(*t, self.truth.len()));
            let truth_first = match (truth_t, poses.peek().map(|(t, _)| *t)) {
                (Some(r), Some(p)) => r <= p,
                (r, _) => r.is_some(),
            };
            if truth_first {
                let (t, pose) = self.truth.pop_front().expect("peeked");
                let t = t as f64 * 1e-9;
                view.transform("/tf", "robot", t, pose)?;
                view.pose("/truth/pose", t, pose)?;
            } else if let Some((t, pose)) = poses.next() {
                view.pose("/board/pose", *t as f64 * 1e-9, pose.to_si())?;
            } else {
                break;
            }
        }
        let t = self.board_ns as f64 * 1e-9;
        if ticked {
            view.json(
                "/encoders",
                t,
                &serde_json::json!({"counts": self.counts, "edges": c.ticks}),
            )?;
        }
        if ticked || posed {
            view.json(
                "/link",
                t,
                &link.view_counters(serde_json::json!({
                    "lost_events": c.lost_events,
                    "lost_updates": c.lost_updates,
                })),
            )?;
        }
        Ok(())
    }
}
