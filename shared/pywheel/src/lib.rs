//! A native library shipped inside a pinned PyPI wheel, such as ONNX Runtime's
//! `onnxruntime/capi/libonnxruntime.so.<version>` or MuJoCo's
//! `mujoco/libmujoco.so.<version>`: where to look for it and how to install it.
//!
//! [`WheelLibrary::search`] looks, first hit wins, in
//! 1. the project's Python environment ([`project_venv`]: `$TELEOP_VENV`, else
//!    `~/.cache/teleop-venv`, made by `bash tests/run.sh`);
//! 2. the package as `python3` imports it (asked with `python3 -c`);
//! 3. the usual site-packages directories of the system,
//!
//! and lists every place it looked, for the caller's error. [`WheelLibrary::install`]
//! installs the pinned wheel into the project's environment with pip (making the
//! environment with `python3 -m venv` if missing). Each caller keeps its own overrides
//! (a config path, `ORT_DYLIB_PATH`, `MUJOCO_DYNAMIC_LINK_DIR`) in front of these.
//!
//! Standard library only: the physics crate's build script compiles it too.

use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::process::Command;

/// A library inside a PyPI package.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct WheelLibrary {
    /// The PyPI name, which is also the import name.
    pub package: &'static str,
    /// The pinned version (`pip install package==version`).
    pub version: &'static str,
    /// The library's directory inside the package (`""`: the package's own).
    pub subdir: &'static str,
    /// The library's file name starts with this; of several, the last in name order.
    pub file_prefix: &'static str,
}

/// Where a library was found.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Found {
    pub path: PathBuf,
    /// Which search step found it.
    pub source: String,
}

/// The project's Python environment, `$TELEOP_VENV`, else `~/.cache/teleop-venv`, with
/// the environment read through `var`.
#[must_use]
pub fn project_venv(var: &dyn Fn(&str) -> Option<OsString>) -> Option<PathBuf> {
    var("TELEOP_VENV")
        .map(PathBuf::from)
        .or_else(|| var("HOME").map(|h| PathBuf::from(h).join(".cache/teleop-venv")))
}

impl WheelLibrary {
    fn dir_in(&self, package_dir: &Path) -> PathBuf {
        if self.subdir.is_empty() {
            package_dir.to_path_buf()
        } else {
            package_dir.join(self.subdir)
        }
    }

    fn package_path(&self) -> String {
        if self.subdir.is_empty() {
            self.package.to_owned()
        } else {
            format!("{}/{}", self.package, self.subdir)
        }
    }

    /// Searches the project's environment `venv`, `python3`'s package and the system's
    /// site-packages; every place looked at is pushed onto `looked`.
    pub fn search(&self, venv: Option<&Path>, looked: &mut Vec<String>) -> Option<Found> {
        if let Some(venv) = venv {
            looked.push(format!(
                "{}/lib/python3*/site-packages/{}",
                venv.display(),
                self.package_path()
            ));
            if let Some(path) = self.in_site_packages(&venv.join("lib")) {
                return Some(Found {
                    path,
                    source: "project environment".to_owned(),
                });
            }
        }
        looked.push(format!("python3 -c 'import {}'", self.package));
        if let Some(path) = self.asked_of_python() {
            return Some(Found {
                path,
                source: format!("python3 {} package", self.package),
            });
        }
        for dir in ["/usr/local/lib", "/usr/lib"] {
            looked.push(format!(
                "{dir}/python3*/{{site,dist}}-packages/{}",
                self.package_path()
            ));
            if let Some(path) = self.in_site_packages(Path::new(dir)) {
                return Some(Found {
                    path,
                    source: "system site-packages".to_owned(),
                });
            }
        }
        None
    }

    /// The library inside `<lib>/python3*/{site,dist}-packages/<package>/<subdir>` (the
    /// newest Python first).
    #[must_use]
    pub fn in_site_packages(&self, lib: &Path) -> Option<PathBuf> {
        let mut pythons = entries_starting_with(lib, "python3")?;
        pythons.reverse();
        pythons.into_iter().find_map(|py| {
            ["site-packages", "dist-packages"]
                .into_iter()
                .find_map(|packages| {
                    self.library_in(&self.dir_in(&py.join(packages).join(self.package)))
                })
        })
    }

    /// The library file in `dir`: the last name in order that starts with the prefix.
    fn library_in(&self, dir: &Path) -> Option<PathBuf> {
        entries_starting_with(dir, self.file_prefix)?.pop()
    }

    fn asked_of_python(&self) -> Option<PathBuf> {
        let out = Command::new("python3")
            .args([
                "-c",
                &format!(
                    "import os, {0}; print(os.path.dirname({0}.__file__))",
                    self.package
                ),
            ])
            .stderr(std::process::Stdio::null())
            .output()
            .ok()?;
        if !out.status.success() {
            return None;
        }
        let dir = String::from_utf8(out.stdout).ok()?;
        self.library_in(&self.dir_in(Path::new(dir.trim())))
    }

    /// Installs `package==version` into the environment `venv` with pip, making the
    /// environment first if it has no Python, and returns the library found there.
    ///
    /// # Errors
    /// What failed (venv, pip with its last line of output, or no library afterwards),
    /// naming the package and the environment.
    pub fn install(&self, venv: &Path) -> Result<PathBuf, String> {
        let fail = |what: String| {
            format!(
                "installing {}=={} into {}: {what}",
                self.package,
                self.version,
                venv.display()
            )
        };
        let python = venv.join("bin/python");
        if !python.is_file() {
            let status = Command::new("python3")
                .args(["-m", "venv"])
                .arg(venv)
                .status()
                .map_err(|e| fail(format!("python3 -m venv: {e}")))?;
            if !status.success() {
                return Err(fail(format!("python3 -m venv exited with {status}")));
            }
        }
        let out = Command::new(&python)
            .args([
                "-m",
                "pip",
                "install",
                "--quiet",
                "--disable-pip-version-check",
                &format!("{}=={}", self.package, self.version),
            ])
            .output()
            .map_err(|e| fail(format!("pip: {e}")))?;
        if !out.status.success() {
            let stderr = String::from_utf8_lossy(&out.stderr);
            let last = stderr.lines().last().unwrap_or("").trim().to_owned();
            return Err(fail(format!("pip exited with {}: {last}", out.status)));
        }
        self.in_site_packages(&venv.join("lib"))
            .ok_or_else(|| fail("pip succeeded but the library is not there".to_owned()))
    }
}

/// The entries of `dir` whose names start with `prefix`, in name order (`None` when
/// `dir` cannot be read).
fn entries_starting_with(dir: &Path, prefix: &str) -> Option<Vec<PathBuf>> {
    let mut entries: Vec<PathBuf> = std::fs::read_dir(dir)
        .ok()?
        .flatten()
        .map(|e| e.path())
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with(prefix))
        })
        .collect();
    entries.sort();
    Some(entries)
}

#[cfg(test)]
mod tests {
    use super::*;

    const LIB: WheelLibrary = WheelLibrary {
        package: "somepkg",
        version: "1.0",
        subdir: "capi",
        file_prefix: "libsome.so",
    };

    #[test]
    fn the_library_is_found_inside_a_wheel_layout() {
        let root = std::env::temp_dir().join(format!("pywheel-find-{}", std::process::id()));
        let capi = root.join("lib/python3.11/site-packages/somepkg/capi");
        std::fs::create_dir_all(&capi).expect("dirs");
        std::fs::write(capi.join("libsome.so.1.0"), b"").expect("file");
        std::fs::write(capi.join("other.so"), b"").expect("file");
        let mut looked = Vec::new();
        let found = LIB.search(Some(&root), &mut looked).expect("found");
        assert!(found.path.ends_with("libsome.so.1.0"), "{found:?}");
        assert_eq!(found.source, "project environment");
        assert_eq!(looked.len(), 1, "found at the first place: {looked:?}");
        assert!(LIB.in_site_packages(&root.join("nothing")).is_none());
        let _ = std::fs::remove_dir_all(&root);
    }

    #[test]
    fn every_place_looked_at_is_listed() {
        let root = std::env::temp_dir().join(format!("pywheel-none-{}", std::process::id()));
        let mut looked = Vec::new();
        assert!(LIB.search(Some(&root), &mut looked).is_none());
        assert!(
            looked[0].contains(&root.display().to_string()),
            "{looked:?}"
        );
        assert!(
            looked.iter().any(|l| l.contains("import somepkg")),
            "{looked:?}"
        );
        assert!(
            looked.iter().any(|l| l.starts_with("/usr/lib/")),
            "{looked:?}"
        );
    }

    #[test]
    fn the_environment_comes_from_teleop_venv_or_home() {
        let v = project_venv(&|k| (k == "TELEOP_VENV").then(|| "/x/venv".into()));
        assert_eq!(v, Some(PathBuf::from("/x/venv")));
        let v = project_venv(&|k| (k == "HOME").then(|| "/home/u".into()));
        assert_eq!(v, Some(PathBuf::from("/home/u/.cache/teleop-venv")));
        assert_eq!(project_venv(&|_| None), None);
    }
}
