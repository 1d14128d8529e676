//! Link setup for the MCU only: host builds (unit tests, the simulator) need none of it.
use std::{env, fs, path::PathBuf};

fn main() {
    // Shown in the start-up banner.
    for (var, name) in [
        ("PROFILE", "FW_BUILD_PROFILE"),
        ("OPT_LEVEL", "FW_OPT_LEVEL"),
    ] {
        let value = env::var(var).unwrap_or_else(|_| "?".into());
        println!("cargo:rustc-env={name}={value}");
    }
    if env::var("CARGO_CFG_TARGET_OS").as_deref() != Ok("none") {
        return;
    }
    let out = PathBuf::from(env::var_os("OUT_DIR").unwrap());
    fs::copy("../memory.x", out.join("memory.x")).expect("copy memory.x");
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rerun-if-changed=../memory.x");
    println!("cargo:rerun-if-changed=build.rs");
    // Link arguments here rather than rustflags: a RUSTFLAGS variable would silently drop them.
    println!("cargo:rustc-link-arg=-Tlink.x");
    println!("cargo:rustc-link-arg=-Tdefmt.x");
}
