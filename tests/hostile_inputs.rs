//! Every decoder of bytes from outside the process fed generated and mutated inputs
//! (`teleop_system_tests::hostile`): none panics, none hangs (a call over
//! `hostile::HANG_LIMIT` aborts the run), the memory live during one call stays bounded,
//! and the inputs reach both outcomes (some accepted, some refused), so the generators
//! are not stuck on one path. The long run (10 million inputs per decoder) is
//! `cargo run --release --example hostile_inputs`; its figures are in
//! docs/robustness.md.
#![allow(clippy::unwrap_used)]

use teleop_system_tests::hostile::{self, PeakAlloc};
use teleop_system_tests::repo_root;

#[global_allocator]
static ALLOC: PeakAlloc = PeakAlloc;

/// Inputs per decoder in the test command (`TELEOP_HOSTILE_INPUTS` overrides).
const INPUTS: u64 = 20_000;
/// The most memory one call may hold beyond what was live before it: a fixed allowance
/// plus a multiple of the longest input (no decoder allocates what a length field
/// claims before checking it against the bytes).
const FIXED_ALLOWANCE: usize = 8 << 20;
const PER_INPUT_BYTE: usize = 64;

#[test]
fn no_decoder_panics_hangs_or_balloons_on_hostile_input() {
    let inputs = std::env::var("TELEOP_HOSTILE_INPUTS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(INPUTS);
    let targets = hostile::targets(&repo_root()).unwrap();
    assert!(targets.len() >= 16, "{} targets", targets.len());
    let mut failures = Vec::new();
    println!("{}", hostile::MARKDOWN_HEADER);
    for t in &targets {
        let r = hostile::run(t, inputs, 2026, Some(&ALLOC));
        let peak = r
            .peak_call_bytes
            .expect("the counting allocator is installed");
        println!("{}", r.markdown_row());
        if r.panics > 0 {
            failures.push(format!(
                "{}: {} panics, first {:?}",
                r.name, r.panics, r.first_panic
            ));
        }
        if peak > FIXED_ALLOWANCE + PER_INPUT_BYTE * r.longest_input {
            failures.push(format!(
                "{}: {peak} bytes live during one call (longest input {} B)",
                r.name, r.longest_input
            ));
        }
        if r.accepted == 0 || r.refused == 0 {
            failures.push(format!(
                "{}: the inputs reached one outcome only ({} accepted, {} refused)",
                r.name, r.accepted, r.refused
            ));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
