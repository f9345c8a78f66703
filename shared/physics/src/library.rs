//! Finding (and, where it is nowhere, installing) MuJoCo's shared library.
//!
//! MuJoCo 3.17.0 comes from the `mujoco` PyPI wheel, which ships
//! `mujoco/libmujoco.so.3.17.0` (self-contained: it needs only libc, libm, libdl,
//! libpthread and librt). Search order, first hit wins:
//!
//! 1. `MUJOCO_DYNAMIC_LINK_DIR` (mujoco-rs's own variable: a directory holding
//!    `libmujoco.so`, e.g. an official release's `lib/`); when it is set, it is the only
//!    place looked at;
//! 2. the wheel's places ([`teleop_pywheel`]): the project's Python environment
//!    (`$TELEOP_VENV` or `~/.cache/teleop-venv`, where `bash tests/run.sh` installs the
//!    pinned wheel), a `mujoco` package of `python3`, the system's site-packages.
//!
//! When nothing is found, [`find_or_install`] installs the pinned wheel into the project's
//! environment with pip (as hand inference does for ONNX Runtime), unless
//! `TELEOP_MUJOCO_NO_INSTALL` is set. The error lists every place looked at and says how
//! to get the library.
//!
//! This file is also compiled into the crate's build script (`#[path]`), so it uses the
//! standard library and `teleop-pywheel` only.

use std::ffi::OsString;
use std::fmt;
use std::path::PathBuf;

pub use teleop_pywheel::Found;
use teleop_pywheel::{WheelLibrary, project_venv};

/// The MuJoCo version mujoco-rs 7.0.0 binds (and the wheel the project pins).
pub const MUJOCO_VERSION: &str = "3.17.0";

/// The library's file name in the wheel (its soname).
pub const MUJOCO_SONAME: &str = "libmujoco.so.3.17.0";

/// The library in the `mujoco` wheel.
pub const MUJOCO_WHEEL: WheelLibrary = WheelLibrary {
    package: "mujoco",
    version: MUJOCO_VERSION,
    subdir: "",
    file_prefix: MUJOCO_SONAME,
};

/// Nothing found: every place looked at, and how to get the library.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct NotFound {
    pub looked: Vec<String>,
}

impl fmt::Display for NotFound {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "MuJoCo {MUJOCO_VERSION} ({MUJOCO_SONAME}) was not found; looked in: {}. \
             Get it with `python3 -m venv ~/.cache/teleop-venv && \
             ~/.cache/teleop-venv/bin/pip install mujoco=={MUJOCO_VERSION}` \
             (bash tests/run.sh does this), or point MUJOCO_DYNAMIC_LINK_DIR at the lib/ \
             directory of a MuJoCo {MUJOCO_VERSION} of your own",
            self.looked.join("; ")
        )
    }
}

impl std::error::Error for NotFound {}

/// Searches for the library (see the module docs) without installing anything.
///
/// # Errors
/// [`NotFound`] listing every place looked at.
pub fn find() -> Result<Found, NotFound> {
    find_with(&|name| std::env::var_os(name))
}

/// [`find`] with the environment read through `var` (so a test can give it one).
///
/// # Errors
/// [`NotFound`] listing every place looked at.
pub fn find_with(var: &dyn Fn(&str) -> Option<OsString>) -> Result<Found, NotFound> {
    if let Some(dir) = var("MUJOCO_DYNAMIC_LINK_DIR") {
        let dir = PathBuf::from(dir);
        for name in ["libmujoco.so", MUJOCO_SONAME] {
            let p = dir.join(name);
            if p.is_file() {
                return Ok(Found {
                    path: p,
                    source: "MUJOCO_DYNAMIC_LINK_DIR".to_owned(),
                });
            }
        }
        return Err(NotFound {
            looked: vec![format!(
                "{} (from MUJOCO_DYNAMIC_LINK_DIR): no libmujoco.so there",
                dir.display()
            )],
        });
    }
    let mut looked = Vec::new();
    MUJOCO_WHEEL
        .search(project_venv(var).as_deref(), &mut looked)
        .ok_or(NotFound { looked })
}

/// Finds the library and, when it is nowhere (and `MUJOCO_DYNAMIC_LINK_DIR` is not set),
/// installs the pinned `mujoco` wheel from PyPI into the project's Python environment
/// and finds it there. Setting `TELEOP_MUJOCO_NO_INSTALL` turns the install off.
///
/// # Errors
/// [`NotFound`] when the library is nowhere and could not be installed, with the reason.
pub fn find_or_install() -> Result<Found, NotFound> {
    let first = match find() {
        Ok(f) => return Ok(f),
        Err(e) => e,
    };
    if std::env::var_os("MUJOCO_DYNAMIC_LINK_DIR").is_some()
        || std::env::var_os("TELEOP_MUJOCO_NO_INSTALL").is_some()
    {
        return Err(first);
    }
    let Some(venv) = project_venv(&|name| std::env::var_os(name)) else {
        return Err(first);
    };
    match MUJOCO_WHEEL.install(&venv) {
        Ok(path) => Ok(Found {
            path,
            source: "installed into the project environment".to_owned(),
        }),
        Err(why) => {
            let mut looked = first.looked;
            looked.push(why);
            Err(NotFound { looked })
        }
    }
}
