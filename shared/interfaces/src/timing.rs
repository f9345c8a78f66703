//! The time step every periodic core measures, written once: the time since its
//! previous step on its own clock, capped, with a stated value for the first step and
//! for a clock that did not advance.

/// Measures a periodic core's time step from the times it is stepped at.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StepTimer {
    last_s: Option<f64>,
}

impl StepTimer {
    /// A timer that has not stepped yet.
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// The step to use at `now_s` (s): the time since the previous call, at most
    /// `max_dt_s`; `first_dt_s` on the first call, when the clock did not advance
    /// (stood still or went backwards) and when `now_s` is not finite. A finite
    /// `now_s` becomes the previous step's time, a non-finite one is not kept.
    pub fn step(&mut self, now_s: f64, first_dt_s: f64, max_dt_s: f64) -> f64 {
        let dt = match self.last_s {
            Some(t) if now_s > t => (now_s - t).min(max_dt_s),
            _ => first_dt_s,
        };
        if now_s.is_finite() {
            self.last_s = Some(now_s);
        }
        dt
    }

    /// When the last step was, s (None before the first).
    #[must_use]
    pub fn last_s(&self) -> Option<f64> {
        self.last_s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn steps_are_measured_capped_and_stated_where_they_cannot_be() {
        let mut t = StepTimer::new();
        assert_eq!(t.step(1.0, 0.01, 0.1), 0.01, "first step");
        assert!((t.step(1.02, 0.01, 0.1) - 0.02).abs() < 1e-12, "measured");
        assert_eq!(t.step(2.0, 0.01, 0.1), 0.1, "capped");
        assert_eq!(t.step(2.0, 0.01, 0.1), 0.01, "clock stood still");
        assert_eq!(t.step(1.5, 0.01, 0.1), 0.01, "clock went backwards");
        assert!(
            (t.step(1.53, 0.01, 0.1) - 0.03).abs() < 1e-12,
            "from the last time"
        );
        assert_eq!(t.step(f64::NAN, 0.01, 0.1), 0.01, "NaN time");
        assert_eq!(t.last_s(), Some(1.53), "a NaN time is not kept");
        assert!((t.step(1.56, 0.01, 0.1) - 0.03).abs() < 1e-12);
    }
}
