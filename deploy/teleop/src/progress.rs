//! Progress of long commands (`teleop record`, `teleop play`) on stderr: one line
//! redrawn in place on a terminal, a plain line now and then otherwise (a log, CI), so
//! the output of a pipe stays readable.

use std::io::Write;
use std::time::{Duration, Instant};

/// One progress line.
#[derive(Debug)]
pub struct Progress {
    in_place: bool,
    every: Duration,
    last: Option<Instant>,
    drawn: bool,
}

impl Progress {
    /// On stderr: redrawn in place (at most 4 times a second) on a terminal, else a line
    /// every 10 s.
    pub fn stderr() -> Self {
        use std::io::IsTerminal;
        let in_place = std::io::stderr().is_terminal();
        Self::new(
            in_place,
            Duration::from_millis(if in_place { 250 } else { 10_000 }),
        )
    }

    pub fn new(in_place: bool, every: Duration) -> Self {
        Self {
            in_place,
            every,
            last: None,
            drawn: false,
        }
    }

    /// What [`Progress::show`] writes for `text`: the line redrawn in place, or a line.
    pub fn render(&self, text: &str) -> String {
        if self.in_place {
            format!("\r{text}\x1b[K")
        } else {
            format!("{text}\n")
        }
    }

    /// Whether a line is due at `now` (the first always is).
    pub fn due(&self, now: Instant) -> bool {
        self.last
            .is_none_or(|t| now.duration_since(t) >= self.every)
    }

    /// Shows `text()` if a line is due (the text is made only then).
    pub fn show(&mut self, text: impl FnOnce() -> String) {
        let now = Instant::now();
        if !self.due(now) {
            return;
        }
        self.last = Some(now);
        self.drawn = true;
        let mut err = std::io::stderr().lock();
        // Progress is a courtesy: a closed stderr stops nothing.
        let _ = err.write_all(self.render(&text()).as_bytes());
        let _ = err.flush();
    }

    /// Clears the line in place (nothing to do for plain lines).
    pub fn finish(&mut self) {
        if self.in_place && self.drawn {
            let _ = std::io::stderr().write_all(b"\r\x1b[K");
            self.drawn = false;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_terminal_gets_one_line_redrawn_a_log_plain_lines_now_and_then() {
        let tty = Progress::new(true, Duration::from_millis(250));
        assert_eq!(tty.render("12 s"), "\r12 s\x1b[K");
        let log = Progress::new(false, Duration::from_secs(10));
        assert_eq!(log.render("12 s"), "12 s\n");
        let mut p = Progress::new(false, Duration::from_secs(3600));
        let now = Instant::now();
        assert!(p.due(now));
        p.last = Some(now);
        assert!(!p.due(now + Duration::from_secs(1)));
        assert!(p.due(now + Duration::from_secs(3600)));
    }
}
