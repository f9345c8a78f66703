//! Finding (and, where it is nowhere, installing) MuJoCo's shared library.
//!
//! MuJoCo 3.17.0 comes from the `mujoco` PyPI wheel, which ships
//! `mujoco/libmujoco.so.3.17.0` (self-contained: it needs only libc, libm, libdl,
//! libpthread and librt). Search order, first hit wins:
//!
//! 1. `MUJOCO_DYNAMIC_LINK_DIR` (mujoco-rs's own variable: a directory holding
//!    `libmujoco.so`, e.g. an official release's `lib/`); when it is set, it is the only
//!    place looked at;
//! 2. the project's Python environment, `$TELEOP_VENV` or `~/.cache/teleop-venv` (made by
//!    `bash tests/run.sh`, which installs the pinned wheel there);
//! 3. a `mujoco` package installed for `python3` (asked with `python3 -c`), or in the
//!    usual site-packages directories.
//!
//! When nothing is found, [`find_or_install`] installs the pinned wheel into the project's
//! environment with pip (as hand inference does for ONNX Runtime), unless
//! `TELEOP_MUJOCO_NO_INSTALL` is set. The error lists every place looked at and says how
//! to get the library.
//!
//! This file is also compiled into the crate's build script (`include!`), so it uses the
//! standard library only.

use std::fmt;
use std::path::{Path, PathBuf};

/// The MuJoCo version mujoco-rs 7.0.0 binds (and the wheel the project pins).
pub const MUJOCO_VERSION: &str = "3.17.0";

/// The library's file name in the wheel (its soname).
pub const MUJOCO_SONAME: &str = "libmujoco.so.3.17.0";

/// Where the library was found.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Found {
    /// The library file (`libmujoco.so.3.17.0`, or `libmujoco.so` in a directory named by
    /// `MUJOCO_DYNAMIC_LINK_DIR`).
    pub path: PathBuf,
    /// Which search step found it.
    pub source: &'static str,
}

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
pub fn find_with(var: &dyn Fn(&str) -> Option<std::ffi::OsString>) -> Result<Found, NotFound> {
    if let Some(dir) = var("MUJOCO_DYNAMIC_LINK_DIR") {
        let dir = PathBuf::from(dir);
        for name in ["libmujoco.so", MUJOCO_SONAME] {
            let p = dir.join(name);
            if p.is_file() {
                return Ok(Found {
                    path: p,
                    source: "MUJOCO_DYNAMIC_LINK_DIR",
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
    let venv = var("TELEOP_VENV")
        .map(PathBuf::from)
        .or_else(|| var("HOME").map(|h| PathBuf::from(h).join(".cache/teleop-venv")));
    if let Some(venv) = venv {
        looked.push(format!(
            "{}/lib/python3*/site-packages/mujoco",
            venv.display()
        ));
        if let Some(p) = in_site_packages(&venv.join("lib")) {
            return Ok(Found {
                path: p,
                source: "project environment",
            });
        }
    }
    looked.push("python3 -c 'import mujoco'".to_owned());
    if let Some(p) = from_python() {
        return Ok(Found {
            path: p,
            source: "python3 mujoco package",
        });
    }
    for dir in ["/usr/local/lib", "/usr/lib"] {
        looked.push(format!("{dir}/python3*/{{site,dist}}-packages/mujoco"));
        if let Some(p) = in_site_packages(Path::new(dir)) {
            return Ok(Found {
                path: p,
                source: "system site-packages",
            });
        }
    }
    Err(NotFound { looked })
}

/// `libmujoco.so.3.17.0` inside `<lib>/python3*/{site,dist}-packages/mujoco`.
fn in_site_packages(lib: &Path) -> Option<PathBuf> {
    let mut pythons: Vec<PathBuf> = std::fs::read_dir(lib)
        .ok()?
        .flatten()
        .map(|e| e.path())
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with("python3"))
        })
        .collect();
    pythons.sort();
    pythons.reverse();
    pythons.into_iter().find_map(|py| {
        ["site-packages", "dist-packages"]
            .into_iter()
            .find_map(|packages| {
                let p = py.join(packages).join("mujoco").join(MUJOCO_SONAME);
                p.is_file().then_some(p)
            })
    })
}

fn from_python() -> Option<PathBuf> {
    let out = std::process::Command::new("python3")
        .args([
            "-c",
            "import os, mujoco; print(os.path.dirname(mujoco.__file__))",
        ])
        .stderr(std::process::Stdio::null())
        .output()
        .ok()?;
    if !out.status.success() {
        return None;
    }
    let dir = String::from_utf8(out.stdout).ok()?;
    let p = PathBuf::from(dir.trim()).join(MUJOCO_SONAME);
    p.is_file().then_some(p)
}

/// The project's Python environment: `$TELEOP_VENV`, else `~/.cache/teleop-venv`.
#[must_use]
pub fn project_venv() -> Option<PathBuf> {
    std::env::var_os("TELEOP_VENV")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache/teleop-venv")))
}

/// Finds the library and, when it is nowhere (and `MUJOCO_DYNAMIC_LINK_DIR` is not set),
/// installs the pinned `mujoco` wheel from PyPI into the project's Python environment
/// ([`project_venv`], made with `python3 -m venv` if missing) and finds it there. Setting
/// `TELEOP_MUJOCO_NO_INSTALL` turns the install off.
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
    let Some(venv) = project_venv() else {
        return Err(first);
    };
    let fail = |what: String| {
        let mut looked = first.looked.clone();
        looked.push(format!(
            "installing mujoco=={MUJOCO_VERSION} into {}: {what}",
            venv.display()
        ));
        NotFound { looked }
    };
    let python = venv.join("bin/python");
    if !python.is_file() {
        let status = std::process::Command::new("python3")
            .args(["-m", "venv"])
            .arg(&venv)
            .status()
            .map_err(|e| fail(format!("python3 -m venv: {e}")))?;
        if !status.success() {
            return Err(fail(format!("python3 -m venv exited with {status}")));
        }
    }
    let out = std::process::Command::new(&python)
        .args([
            "-m",
            "pip",
            "install",
            "--quiet",
            "--disable-pip-version-check",
            &format!("mujoco=={MUJOCO_VERSION}"),
        ])
        .output()
        .map_err(|e| fail(format!("pip: {e}")))?;
    if !out.status.success() {
        let stderr = String::from_utf8_lossy(&out.stderr);
        let last = stderr.lines().last().unwrap_or("").trim().to_owned();
        return Err(fail(format!("pip exited with {}: {last}", out.status)));
    }
    match in_site_packages(&venv.join("lib")) {
        Some(path) => Ok(Found {
            path,
            source: "installed into the project environment",
        }),
        None => Err(fail(
            "pip succeeded but the library is not there".to_owned(),
        )),
    }
}
