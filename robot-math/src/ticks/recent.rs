//! Ticks kept at the edge and put through their wheel's [`TickTracker`] at the next update.
//!
//! On the slave an edge should cost as little as possible (its budget: ≤ 60 instructions; the
//! edge interrupts of four wheels at several kHz each add up), while the tracker's own work
//! per tick (its edge, its intervals, its edge learner's window) is more. That work need not be
//! done per tick: after any run of ticks a tracker's state depends on its count and on its
//! **last nine ticks only** — its edge on the count and the last step, its interval on the last
//! two ticks' times and directions, its interval before that on the last three's, and its edge
//! learner's window on the intervals between the last nine ([`super::edges`]: eight slots, each
//! overwritten by the next tick over its edge, or all cleared by a reversal). So the edge only
//! keeps its time and step in a ring, and [`TickTracker::catch_up`] replays the last nine at
//! most when the wheel's position is next needed: bit for bit what ticking every one of them
//! would have left, and a bounded amount of work per wheel per update however fast the wheel
//! turns.
//!
//! Only for a wheel that has gathered its first ticks one way ([`TickTracker::placing`] false:
//! nine, or fewer and a reversal): while they are gathered every tick feeds the start fit,
//! which needs each one.

use super::TickTracker;
use super::WINDOW;

/// The last ticks replayed: what a tracker's state depends on (its edge learner's window of
/// nine).
const REPLAYED: u32 = WINDOW as u32;
/// The ring's slots: a power of two (the slot is a mask, not a division), at least that many.
const SLOTS: usize = (REPLAYED as usize).next_power_of_two();
const MASK: u32 = SLOTS as u32 - 1;

/// One wheel's ticks since its tracker last caught up: a ring of [`SLOTS`] of which the last
/// [`REPLAYED`] are used (sixteen and nine).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RecentTicks {
    t_ns: [u64; SLOTS],
    steps: [i8; SLOTS],
    /// Ticks since the tracker caught up; the next goes to slot `waiting % SLOTS`. A `u32` counted
    /// without a saturating check (a saturating count costs the edge six instructions): it
    /// would wrap after 2³² ticks of one wheel between two updates, which no encoder gives
    /// (4·10¹² edges a second at 1 kHz) and no tick stream holds (the host reads at most 2²²
    /// rows).
    waiting: u32,
    /// The wheel's first ticks have placed it: its ticks may wait here (kept by the owner, next
    /// to the ring, so the edge reads one place).
    pub open: bool,
}

impl RecentTicks {
    /// A tick at `t_ns`, `step` ±1 (the caller has checked it).
    #[inline(always)]
    pub fn push(&mut self, t_ns: u64, step: i8) {
        let k = (self.waiting & MASK) as usize;
        self.t_ns[k] = t_ns;
        self.steps[k] = step;
        self.waiting = self.waiting.wrapping_add(1);
    }

    /// True when ticks wait for the tracker.
    #[inline(always)]
    pub fn any(&self) -> bool {
        self.waiting != 0
    }
}

impl TickTracker {
    /// Take in the ticks kept in `recent` since this tracker last saw one, `count` being the
    /// wheel's count after all of them, and empty `recent`. Equal, bit for bit, to having
    /// [`tick`](Self::tick)ed every one of them (see the module's comment for why). For a
    /// wheel that is not [`placing`](Self::placing) any more. Integer-only.
    pub fn catch_up(&mut self, count: i64, recent: &mut RecentTicks) {
        let replayed = recent.waiting.min(REPLAYED);
        let first = recent.waiting.wrapping_sub(replayed);
        // Emptied: the next tick goes to slot 0.
        recent.waiting = 0;
        // The count before the replayed ticks: their steps taken off the final count.
        let mut before = count;
        for i in 0..replayed {
            before -= recent.steps[(first.wrapping_add(i) & MASK) as usize] as i64;
        }
        self.count = before;
        for i in 0..replayed {
            let k = (first.wrapping_add(i) & MASK) as usize;
            // An earlier tick's interval, from a state older than its own tick before it, is
            // overwritten by the ticks after it: the tracker's intervals by the next two, the
            // learner's window slot by the eighth tick after it one way (or a reversal clears
            // it), so only what the last nine ticks make survives.
            self.advance(recent.t_ns[k], recent.steps[k]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// One tracker ticked at every tick, one that keeps its ticks for the update as the slave
    /// does, and the ring between them.
    struct Pair {
        every: TickTracker,
        deferred: TickTracker,
        recent: RecentTicks,
        count: i64,
    }

    impl Pair {
        fn new(every: TickTracker, count: i64) -> Self {
            let recent = RecentTicks::default();
            Pair {
                every,
                deferred: every,
                recent,
                count,
            }
        }

        fn tick(&mut self, t: u64, step: i8) {
            self.count += step as i64;
            self.every.tick(t, step);
            if self.deferred.placing() {
                self.deferred.tick(t, step);
            } else {
                self.recent.push(t, step);
            }
        }

        /// An update: the kept ticks caught up, both trackers learn; they must be equal.
        fn update(&mut self) -> Result<(), TestCaseError> {
            if self.recent.any() {
                self.deferred.catch_up(self.count, &mut self.recent);
            }
            self.deferred.learn();
            self.every.learn();
            prop_assert_eq!(self.deferred, self.every);
            Ok(())
        }
    }

    proptest! {
        /// A tracker caught up at random instants equals one that saw every tick: random
        /// steps (reversals, runs), random intervals (including equal times), any start.
        #[test]
        fn catching_up_equals_ticking_every_tick(
            learn in proptest::bool::ANY,
            start in -1000i64..1000,
            ticks in proptest::collection::vec(
                (0u64..5_000, prop_oneof![Just(1i8), Just(-1i8)], proptest::bool::weighted(0.2)),
                0..400,
            ),
        ) {
            let mut first = TickTracker::starting(start, 50);
            first.set_edge_learning(learn);
            let mut p = Pair::new(first, start);
            let mut t = 100u64;
            for (dt, step, update_here) in ticks {
                t += dt;
                p.tick(t, step);
                if update_here {
                    p.update()?;
                    prop_assert_eq!(p.deferred.position_q16(t + 37), p.every.position_q16(t + 37));
                }
            }
            p.update()?;
        }
    }

    proptest! {
        /// Three wheels at once, as the estimator runs them: each tick through `tick_wheel`
        /// while its wheel gathers its first ticks (which may place the others together), else
        /// kept; at each update the kept ticks caught up and `learn_edges` (which may fit a
        /// start again and place the wheels together again). Abrupt starts after a rest at
        /// random speeds on uneven edges, so the starts are placed together again on learned
        /// edges: equal, bit for bit, to the wheels that saw every tick.
        #[test]
        fn wheels_caught_up_equal_wheels_ticked_every_tick(
            wheels in proptest::collection::vec(
                (300.0f64..3_000.0, 0.05f64..0.95, proptest::array::uniform4(0.03f64..0.06)),
                3,
            ),
            updates in proptest::collection::vec(proptest::bool::weighted(0.3), 600),
        ) {
            let start = 1_000_000_000u64;
            let mut ticks: Vec<(u64, usize)> = wheels
                .iter()
                .enumerate()
                .flat_map(|(j, &(per_s, phi, off))| {
                    (1..=200i64).map(move |m| {
                        // Alternate signs: every encoder's edges measurably uneven.
                        let sign = if m & 1 == 0 { 1.0 } else { -1.0 };
                        let place = m as f64 + sign * off[(m & 3) as usize];
                        (start + ((place - phi) / per_s * 1e9) as u64, j)
                    })
                })
                .collect();
            ticks.sort();
            let mut every = [TickTracker::starting(0, 0); 3];
            let mut deferred = every;
            let mut recent = [RecentTicks::default(); 3];
            let mut counts = [0i64; 3];
            let last = ticks.len() - 1;
            for (i, (&(t, j), update_here)) in ticks.iter().zip(updates.iter().cycle()).enumerate() {
                counts[j] += 1;
                super::super::tick_wheel(&mut every, j, t, 1);
                if deferred[j].placing() {
                    super::super::tick_wheel(&mut deferred, j, t, 1);
                } else {
                    recent[j].push(t, 1);
                }
                if *update_here || i == last {
                    for ((w, r), &c) in deferred.iter_mut().zip(&mut recent).zip(&counts) {
                        if r.any() {
                            w.catch_up(c, r);
                        }
                    }
                    super::super::learn_edges(&mut deferred);
                    super::super::learn_edges(&mut every);
                    prop_assert_eq!(deferred, every);
                }
            }
            prop_assert!(every.iter().all(|w| w.edges().uneven()), "not learned uneven");
            // An abrupt start: no wheel's own fit places it, they were placed together.
            prop_assert!(every.iter().all(|w| !w.placed), "placed by its own fit");
        }
    }

    proptest! {
        /// The same with the edges learned: runs one way at a near-constant speed (so windows
        /// are measured and the start is fitted again), reversals, updates at random; the
        /// deferred tracker must equal the one that saw every tick, and it must have learned.
        #[test]
        fn catching_up_equals_ticking_every_tick_while_learning(
            base in 2_000u64..20_000,
            ticks in proptest::collection::vec(
                (0u64..40, proptest::bool::weighted(0.02), proptest::bool::weighted(0.15)),
                200..600,
            ),
        ) {
            let first = TickTracker::starting(0, 0);
            let mut p = Pair::new(first, 0);
            let (mut t, mut step) = (1_000u64, 1i8);
            for (jitter, reverse, update_here) in ticks {
                if reverse {
                    step = -step;
                }
                t += base + jitter;
                p.tick(t, step);
                if update_here {
                    p.update()?;
                }
            }
            prop_assert!(p.every.edges().windows() > 0, "nothing learned");
        }
    }
}
