//! Puts the board's memory map where the linker finds it, selects the linker scripts, and
//! writes the world the firmware is built for.
//!
//! `memory.x` lives at the repository root (one copy for the firmware and the emulator
//! harness); it is copied into `OUT_DIR`, which is added to the linker search path.
//!
//! The world is a scenario file: `BUGBOT_WORLD` names it (`cargo xtask firmware --world
//! FILE` sets it; default `../host-sim/scenarios/seed-mat.toml`, from this directory). It
//! is checked by the `world` crate, with the same code and errors as `host-sim run`, and
//! written into `OUT_DIR/world.rs` for `src/world.rs` to include. An invalid world builds
//! nothing.

use std::env;
use std::fs;
use std::path::PathBuf;

/// The variable that names the world file.
const WORLD_VAR: &str = "BUGBOT_WORLD";

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

    write_world(&manifest, &out);
}

/// Checks the world file and writes its constants to `OUT_DIR/world.rs`; on a bad world,
/// says why and fails the build.
fn write_world(manifest: &std::path::Path, out: &std::path::Path) {
    println!("cargo:rerun-if-env-changed={WORLD_VAR}");
    let path = match env::var_os(WORLD_VAR) {
        Some(p) if !p.is_empty() => manifest.join(PathBuf::from(p)),
        _ => manifest
            .join("..")
            .join("host-sim")
            .join("scenarios")
            .join("seed-mat.toml"),
    };
    println!("cargo:rerun-if-changed={}", path.display());
    let fail = |what: String| -> ! {
        eprintln!("error: world {}: {what}", path.display());
        std::process::exit(1);
    };
    let scenario = world::Scenario::load(&path).unwrap_or_else(|e| fail(e.to_string()));
    let robot = world::RobotWorld::of(&scenario).unwrap_or_else(|e| fail(e.to_string()));
    let mut text = world::codegen::firmware_constants(&robot, &path.display().to_string());
    // The world's identity: a hash of its constants (the first line names the file, which
    // may move), so that state saved in another world is never resumed in this one.
    let constants = text.split_once('\n').map_or("", |(_, rest)| rest);
    text.push_str(&format!(
        "/// A hash of this world's constants (FNV-1a): what the retained state is tagged with.\npub const WORLD_ID: u32 = {:#010x};\n",
        fnv1a(constants.as_bytes())
    ));
    fs::write(out.join("world.rs"), text).expect("cannot write world.rs into OUT_DIR");
}

/// 32-bit FNV-1a.
fn fnv1a(bytes: &[u8]) -> u32 {
    bytes.iter().fold(0x811c_9dc5, |h: u32, &b| {
        (h ^ u32::from(b)).wrapping_mul(0x0100_0193)
    })
}
