//! The operator panel on a keyboard, `[panel] kind = "keyboard"`: the deadman, the
//! clutch, the camera-arm stop and the motion scale for a person at the keys of the
//! terminal the wrist tracker runs in.
//!
//! | key | what |
//! |---|---|
//! | space, held | enable (the deadman): held while its auto-repeat keeps arriving |
//! | `c` | clutch (right pedal) on / off; engages only while enable is held |
//! | `s` | camera-arm stop (left pedal) on / off |
//! | `1` `2` `3` `4` | motion scale 1, 1/2, 1/3, 1/4 |
//! | `x` or Esc | release: enable and clutch off at once |
//!
//! Letters are taken in either case. A terminal sends no key-up events: a held key
//! arrives once, then, after the terminal's auto-repeat delay (typically 250-660 ms),
//! over and over (typically 25-30 per second). Enable is therefore true while the last
//! space is younger than `hold_timeout_s` (default 0.7 s), which must exceed the
//! initial auto-repeat delay, or a held space drops enable before its first repeat.
//! Letting go of space drops enable `hold_timeout_s` after its last repeat; the clutch
//! is released with it, so a fresh `c` (with space held) is needed to move again.
//!
//! The toggles (`c`, `s`) count once per press: the same key arriving again within
//! `hold_timeout_s` of itself, with no other key in between, is its auto-repeat and is
//! ignored, so holding `c` does not flicker the clutch. Keys that send escape sequences
//! (arrows, function keys) begin with Esc: they release as Esc does, and the rest of
//! the sequence is ignored as one unknown key. Other keys are ignored and counted.
//!
//! [`KeyboardPanel`] is the pure core: key bytes with their arrival times in, the
//! [`PedalState`] at a time out, no I/O. [`KeyboardReader`] feeds it from stdin (or
//! any byte stream) on a thread of its own and implements [`OperatorPanel`]: on a
//! terminal it switches off line buffering and echo (Ctrl-C still stops the node) and
//! restores the terminal's settings when it is dropped or its input ends; when the
//! input ends or fails, the panel is lost and every read fails with
//! [`HardwareError::NotConnected`] (the robots stop on a lost panel).

use std::fmt;
use std::io::{IsTerminal, Read};
use std::os::fd::{AsFd, OwnedFd};
use std::sync::{Arc, Mutex, MutexGuard};

use nix::sys::termios::{self, LocalFlags, SetArg, SpecialCharacterIndices, Termios};
use serde::{Deserialize, Serialize};
use teleop_bus::Clock;
use teleop_hardware::{HardwareError, OperatorPanel, PedalState};

/// One line of help, logged when the panel starts.
pub const HELP: &str = "keyboard panel: hold space = enable (deadman), c = clutch on/off \
(with space held), s = camera-arm stop on/off, 1-4 = motion scale 1, 1/2, 1/3, 1/4, \
x or Esc = release all, Ctrl-C = stop the node";

/// The bytes of one escape sequence arrive together: a byte arriving later than this
/// after the previous one is a key of its own, s.
const ESCAPE_SEQUENCE_GAP_S: f64 = 0.05;
/// Longest escape sequence taken as one; a longer one ends there.
const ESCAPE_SEQUENCE_MAX_LEN: usize = 16;
const ESC: u8 = 0x1b;

/// Bounds of `hold_timeout_s`, `(min, max]`, s: the upper bound caps how long the
/// robots keep moving after the person lets go of space.
pub const HOLD_TIMEOUT_RANGE_S: (f64, f64) = (0.0, 2.0);

/// The keyboard panel, `[panel] kind = "keyboard"`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct KeyboardPanelConfig {
    /// Enable is held while the last space is younger than this, s, in (0, 2]. It must
    /// exceed the terminal's initial auto-repeat delay (typically 250-660 ms). Default
    /// 0.7.
    pub hold_timeout_s: f64,
    /// The motion scale at start, in (0, 1]; the keys `1`-`4` change it. Default 1.
    pub motion_scale: f64,
}

impl Default for KeyboardPanelConfig {
    fn default() -> Self {
        Self {
            hold_timeout_s: 0.7,
            motion_scale: 1.0,
        }
    }
}

impl KeyboardPanelConfig {
    /// # Errors
    /// [`KeyboardError::OutOfRange`] naming the first field out of its range.
    pub fn validate(&self) -> Result<(), KeyboardError> {
        let (lo, hi) = HOLD_TIMEOUT_RANGE_S;
        for (name, value, min, max) in [
            ("hold_timeout_s", self.hold_timeout_s, lo, hi),
            ("motion_scale", self.motion_scale, 0.0, 1.0),
        ] {
            if !(value.is_finite() && value > min && value <= max) {
                return Err(KeyboardError::OutOfRange {
                    name,
                    value,
                    min,
                    max,
                });
            }
        }
        Ok(())
    }
}

/// Errors of the keyboard panel.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum KeyboardError {
    /// A config value outside its range.
    #[error("{name} must be in ({min}, {max}], got {value}")]
    OutOfRange {
        /// Field name.
        name: &'static str,
        /// The value given.
        value: f64,
        /// Bound, excluded.
        min: f64,
        /// Bound, included.
        max: f64,
    },
    /// Reading or setting the terminal's mode failed.
    #[error("keyboard: cannot {what} the terminal's mode: {source}")]
    Terminal {
        /// `read` or `set`.
        what: &'static str,
        source: nix::errno::Errno,
    },
    /// The input cannot be duplicated or the reader thread not started.
    #[error("keyboard: {what}: {source}")]
    Io {
        /// What was being done.
        what: &'static str,
        source: std::io::Error,
    },
}

/// A key as the panel understands it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Key {
    Enable,
    Clutch,
    CameraStop,
    /// Motion scale `1 / n`.
    Scale(u8),
    /// `x` or Esc.
    Release(u8),
    /// An escape sequence after its Esc (arrows, function keys).
    Sequence,
    Unknown(u8),
}

impl Key {
    fn of(byte: u8) -> Self {
        match byte {
            b' ' => Self::Enable,
            b'c' | b'C' => Self::Clutch,
            b's' | b'S' => Self::CameraStop,
            b'1'..=b'4' => Self::Scale(byte - b'0'),
            b'x' | b'X' | ESC => Self::Release(byte),
            other => Self::Unknown(other),
        }
    }
}

/// Why the clutch was released.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ClutchRelease {
    /// `c` pressed while engaged.
    Key,
    /// Enable dropped (space not repeated for `hold_timeout_s`).
    EnableDropped,
    /// `x` or Esc.
    ReleaseKey,
}

/// A change of the panel's state (or a key it refused), in the order it happened: what
/// the person is told they did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Notice {
    /// Space arrived while enable was off.
    EnableHeld,
    /// No space for `hold_timeout_s` (s): enable off.
    EnableDropped {
        after_s: f64,
    },
    ClutchEngaged,
    ClutchReleased(ClutchRelease),
    /// `c` while enable was not held: the clutch stays off.
    ClutchRefused,
    CameraStop(bool),
    /// Motion scale `1 / n`.
    MotionScale(u8),
    /// `x` or Esc (the byte) released enable and the clutch.
    Released(u8),
    /// A key the panel does not know (`None`: an escape sequence).
    UnknownKey(Option<u8>),
}

fn key_name(byte: u8) -> String {
    match byte {
        ESC => "Esc".into(),
        b' ' => "space".into(),
        b if b.is_ascii_graphic() => char::from(b).to_string(),
        b => format!("0x{b:02x}"),
    }
}

impl fmt::Display for Notice {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::EnableHeld => write!(f, "keyboard: enable held (space)"),
            Self::EnableDropped { after_s } => write!(
                f,
                "keyboard: enable dropped (no space for {after_s} s: let go)"
            ),
            Self::ClutchEngaged => write!(f, "keyboard: clutch engaged (c)"),
            Self::ClutchReleased(ClutchRelease::Key) => {
                write!(f, "keyboard: clutch released (c)")
            }
            Self::ClutchReleased(ClutchRelease::EnableDropped) => write!(
                f,
                "keyboard: clutch released (enable dropped; press c again with space held)"
            ),
            Self::ClutchReleased(ClutchRelease::ReleaseKey) => {
                write!(f, "keyboard: clutch released (release key)")
            }
            Self::ClutchRefused => write!(
                f,
                "keyboard: clutch refused (c): hold space first, then press c"
            ),
            Self::CameraStop(true) => write!(f, "keyboard: camera arm stopped (s)"),
            Self::CameraStop(false) => write!(f, "keyboard: camera arm free to move (s)"),
            Self::MotionScale(1) => write!(f, "keyboard: motion scale 1 (1)"),
            Self::MotionScale(n) => write!(f, "keyboard: motion scale 1/{n} ({n})"),
            Self::Released(b) => write!(
                f,
                "keyboard: released: enable off, clutch off ({})",
                key_name(*b)
            ),
            Self::UnknownKey(Some(b)) => {
                write!(f, "keyboard: key {} ignored; {HELP}", key_name(*b))
            }
            Self::UnknownKey(None) => {
                write!(
                    f,
                    "keyboard: special key ignored (it released as Esc); {HELP}"
                )
            }
        }
    }
}

/// Where the escape-sequence parser is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Escape {
    None,
    /// Right after an Esc.
    AfterEsc,
    /// In a CSI sequence (`Esc [`), bytes so far.
    Csi(usize),
    /// In an SS3 sequence (`Esc O`): one byte to come.
    Ss3,
}

/// The pure core of the keyboard panel: fed with key bytes and their arrival times,
/// asked for the state at a time. Times are seconds on any clock whose differences
/// are seconds (the node's).
///
/// The clutch is never on while enable is off: it engages only with enable held and
/// is released when enable drops.
#[derive(Debug, Clone)]
pub struct KeyboardPanel {
    hold_timeout_s: f64,
    last_enable_s: Option<f64>,
    enable: bool,
    clutch: bool,
    camera_stop: bool,
    scale: u8,
    motion_scale: f64,
    /// The previous key and when it arrived (auto-repeat detection).
    previous: Option<(Key, f64)>,
    /// `previous` before the last Esc: an escape sequence is one key after what came
    /// before its Esc.
    before_esc: Option<(Key, f64)>,
    escape: Escape,
    last_byte_s: f64,
    keys: u64,
    unknown_keys: u64,
    notices: Vec<Notice>,
}

impl KeyboardPanel {
    /// Everything off, the configured motion scale.
    ///
    /// # Errors
    /// [`KeyboardError::OutOfRange`] for an invalid config.
    pub fn new(cfg: &KeyboardPanelConfig) -> Result<Self, KeyboardError> {
        cfg.validate()?;
        Ok(Self {
            hold_timeout_s: cfg.hold_timeout_s,
            last_enable_s: None,
            enable: false,
            clutch: false,
            camera_stop: false,
            scale: 0,
            motion_scale: cfg.motion_scale,
            previous: None,
            before_esc: None,
            escape: Escape::None,
            last_byte_s: f64::NEG_INFINITY,
            keys: 0,
            unknown_keys: 0,
            notices: Vec::new(),
        })
    }

    /// A key byte that arrived at `t_s`.
    pub fn press(&mut self, t_s: f64, byte: u8) {
        self.keys += 1;
        self.expire(t_s);
        let key = self.parse(t_s, byte);
        self.last_byte_s = t_s;
        let Some(key) = key else {
            return;
        };
        // The same key again, nothing in between, within the hold timeout: the
        // terminal's auto-repeat of a held key.
        let repeat = self
            .previous
            .is_some_and(|(k, at)| k == key && (t_s - at).abs() < self.hold_timeout_s);
        if key == Key::Release(ESC) {
            self.before_esc = self.previous;
        }
        self.previous = Some((key, t_s));
        match key {
            Key::Enable => {
                self.last_enable_s = Some(t_s);
                if !self.enable {
                    self.enable = true;
                    self.notices.push(Notice::EnableHeld);
                }
            }
            Key::Clutch if repeat => {}
            Key::Clutch => {
                if self.clutch {
                    self.clutch = false;
                    self.notices
                        .push(Notice::ClutchReleased(ClutchRelease::Key));
                } else if self.enable {
                    self.clutch = true;
                    self.notices.push(Notice::ClutchEngaged);
                } else {
                    self.notices.push(Notice::ClutchRefused);
                }
            }
            Key::CameraStop if repeat => {}
            Key::CameraStop => {
                self.camera_stop = !self.camera_stop;
                self.notices.push(Notice::CameraStop(self.camera_stop));
            }
            Key::Scale(n) => {
                if self.scale != n {
                    self.scale = n;
                    self.motion_scale = 1.0 / f64::from(n);
                    self.notices.push(Notice::MotionScale(n));
                }
            }
            Key::Release(b) => self.release(b),
            Key::Sequence => {
                self.unknown_keys += 1;
                if !repeat {
                    self.notices.push(Notice::UnknownKey(None));
                }
            }
            Key::Unknown(b) => {
                self.unknown_keys += 1;
                if !repeat {
                    self.notices.push(Notice::UnknownKey(Some(b)));
                }
            }
        }
    }

    /// The state at `now_s` (enable and, with it, the clutch dropped when the last
    /// space is `hold_timeout_s` old).
    pub fn state(&mut self, now_s: f64) -> PedalState {
        self.expire(now_s);
        PedalState {
            clutch: self.clutch,
            enable: self.enable,
            camera_stop: self.camera_stop,
            motion_scale: self.motion_scale,
        }
    }

    /// Key bytes received (escape-sequence bytes included).
    pub fn keys(&self) -> u64 {
        self.keys
    }

    /// Keys ignored: unknown bytes, escape sequences (each counted once).
    pub fn unknown_keys(&self) -> u64 {
        self.unknown_keys
    }

    /// The changes since the last call, oldest first.
    pub fn take_notices(&mut self) -> Vec<Notice> {
        std::mem::take(&mut self.notices)
    }

    /// The escape-sequence parser: the key a byte makes, `None` when it is inside a
    /// sequence.
    fn parse(&mut self, t_s: f64, byte: u8) -> Option<Key> {
        let together = (t_s - self.last_byte_s).abs() <= ESCAPE_SEQUENCE_GAP_S;
        match self.escape {
            Escape::None => {}
            // A sequence cut short by a pause: it ends there, counted once; the byte
            // is a key of its own.
            Escape::Csi(_) | Escape::Ss3 if !together => {
                self.escape = Escape::None;
                self.count_sequence();
            }
            Escape::AfterEsc if together && (byte == b'[' || byte == b'O') => {
                // A held arrow key repeats as sequences, not as Esc then something.
                self.previous = self.before_esc;
                self.escape = if byte == b'[' {
                    Escape::Csi(0)
                } else {
                    Escape::Ss3
                };
                return None;
            }
            // A lone Esc, Alt+key (Esc, key): the key is taken as such.
            Escape::AfterEsc => self.escape = Escape::None,
            Escape::Csi(n) => {
                // A CSI ends with its final byte (0x40-0x7e).
                if (0x40..=0x7e).contains(&byte) || n + 1 >= ESCAPE_SEQUENCE_MAX_LEN {
                    self.escape = Escape::None;
                    return Some(Key::Sequence);
                }
                self.escape = Escape::Csi(n + 1);
                return None;
            }
            Escape::Ss3 => {
                self.escape = Escape::None;
                return Some(Key::Sequence);
            }
        }
        if byte == ESC {
            self.escape = Escape::AfterEsc;
        }
        Some(Key::of(byte))
    }

    /// An escape sequence cut short, counted as one unknown key.
    fn count_sequence(&mut self) {
        self.unknown_keys += 1;
        self.notices.push(Notice::UnknownKey(None));
        self.previous = Some((Key::Sequence, self.last_byte_s));
    }

    fn held_at(&self, t_s: f64) -> bool {
        // A space stamped later than `t_s` by more than the timeout (the clock stepped
        // back) does not count either. NaN: not held.
        self.last_enable_s
            .is_some_and(|p| (t_s - p).abs() < self.hold_timeout_s)
    }

    /// Applies the hold timeout at `t_s`.
    fn expire(&mut self, t_s: f64) {
        let held = self.held_at(t_s);
        if self.enable && !held {
            self.enable = false;
            self.notices.push(Notice::EnableDropped {
                after_s: self.hold_timeout_s,
            });
        }
        if self.clutch && !self.enable {
            self.clutch = false;
            self.notices
                .push(Notice::ClutchReleased(ClutchRelease::EnableDropped));
        }
    }

    fn release(&mut self, byte: u8) {
        let was = self.enable || self.clutch;
        self.last_enable_s = None;
        self.enable = false;
        if self.clutch {
            self.clutch = false;
            self.notices
                .push(Notice::ClutchReleased(ClutchRelease::ReleaseKey));
        }
        if was {
            self.notices.push(Notice::Released(byte));
        }
    }
}

/// A terminal switched to non-canonical, no-echo mode; [`TerminalMode::restore`] (or
/// dropping it) puts the original settings back (once). Also used by `teleop launch
/// --keyboard`, which reads the keys in its own terminal and forwards them to the wrist
/// tracker.
pub struct TerminalMode {
    fd: Box<dyn AsFd + Send + Sync>,
    original: Mutex<Option<Termios>>,
}

impl TerminalMode {
    /// Switches off line buffering (each key is delivered as it is pressed) and echo;
    /// signals stay on (Ctrl-C stops the node).
    ///
    /// # Errors
    /// [`KeyboardError::Terminal`] when `fd` is no terminal or its mode cannot be set.
    pub fn enter(fd: Box<dyn AsFd + Send + Sync>) -> Result<Arc<Self>, KeyboardError> {
        let original =
            termios::tcgetattr(fd.as_fd()).map_err(|source| KeyboardError::Terminal {
                what: "read",
                source,
            })?;
        let mut keys = original.clone();
        keys.local_flags
            .remove(LocalFlags::ICANON | LocalFlags::ECHO | LocalFlags::ECHONL);
        keys.control_chars[SpecialCharacterIndices::VMIN as usize] = 1;
        keys.control_chars[SpecialCharacterIndices::VTIME as usize] = 0;
        termios::tcsetattr(fd.as_fd(), SetArg::TCSANOW, &keys).map_err(|source| {
            KeyboardError::Terminal {
                what: "set",
                source,
            }
        })?;
        Ok(Arc::new(Self {
            fd,
            original: Mutex::new(Some(original)),
        }))
    }

    /// True until the original settings were put back (or tried to).
    pub fn active(&self) -> bool {
        self.original.lock().is_ok_and(|o| o.is_some())
    }

    /// Puts the original settings back (the first call only).
    pub fn restore(&self) {
        let original = match self.original.lock() {
            Ok(mut o) => o.take(),
            Err(poisoned) => poisoned.into_inner().take(),
        };
        if let Some(t) = original {
            match termios::tcsetattr(self.fd.as_fd(), SetArg::TCSANOW, &t) {
                Ok(()) => tracing::debug!("keyboard: terminal settings restored"),
                Err(e) => tracing::warn!("keyboard: cannot restore the terminal's settings: {e}"),
            }
        }
    }
}

impl fmt::Debug for TerminalMode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("TerminalMode")
            .field("active", &self.active())
            .finish_non_exhaustive()
    }
}

impl Drop for TerminalMode {
    fn drop(&mut self) {
        self.restore();
    }
}

#[derive(Debug)]
struct Shared {
    panel: KeyboardPanel,
    /// Why the input ended: the panel is lost for good.
    lost: Option<String>,
    /// The [`KeyboardReader`] was dropped.
    stopped: bool,
}

fn log(notices: Vec<Notice>) {
    for n in notices {
        tracing::info!("{n}");
    }
}

/// The keyboard panel as an [`OperatorPanel`]: a thread reads the input's bytes into a
/// [`KeyboardPanel`], each stamped with the node's clock when it arrives.
pub struct KeyboardReader {
    shared: Arc<Mutex<Shared>>,
    terminal: Option<Arc<TerminalMode>>,
}

impl fmt::Debug for KeyboardReader {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("KeyboardReader")
            .field("terminal", &self.terminal.is_some())
            .finish_non_exhaustive()
    }
}

impl KeyboardReader {
    /// Reads the process's stdin; a terminal is switched to key-by-key, no-echo mode
    /// until the reader is dropped or the input ends.
    ///
    /// # Errors
    /// An invalid config, the terminal's mode cannot be set, no thread.
    pub fn stdin(cfg: &KeyboardPanelConfig, clock: Arc<dyn Clock>) -> Result<Self, KeyboardError> {
        let stdin = std::io::stdin();
        if stdin.is_terminal() {
            // Validate before touching the terminal.
            let panel = KeyboardPanel::new(cfg)?;
            let mode = TerminalMode::enter(Box::new(std::io::stdin()))?;
            Self::spawn(stdin, "stdin", panel, clock, Some(mode))
        } else {
            tracing::warn!(
                "keyboard: stdin is not a terminal: its bytes are read as keys, enable \
                 holds only while spaces keep arriving (`teleop launch --keyboard` \
                 forwards its terminal's keys, auto-repeat included)"
            );
            Self::from_reader(stdin, "stdin", cfg, clock)
        }
    }

    /// Reads any byte stream (a pipe, a file, a test's scripted input) as keys;
    /// `name` names it in errors.
    ///
    /// # Errors
    /// An invalid config, no thread.
    pub fn from_reader<R: Read + Send + 'static>(
        input: R,
        name: &str,
        cfg: &KeyboardPanelConfig,
        clock: Arc<dyn Clock>,
    ) -> Result<Self, KeyboardError> {
        Self::spawn(input, name, KeyboardPanel::new(cfg)?, clock, None)
    }

    /// Reads a terminal given by its file descriptor (a pseudo-terminal), switched to
    /// key-by-key, no-echo mode as for [`KeyboardReader::stdin`].
    ///
    /// # Errors
    /// An invalid config, `terminal` is no terminal, no thread.
    pub fn from_terminal(
        terminal: OwnedFd,
        name: &str,
        cfg: &KeyboardPanelConfig,
        clock: Arc<dyn Clock>,
    ) -> Result<Self, KeyboardError> {
        let panel = KeyboardPanel::new(cfg)?;
        let input = terminal.try_clone().map_err(|source| KeyboardError::Io {
            what: "cannot duplicate the terminal's descriptor",
            source,
        })?;
        let mode = TerminalMode::enter(Box::new(terminal))?;
        Self::spawn(std::fs::File::from(input), name, panel, clock, Some(mode))
    }

    fn spawn<R: Read + Send + 'static>(
        input: R,
        name: &str,
        panel: KeyboardPanel,
        clock: Arc<dyn Clock>,
        terminal: Option<Arc<TerminalMode>>,
    ) -> Result<Self, KeyboardError> {
        let shared = Arc::new(Mutex::new(Shared {
            panel,
            lost: None,
            stopped: false,
        }));
        tracing::info!("{HELP}");
        let thread_shared = shared.clone();
        let thread_terminal = terminal.clone();
        let name = name.to_owned();
        let spawned = std::thread::Builder::new()
            .name("keyboard-panel".into())
            .spawn(move || read_keys(input, &name, &thread_shared, &*clock, thread_terminal));
        if let Err(source) = spawned {
            if let Some(t) = &terminal {
                t.restore();
            }
            return Err(KeyboardError::Io {
                what: "cannot start the reader thread",
                source,
            });
        }
        Ok(Self { shared, terminal })
    }

    fn lock(&self) -> Result<MutexGuard<'_, Shared>, HardwareError> {
        self.shared
            .lock()
            .map_err(|_| HardwareError::NotConnected("keyboard: the reader thread failed".into()))
    }

    /// Key bytes received so far.
    pub fn keys(&self) -> u64 {
        self.lock().map_or(0, |s| s.panel.keys())
    }

    /// Keys ignored so far.
    pub fn unknown_keys(&self) -> u64 {
        self.lock().map_or(0, |s| s.panel.unknown_keys())
    }

    /// True while a terminal is in the panel's key-by-key mode (false for other
    /// inputs, and once the terminal's settings were restored).
    pub fn terminal_mode_active(&self) -> bool {
        self.terminal.as_ref().is_some_and(|t| t.active())
    }
}

impl Drop for KeyboardReader {
    fn drop(&mut self) {
        if let Ok(mut s) = self.shared.lock() {
            s.stopped = true;
        }
        // The thread may stay blocked in a read: restore now, not when it ends.
        if let Some(t) = &self.terminal {
            t.restore();
        }
    }
}

impl OperatorPanel for KeyboardReader {
    fn read(&mut self, now_s: f64) -> Result<PedalState, HardwareError> {
        let (state, notices) = {
            let mut s = self.lock()?;
            if let Some(reason) = &s.lost {
                return Err(HardwareError::NotConnected(format!("keyboard: {reason}")));
            }
            let state = s.panel.state(now_s);
            (state, s.panel.take_notices())
        };
        log(notices);
        Ok(state)
    }
}

/// The reader thread: bytes into the panel until the input ends, fails or the reader
/// is dropped.
fn read_keys<R: Read>(
    mut input: R,
    name: &str,
    shared: &Mutex<Shared>,
    clock: &dyn Clock,
    terminal: Option<Arc<TerminalMode>>,
) {
    let mut buf = [0u8; 64];
    let reason = loop {
        match input.read(&mut buf) {
            Ok(0) => break format!("{name} closed (end of file)"),
            Ok(n) => {
                let t_s = clock.now_s();
                let notices = {
                    let Ok(mut s) = shared.lock() else {
                        break "the panel failed".into();
                    };
                    if s.stopped {
                        break String::new();
                    }
                    for &b in buf.iter().take(n) {
                        s.panel.press(t_s, b);
                    }
                    s.panel.take_notices()
                };
                log(notices);
            }
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => break format!("reading {name} failed: {e}"),
        }
    };
    if let Some(t) = &terminal {
        t.restore();
    }
    if let Ok(mut s) = shared.lock()
        && !s.stopped
    {
        tracing::warn!("keyboard: panel lost: {reason}; the robots stop");
        s.lost = Some(reason);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::mpsc;
    use std::time::{Duration, Instant};
    use teleop_bus::ManualClock;

    const T0: f64 = 1000.0;
    /// A typical auto-repeat: first repeat after 500 ms, then 30 per second.
    const DELAY_S: f64 = 0.5;
    const RATE_S: f64 = 1.0 / 30.0;

    fn panel() -> KeyboardPanel {
        KeyboardPanel::new(&KeyboardPanelConfig::default()).expect("valid")
    }

    /// Space held from `from_s` to `to_s` as a terminal delivers it: once, then after
    /// the repeat delay at the repeat rate. Returns the last arrival.
    fn hold_space(p: &mut KeyboardPanel, from_s: f64, to_s: f64) -> f64 {
        p.press(from_s, b' ');
        let mut t = from_s + DELAY_S;
        let mut last = from_s;
        while t <= to_s {
            p.press(t, b' ');
            last = t;
            t += RATE_S;
        }
        last
    }

    #[test]
    fn space_held_through_auto_repeat_keeps_enable() {
        let mut p = panel();
        let s = p.state(T0);
        assert!(!s.enable && !s.clutch && !s.camera_stop);
        assert_eq!(s.motion_scale, 1.0);
        // Checked at every 10 ms while space is held for 5 s: never dropped, not even
        // in the 0.5 s before the first repeat.
        p.press(T0, b' ');
        let mut t = T0;
        let mut next_repeat = T0 + DELAY_S;
        while t < T0 + 5.0 {
            while next_repeat <= t {
                p.press(next_repeat, b' ');
                next_repeat += RATE_S;
            }
            assert!(p.state(t).enable, "enable dropped at {}", t - T0);
            t += 0.01;
        }
        assert_eq!(p.take_notices(), vec![Notice::EnableHeld]);
        assert_eq!(p.unknown_keys(), 0);
    }

    #[test]
    fn letting_go_drops_enable_and_the_clutch_after_the_timeout() {
        let mut p = panel();
        p.press(T0, b' ');
        p.press(T0 + 0.1, b'c');
        assert!(p.state(T0 + 0.1).clutch);
        // `c` interrupts the repeat of space on most terminals: re-pressed at once.
        let last = hold_space(&mut p, T0 + 0.2, T0 + 3.0);
        let s = p.state(last + 0.69);
        assert!(s.enable && s.clutch, "{s:?}");
        let s = p.state(last + 0.71);
        assert!(!s.enable && !s.clutch, "{s:?}");
        assert_eq!(
            p.take_notices(),
            vec![
                Notice::EnableHeld,
                Notice::ClutchEngaged,
                Notice::EnableDropped { after_s: 0.7 },
                Notice::ClutchReleased(ClutchRelease::EnableDropped),
            ]
        );
        // Holding space again does not bring the clutch back: a fresh `c` is needed.
        let last = hold_space(&mut p, T0 + 5.0, T0 + 6.0);
        let s = p.state(last);
        assert!(s.enable && !s.clutch, "{s:?}");
        p.press(last + 0.01, b'c');
        assert!(p.state(last + 0.02).clutch);
    }

    #[test]
    fn a_gap_is_applied_at_the_next_key_even_without_a_read() {
        let mut p = panel();
        p.press(T0, b' ');
        p.press(T0 + 0.05, b'c');
        // No state read in between: space comes back 1 s later, `c` then toggles the
        // clutch ON again (it was released by the gap), not off.
        p.press(T0 + 1.05, b' ');
        let s = p.state(T0 + 1.06);
        assert!(s.enable && !s.clutch, "{s:?}");
        p.press(T0 + 1.1, b'c');
        assert!(p.state(T0 + 1.1).clutch);
        assert_eq!(
            p.take_notices(),
            vec![
                Notice::EnableHeld,
                Notice::ClutchEngaged,
                Notice::EnableDropped { after_s: 0.7 },
                Notice::ClutchReleased(ClutchRelease::EnableDropped),
                Notice::EnableHeld,
                Notice::ClutchEngaged,
            ]
        );
    }

    #[test]
    fn the_clutch_needs_enable_held() {
        let mut p = panel();
        p.press(T0, b'c');
        let s = p.state(T0 + 0.01);
        assert!(!s.clutch && !s.enable);
        assert_eq!(p.take_notices(), vec![Notice::ClutchRefused]);
        // A clock stepped back further than the timeout: the space does not count.
        p.press(T0 + 10.0, b' ');
        assert!(p.state(T0 + 10.0).enable);
        assert!(!p.state(T0 + 9.0).enable);
    }

    #[test]
    fn toggles_count_once_per_press() {
        let mut p = panel();
        // Camera stop: tapped on, tapped off, each tap a toggle.
        p.press(T0, b's');
        assert!(p.state(T0).camera_stop);
        p.press(T0 + 1.0, b's');
        assert!(!p.state(T0 + 1.0).camera_stop);
        // Held for 2 s (auto-repeat): one toggle only.
        p.press(T0 + 2.0, b'S');
        let mut t = T0 + 2.0 + DELAY_S;
        while t < T0 + 4.0 {
            p.press(t, b's');
            t += RATE_S;
        }
        assert!(p.state(t).camera_stop);
        // The clutch: on with space held, off with `c` again (after another key, so not
        // a repeat), on again with `C`.
        p.press(T0 + 5.0, b' ');
        p.press(T0 + 5.1, b'c');
        assert!(p.state(T0 + 5.1).clutch);
        p.press(T0 + 5.15, b'c');
        assert!(
            p.state(T0 + 5.15).clutch,
            "a repeat of c toggled the clutch"
        );
        p.press(T0 + 5.2, b' ');
        p.press(T0 + 5.3, b'c');
        assert!(!p.state(T0 + 5.3).clutch);
        p.press(T0 + 5.4, b' ');
        p.press(T0 + 5.5, b'C');
        let s = p.state(T0 + 5.5);
        assert!(s.clutch && s.enable && s.camera_stop, "{s:?}");
        assert_eq!(
            p.take_notices(),
            vec![
                Notice::CameraStop(true),
                Notice::CameraStop(false),
                Notice::CameraStop(true),
                Notice::EnableHeld,
                Notice::ClutchEngaged,
                Notice::ClutchReleased(ClutchRelease::Key),
                Notice::ClutchEngaged,
            ]
        );
        assert_eq!(p.unknown_keys(), 0);
    }

    #[test]
    fn scale_keys_select_the_motion_scale() {
        let cfg = KeyboardPanelConfig {
            motion_scale: 0.25,
            ..Default::default()
        };
        let mut p = KeyboardPanel::new(&cfg).expect("valid");
        assert_eq!(p.state(T0).motion_scale, 0.25);
        for (key, scale) in [(b'1', 1.0), (b'2', 0.5), (b'3', 1.0 / 3.0), (b'4', 0.25)] {
            p.press(T0, key);
            assert_eq!(p.state(T0).motion_scale, scale, "key {}", char::from(key));
        }
        // Again the same: no change, no notice; `5` is not a scale key.
        p.press(T0 + 1.0, b'4');
        p.press(T0 + 2.0, b'5');
        assert_eq!(p.state(T0 + 2.0).motion_scale, 0.25);
        assert_eq!(
            p.take_notices(),
            vec![
                Notice::MotionScale(1),
                Notice::MotionScale(2),
                Notice::MotionScale(3),
                Notice::MotionScale(4),
                Notice::UnknownKey(Some(b'5')),
            ]
        );
        // The scale survives enable dropping.
        p.press(T0 + 3.0, b' ');
        assert_eq!(p.state(T0 + 10.0).motion_scale, 0.25);
    }

    #[test]
    fn x_and_esc_release_everything_at_once() {
        for key in [b'x', b'X', ESC] {
            let mut p = panel();
            p.press(T0, b' ');
            p.press(T0 + 0.1, b'c');
            p.press(T0 + 0.2, b's');
            p.press(T0 + 0.3, b'2');
            p.press(T0 + 0.4, key);
            // Released at once, well within the hold timeout; camera stop and scale
            // stay as they are.
            let s = p.state(T0 + 0.41);
            assert!(!s.enable && !s.clutch, "{s:?}");
            assert!(s.camera_stop);
            assert_eq!(s.motion_scale, 0.5);
            let notices = p.take_notices();
            assert_eq!(
                notices[notices.len() - 2..],
                [
                    Notice::ClutchReleased(ClutchRelease::ReleaseKey),
                    Notice::Released(key),
                ]
            );
            // A new space holds enable again, the clutch stays off.
            p.press(T0 + 1.0, b' ');
            let s = p.state(T0 + 1.0);
            assert!(s.enable && !s.clutch, "{s:?}");
            assert_eq!(p.unknown_keys(), 0);
        }
        assert_eq!(
            Notice::Released(ESC).to_string(),
            "keyboard: released: enable off, clutch off (Esc)"
        );
    }

    #[test]
    fn unknown_keys_are_ignored_and_counted() {
        let mut p = panel();
        p.press(T0, b' ');
        let before = p.state(T0);
        for (i, b) in b"q\nz\x04".iter().enumerate() {
            p.press(T0 + 0.01 * (i as f64 + 1.0), *b);
        }
        // Held `q` (auto-repeat): counted each time, logged once.
        for i in 0..5 {
            p.press(T0 + 0.1 + 0.03 * f64::from(i), b'q');
        }
        assert_eq!(p.unknown_keys(), 9);
        assert_eq!(p.keys(), 10);
        assert_eq!(p.state(T0 + 0.3), before);
        assert_eq!(
            p.take_notices(),
            vec![
                Notice::EnableHeld,
                Notice::UnknownKey(Some(b'q')),
                Notice::UnknownKey(Some(b'\n')),
                Notice::UnknownKey(Some(b'z')),
                Notice::UnknownKey(Some(0x04)),
                Notice::UnknownKey(Some(b'q')),
            ]
        );
    }

    #[test]
    fn arrow_keys_release_and_are_one_unknown_key() {
        fn burst(p: &mut KeyboardPanel, t_s: f64, bytes: &[u8]) {
            for (i, b) in bytes.iter().enumerate() {
                p.press(t_s + 0.001 * i as f64, *b);
            }
        }
        let mut p = panel();
        p.press(T0, b' ');
        p.press(T0 + 0.1, b'c');
        // Right arrow `Esc [ C`, arriving together: released by its Esc, its `C`
        // toggles nothing.
        burst(&mut p, T0 + 0.2, b"\x1b[C");
        let s = p.state(T0 + 0.21);
        assert!(!s.enable && !s.clutch && !s.camera_stop, "{s:?}");
        // F4 `Esc O S` and Ctrl+Right `Esc [ 1 ; 5 C`: their `S` and `C` do nothing.
        burst(&mut p, T0 + 0.3, b"\x1bOS");
        burst(&mut p, T0 + 0.4, b"\x1b[1;5C");
        assert!(!p.state(T0 + 0.5).camera_stop);
        assert_eq!(p.unknown_keys(), 3);
        assert_eq!(
            p.take_notices(),
            vec![
                Notice::EnableHeld,
                Notice::ClutchEngaged,
                Notice::ClutchReleased(ClutchRelease::ReleaseKey),
                Notice::Released(ESC),
                // Special keys are not told apart: one within the hold timeout of
                // another is logged as its repeat.
                Notice::UnknownKey(None),
            ]
        );
        // Right arrow held (auto-repeat): counted each time, logged once.
        for k in 0..10 {
            burst(&mut p, T0 + 1.2 + RATE_S * f64::from(k), b"\x1b[C");
        }
        assert_eq!(p.unknown_keys(), 13);
        assert_eq!(p.take_notices(), vec![Notice::UnknownKey(None)]);
        // A lone Esc, then `s` pressed later: `s` is a key of its own.
        p.press(T0 + 2.0, ESC);
        p.press(T0 + 2.5, b's');
        assert!(p.state(T0 + 2.5).camera_stop);
        // Esc then `[` typed later: no sequence, `[` is an unknown key, and the keys
        // after it are keys.
        p.press(T0 + 3.0, ESC);
        p.press(T0 + 3.5, b'[');
        p.press(T0 + 3.6, b' ');
        p.press(T0 + 3.7, b'c');
        assert!(p.state(T0 + 3.7).clutch);
        assert_eq!(p.unknown_keys(), 14);
        // A sequence cut short by a pause (`Esc [`, then nothing): counted once; the
        // `s` after the pause is a key (the camera stop goes off again).
        p.press(T0 + 4.0, ESC);
        p.press(T0 + 4.001, b'[');
        p.press(T0 + 4.5, b's');
        let s = p.state(T0 + 4.5);
        assert!(!s.camera_stop && !s.clutch, "{s:?}");
        assert_eq!(p.unknown_keys(), 15);
    }

    #[test]
    fn config_values_are_checked_by_name() {
        KeyboardPanelConfig::default()
            .validate()
            .expect("default valid");
        for (cfg, name) in [
            (
                KeyboardPanelConfig {
                    hold_timeout_s: 0.0,
                    ..Default::default()
                },
                "hold_timeout_s",
            ),
            (
                KeyboardPanelConfig {
                    hold_timeout_s: 2.5,
                    ..Default::default()
                },
                "hold_timeout_s",
            ),
            (
                KeyboardPanelConfig {
                    motion_scale: 1.5,
                    ..Default::default()
                },
                "motion_scale",
            ),
            (
                KeyboardPanelConfig {
                    motion_scale: 0.0,
                    ..Default::default()
                },
                "motion_scale",
            ),
            (
                KeyboardPanelConfig {
                    motion_scale: f64::NAN,
                    ..Default::default()
                },
                "motion_scale",
            ),
        ] {
            let e = KeyboardPanel::new(&cfg).expect_err("invalid");
            assert!(e.to_string().starts_with(name), "{e}");
        }
    }

    /// A byte stream written by the test: each `send` is one read's worth; dropping
    /// the sender is the end of file.
    struct Pipe(mpsc::Receiver<Vec<u8>>, Vec<u8>);

    impl Read for Pipe {
        fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
            if self.1.is_empty() {
                match self.0.recv() {
                    Ok(bytes) => self.1 = bytes,
                    Err(_) => return Ok(0),
                }
            }
            let n = buf.len().min(self.1.len());
            buf[..n].copy_from_slice(&self.1[..n]);
            self.1.drain(..n);
            Ok(n)
        }
    }

    fn wait_for(what: &str, mut f: impl FnMut() -> bool) {
        let deadline = Instant::now() + Duration::from_secs(10);
        while !f() {
            assert!(Instant::now() < deadline, "timed out waiting for {what}");
            std::thread::sleep(Duration::from_millis(1));
        }
    }

    #[test]
    fn the_reader_feeds_the_panel_and_is_lost_at_end_of_file() {
        let clock = ManualClock::starting_at(T0);
        let (tx, rx) = mpsc::channel();
        let mut r = KeyboardReader::from_reader(
            Pipe(rx, Vec::new()),
            "pipe",
            &KeyboardPanelConfig::default(),
            clock.clone(),
        )
        .expect("reader");
        assert!(!r.terminal_mode_active());
        let s = r.read(T0).expect("connected");
        assert!(!s.enable && !s.clutch);
        // Stamped with the clock when they arrive.
        tx.send(b" c".to_vec()).expect("send");
        wait_for("2 keys", || r.keys() == 2);
        let s = r.read(T0 + 0.1).expect("connected");
        assert!(s.enable && s.clutch, "{s:?}");
        clock.set_s(T0 + 0.5);
        tx.send(b" q".to_vec()).expect("send");
        wait_for("4 keys", || r.keys() == 4);
        assert_eq!(r.unknown_keys(), 1);
        assert!(r.read(T0 + 1.1).expect("connected").enable);
        let s = r.read(T0 + 1.3).expect("connected");
        assert!(!s.enable && !s.clutch, "{s:?}");
        // End of file: lost, from then on.
        drop(tx);
        wait_for("the panel lost", || r.read(T0 + 1.4).is_err());
        for t in [T0 + 1.4, T0 + 100.0] {
            match r.read(t) {
                Err(HardwareError::NotConnected(m)) => {
                    assert_eq!(m, "keyboard: pipe closed (end of file)");
                }
                other => panic!("{other:?}"),
            }
        }
    }

    #[test]
    fn a_scripted_input_is_read_to_its_end() {
        let clock = ManualClock::starting_at(T0);
        let mut r = KeyboardReader::from_reader(
            std::io::Cursor::new(b" s3".to_vec()),
            "script",
            &KeyboardPanelConfig::default(),
            clock,
        )
        .expect("reader");
        wait_for("the end of the script", || r.read(T0).is_err());
        assert_eq!(r.keys(), 3);
        assert!(matches!(
            r.read(T0),
            Err(HardwareError::NotConnected(m)) if m.starts_with("keyboard: script closed")
        ));
    }

    struct FailingInput;

    impl Read for FailingInput {
        fn read(&mut self, _buf: &mut [u8]) -> std::io::Result<usize> {
            Err(std::io::Error::other("device gone"))
        }
    }

    #[test]
    fn a_failing_input_loses_the_panel_and_an_invalid_config_is_refused() {
        let clock = ManualClock::starting_at(T0);
        let mut r = KeyboardReader::from_reader(
            FailingInput,
            "stdin",
            &KeyboardPanelConfig::default(),
            clock.clone(),
        )
        .expect("reader");
        wait_for("the panel lost", || r.read(T0).is_err());
        assert_eq!(
            r.read(T0),
            Err(HardwareError::NotConnected(
                "keyboard: reading stdin failed: device gone".into()
            ))
        );
        let bad = KeyboardPanelConfig {
            hold_timeout_s: -1.0,
            ..Default::default()
        };
        let e = KeyboardReader::from_reader(FailingInput, "stdin", &bad, clock)
            .expect_err("invalid config");
        assert!(
            matches!(
                e,
                KeyboardError::OutOfRange {
                    name: "hold_timeout_s",
                    ..
                }
            ),
            "{e}"
        );
    }

    fn local_flags(fd: &OwnedFd) -> LocalFlags {
        termios::tcgetattr(fd).expect("tcgetattr").local_flags
    }

    #[test]
    fn a_terminal_is_read_key_by_key_and_restored_on_drop() {
        use std::io::Write;
        let pty = nix::pty::openpty(None, None).expect("a pseudo-terminal");
        let slave = pty.slave.try_clone().expect("dup");
        let before = local_flags(&slave);
        assert!(before.contains(LocalFlags::ICANON | LocalFlags::ECHO | LocalFlags::ISIG));
        let clock = ManualClock::starting_at(T0);
        let mut r = KeyboardReader::from_terminal(
            pty.slave,
            "terminal",
            &KeyboardPanelConfig::default(),
            clock,
        )
        .expect("reader");
        assert!(r.terminal_mode_active());
        let during = local_flags(&slave);
        assert!(
            !during.intersects(LocalFlags::ICANON | LocalFlags::ECHO),
            "{during:?}"
        );
        assert!(
            during.contains(LocalFlags::ISIG),
            "Ctrl-C must still stop the node"
        );
        // No newline: in line mode the space would never be delivered.
        let mut master = std::fs::File::from(pty.master);
        master.write_all(b" ").expect("write");
        wait_for("the space", || r.keys() == 1);
        assert!(r.read(T0).expect("connected").enable);
        drop(r);
        assert_eq!(local_flags(&slave), before);
    }

    #[test]
    fn a_terminal_that_goes_away_loses_the_panel() {
        let pty = nix::pty::openpty(None, None).expect("a pseudo-terminal");
        let clock = ManualClock::starting_at(T0);
        let mut r = KeyboardReader::from_terminal(
            pty.slave,
            "terminal",
            &KeyboardPanelConfig::default(),
            clock,
        )
        .expect("reader");
        assert!(r.read(T0).is_ok());
        // The terminal closed (a window closed, an ssh session ended).
        drop(pty.master);
        wait_for("the panel lost", || r.read(T0).is_err());
        match r.read(T0) {
            Err(HardwareError::NotConnected(m)) => assert!(m.starts_with("keyboard: "), "{m}"),
            other => panic!("{other:?}"),
        }
        // The reader thread's exit put the settings back (or tried: a hung-up terminal
        // takes none).
        assert!(!r.terminal_mode_active());
    }
}
