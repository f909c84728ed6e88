//! Puts the board's memory map where the linker finds it and selects the linker scripts.
//!
//! `memory.x` lives at the repository root (one copy for the firmware and the emulator
//! harness); it is copied into `OUT_DIR`, which is added to the linker search path.

use std::env;
use std::fs;
use std::path::PathBuf;

fn main() {
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    let manifest =
        PathBuf::from(env::var_os("CARGO_MANIFEST_DIR").expect("cargo sets CARGO_MANIFEST_DIR"));
    let memory_x = manifest.join("..").join("memory.x");
    let contents =
        fs::read(&memory_x).unwrap_or_else(|e| panic!("cannot read {}: {e}", memory_x.display()));
    fs::write(out.join("memory.x"), contents).expect("cannot write memory.x into OUT_DIR");
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rerun-if-changed={}", memory_x.display());
    println!("cargo:rerun-if-changed=build.rs");

    println!("cargo:rustc-link-arg-bins=--nmagic");
    println!("cargo:rustc-link-arg-bins=-Tlink.x");
    println!("cargo:rustc-link-arg-bins=-Tlink-rp.x");
    println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
}
