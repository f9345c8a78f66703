//! The long hostile-input run: every decoder of outside bytes fed `--inputs N` (default
//! ten million) generated and mutated inputs; one markdown row per decoder (inputs,
//! accepted, refused, panics, slowest call, most memory live in one call, inputs per
//! second). `--target TEXT` runs the decoders whose name contains TEXT; `--list` names
//! them. Run decoders in separate processes to use more cores: the memory figures are
//! per process.
//!
//! `cargo run --release --example hostile_inputs -- --inputs 10000000 --target MCAP`

use teleop_system_tests::hostile::{self, PeakAlloc};
use teleop_system_tests::repo_root;

#[global_allocator]
static ALLOC: PeakAlloc = PeakAlloc;

fn main() -> anyhow::Result<()> {
    let mut inputs: u64 = 10_000_000;
    let mut seed: u64 = 2026;
    let mut filter = String::new();
    let mut list = false;
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--inputs" => inputs = args.next().unwrap_or_default().parse()?,
            "--seed" => seed = args.next().unwrap_or_default().parse()?,
            "--target" => filter = args.next().unwrap_or_default(),
            "--list" => list = true,
            other => anyhow::bail!(
                "unknown argument `{other}` (--inputs N, --seed S, --target TEXT, --list)"
            ),
        }
    }
    let targets = hostile::targets(&repo_root())?;
    let chosen: Vec<_> = targets
        .iter()
        .filter(|t| t.name.contains(&filter))
        .collect();
    if list {
        for t in &chosen {
            println!("{}", t.name);
        }
        return Ok(());
    }
    anyhow::ensure!(!chosen.is_empty(), "no decoder's name contains `{filter}`");
    let mut panicked = false;
    println!("{}", hostile::MARKDOWN_HEADER);
    for t in chosen {
        let r = hostile::run(t, inputs, seed, Some(&ALLOC));
        println!("{}", r.markdown_row());
        if let Some((i, msg)) = &r.first_panic {
            eprintln!(
                "{}: first panic at iteration {i} (seed {seed}): {msg}",
                r.name
            );
            panicked = true;
        }
    }
    anyhow::ensure!(!panicked, "a decoder panicked");
    Ok(())
}
