//! A latency distribution reported in a node's status counters as
//! `latency.<name>_us.{p50,p99,max}` (µs), for the stages a node measures itself.

use hdrhistogram::Histogram;

/// A latency distribution in µs (1 µs to 100 s, 3 significant digits).
#[derive(Debug)]
pub struct LatencyHistogram {
    name: &'static str,
    hist: Option<Histogram<u64>>,
}

impl LatencyHistogram {
    /// An empty distribution named `name` (the counters' `latency.<name>_us.*`).
    #[must_use]
    pub fn new(name: &'static str) -> Self {
        // The bounds are constants: creating the histogram does not fail.
        Self {
            name,
            hist: Histogram::new_with_bounds(1, 100_000_000, 3).ok(),
        }
    }

    /// Records `seconds`; a non-finite value is ignored, a negative one (clock offset)
    /// counts as the smallest value.
    pub fn record_s(&mut self, seconds: f64) {
        if !seconds.is_finite() {
            return;
        }
        let us = (seconds * 1e6).round().clamp(1.0, 1e12) as u64;
        if let Some(h) = &mut self.hist {
            h.saturating_record(us);
        }
    }

    /// Values recorded so far.
    #[must_use]
    pub fn len(&self) -> u64 {
        self.hist.as_ref().map_or(0, Histogram::len)
    }

    /// Whether nothing has been recorded.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Appends `latency.<name>_us.p50`, `.p99` and `.max` (µs; 0 while empty).
    pub fn named(&self, out: &mut Vec<(String, u64)>) {
        let (p50, p99, max) = match &self.hist {
            Some(h) if !h.is_empty() => {
                (h.value_at_quantile(0.5), h.value_at_quantile(0.99), h.max())
            }
            _ => (0, 0, 0),
        };
        for (q, v) in [("p50", p50), ("p99", p99), ("max", max)] {
            out.push((format!("latency.{}_us.{q}", self.name), v));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantiles_of_known_values_are_named_in_microseconds() {
        let mut h = LatencyHistogram::new("stage");
        let mut out = Vec::new();
        h.named(&mut out);
        assert!(out.iter().all(|(_, v)| *v == 0), "{out:?}");
        for ms in 1..=100 {
            h.record_s(f64::from(ms) * 1e-3);
        }
        h.record_s(f64::NAN);
        h.record_s(-1.0);
        assert_eq!(h.len(), 101);
        let mut out = Vec::new();
        h.named(&mut out);
        let get = |n: &str| {
            out.iter()
                .find(|(k, _)| k == n)
                .map(|(_, v)| *v)
                .unwrap_or(0)
        };
        assert!(
            (49_900..=51_100).contains(&get("latency.stage_us.p50")),
            "{out:?}"
        );
        assert!(
            (98_900..=100_100).contains(&get("latency.stage_us.p99")),
            "{out:?}"
        );
        assert!(
            (99_900..=100_100).contains(&get("latency.stage_us.max")),
            "{out:?}"
        );
    }
}
