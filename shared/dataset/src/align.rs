//! Frames at a fixed rate from messages stamped at their source.
//!
//! A frame at time `t` holds, for each input, the newest message whose source stamp
//! is at or before `t` (what was known by then, never a later message), provided that
//! message is at most the input's `max_age` old; otherwise the input is *missing* for
//! that frame. Frame times are `start + k / fps` exactly; no message is ever assumed
//! to have come at its nominal rate.

/// One input's messages, sorted by source stamp (ns).
#[derive(Debug, Clone, PartialEq)]
pub struct Stream<T> {
    stamps: Vec<i64>,
    values: Vec<T>,
}

impl<T> Default for Stream<T> {
    fn default() -> Self {
        Self {
            stamps: Vec::new(),
            values: Vec::new(),
        }
    }
}

impl<T> Stream<T> {
    /// From (stamp, value) pairs in any order; equal stamps keep their given order
    /// (the later one wins a lookup).
    #[must_use]
    pub fn new(mut samples: Vec<(i64, T)>) -> Self {
        samples.sort_by_key(|s| s.0);
        let (stamps, values) = samples.into_iter().unzip();
        Self { stamps, values }
    }

    /// From (arrival, stamp, value) triples in any order: sorted by stamp, messages of
    /// equal stamps by arrival (the later arrival wins a lookup), then in the given
    /// order. A bag's file order and its log times may differ; this order does not
    /// depend on either reader's choice.
    #[must_use]
    pub fn from_arrivals(mut samples: Vec<(u64, i64, T)>) -> Self {
        samples.sort_by_key(|s| (s.1, s.0));
        Self::new(samples.into_iter().map(|(_, t, v)| (t, v)).collect())
    }

    #[must_use]
    pub fn len(&self) -> usize {
        self.stamps.len()
    }

    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.stamps.is_empty()
    }

    /// The newest message at or before `t_ns` and its age (ns), if it is at most
    /// `max_age_ns` old.
    #[must_use]
    pub fn at(&self, t_ns: i64, max_age_ns: i64) -> Option<(&T, i64)> {
        let i = newest_at(&self.stamps, t_ns, max_age_ns)?;
        Some((&self.values[i], t_ns - self.stamps[i]))
    }

    /// Index of the message [`Stream::at`] would give.
    #[must_use]
    pub fn index_at(&self, t_ns: i64, max_age_ns: i64) -> Option<usize> {
        newest_at(&self.stamps, t_ns, max_age_ns)
    }

    #[must_use]
    pub fn stamps(&self) -> &[i64] {
        &self.stamps
    }

    #[must_use]
    pub fn values(&self) -> &[T] {
        &self.values
    }

    #[must_use]
    pub fn first_stamp(&self) -> Option<i64> {
        self.stamps.first().copied()
    }

    #[must_use]
    pub fn last_stamp(&self) -> Option<i64> {
        self.stamps.last().copied()
    }
}

/// In sorted `stamps`, the index of the newest at or before `t_ns`, if it is at most
/// `max_age_ns` old: the alignment rule of every frame.
#[must_use]
pub fn newest_at(stamps: &[i64], t_ns: i64, max_age_ns: i64) -> Option<usize> {
    let i = stamps.partition_point(|&s| s <= t_ns).checked_sub(1)?;
    (t_ns - stamps[i] <= max_age_ns).then_some(i)
}

/// The time of frame `k` of an episode that starts at `start_ns`, at `fps`: exact
/// integer arithmetic (no drift over long episodes).
#[must_use]
pub fn frame_time_ns(start_ns: i64, k: u64, fps: u32) -> i64 {
    let offset = i128::from(k) * 1_000_000_000 / i128::from(fps.max(1));
    start_ns.saturating_add(i64::try_from(offset).unwrap_or(i64::MAX))
}

/// Runs of consecutive `true` in `complete` of at least `min_len`: (first, end) frame
/// indices, end exclusive.
#[must_use]
pub fn complete_runs(complete: &[bool], min_len: usize) -> Vec<(usize, usize)> {
    let mut runs = Vec::new();
    let mut start = None;
    for (i, &ok) in complete.iter().chain(std::iter::once(&false)).enumerate() {
        match (ok, start) {
            (true, None) => start = Some(i),
            (false, Some(s)) => {
                if i - s >= min_len.max(1) {
                    runs.push((s, i));
                }
                start = None;
            }
            _ => {}
        }
    }
    runs
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_frame_takes_the_newest_message_at_or_before_it_within_its_age() {
        // Out of order on purpose.
        let s = Stream::new(vec![(30, 'c'), (10, 'a'), (20, 'b')]);
        assert_eq!(s.at(5, 100), None, "nothing before the first message");
        assert_eq!(s.at(10, 100), Some((&'a', 0)));
        assert_eq!(s.at(19, 100), Some((&'a', 9)));
        assert_eq!(s.at(20, 100), Some((&'b', 0)));
        assert_eq!(s.at(55, 100), Some((&'c', 25)));
        assert_eq!(s.at(55, 24), None, "too old");
        assert_eq!(s.index_at(25, 10), Some(1));
    }

    #[test]
    fn equal_stamps_are_ordered_by_arrival() {
        let s = Stream::from_arrivals(vec![(5, 10, 'b'), (3, 10, 'a'), (9, 5, 'z'), (4, 20, 'c')]);
        assert_eq!(s.values(), &['z', 'a', 'b', 'c']);
        assert_eq!(s.at(15, 100), Some((&'b', 5)));
    }

    #[test]
    fn frame_times_are_exact_at_any_rate() {
        assert_eq!(frame_time_ns(1_000, 0, 30), 1_000);
        assert_eq!(frame_time_ns(0, 30, 30), 1_000_000_000);
        assert_eq!(frame_time_ns(0, 1, 30), 33_333_333);
        // Three hours at 30 fps: still exact seconds.
        assert_eq!(frame_time_ns(0, 324_000, 30), 10_800_000_000_000);
    }

    #[test]
    fn runs_of_complete_frames() {
        let c = [true, true, false, true, true, true, false, false, true];
        assert_eq!(complete_runs(&c, 1), vec![(0, 2), (3, 6), (8, 9)]);
        assert_eq!(complete_runs(&c, 3), vec![(3, 6)]);
        assert!(complete_runs(&[], 1).is_empty());
    }
}
