//! Where a step's encoder edges fall: each whole count an encoder's position crosses, on the
//! cubic through the step's end positions and speeds, and the two encoders' edges in one
//! time order.

/// An edge: its time (s), its encoder, the count after it.
pub(super) type Edge = (f64, usize, i64);

/// Push encoder `j`'s edges in a step of `h` s from `t0`, in time order: its position goes
/// from `a` to `b` (counts) with speeds `v0`, `v1` at the ends (counts per step), and every
/// whole count between is an edge.
pub(super) fn push_crossings(
    edges: &mut Vec<Edge>,
    j: usize,
    t0: f64,
    h: f64,
    (a, b): (f64, f64),
    (v0, v1): (f64, f64),
) {
    let position = |u: f64| {
        let (u2, u3) = (u * u, u * u * u);
        (2.0 * u3 - 3.0 * u2 + 1.0) * a
            + (u3 - 2.0 * u2 + u) * v0
            + (3.0 * u2 - 2.0 * u3) * b
            + (u3 - u2) * v1
    };
    let slope = |u: f64| {
        let u2 = u * u;
        (6.0 * u2 - 6.0 * u) * (a - b) + (3.0 * u2 - 4.0 * u + 1.0) * v0 + (3.0 * u2 - 2.0 * u) * v1
    };
    // Where the cubic reaches each edge (it is on opposite sides at the ends): Newton
    // from the straight line's guess, kept inside the bracket by bisection
    // ([`Crossing`]). The edges are solved `CROSSING_LANES` at a time, side by side:
    // each runs exactly the one-edge iteration, so each result is the same to the bit,
    // but their chains of dependent multiplications and divisions overlap in the CPU
    // instead of each waiting for the one before (the loop was most of the plant's
    // time).
    let rising = b > a;
    let (lo, hi) = (
        a.floor().min(b.floor()) as i64,
        a.floor().max(b.floor()) as i64,
    );
    let mut first = lo + 1;
    while first <= hi {
        let mut lanes = [Crossing::DONE; CROSSING_LANES];
        for (k, lane) in lanes.iter_mut().enumerate() {
            let edge = first + k as i64;
            if edge <= hi {
                *lane = Crossing::start(edge as f64, a, b);
            }
        }
        for _ in 0..60 {
            let mut active = false;
            for lane in lanes.iter_mut().filter(|l| !l.done) {
                lane.iterate(&position, &slope, rising);
                active |= !lane.done;
            }
            if !active {
                break;
            }
        }
        for (k, lane) in lanes.iter().enumerate() {
            let edge = first + k as i64;
            if edge > hi {
                break;
            }
            let t = t0 + h * lane.u;
            let count_after = if rising { edge } else { edge - 1 };
            edges.push((t, j, count_after));
        }
        first += CROSSING_LANES as i64;
    }
    if b < a {
        // Downward, the higher edges are crossed first.
        let n = edges.len();
        let k = (hi - lo) as usize;
        edges[n - k..].reverse();
    }
}

const CROSSING_LANES: usize = 4;

/// One edge's crossing of a step's cubic, found by Newton's method from the straight line's
/// guess, kept inside the bracket `[lo, hi]` by bisection: `u` is the fraction of the step.
#[derive(Clone, Copy, Debug)]
struct Crossing {
    edge: f64,
    u: f64,
    lo: f64,
    hi: f64,
    done: bool,
}

impl Crossing {
    /// A lane with nothing to solve.
    const DONE: Crossing = Crossing {
        edge: 0.0,
        u: 0.0,
        lo: 0.0,
        hi: 1.0,
        done: true,
    };

    fn start(edge: f64, a: f64, b: f64) -> Crossing {
        Crossing {
            edge,
            u: ((edge - a) / (b - a)).clamp(0.0, 1.0),
            lo: 0.0,
            hi: 1.0,
            done: false,
        }
    }

    /// One Newton step; `done` once `u` is the crossing. At most 60 are taken (`u` is then
    /// the last step's).
    #[inline(always)]
    fn iterate(
        &mut self,
        position: &impl Fn(f64) -> f64,
        slope: &impl Fn(f64) -> f64,
        rising: bool,
    ) {
        let u = self.u;
        let g = position(u) - self.edge;
        // 1e-9 of a count: far below the slave's microsecond, near the rounding of positions
        // of 10^5 counts.
        if g.abs() < 1e-9 {
            self.done = true;
            return;
        }
        if (g < 0.0) == rising {
            self.lo = u;
        } else {
            self.hi = u;
        }
        let newton = u - g / slope(u);
        let next = if newton > self.lo && newton < self.hi {
            newton
        } else {
            0.5 * (self.lo + self.hi)
        };
        self.done = (next - u).abs() < 1e-12 || self.hi - self.lo < 1e-12;
        self.u = next;
    }
}

/// Merge the time-ordered runs `edges[..mid]` and `edges[mid..]` in place, stably (the
/// first run's edge first on a tie), through `scratch`: rotating each of the later run's
/// edges into place was a `memmove` call per edge, 2.4 % of an emulation.
pub(super) fn merge_by_time(edges: &mut [Edge], mid: usize, scratch: &mut Vec<Edge>) {
    if mid == 0 || mid == edges.len() || edges[mid - 1].0 <= edges[mid].0 {
        return; // already in order
    }
    scratch.clear();
    scratch.extend_from_slice(&edges[..mid]);
    // The write position never passes the later run's read position: it trails it by the
    // first run's edges not yet written.
    let (mut i, mut j) = (0, mid);
    for k in 0..edges.len() {
        if i == scratch.len() {
            break; // the later run's rest is already in place
        }
        if j < edges.len() && edges[j].0 < scratch[i].0 {
            edges[k] = edges[j];
            j += 1;
        } else {
            edges[k] = scratch[i];
            i += 1;
        }
    }
}
