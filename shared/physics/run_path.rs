//! For the build scripts of the crates with binaries that link MuJoCo (included by
//! path: `shared/sim_nodes`, `deploy/teleop`, `tests`): writes MuJoCo's library
//! directory (the physics crate's build script passes it as `DEP_TELEOP_MUJOCO_LIB_DIR`)
//! and `$ORIGIN/../lib` (an installation that puts the library beside `bin/`, the
//! container images) into the run path of every binary, test, example and bench of the
//! crate, so a binary started by anyone (the launcher, a test, a shell) finds the
//! library. The crate must depend on `teleop-physics` directly.

pub fn emit() {
    println!("cargo::rerun-if-env-changed=DEP_TELEOP_MUJOCO_LIB_DIR");
    if let Some(dir) = std::env::var_os("DEP_TELEOP_MUJOCO_LIB_DIR") {
        let dir = std::path::PathBuf::from(dir);
        println!("cargo::rustc-link-arg=-Wl,-rpath,{}", dir.display());
    }
    println!("cargo::rustc-link-arg=-Wl,-rpath,$ORIGIN/../lib");
}
