//! One commander at a time: a command topic's samples are taken from one publisher,
//! never blended with another's.
//!
//! A [`SourceLock`] wraps a subscriber. The first publisher heard while unlocked becomes
//! the source; from then on the subscriber drops every other publisher's samples
//! before they are queued (counted as `<topic>.rejected_foreign`), so a second operator
//! station can neither steer the robot nor displace the locked station's newest sample.
//! The lock is released only when the owner asks ([`SourceLock::release`], e.g. a
//! takeover allowed at a new engagement) or when the locked publisher has been silent
//! for `release_after_s` and the owner allows it ([`SourceLock::release_if_silent`]).
//! Foreign publishers heard within the last [`CONFLICT_WINDOW_S`] make a conflict,
//! reported by [`SourceLock::conflict`] for the node's status.

use serde::{Deserialize, Serialize};
use teleop_bus::{PublisherInfo, Received, Subscriber};
use teleop_msgs::Message;

/// Foreign publishers heard within this window make an active conflict, s.
pub const CONFLICT_WINDOW_S: f64 = 1.0;

/// When another operator site may take over the robot.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Takeover {
    /// Only once the commanding site has fallen silent for `release_after_s` while the
    /// robot is disengaged (default).
    #[default]
    WhenSilent,
    /// Also at every new engagement: while the robot is disengaged any site's fresh
    /// clutch press may take over.
    OnNewEngagement,
}

/// One commanding operator site at a time: each command topic is locked onto one
/// publisher ([`SourceLock`]); samples of any other are refused, counted
/// and reported as a conflict, never blended.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CommanderConfig {
    pub takeover: Takeover,
    /// A locked publisher silent this long may be replaced (while disengaged), s.
    pub release_after_s: f64,
}

impl Default for CommanderConfig {
    fn default() -> Self {
        Self {
            takeover: Takeover::WhenSilent,
            release_after_s: 1.0,
        }
    }
}

impl CommanderConfig {
    /// # Errors
    /// A text naming the bad field.
    pub fn validate(&self) -> Result<(), String> {
        if self.release_after_s.is_finite()
            && self.release_after_s > 0.0
            && self.release_after_s <= 60.0
        {
            Ok(())
        } else {
            Err(format!(
                "commander.release_after_s must be in (0, 60] s, got {}",
                self.release_after_s
            ))
        }
    }
}

impl CommanderConfig {
    /// What a node does with its command locks in a period where its robot is
    /// disengaged: a lock whose publisher has been silent for `release_after_s` goes, and
    /// with [`Takeover::OnNewEngagement`] every lock goes (the next clutch press may come
    /// from another site).
    pub fn disengaged(&self, now_s: f64, locks: &mut [&mut dyn CommandLock]) {
        for lock in locks.iter_mut() {
            lock.release_if_silent(now_s);
            if self.takeover == Takeover::OnNewEngagement {
                lock.release();
            }
        }
    }
}

/// The part of a [`SourceLock`] a node handles alike for all its command topics.
pub trait CommandLock {
    /// See [`SourceLock::release_if_silent`].
    fn release_if_silent(&mut self, now_s: f64);
    /// See [`SourceLock::release`].
    fn release(&mut self);
    /// See [`SourceLock::conflict`].
    fn conflict(&mut self, now_s: f64) -> Option<&str>;
}

impl<T: Message> CommandLock for SourceLock<T> {
    fn release_if_silent(&mut self, now_s: f64) {
        SourceLock::release_if_silent(self, now_s);
    }
    fn release(&mut self) {
        SourceLock::release(self);
    }
    fn conflict(&mut self, now_s: f64) -> Option<&str> {
        SourceLock::conflict(self, now_s)
    }
}

/// The conflicts of `locks` at `now_s` (each updated), the last one's text if any: what
/// a node reports as its last error.
pub fn conflict(now_s: f64, locks: &mut [&mut dyn CommandLock]) -> Option<String> {
    let mut text = None;
    for lock in locks.iter_mut() {
        if let Some(t) = lock.conflict(now_s) {
            text = Some(t.to_owned());
        }
    }
    text
}

/// A subscriber locked onto one publisher; see the [module docs](self).
#[derive(Debug)]
pub struct SourceLock<T: Message> {
    sub: Subscriber<T>,
    release_after_s: f64,
    locked: Option<[u8; 16]>,
    last_heard_s: f64,
    locks: u64,
    conflicts: u64,
    conflict: Option<String>,
    /// Names of publishers once resolved (they stay named after their tokens go).
    names: std::collections::HashMap<[u8; 16], String>,
}

impl<T: Message> SourceLock<T> {
    /// An unlocked source on `sub`; a locked publisher silent for `release_after_s`
    /// may be released.
    pub fn new(sub: Subscriber<T>, release_after_s: f64) -> Self {
        Self {
            sub,
            release_after_s,
            locked: None,
            last_heard_s: f64::NEG_INFINITY,
            locks: 0,
            conflicts: 0,
            conflict: None,
            names: std::collections::HashMap::new(),
        }
    }

    /// The newest sample of the locked publisher since the last call. Unlocked, the
    /// first publisher in the queue becomes the source.
    pub fn poll(&mut self) -> Option<Received<T>> {
        let mut newest = None;
        self.take_each(|r| newest = Some(r));
        newest
    }

    /// Every sample of the locked publisher since the last call, oldest first, for a
    /// node that keeps a history (a pose buffer) rather than the newest command.
    /// Unlocked, the first publisher in the queue becomes the source.
    pub fn drain(&mut self) -> Vec<Received<T>> {
        let mut all = Vec::new();
        self.take_each(|r| all.push(r));
        all
    }

    fn take_each(&mut self, mut take: impl FnMut(Received<T>)) {
        let mut heard = None;
        while let Some(r) = self.sub.try_recv() {
            let from_source = match self.locked {
                None => {
                    self.locked = Some(r.publisher_gid);
                    self.sub.lock_source(Some(r.publisher_gid));
                    self.locks += 1;
                    let source = self.describe(&r.publisher_gid);
                    tracing::info!(
                        topic = self.sub.spec().name,
                        %source,
                        "commands locked onto one publisher"
                    );
                    true
                }
                // Another's, queued just before the lock took effect: dropped.
                Some(g) => g == r.publisher_gid,
            };
            if from_source {
                heard = Some(r.receive_time_s());
                take(r);
            }
        }
        if let Some(t) = heard {
            self.last_heard_s = t;
        }
    }

    /// Drops the lock: the next publisher heard becomes the source.
    pub fn release(&mut self) {
        if self.locked.take().is_some() {
            self.sub.lock_source(None);
            self.last_heard_s = f64::NEG_INFINITY;
        }
    }

    /// Drops the lock if the locked publisher has been silent for `release_after_s`.
    pub fn release_if_silent(&mut self, now_s: f64) {
        if self.locked.is_some() && now_s - self.last_heard_s > self.release_after_s {
            tracing::info!(
                topic = self.sub.spec().name,
                "locked publisher silent: lock released"
            );
            self.release();
        }
    }

    /// The locked publisher's GID.
    pub fn locked(&self) -> Option<[u8; 16]> {
        self.locked
    }

    /// What the bus knows of the locked publisher.
    pub fn locked_info(&self) -> Option<PublisherInfo> {
        self.locked.and_then(|g| self.sub.publisher_info(&g))
    }

    fn describe(&mut self, gid: &[u8; 16]) -> String {
        if let Some(name) = self.names.get(gid) {
            return name.clone();
        }
        match self.sub.publisher_info(gid) {
            Some(p) => {
                // Bounded: a few stations, not a flood of made-up GIDs.
                if self.names.len() < 64 {
                    self.names.insert(*gid, p.label());
                }
                p.label()
            }
            None => "an unannounced publisher".to_owned(),
        }
    }

    /// Updates and returns the conflict at `now_s`: foreign publishers heard within
    /// [`CONFLICT_WINDOW_S`] while locked, named.
    pub fn conflict(&mut self, now_s: f64) -> Option<&str> {
        let since_ns = ((now_s - CONFLICT_WINDOW_S) * 1e9) as i64;
        let foreign_gids: Vec<[u8; 16]> = match self.locked {
            None => Vec::new(),
            Some(locked) => self
                .sub
                .publishers_since(since_ns)
                .into_iter()
                .filter(|p| p.gid != locked)
                .map(|p| p.gid)
                .collect(),
        };
        let foreign: Vec<String> = foreign_gids.iter().map(|g| self.describe(g)).collect();
        let locked_name = match self.locked {
            Some(g) => self.describe(&g),
            None => String::new(),
        };
        if foreign.is_empty() {
            self.conflict = None;
        } else {
            let text = format!(
                "conflicting commander on /{}: {} (locked to {})",
                self.sub.spec().name,
                foreign.join(", "),
                locked_name
            );
            if self.conflict.is_none() {
                self.conflicts += 1;
                tracing::warn!("{text}");
            }
            self.conflict = Some(text);
        }
        self.conflict.as_deref()
    }

    /// The subscription (statistics).
    pub fn subscriber(&self) -> &Subscriber<T> {
        &self.sub
    }

    /// Counters: the subscription's, plus `<prefix>.source_locks`,
    /// `<prefix>.conflicts` and `<prefix>.conflict_active`.
    pub fn named_counters(&self) -> Vec<(String, u64)> {
        let prefix = self.sub.spec().name.rsplit('/').next().unwrap_or_default();
        let mut out = self.sub.named_counters();
        out.push((format!("{prefix}.source_locks"), self.locks));
        out.push((format!("{prefix}.conflicts"), self.conflicts));
        out.push((
            format!("{prefix}.conflict_active"),
            u64::from(self.conflict.is_some()),
        ));
        out
    }
}
