//! How far the poses of a play are from the stream's truth rows.

use robot_math::Pose2;

/// Error of the board's poses against the truth rows, as the poses come: the board's pose at a
/// row's instant is interpolated between the two updates around it (the start pose before the
/// first); a row past the last update is not scored.
pub struct Scorer<I: Iterator<Item = (u64, Pose2)>> {
    truth: std::iter::Peekable<I>,
    period_ns: f64,
    /// The last two poses (update `poses - 2` and `poses - 1`; the start is pose 0).
    before: Pose2,
    last: Pose2,
    poses: usize,
    final_error: Option<f64>,
    max: f64,
    rows: usize,
    /// With [`keep_rows`](Self::keep_rows): each row scored since the last
    /// [`take_rows`](Self::take_rows), as (t ns, estimate, truth).
    kept: Option<Vec<(u64, Pose2, Pose2)>>,
}

impl<I: Iterator<Item = (u64, Pose2)>> Scorer<I> {
    /// `truth` rows (ns from the start, in order) against updates every `period_us`.
    pub fn new(truth: I, period_us: u32, start: Pose2) -> Self {
        Scorer {
            truth: truth.peekable(),
            period_ns: period_us as f64 * 1e3,
            before: start,
            last: start,
            poses: 1,
            final_error: None,
            max: 0.0,
            rows: 0,
            kept: None,
        }
    }

    /// Keep each scored row for [`take_rows`](Self::take_rows) (the live view, the MCAP file).
    pub fn keep_rows(mut self) -> Self {
        self.kept = Some(Vec::new());
        self
    }

    /// The rows scored since the last call, as (t ns, estimate, truth).
    pub fn take_rows(&mut self) -> Vec<(u64, Pose2, Pose2)> {
        self.kept.as_mut().map(std::mem::take).unwrap_or_default()
    }

    /// The pose of the next update.
    pub fn push(&mut self, pose: Pose2) {
        self.before = self.last;
        self.last = pose;
        self.poses += 1;
        // Rows between the two last poses (the earlier ones were scored at the pose before).
        self.score_until(self.poses - 1, true);
    }

    /// Score the rows before pose `end`'s instant, between the last two poses (else at the
    /// last pose).
    fn score_until(&mut self, end: usize, between: bool) {
        while let Some(&(t_ns, truth)) = self.truth.peek() {
            let k = t_ns as f64 / self.period_ns;
            if k.floor() as usize >= end {
                return;
            }
            self.truth.next();
            let (a, b) = if between {
                (self.before, self.last)
            } else {
                (self.last, self.last)
            };
            let f = k - k.floor();
            let est = Pose2::new(a.x + (b.x - a.x) * f, a.y + (b.y - a.y) * f, a.theta);
            let e = est.distance_to(truth);
            self.max = self.max.max(e);
            self.final_error = Some(e);
            self.rows += 1;
            if let Some(k) = &mut self.kept {
                k.push((t_ns, est, truth));
            }
        }
    }

    /// The final and largest error, and the rows scored; the rows up to the next period after
    /// the last update are scored at its pose.
    pub fn finish(mut self) -> (Option<f64>, Option<f64>, usize) {
        self.score_until(self.poses, false);
        (
            self.final_error,
            self.final_error.map(|_| self.max),
            self.rows,
        )
    }
}
