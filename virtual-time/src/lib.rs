//! Virtual time for running embassy firmware logic on the host.
//!
//! * An `embassy-time` driver whose clock only moves when the simulation says so, so runs are
//!   deterministic and as fast as the CPU allows. The clock is **per thread**: each test (or
//!   emulation) on its own thread has its own clock and timer queue, which sidesteps the
//!   one-driver-per-process rule of embassy-time without tests stepping on each other.
//! * A small single-thread executor that polls the firmware's async tasks until they all wait,
//!   and a [`Simulation`] that then jumps the clock to the next timer deadline.
//!
//! Link this crate into every host binary that runs firmware code (and nothing else that
//! provides an embassy-time driver: no `std` or `mock-driver` features anywhere).

use std::cell::{Cell, RefCell};
use std::future::Future;
use std::pin::Pin;
use std::sync::atomic::{AtomicBool, Ordering};
use std::task::{Context, Poll, RawWaker, RawWakerVTable, Waker};

use embassy_time::{Duration, Instant};

struct Clock {
    now: u64,
    /// Wake-ups: one entry per waker that ever slept on a timer (one per task), at its
    /// earliest deadline, or [`IDLE`] once woken. An entry stays after it fires, so a task's
    /// next timer (every millisecond or so in an emulation) finds its waker there instead of
    /// cloning it in and dropping it again, each an atomic update. Small, so a Vec beats a
    /// heap here.
    queue: Vec<(u64, Waker)>,
}

/// A queue entry with no pending wake-up (as if removed: it never comes due).
const IDLE: u64 = u64::MAX;

thread_local! {
    static CLOCK: RefCell<Clock> = const { RefCell::new(Clock { now: 0, queue: Vec::new() }) };
    static ACTIVE: Cell<bool> = const { Cell::new(false) };
}

struct VirtualDriver;

impl embassy_time_driver::Driver for VirtualDriver {
    fn now(&self) -> u64 {
        CLOCK.with(|c| c.borrow().now)
    }

    fn schedule_wake(&self, at: u64, waker: &Waker) {
        CLOCK.with(|c| {
            let mut c = c.borrow_mut();
            // A timer re-registers on every poll; keep one entry per waker, the earliest.
            if let Some(e) = c.queue.iter_mut().find(|(_, w)| w.will_wake(waker)) {
                // `at` is never IDLE here in practice (u64::MAX ticks is 584 000 years); if
                // it were, the entry would just never come due, as it would not have.
                e.0 = e.0.min(at);
            } else {
                c.queue.push((at, waker.clone()));
            }
        });
    }
}

embassy_time_driver::time_driver_impl!(static DRIVER: VirtualDriver = VirtualDriver);

/// Ticks per second of the embassy clock (1 MHz: one tick is a microsecond).
pub const TICK_HZ: u64 = embassy_time_driver::TICK_HZ;

/// A task's "woken" flag. Flags live for the whole process (a thread's are leaked once and
/// reused by its later simulations), so a waker is just a pointer to one: cloning and dropping
/// it touch nothing. With reference-counted (`Arc`) wakers, the firmware storing and dropping
/// its wakers was two locked instructions a time, 4 % of an emulation (`perf`). A waker that
/// outlives its simulation can only set a flag a later task on this thread then finds set: a
/// spurious wake, which every future tolerates.
type WokenFlag = &'static AtomicBool;

thread_local! {
    /// Flags no task of this thread holds now. A thread's flags are never freed: one per
    /// task it ran at once (a byte each, in its own allocation), lost when it exits, so a
    /// test harness that starts a thread per test leaves a few per test behind.
    static FREE_FLAGS: RefCell<Vec<WokenFlag>> = const { RefCell::new(Vec::new()) };
}

fn take_flag() -> WokenFlag {
    FREE_FLAGS
        .with(|f| f.borrow_mut().pop())
        .unwrap_or_else(|| Box::leak(Box::new(AtomicBool::new(false))))
}

static FLAG_WAKER: RawWakerVTable = RawWakerVTable::new(
    |p| RawWaker::new(p, &FLAG_WAKER),
    wake_flag,
    wake_flag,
    |_| {},
);

fn wake_flag(p: *const ()) {
    // SAFETY: `p` is a `WokenFlag` (see `flag_waker`), which is never freed.
    unsafe { &*(p as *const AtomicBool) }.store(true, Ordering::Release);
}

fn flag_waker(flag: WokenFlag) -> Waker {
    let p = flag as *const AtomicBool as *const ();
    // SAFETY: the vtable's functions only read the flag behind `p`, which lives for the rest
    // of the process and is an atomic (wakers may be sent to and woken from any thread).
    unsafe { Waker::from_raw(RawWaker::new(p, &FLAG_WAKER)) }
}

struct Task<'a> {
    future: Pin<Box<dyn Future<Output = ()> + 'a>>,
    woken: WokenFlag,
    waker: Waker,
    done: bool,
}

/// Why a [`Simulation`] could not start.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct AlreadyRunning;

impl std::fmt::Display for AlreadyRunning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("a virtual-time simulation is already running on this thread")
    }
}

impl std::error::Error for AlreadyRunning {}

/// Owns this thread's virtual clock and the tasks running on it.
pub struct Simulation<'a> {
    tasks: Vec<Task<'a>>,
    polls: u64,
}

impl<'a> Simulation<'a> {
    /// Start a simulation at time zero. One per thread at a time: the clock is shared by
    /// everything on the thread.
    pub fn new() -> Result<Self, AlreadyRunning> {
        if ACTIVE.with(|a| a.replace(true)) {
            return Err(AlreadyRunning);
        }
        CLOCK.with(|c| {
            let mut c = c.borrow_mut();
            c.now = 0;
            c.queue.clear();
        });
        Ok(Simulation {
            tasks: Vec::new(),
            polls: 0,
        })
    }

    /// Add a task. Tasks are polled in the order they were spawned (deterministic).
    pub fn spawn(&mut self, future: impl Future<Output = ()> + 'a) {
        let woken = take_flag();
        woken.store(true, Ordering::Relaxed);
        let waker = flag_waker(woken);
        self.tasks.push(Task {
            future: Box::pin(future),
            woken,
            waker,
            done: false,
        });
    }

    /// The current virtual time.
    pub fn now(&self) -> Instant {
        Instant::now()
    }

    /// Poll every woken task, repeatedly, until none is woken. Returns the number of polls.
    pub fn run_until_idle(&mut self) -> u64 {
        let mut polls = 0;
        loop {
            let mut progressed = false;
            for t in self.tasks.iter_mut().filter(|t| !t.done) {
                // Most tasks are not woken on a pass: a plain load first spares them the
                // locked swap.
                if t.woken.load(Ordering::Relaxed) && t.woken.swap(false, Ordering::Acquire) {
                    progressed = true;
                    polls += 1;
                    let mut cx = Context::from_waker(&t.waker);
                    if let Poll::Ready(()) = t.future.as_mut().poll(&mut cx) {
                        t.done = true;
                    }
                }
            }
            if !progressed {
                break;
            }
        }
        self.polls += polls;
        polls
    }

    /// The earliest pending timer deadline, if any task sleeps on one.
    pub fn next_deadline(&self) -> Option<Instant> {
        CLOCK
            .with(|c| c.borrow().queue.iter().map(|(at, _)| *at).min())
            .filter(|at| *at != IDLE)
            .map(Instant::from_ticks)
    }

    /// Run the tasks up to time `until`: jump from deadline to deadline, waking the sleepers
    /// and letting everything settle at each one, then set the clock to `until`.
    pub fn run_until(&mut self, until: Instant) {
        self.run_until_idle();
        loop {
            match self.next_deadline() {
                Some(at) if at <= until => {
                    self.set_clock(at.as_ticks().max(Instant::now().as_ticks()));
                    self.run_until_idle();
                }
                _ => break,
            }
        }
        // Most often the last deadline was `until` itself (an emulation's physics grid is
        // every firmware timer's): the clock is there already and nothing left in the queue is
        // due by then (the loop above took every deadline up to it), so setting it again would
        // only walk the queue (0.9 % of an emulation's instructions, about 1 % of its time).
        if until.as_ticks() > Instant::now().as_ticks() {
            self.set_clock(until.as_ticks());
        }
        self.run_until_idle();
    }

    /// Run for `d` of virtual time.
    pub fn run_for(&mut self, d: Duration) {
        self.run_until(Instant::now() + d);
    }

    /// Total task polls so far (a cost measure that does not depend on the machine).
    pub fn polls(&self) -> u64 {
        self.polls
    }

    /// Whether every task has finished.
    pub fn all_done(&self) -> bool {
        self.tasks.iter().all(|t| t.done)
    }

    fn set_clock(&mut self, ticks: u64) {
        // The clock moves at every physics step of an emulation: this once allocated a list
        // of the due wakers, cloned each into it and dropped its queue entry, a twentieth of
        // the run. Now the due entries are woken by reference and stay in the queue, idle.
        let mut queue = CLOCK.with(|c| {
            let mut c = c.borrow_mut();
            c.now = ticks;
            std::mem::take(&mut c.queue)
        });
        // Wake outside the borrow: a waker may re-enter the driver.
        for (at, w) in queue.iter_mut().filter(|(at, _)| *at <= ticks) {
            *at = IDLE;
            w.wake_by_ref();
        }
        CLOCK.with(|c| {
            let mut c = c.borrow_mut();
            // Wake-ups registered while the wakers ran (this executor's wakers register none)
            // join the queue as `schedule_wake` would have added them. Most often there are
            // none: the empty list is then just swapped back (draining it was 0.5 % of an
            // emulation).
            let during = std::mem::replace(&mut c.queue, queue);
            for (at, waker) in during {
                match c.queue.iter_mut().find(|(_, w)| w.will_wake(&waker)) {
                    Some(e) => e.0 = e.0.min(at),
                    None => c.queue.push((at, waker)),
                }
            }
        });
    }
}

impl Drop for Simulation<'_> {
    fn drop(&mut self) {
        // Drop the tasks (and with them their timers) before releasing the clock; their
        // flags go back for the next simulation on this thread.
        let flags: Vec<WokenFlag> = self.tasks.iter().map(|t| t.woken).collect();
        self.tasks.clear();
        // `try_with`: nothing to give back to a thread that is being torn down.
        let _ = FREE_FLAGS.try_with(|f| f.borrow_mut().extend(flags));
        CLOCK.with(|c| c.borrow_mut().queue.clear());
        ACTIVE.with(|a| a.set(false));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use embassy_time::{Ticker, Timer};
    use std::rc::Rc;

    #[test]
    fn timers_fire_at_their_virtual_instants_in_order() {
        let log = Rc::new(RefCell::new(Vec::new()));
        let mut sim = Simulation::new().unwrap();
        for (name, ms) in [("b", 30u64), ("a", 10)] {
            let log = log.clone();
            sim.spawn(async move {
                Timer::after_millis(ms).await;
                log.borrow_mut().push((name, Instant::now().as_micros()));
            });
        }
        sim.run_for(Duration::from_secs(1));
        assert_eq!(*log.borrow(), vec![("a", 10_000), ("b", 30_000)]);
        assert!(sim.all_done());
        assert_eq!(sim.now().as_micros(), 1_000_000);
    }

    #[test]
    fn a_ticker_ticks_exactly_once_per_period() {
        let n = Rc::new(Cell::new(0u32));
        let mut sim = Simulation::new().unwrap();
        let n2 = n.clone();
        sim.spawn(async move {
            let mut t = Ticker::every(Duration::from_micros(250));
            loop {
                t.next().await;
                n2.set(n2.get() + 1);
            }
        });
        sim.run_for(Duration::from_secs(10));
        // Ticks at 250 µs .. 10 s inclusive.
        assert_eq!(n.get(), 40_000);
    }

    #[test]
    fn one_simulation_per_thread() {
        let _a = Simulation::new().unwrap();
        assert!(Simulation::new().is_err());
    }

    #[test]
    fn each_thread_has_its_own_clock() {
        let mut sim = Simulation::new().unwrap();
        sim.run_for(Duration::from_secs(5));
        let other = std::thread::spawn(|| {
            let mut s = Simulation::new().unwrap();
            s.run_for(Duration::from_millis(3));
            Instant::now().as_micros()
        })
        .join()
        .unwrap();
        assert_eq!(other, 3_000);
        assert_eq!(Instant::now().as_micros(), 5_000_000);
    }

    /// A task waiting on something another thread finishes: that thread's wake is seen, and a
    /// task nobody woke is not polled again.
    #[test]
    fn a_wake_from_another_thread_gets_its_task_polled() {
        use std::sync::{Arc, Mutex};
        let parked: Arc<Mutex<Option<Waker>>> = Arc::default();
        let ready = Arc::new(AtomicBool::new(false));
        let mut sim = Simulation::new().unwrap();
        let (p, r) = (parked.clone(), ready.clone());
        sim.spawn(std::future::poll_fn(move |cx| {
            if r.load(Ordering::Acquire) {
                return Poll::Ready(());
            }
            *p.lock().unwrap() = Some(cx.waker().clone());
            Poll::Pending
        }));
        assert_eq!(sim.run_until_idle(), 1);
        assert_eq!(sim.run_until_idle(), 0, "polled without a wake");
        let waker = parked.lock().unwrap().take().unwrap();
        std::thread::spawn(move || {
            ready.store(true, Ordering::Release);
            waker.wake();
        })
        .join()
        .unwrap();
        assert_eq!(sim.run_until_idle(), 1);
        assert!(sim.all_done());
    }

    /// A waker kept past its simulation can still be cloned, woken and dropped; the next
    /// simulation on the thread runs as if nothing happened (at most a spurious first poll).
    #[test]
    fn a_waker_outliving_its_simulation_is_harmless() {
        let kept: Rc<RefCell<Option<Waker>>> = Rc::default();
        {
            let mut sim = Simulation::new().unwrap();
            let k = kept.clone();
            sim.spawn(std::future::poll_fn(move |cx| {
                *k.borrow_mut() = Some(cx.waker().clone());
                Poll::<()>::Pending
            }));
            sim.run_until_idle();
        }
        let waker = kept.borrow_mut().take().unwrap();
        let twin = waker.clone();
        assert!(twin.will_wake(&waker));
        twin.wake();
        let n = Rc::new(Cell::new(0u32));
        let mut sim = Simulation::new().unwrap();
        let n2 = n.clone();
        sim.spawn(async move {
            Timer::after_millis(5).await;
            n2.set(n2.get() + 1);
        });
        waker.wake_by_ref();
        sim.run_for(Duration::from_millis(10));
        drop(waker);
        assert_eq!(n.get(), 1);
        assert!(sim.all_done());
    }
}
