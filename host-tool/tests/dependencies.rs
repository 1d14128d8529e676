//! `rlg-cal` depends on what it uses: the firmware and host-cli, never the simulator's CLI
//! (`rlg-sim`, with its thread pool `rayon`); and a build for real boards only
//! (`--no-default-features`) has neither the simulated board (`hal-sim`) nor a random-number
//! generator (`rand`). Checked on `cargo tree` (offline: the lock file, no network; well under
//! a second).

use std::process::Command;

/// The package names in `cargo tree -p rlg-cal` with `extra` arguments.
fn tree(extra: &[&str]) -> Vec<String> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let out = Command::new(cargo)
        .current_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
        .args(["tree", "--offline", "-p", "rlg-cal", "--prefix", "none"])
        .args(["--format", "{p}"])
        .args(extra)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    stdout
        .lines()
        .filter_map(|l| l.split_whitespace().next())
        .map(str::to_owned)
        .collect()
}

fn has(packages: &[String], name: &str) -> bool {
    packages.iter().any(|p| p == name)
}

#[test]
fn rlg_cal_depends_on_what_it_uses() {
    // Every kind of dependency (normal, build, dev), the default features (`sim`).
    let all = tree(&[]);
    for name in ["firmware", "host-cli", "hal-sim"] {
        assert!(has(&all, name), "{name} in {all:?}");
    }
    for name in ["rlg-sim", "rayon"] {
        assert!(!has(&all, name), "{name} in {all:?}");
    }
    // What a build for real boards links.
    let real = tree(&["--no-default-features", "-e", "normal"]);
    assert!(
        has(&real, "firmware") && has(&real, "serialport"),
        "{real:?}"
    );
    for name in ["hal-sim", "rand", "rand_core", "rlg-sim", "rayon"] {
        assert!(!has(&real, name), "{name} in {real:?}");
    }
}
