//! What every fuzz target links: an allocator that makes an over-large allocation a finding.
//!
//! libFuzzer's `-malloc_limit_mb` works only through the sanitizer's malloc hooks, so a run
//! without AddressSanitizer (`scripts/fuzz --no-sanitizer`, 4 to 10 times the inputs per
//! second) would not catch an allocation whose size the input decides. This allocator holds
//! the same bounds in both modes: one allocation over [`MAX_ONE_ALLOCATION`] or more than
//! [`MAX_LIVE`] held at once aborts, and libFuzzer writes the input as a crash.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

/// The largest single allocation an input may cause (scripts/fuzz's `-malloc_limit_mb=64`).
pub const MAX_ONE_ALLOCATION: usize = 64 << 20;
/// The most an input may hold at once (under the script's 512 MB RSS limit, which also
/// counts the corpus and libFuzzer's own tables).
pub const MAX_LIVE: usize = 256 << 20;

/// [`System`], counting what is live and refusing what is over the bounds.
pub struct BoundedAlloc {
    live: AtomicUsize,
}

impl BoundedAlloc {
    const fn new() -> Self {
        Self {
            live: AtomicUsize::new(0),
        }
    }

    fn check(&self, size: usize) {
        let live = self.live.fetch_add(size, Ordering::Relaxed) + size;
        if size > MAX_ONE_ALLOCATION || live > MAX_LIVE {
            // No formatting here: it would allocate. The numbers are in the core dump's
            // frame, and the input in libFuzzer's crash file.
            let msg: &[u8] = if size > MAX_ONE_ALLOCATION {
                b"fuzz: one allocation over 64 MB: the input decides a size it should not\n"
            } else {
                b"fuzz: over 256 MB held at once: memory grows with the input unbounded\n"
            };
            use std::io::Write;
            let _ = std::io::stderr().write_all(msg);
            std::process::abort();
        }
    }

    /// A failed allocation holds nothing.
    fn unless_null(&self, p: *mut u8, size: usize) -> *mut u8 {
        if p.is_null() {
            self.live.fetch_sub(size, Ordering::Relaxed);
        }
        p
    }
}

unsafe impl GlobalAlloc for BoundedAlloc {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        self.check(layout.size());
        self.unless_null(System.alloc(layout), layout.size())
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        self.check(layout.size());
        self.unless_null(System.alloc_zeroed(layout), layout.size())
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        self.live.fetch_sub(layout.size(), Ordering::Relaxed);
        System.dealloc(ptr, layout)
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        // Count the new block before the old one goes: for a moment both are held.
        self.check(new_size);
        let p = self.unless_null(System.realloc(ptr, layout, new_size), new_size);
        if !p.is_null() {
            self.live.fetch_sub(layout.size(), Ordering::Relaxed);
        }
        p
    }
}

#[global_allocator]
static ALLOCATOR: BoundedAlloc = BoundedAlloc::new();
