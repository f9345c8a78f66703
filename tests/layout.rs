//! The crates' layout, read from `cargo metadata` (every dependency kind: normal, build
//! and dev):
//!
//! * the sites' crates (`local_site/`, `remote_site/`) do not depend on the simulators
//!   (`teleop-sim`, `teleop-physics`) or on the simulator processes
//!   (`teleop-sim-nodes`): a node cannot tell a simulated device from a driver, and a
//!   real robot's build links no simulator;
//! * no crate under `shared/` depends on a site's crate, on the `teleop` program
//!   (`deploy/`) or on the tests: shared code is below the sites;
//! * the dependency graph of the workspace has no cycle through path dependencies of
//!   any kind (cargo refuses a cycle of normal dependencies, not one closed by a
//!   dev-dependency).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::process::Command;

use teleop_system_tests::repo_root;

/// The simulators, which the sites' crates must not link.
const SIMULATORS: [&str; 3] = ["teleop-sim", "teleop-physics", "teleop-sim-nodes"];

/// A workspace crate: where it sits, and its workspace dependencies (name, kind).
#[derive(Debug)]
struct Crate {
    dir: PathBuf,
    deps: Vec<(String, String)>,
}

fn workspace() -> BTreeMap<String, Crate> {
    let root = repo_root();
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    let out = Command::new(cargo)
        .args([
            "metadata",
            "--format-version",
            "1",
            "--no-deps",
            "--offline",
        ])
        .arg("--manifest-path")
        .arg(root.join("Cargo.toml"))
        .output()
        .expect("cargo metadata runs");
    assert!(
        out.status.success(),
        "cargo metadata failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let meta: serde_json::Value = serde_json::from_slice(&out.stdout).expect("metadata is JSON");
    let packages = meta["packages"].as_array().expect("packages");
    let names: BTreeSet<String> = packages
        .iter()
        .filter_map(|p| p["name"].as_str().map(str::to_owned))
        .collect();
    packages
        .iter()
        .map(|p| {
            let name = p["name"].as_str().expect("name").to_owned();
            let manifest = PathBuf::from(p["manifest_path"].as_str().expect("manifest"));
            let dir = manifest
                .parent()
                .and_then(|d| d.strip_prefix(&root).ok())
                .map(Path::to_path_buf)
                .expect("a workspace crate lies inside the repository");
            let deps = p["dependencies"]
                .as_array()
                .expect("dependencies")
                .iter()
                .filter_map(|d| {
                    let dep = d["name"].as_str()?;
                    names.contains(dep).then(|| {
                        let kind = d["kind"].as_str().unwrap_or("normal").to_owned();
                        (dep.to_owned(), kind)
                    })
                })
                .collect();
            (name, Crate { dir, deps })
        })
        .collect()
}

fn under(c: &Crate, top: &str) -> bool {
    c.dir.starts_with(top)
}

#[test]
fn the_sites_crates_link_no_simulator() {
    let ws = workspace();
    let sites: Vec<_> = ws
        .iter()
        .filter(|(_, c)| under(c, "local_site") || under(c, "remote_site"))
        .collect();
    // The site crates are all found (the filter is not vacuous).
    for name in [
        "teleop-local-site",
        "teleop-remote-site",
        "teleop-hand-inference",
    ] {
        assert!(
            sites.iter().any(|(n, _)| n.as_str() == name),
            "{name} not found under local_site/ or remote_site/: {:?}",
            ws.keys().collect::<Vec<_>>()
        );
    }
    let mut wrong = Vec::new();
    for (name, c) in &sites {
        for (dep, kind) in &c.deps {
            if SIMULATORS.contains(&dep.as_str()) {
                wrong.push(format!("{name} -> {dep} ({kind})"));
            }
        }
    }
    assert!(
        wrong.is_empty(),
        "the sites' crates depend on a simulator: {wrong:?}"
    );
    // The simulator processes exist and are what links the simulators.
    let nodes = &ws["teleop-sim-nodes"];
    assert!(under(nodes, "shared"), "{:?}", nodes.dir);
    assert!(nodes.deps.iter().any(|(d, _)| d == "teleop-sim"));
}

#[test]
fn shared_crates_depend_on_shared_crates_only() {
    let ws = workspace();
    let shared: Vec<_> = ws.iter().filter(|(_, c)| under(c, "shared")).collect();
    assert!(shared.len() >= 15, "{} crates under shared/", shared.len());
    let mut wrong = Vec::new();
    for (name, c) in &shared {
        for (dep, kind) in &c.deps {
            if !under(&ws[dep], "shared") {
                wrong.push(format!("{name} -> {dep} ({kind}, in {:?})", ws[dep].dir));
            }
        }
    }
    assert!(
        wrong.is_empty(),
        "crates under shared/ depend on crates outside it: {wrong:?}"
    );
}

#[test]
fn the_workspace_has_no_dependency_cycle() {
    let ws = workspace();
    // Depth-first search over every kind of workspace dependency.
    fn visit<'a>(
        name: &'a str,
        ws: &'a BTreeMap<String, Crate>,
        path: &mut Vec<&'a str>,
        done: &mut BTreeSet<&'a str>,
    ) -> Option<Vec<String>> {
        if let Some(i) = path.iter().position(|n| *n == name) {
            let mut cycle: Vec<String> = path[i..].iter().map(|s| s.to_string()).collect();
            cycle.push(name.to_owned());
            return Some(cycle);
        }
        if done.contains(name) {
            return None;
        }
        path.push(name);
        for (dep, _) in &ws[name].deps {
            // A crate's dev-dependency on itself is not a cycle cargo would build.
            if dep != name
                && let Some(c) = visit(dep, ws, path, done)
            {
                return Some(c);
            }
        }
        path.pop();
        done.insert(name);
        None
    }
    let mut done = BTreeSet::new();
    for name in ws.keys() {
        let cycle = visit(name, &ws, &mut Vec::new(), &mut done);
        assert!(cycle.is_none(), "dependency cycle: {cycle:?}");
    }
}
