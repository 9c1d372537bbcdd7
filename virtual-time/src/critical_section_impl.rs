//! The host's critical section: one lock for the process, re-entrant per thread.
//!
//! `critical-section`'s own `std` implementation is a `std::sync::Mutex`: two atomic
//! read-modify-writes per section (the unlock swaps, to learn whether to wake a sleeper).
//! The firmware takes a few hundred thousand short sections in an emulated run, and those
//! two were 12 % of its time (`perf`, futex.rs). Here the lock is taken with one
//! compare-exchange and given back with a plain release store; a thread that finds it taken
//! spins, then yields. Sections are a few dozen instructions, and only tests running side by
//! side ever meet one.

use std::cell::Cell;
use std::sync::atomic::{AtomicBool, Ordering};

static LOCKED: AtomicBool = AtomicBool::new(false);

std::thread_local! {
    /// This thread holds the lock (so a nested section only looks here).
    static HELD: Cell<bool> = const { Cell::new(false) };
}

struct HostCriticalSection;
critical_section::set_impl!(HostCriticalSection);

unsafe impl critical_section::Impl for HostCriticalSection {
    unsafe fn acquire() -> bool {
        if HELD.with(Cell::get) {
            return true; // nested: the outer section releases
        }
        let mut spins = 0u32;
        while LOCKED
            .compare_exchange_weak(false, true, Ordering::Acquire, Ordering::Relaxed)
            .is_err()
        {
            spins += 1;
            if spins < 64 {
                std::hint::spin_loop();
            } else {
                std::thread::yield_now();
            }
        }
        HELD.with(|h| h.set(true));
        false
    }

    unsafe fn release(nested: bool) {
        if !nested {
            HELD.with(|h| h.set(false));
            LOCKED.store(false, Ordering::Release);
        }
    }
}

#[cfg(test)]
mod tests {
    use std::cell::Cell;

    /// A plain (non-atomic) counter bumped in sections from four threads at once loses no
    /// update: the sections exclude each other.
    #[test]
    fn sections_exclude_other_threads() {
        static COUNTER: critical_section::Mutex<Cell<u64>> =
            critical_section::Mutex::new(Cell::new(0));
        let threads: Vec<_> = (0..4)
            .map(|_| {
                std::thread::spawn(|| {
                    for _ in 0..50_000 {
                        critical_section::with(|cs| {
                            let c = COUNTER.borrow(cs);
                            // Read, then write: an update is lost if another thread
                            // gets in between (it does, without the lock).
                            let v = c.get();
                            std::hint::black_box(&v);
                            c.set(v + 1);
                        });
                    }
                })
            })
            .collect();
        for t in threads {
            t.join().unwrap();
        }
        assert_eq!(
            critical_section::with(|cs| COUNTER.borrow(cs).get()),
            200_000
        );
    }

    /// A section inside a section does not deadlock, and the lock is free again only when
    /// the outer one ends.
    #[test]
    fn nested_sections_release_with_the_outer_one() {
        critical_section::with(|_| {
            critical_section::with(|_| {});
            assert!(
                super::HELD.with(Cell::get),
                "the inner section released the lock"
            );
        });
        assert!(!super::HELD.with(Cell::get));
        // Another thread can take it now.
        std::thread::spawn(|| critical_section::with(|_| ()))
            .join()
            .unwrap();
    }
}
