//! A recording shown as it goes (`record --mcap`, `--live`): what was collected since the last
//! look, as the view's messages, on the board's clock.

use anyhow::Result;
use std::cell::RefCell;

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
    last_ns: u64,
}

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
                    self.last_ns = self.last_ns.max(t_ns);
                    ticked = true;
                }
                Row::Truth {
                    t_ns,
                    x_m,
                    y_m,
                    theta_rad,
                } => {
                    let t = t_ns as f64 * 1e-9;
                    view.transform("/tf", "robot", t, (x_m, y_m, theta_rad))?;
                    view.pose("/truth/pose", t, (x_m, y_m, theta_rad))?;
                    self.last_ns = self.last_ns.max(t_ns);
                }
                Row::Abs { .. } => {}
            }
        }
        self.rows = c.rows.len();
        for (t_ns, pose) in &c.board[self.board..] {
            view.pose("/board/pose", *t_ns as f64 * 1e-9, pose.to_si())?;
            self.last_ns = self.last_ns.max(*t_ns);
        }
        let posed = c.board.len() > self.board;
        self.board = c.board.len();
        let t = self.last_ns as f64 * 1e-9;
        if ticked {
            view.json(
                "/encoders",
                t,
                &serde_json::json!({"counts": self.counts, "edges": c.ticks}),
            )?;
        }
        if ticked || posed {
            let s = &link.stats;
            view.json(
                "/link",
                t,
                &serde_json::json!({
                    "baud": link.baud(),
                    "bytes_out": s.bytes_sent,
                    "bytes_in": s.bytes_received,
                    "frames_in": s.frames_received,
                    "frames_rejected": s.frames_rejected,
                    "lost_events": c.lost_events,
                    "lost_updates": c.lost_updates,
                }),
            )?;
        }
        Ok(())
    }
}
