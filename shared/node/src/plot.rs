//! What the project's pictures share (feature `plot`): the font, and the tick labels.
//!
//! The evidence plots (the hand scenarios' example in `teleop-system-tests`, the
//! `reachability_map` tool in `teleop-tools`) are drawn with `plotters` built without
//! system C libraries: its `ab_glyph` text backend finds no system fonts and draws only
//! fonts registered from TTF bytes. [`register_fonts`] does that once per process, from
//! the DejaVu Sans file of the Debian package `fonts-dejavu-core`, read at run time (no
//! font bytes in the repository).
//!
//! It lives here because `teleop-node` is the one library both picture-making programs
//! already depend on that is about programs rather than robots or wire formats; it is
//! behind the optional `plot` feature so node binaries do not build `plotters`.

use std::path::Path;
use std::sync::OnceLock;

use plotters::style::FontStyle;

/// The TTF file the pictures' text is drawn with.
pub const FONT_PATH: &str = "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf";
/// The Debian package that installs [`FONT_PATH`].
pub const FONT_PACKAGE: &str = "fonts-dejavu-core";
/// The family name the font is registered under; it is also `plotters`' default, so
/// `("sans-serif", 20).into_font()` and unstyled text both use it.
pub const FONT_FAMILY: &str = "sans-serif";

/// Why the font could not be registered.
#[derive(Debug, Clone, thiserror::Error)]
pub enum FontError {
    #[error(
        "cannot read the font file {path} ({reason}); install the Debian package \
         {FONT_PACKAGE} (apt-get install {FONT_PACKAGE})"
    )]
    Read { path: String, reason: String },
    #[error("{path} is not a TrueType/OpenType font the plots can use")]
    Invalid { path: String },
}

/// Registers DejaVu Sans ([`FONT_PATH`]) with `plotters` as [`FONT_FAMILY`], for every
/// style. Call before drawing any text; later calls return the first call's outcome.
///
/// # Errors
/// [`FontError::Read`] if the file is missing or unreadable (naming the file and the
/// package that installs it), [`FontError::Invalid`] if it does not parse.
pub fn register_fonts() -> Result<(), FontError> {
    static REGISTERED: OnceLock<Result<(), FontError>> = OnceLock::new();
    REGISTERED
        .get_or_init(|| register_file(Path::new(FONT_PATH)))
        .clone()
}

fn register_file(path: &Path) -> Result<(), FontError> {
    let bytes = std::fs::read(path).map_err(|e| FontError::Read {
        path: path.display().to_string(),
        reason: e.to_string(),
    })?;
    // `plotters` keeps fonts for the whole process (`&'static`); this runs once.
    let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
    plotters::style::register_font(FONT_FAMILY, FontStyle::Normal, bytes).map_err(|_| {
        FontError::Invalid {
            path: path.display().to_string(),
        }
    })
}

/// An axis tick label: up to three decimals, without trailing zeros (`2`, `0.25`, not
/// `2.0`, `-0.0` or `0.15000000000000002`). For `plotters`' `x_label_formatter` /
/// `y_label_formatter` (hence `&f64`).
pub fn tick_label(v: &f64) -> String {
    let s = format!("{v:.3}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" {
        "0".to_owned()
    } else {
        s.to_owned()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn missing_file_names_file_and_package() {
        let e = register_file(Path::new("/nonexistent/DejaVuSans.ttf"))
            .expect_err("no such file")
            .to_string();
        assert!(e.contains("/nonexistent/DejaVuSans.ttf"), "{e}");
        assert!(e.contains(FONT_PACKAGE), "{e}");
    }

    #[test]
    fn tick_labels() {
        let labels: Vec<String> = [2.0, 0.25, -0.0001, 0.15000000000000002, -1.5, 100.0]
            .iter()
            .map(tick_label)
            .collect();
        assert_eq!(labels, ["2", "0.25", "0", "0.15", "-1.5", "100"]);
    }
}
