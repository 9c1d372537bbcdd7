//! Every EXTI line the slave uses, handled here rather than by embassy's `ExtiInput`.
//!
//! Why: embassy-stm32's shared EXTI handler masks and clears *every* pending line 0..15 it
//! sees, not just its own. With the encoders' edges arriving at tens of kHz and NSS firing
//! twice per SPI poll, that handler would regularly mask an encoder line (edges silently
//! stop) or clear an edge before it is time-stamped. So the board owns its lines:
//!
//! * lines 0, 1 (PA0/PA1, left wheel A/B) and 8, 9 (PA8/PA9, right wheel A/B): both edges,
//!   highest priority; each edge is time-stamped with the embassy clock and queued with the
//!   A/B levels for [`firmware_slave::ports::EncoderEdges`]. On the F1 the EXTI reads the pin
//!   whatever else uses it, so the timers keep counting the same edges in hardware;
//! * line 4 (PA4, SPI NSS): rising edge, one priority lower, signals the end of a transaction.

use core::sync::atomic::{AtomicBool, Ordering};

use embassy_stm32::interrupt::{self as irq, InterruptExt, Priority};
// cortex-m-rt's `#[interrupt]` attribute and the vector names it checks against.
use embassy_stm32::pac::{self, interrupt};
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::signal::Signal;
use firmware_slave::ports::{widen_us, EdgeBatch, EncoderEdge, EncoderEdges, MEASURING_WHEELS};
use heapless::spsc::{Consumer, Producer, Queue};

const LEFT: u32 = 0b11; // lines 0, 1
const RIGHT: u32 = 0b11 << 8; // lines 8, 9
const ENCODER_LINES: u32 = LEFT | RIGHT;
const NSS_LINE: u32 = 1 << 4;

/// An edge as queued: its time's low 32 bits only (8 bytes, not [`EncoderEdge`]'s 16: the
/// queue is the slave's largest buffer); [`widen_us`] makes it whole at the drain.
#[derive(Clone, Copy)]
struct QueuedEdge {
    t_us: u32,
    encoder: u8,
    levels: u8,
}

/// Edges between two odometry updates: at 1 kHz and 0.6 m/s a 32.7 µm-count wheel makes about
/// 20 edges per update, so 255 leave room for fast motion and a late update. A lock-free
/// single-producer, single-consumer queue (heapless'): the producer is the encoder lines'
/// handlers, which share one priority (none preempts another: one producer at a time), the
/// consumer the odometry task's drain. embassy-sync's `Channel` took a critical section on each
/// end and 224 B more of the slave's flash.
static mut EDGES: (Producer<'static, QueuedEdge>, Consumer<'static, QueuedEdge>) = {
    static mut QUEUE: Queue<QueuedEdge, 256> = Queue::new();
    // SAFETY: `QUEUE` is reachable only here, and split once, at compile time.
    let queue = &raw mut QUEUE;
    unsafe { (*queue).split_const() }
};

/// The producer's end. SAFETY (the caller's): only from the encoder lines' handlers, which run
/// at one priority and so never at the same time.
unsafe fn edge_producer() -> &'static mut Producer<'static, QueuedEdge> {
    // SAFETY: as the caller promises, no other reference to it lives.
    let ends = &raw mut EDGES;
    unsafe { &mut (*ends).0 }
}

/// The consumer's end. SAFETY (the caller's): only from [`drain_edges`], through the one
/// [`EdgeCapture`] (its `new` is `unsafe` for that).
unsafe fn edge_consumer() -> &'static mut Consumer<'static, QueuedEdge> {
    // SAFETY: as the caller promises, no other reference to it lives.
    let ends = &raw mut EDGES;
    unsafe { &mut (*ends).1 }
}
static EDGES_LOST: AtomicBool = AtomicBool::new(false);
static NSS_ROSE: Signal<CriticalSectionRawMutex, ()> = Signal::new();

/// Route the lines to port A, set their triggers and priorities, and unmask them.
pub fn init() {
    critical_section::with(|_| {
        // Port A (0) for lines 0, 1, 4 (EXTICR1, EXTICR2) and 8, 9 (EXTICR3).
        pac::AFIO.exticr(0).modify(|w| {
            w.set_exti(0, 0);
            w.set_exti(1, 0);
        });
        pac::AFIO.exticr(1).modify(|w| w.set_exti(0, 0));
        pac::AFIO.exticr(2).modify(|w| {
            w.set_exti(0, 0);
            w.set_exti(1, 0);
        });
        let exti = pac::EXTI;
        exti.rtsr(0).modify(|w| w.0 |= ENCODER_LINES | NSS_LINE);
        exti.ftsr(0).modify(|w| w.0 |= ENCODER_LINES);
        exti.pr(0).write(|w| w.0 = ENCODER_LINES | NSS_LINE);
        exti.imr(0).modify(|w| w.0 |= ENCODER_LINES | NSS_LINE);
    });
    for line in [irq::EXTI0, irq::EXTI1, irq::EXTI9_5] {
        line.set_priority(Priority::P0);
        // SAFETY: the handlers below are defined for these vectors and only touch their own
        // lines and lock-free / critical-section state.
        unsafe { line.enable() };
    }
    irq::EXTI4.set_priority(Priority::P1);
    // SAFETY: as above.
    unsafe { irq::EXTI4.enable() };
}

fn encoder_levels() -> [u8; MEASURING_WHEELS] {
    // One read of the port: both wheels' A/B levels at the same instant.
    let idr = pac::GPIOA.idr().read().0;
    [(idr & 0b11) as u8, ((idr >> 8) & 0b11) as u8]
}

fn on_encoder_edge(lines: u32) {
    let t_us = embassy_time::Instant::now().as_micros() as u32;
    // Clear first: an edge arriving while this runs pends again instead of being lost.
    pac::EXTI.pr(0).write(|w| w.0 = lines);
    let levels = encoder_levels();
    // SAFETY: this runs in the encoder lines' handlers alone (priority P0, `init`).
    let edges = unsafe { edge_producer() };
    for (encoder, mask) in [(0u8, LEFT), (1u8, RIGHT)] {
        if lines & mask != 0
            && edges
                .enqueue(QueuedEdge {
                    t_us,
                    encoder,
                    levels: levels[encoder as usize],
                })
                .is_err()
        {
            EDGES_LOST.store(true, Ordering::Relaxed);
        }
    }
}

fn pending(mask: u32) -> u32 {
    pac::EXTI.pr(0).read().0 & mask
}

#[interrupt]
fn EXTI0() {
    on_encoder_edge(pending(1 << 0));
}

#[interrupt]
fn EXTI1() {
    on_encoder_edge(pending(1 << 1));
}

#[interrupt]
fn EXTI9_5() {
    // Lines 5..9 share this vector; only 8 and 9 are ours.
    on_encoder_edge(pending(RIGHT));
}

#[interrupt]
fn EXTI4() {
    pac::EXTI.pr(0).write(|w| w.0 = NSS_LINE);
    NSS_ROSE.signal(());
}

/// The encoder edges, for tick-timestamp mode.
pub struct EdgeCapture(());

impl EdgeCapture {
    /// Requires [`init`] to have run.
    ///
    /// # Safety
    ///
    /// At most one `EdgeCapture` may exist: its drain is the edge queue's one consumer.
    pub unsafe fn new() -> Self {
        EdgeCapture(())
    }
}

impl EncoderEdges for EdgeCapture {
    fn levels(&mut self) -> [u8; MEASURING_WHEELS] {
        encoder_levels()
    }

    fn drain(&mut self, mut f: impl FnMut(EncoderEdge)) -> EdgeBatch {
        drain_edges(&mut f)
    }
}

/// [`EdgeCapture`]'s drain, once in the image for all its callers.
#[inline(never)]
fn drain_edges(f: &mut dyn FnMut(EncoderEdge)) -> EdgeBatch {
    // The cut: how many edges are queued, and the timers, with no edge in between. An
    // edge the timers have counted but whose interrupt has not queued it yet shows as a
    // pending EXTI line (the EXTI latches the pin edge before the timer's 111 ns input
    // filter passes it), so inside the critical section a quiet EXTI means the queue and
    // the timers agree; otherwise let the interrupt run and try again. At tens of kHz of
    // edges and a sub-microsecond critical section, a retry is rare and three in a row
    // are rarer still (the cross-check is then skipped once).
    // SAFETY: the drain is the queue's one consumer (the odometry task's).
    let edges = unsafe { edge_consumer() };
    let cut = (0..3).find_map(|_| {
        critical_section::with(|_| {
            (pending(ENCODER_LINES) == 0).then(|| {
                let counters = [
                    // Read-only register reads: `Counters` (`board/qei.rs`) owns these timers.
                    pac::TIM2.cnt().read().cnt(),
                    pac::TIM1.cnt().read().cnt(),
                ];
                (edges.len(), counters)
            })
        })
    });
    // Only the edges up to the cut (or, without one, those queued now): later ones stay
    // queued for the next drain. The clock is read after they were counted, so every one
    // of them is older than `now_us`, as `widen_us` needs.
    let take = cut.map_or_else(|| edges.len(), |(queued, _)| queued);
    let now_us = embassy_time::Instant::now().as_micros();
    for _ in 0..take {
        match edges.dequeue() {
            Some(e) => f(EncoderEdge {
                t_us: widen_us(e.t_us, now_us),
                encoder: e.encoder,
                levels: e.levels,
            }),
            None => break,
        }
    }
    EdgeBatch {
        complete: !EDGES_LOST.swap(false, Ordering::Relaxed),
        counters: cut.map(|(_, counters)| counters),
    }
}

/// PA4 as the SPI slave's NSS: its level, and its rising edge (end of a transaction).
pub struct Nss(());

impl Nss {
    /// Requires [`init`]; PA4 must already be an input (with pull-up).
    pub fn new() -> Self {
        Nss(())
    }

    pub fn is_high(&self) -> bool {
        pac::GPIOA.idr().read().0 & NSS_LINE != 0
    }

    pub fn is_low(&self) -> bool {
        !self.is_high()
    }

    /// The next rising edge after this call.
    pub async fn wait_for_rising_edge(&mut self) {
        NSS_ROSE.reset();
        NSS_ROSE.wait().await;
    }

    /// Until NSS is high (now, or at its next rising edge).
    pub async fn wait_for_high(&mut self) {
        NSS_ROSE.reset();
        if self.is_high() {
            return;
        }
        NSS_ROSE.wait().await;
    }
}
