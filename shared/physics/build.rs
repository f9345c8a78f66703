//! Supplies the directory of MuJoCo's shared library to the linker.
//!
//! mujoco-rs's build script asks pkg-config for `mujoco` (the project's .pc file names the
//! library: `.cargo/config.toml`); this script finds the library, or installs the pinned
//! `mujoco` wheel into the project's Python environment (`src/library.rs`), links
//! `libmujoco.so` and its soname into `$OUT_DIR/lib` and passes that directory to every
//! crate that links this one. Cargo puts search paths inside the target directory on the
//! library path of what it runs (`cargo run`, `cargo test`), so the binaries find it there.
//! With `MUJOCO_DYNAMIC_LINK_DIR` set, mujoco-rs links from that directory and this script
//! only passes it on. Crates whose binaries link MuJoCo read the directory as
//! `DEP_TELEOP_MUJOCO_LIB_DIR` and write it into the binaries' run path, so a binary
//! started by anyone (the launcher, a test, a shell) finds the library.

#[path = "src/library.rs"]
#[allow(dead_code)]
mod library;

use std::path::PathBuf;

fn main() {
    for var in [
        "MUJOCO_DYNAMIC_LINK_DIR",
        "TELEOP_VENV",
        "TELEOP_MUJOCO_NO_INSTALL",
        "HOME",
    ] {
        println!("cargo::rerun-if-env-changed={var}");
    }
    println!("cargo::rerun-if-changed=src/library.rs");
    if let Some(dir) = std::env::var_os("MUJOCO_DYNAMIC_LINK_DIR") {
        println!("cargo::metadata=lib_dir={}", PathBuf::from(dir).display());
        return;
    }
    let found = match library::find_or_install() {
        Ok(found) => found,
        Err(e) => {
            eprintln!("error: {e}");
            panic!("teleop-physics needs MuJoCo's library: {e}");
        }
    };
    println!("cargo::rerun-if-changed={}", found.path.display());
    let Some(out_dir) = std::env::var_os("OUT_DIR") else {
        panic!("OUT_DIR is not set (this script runs under cargo)");
    };
    let lib_dir = PathBuf::from(out_dir).join("lib");
    if let Err(e) = std::fs::create_dir_all(&lib_dir) {
        panic!("cannot create {}: {e}", lib_dir.display());
    }
    for name in ["libmujoco.so", library::MUJOCO_SONAME] {
        let link = lib_dir.join(name);
        let _ = std::fs::remove_file(&link);
        if let Err(e) = std::os::unix::fs::symlink(&found.path, &link) {
            panic!(
                "cannot link {} -> {}: {e}",
                link.display(),
                found.path.display()
            );
        }
    }
    println!("cargo::rustc-link-search=native={}", lib_dir.display());
    // For the build scripts of crates with binaries (`links` in Cargo.toml): they write
    // this directory into their binaries' run path.
    println!("cargo::metadata=lib_dir={}", lib_dir.display());
    println!(
        "cargo::rustc-env=TELEOP_MUJOCO_LINKED={} ({})",
        found.path.display(),
        found.source
    );
}
