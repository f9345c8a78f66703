//! Finding and loading ONNX Runtime (`libonnxruntime.so`) at run time.
//!
//! The library comes from the PyPI `onnxruntime` wheel (it ships
//! `onnxruntime/capi/libonnxruntime.so.<version>`). Search order, first hit wins:
//!
//! 1. the path given by the caller (a node's config);
//! 2. the environment variable `ORT_DYLIB_PATH` (ort's convention);
//! 3. the wheel's places ([`teleop_pywheel`]): the project's Python environment,
//!    `$TELEOP_VENV` or `~/.cache/teleop-venv` (made by `bash tests/run.sh`, which
//!    installs `onnxruntime` there), an `onnxruntime` package installed for `python3`
//!    (asked with `python3 -c`), the usual site-packages directories.
//!
//! When nothing is found, the error lists every place looked at and says how to get
//! the library. The first successful load wins for the whole process (ONNX Runtime
//! allows one environment per process).

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

pub use teleop_pywheel::Found;
use teleop_pywheel::WheelLibrary;

use crate::InferenceError;

/// The onnxruntime version the project pins (PyPI wheel) and tests against.
pub const ONNXRUNTIME_VERSION: &str = "1.32.0";

static ENVIRONMENT: OnceLock<Result<(ort::environment::Environment, PathBuf), String>> =
    OnceLock::new();

/// The library in the `onnxruntime` wheel (`onnxruntime/capi/libonnxruntime.so.*`).
pub const ONNXRUNTIME_WHEEL: WheelLibrary = WheelLibrary {
    package: "onnxruntime",
    version: ONNXRUNTIME_VERSION,
    subdir: "capi",
    file_prefix: "libonnxruntime.so",
};

/// Searches for `libonnxruntime.so` (see the module docs); `explicit` is step 1.
///
/// # Errors
/// [`InferenceError::RuntimeNotFound`] listing every place looked at, or naming an
/// explicit/`ORT_DYLIB_PATH` path that does not exist.
pub fn find(explicit: Option<&Path>) -> Result<Found, InferenceError> {
    if let Some(p) = explicit {
        if p.is_file() {
            return Ok(Found {
                path: p.to_path_buf(),
                source: "config".to_owned(),
            });
        }
        return Err(InferenceError::RuntimeNotFound {
            looked: vec![format!("{} (from the config): no such file", p.display())],
        });
    }
    if let Some(p) = std::env::var_os("ORT_DYLIB_PATH") {
        let p = PathBuf::from(p);
        if p.is_file() {
            return Ok(Found {
                path: p,
                source: "ORT_DYLIB_PATH".to_owned(),
            });
        }
        return Err(InferenceError::RuntimeNotFound {
            looked: vec![format!(
                "{} (from ORT_DYLIB_PATH): no such file",
                p.display()
            )],
        });
    }
    let mut looked = Vec::new();
    ONNXRUNTIME_WHEEL
        .search(project_venv().as_deref(), &mut looked)
        .ok_or(InferenceError::RuntimeNotFound { looked })
}

/// The project's Python environment: `$TELEOP_VENV`, else `~/.cache/teleop-venv`.
#[must_use]
pub fn project_venv() -> Option<PathBuf> {
    teleop_pywheel::project_venv(&|name| std::env::var_os(name))
}

/// Finds the library, and when it is nowhere, installs the pinned `onnxruntime` wheel
/// from PyPI into the project's Python environment ([`project_venv`], created with
/// `python3 -m venv` if missing) and finds it there. What it does is logged, since it
/// downloads.
///
/// # Errors
/// [`InferenceError::RuntimeNotFound`] when the install failed, with pip's reason.
pub fn find_or_install(explicit: Option<&Path>) -> Result<Found, InferenceError> {
    let first = match find(explicit) {
        Ok(f) => return Ok(f),
        Err(e) if explicit.is_some() => return Err(e),
        Err(e) => e,
    };
    let Some(venv) = project_venv() else {
        return Err(first);
    };
    tracing::info!(venv = %venv.display(), "ONNX Runtime not found: installing onnxruntime=={ONNXRUNTIME_VERSION} from PyPI into the project environment");
    ONNXRUNTIME_WHEEL
        .install(&venv)
        .map_err(|why| InferenceError::RuntimeNotFound { looked: vec![why] })?;
    find(None)
}

/// Loads ONNX Runtime once per process (from `explicit` or the search) and returns
/// the environment and the library's path. Later calls return the first result.
///
/// # Errors
/// [`InferenceError::RuntimeNotFound`] or [`InferenceError::RuntimeLoad`].
pub fn environment(
    explicit: Option<&Path>,
) -> Result<(&'static ort::environment::Environment, &'static Path), InferenceError> {
    // A failed search is not cached: the user may install the library and retry.
    if ENVIRONMENT.get().is_none() {
        let found = find(explicit)?;
        let _ = ENVIRONMENT.set(load(&found));
    }
    match ENVIRONMENT.get() {
        Some(Ok((env, path))) => Ok((env, path.as_path())),
        Some(Err(e)) => Err(InferenceError::RuntimeLoad(e.clone())),
        None => Err(InferenceError::RuntimeLoad(
            "ONNX Runtime was not initialised".into(),
        )),
    }
}

fn load(found: &Found) -> Result<(ort::environment::Environment, PathBuf), String> {
    let builder = ort::init_from(&found.path).map_err(|e| {
        format!(
            "{} (found via {}) could not be loaded: {e}; install onnxruntime=={ONNXRUNTIME_VERSION} from PyPI",
            found.path.display(),
            found.source
        )
    })?;
    let env = builder
        .with_name("teleop-hand-inference")
        .build()
        .map_err(|e| format!("ONNX Runtime from {}: {e}", found.path.display()))?;
    tracing::info!(library = %found.path.display(), via = found.source, "ONNX Runtime loaded");
    Ok((env, found.path.clone()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_missing_explicit_path_is_named() {
        let err = find(Some(Path::new("/nonexistent/libonnxruntime.so"))).expect_err("missing");
        let msg = err.to_string();
        assert!(msg.contains("/nonexistent/libonnxruntime.so"), "{msg}");
        assert!(msg.contains("pip install onnxruntime"), "{msg}");
    }

    #[test]
    fn the_library_is_found_inside_a_wheel_layout() {
        let root = std::env::temp_dir().join(format!("ort-find-{}", std::process::id()));
        let capi = root.join("lib/python3.11/site-packages/onnxruntime/capi");
        std::fs::create_dir_all(&capi).expect("dirs");
        std::fs::write(capi.join("libonnxruntime.so.1.32.0"), b"").expect("file");
        std::fs::write(capi.join("other.so"), b"").expect("file");
        let found = ONNXRUNTIME_WHEEL
            .in_site_packages(&root.join("lib"))
            .expect("found");
        assert!(found.ends_with("libonnxruntime.so.1.32.0"));
        assert!(
            ONNXRUNTIME_WHEEL
                .in_site_packages(&root.join("nothing"))
                .is_none()
        );
        let _ = std::fs::remove_dir_all(&root);
    }
}
