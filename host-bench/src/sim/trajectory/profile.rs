//! Time scaling: distance along a path as a smooth function of time.

/// Distance along a path as a function of time: smoothstep speed ramp up, cruise, ramp down.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Profile {
    pub(super) length: f64,
    speed: f64,
    ramp: f64,
    cruise: f64,
}

impl Profile {
    pub(super) fn new(length: f64, max_speed: f64, ramp: f64) -> Profile {
        assert!(length > 0.0 && max_speed > 0.0 && ramp > 0.0);
        // Each ramp covers speed·ramp/2.
        if length >= max_speed * ramp {
            Profile {
                length,
                speed: max_speed,
                ramp,
                cruise: (length - max_speed * ramp) / max_speed,
            }
        } else {
            Profile {
                length,
                speed: length / ramp,
                ramp,
                cruise: 0.0,
            }
        }
    }

    pub(super) fn duration(&self) -> f64 {
        2.0 * self.ramp + self.cruise
    }

    pub(super) fn breakpoints(&self) -> Vec<f64> {
        if self.cruise > 0.0 {
            vec![self.ramp, self.ramp + self.cruise]
        } else {
            vec![self.ramp]
        }
    }

    /// The first time at which the distance reaches `s` (bisection to the last bit).
    pub(super) fn time_at(&self, s: f64) -> f64 {
        let (mut lo, mut hi) = (0.0, self.duration());
        loop {
            let mid = 0.5 * (lo + hi);
            if mid <= lo || mid >= hi {
                return hi;
            }
            if self.at(mid).0 >= s {
                hi = mid;
            } else {
                lo = mid;
            }
        }
    }

    /// `(s, ds/dt)` at time `t` (clamped to the motion).
    pub(super) fn at(&self, t: f64) -> (f64, f64) {
        let t = t.clamp(0.0, self.duration());
        // Ramp from rest over x in [0, 1]: speed v·(3x² − 2x³), distance v·T·(x³ − x⁴/2).
        let ramp = |x: f64| {
            let x2 = x * x;
            (
                self.speed * self.ramp * x2 * x * (1.0 - 0.5 * x),
                self.speed * x2 * (3.0 - 2.0 * x),
            )
        };
        if t < self.ramp {
            ramp(t / self.ramp)
        } else if t <= self.ramp + self.cruise {
            (
                0.5 * self.speed * self.ramp + self.speed * (t - self.ramp),
                self.speed,
            )
        } else {
            let (d, v) = ramp((self.duration() - t) / self.ramp);
            (self.length - d, v)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn profile_is_continuous_and_reaches_the_length() {
        for (len, v, ramp) in [(0.8, 0.4, 0.8), (0.1, 0.4, 0.8), (40.0, 0.4, 0.8)] {
            let p = Profile::new(len, v, ramp);
            let t_end = p.duration();
            assert_eq!(p.at(0.0), (0.0, 0.0));
            let (s, sd) = p.at(t_end);
            assert!((s - len).abs() < 1e-12 && sd.abs() < 1e-12, "{s} {sd}");
            for &b in &p.breakpoints() {
                let (a, va) = p.at(b - 1e-9);
                let (c, vc) = p.at(b + 1e-9);
                assert!((a - c).abs() < 1e-8 && (va - vc).abs() < 1e-7);
            }
            // ds/dt is the derivative of s.
            for k in 1..20 {
                let t = t_end * k as f64 / 20.0;
                let h = 1e-6;
                let num = (p.at(t + h).0 - p.at(t - h).0) / (2.0 * h);
                assert!(
                    (num - p.at(t).1).abs() < 1e-7,
                    "t {t}: {num} vs {}",
                    p.at(t).1
                );
            }
        }
    }
}
