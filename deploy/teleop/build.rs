//! MuJoCo's library into the run path of this crate's binaries (`../../shared/physics/run_path.rs`).

#[path = "../../shared/physics/run_path.rs"]
mod run_path;

fn main() {
    println!("cargo::rerun-if-changed=../../shared/physics/run_path.rs");
    run_path::emit();
}
