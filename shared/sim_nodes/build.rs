//! MuJoCo's library into the run path of this crate's binaries (`../physics/run_path.rs`).

#[path = "../physics/run_path.rs"]
mod run_path;

fn main() {
    println!("cargo::rerun-if-changed=../physics/run_path.rs");
    run_path::emit();
}
