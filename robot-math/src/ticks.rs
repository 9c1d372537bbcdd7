//! Tick-timestamp mode: where each wheel is *between* its ticks.
//!
//! With edge interrupts or input capture the slave knows when every count happened. An ideal
//! encoder ticks when its wheel's rolling distance crosses a multiple of its step, so at a
//! tick the wheel is exactly on that edge; between ticks it is somewhere in the next step.
//! Integrating only at tick instants with whole counts lets the wheels that have not ticked
//! yet lag by up to a step, and that lag turns into heading error. Interpolating each wheel
//! to the update instant from its last tick interval (seed 000's speed estimate, Δ / interval)
//! removes most of it; the estimate is clamped so it never passes the next edge (no tick has
//! said so) and is corrected by the next real tick, so its errors do not accumulate.
//!
//! Integer-only: times in nanoseconds, positions in Q16 counts.

/// One wheel's tick history.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TickTracker {
    /// Cumulative count after the last tick.
    count: i64,
    /// The edge (multiple of the step, in counts) the last tick crossed.
    edge: i64,
    last_t: Option<u64>,
    /// Interval between the last two ticks, when they went the same way.
    interval: Option<u64>,
    dir: i8,
}

/// The interpolated fraction never reaches a whole step: 1 - 2^-16.
const MAX_FRACTION: i64 = 0xFFFF;

impl TickTracker {
    pub const fn new() -> Self {
        TickTracker {
            count: 0,
            edge: 0,
            last_t: None,
            interval: None,
            dir: 0,
        }
    }

    /// A tick at `t_ns`, `step` = +1 or -1 (anything else is ignored: a corrupt event must
    /// not move the count by more than one).
    pub fn tick(&mut self, t_ns: u64, step: i8) {
        if step != 1 && step != -1 {
            return;
        }
        // Forward to count m crosses edge m; backward to count m - 1 crosses edge m too.
        self.edge = if step > 0 { self.count + 1 } else { self.count };
        self.count += step as i64;
        self.interval = match self.last_t {
            Some(prev) if self.dir == step && t_ns > prev => Some(t_ns - prev),
            _ => None,
        };
        self.last_t = Some(t_ns);
        self.dir = step;
    }

    /// Cumulative whole counts.
    pub fn count(&self) -> i64 {
        self.count
    }

    /// Best estimate of the wheel's position at `t_ns` (not before the last tick), Q16 counts.
    /// Before the first tick, and after a reversal until a second tick in the new direction,
    /// there is no speed to go on: the wheel is taken to be at its last edge (or count).
    pub fn position_q16(&self, t_ns: u64) -> i64 {
        let (Some(last), Some(interval)) = (self.last_t, self.interval) else {
            return match self.last_t {
                Some(_) => self.edge << 16,
                None => self.count << 16,
            };
        };
        let since = t_ns.saturating_sub(last);
        // (since / interval) in Q16, clamped below one step. `since < interval < 2^47` keeps
        // the shift in range (an interval of 39 hours is a stopped wheel anyway).
        let frac = if since >= interval || interval >= 1 << 47 {
            MAX_FRACTION
        } else {
            (((since << 16) / interval) as i64).min(MAX_FRACTION)
        };
        (self.edge << 16) + self.dir as i64 * frac
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constant_speed_is_interpolated_exactly() {
        let mut w = TickTracker::new();
        // Edges every 1 ms, moving forward.
        for k in 1..=5u64 {
            w.tick(k * 1_000_000, 1);
        }
        assert_eq!(w.count(), 5);
        assert_eq!(w.position_q16(5_000_000), 5 << 16);
        assert_eq!(w.position_q16(5_250_000), (5 << 16) + (1 << 14));
        // Never past the next edge, however long the wheel is silent.
        assert_eq!(w.position_q16(99_000_000), (5 << 16) + MAX_FRACTION);
    }

    #[test]
    fn backward_ticks_sit_on_the_upper_edge() {
        let mut w = TickTracker::new();
        w.tick(1_000, 1); // count 1, on edge 1
        w.tick(2_000, -1); // back over edge 1: count 0, position 1
        assert_eq!(w.count(), 0);
        assert_eq!(
            w.position_q16(2_500),
            1 << 16,
            "no speed yet after a reversal"
        );
        w.tick(3_000, -1); // over edge 0: count -1, position 0
        assert_eq!(w.position_q16(3_000), 0);
        assert_eq!(w.position_q16(3_500), -(1 << 15));
    }

    #[test]
    fn corrupt_steps_are_ignored() {
        let mut w = TickTracker::new();
        w.tick(1, 3);
        w.tick(2, 0);
        assert_eq!(w.count(), 0);
        assert_eq!(w.position_q16(10), 0);
    }
}
