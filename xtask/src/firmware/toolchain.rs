//! Which Rust toolchain builds the firmware, and the packages and tools each needs.
//!
//! - **rustup**, when the active toolchain has `thumbv6m-none-eabi` (or `rustup target add`
//!   gets it): plain `cargo build --release` in `firmware/`.
//! - **Debian** otherwise (machines without access to rustup's servers):
//!   `scripts/install-cross-toolchain.sh --rust` installs Debian's Rust 1.96 with its library
//!   source, and core is built from source with `-Zbuild-std=core`.
//!
//! `BUGBOT_FIRMWARE_TOOLCHAIN=rustup|debian` forces one path. Both link through flip-link
//! (`scripts/install-flip-link.sh`), which calls `rust-lld`: rustup's rustc puts its own in
//! the linker's `PATH`, Debian's is `/usr/bin/rust-lld`.

use std::fmt;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::thread;
use std::time::{Duration, Instant};

use super::TARGET;
use crate::run_in;

/// Debian's compiler and cargo, installed by `scripts/install-cross-toolchain.sh`.
const DEBIAN_RUSTC: &str = "/usr/bin/rustc";
const DEBIAN_CARGO: &str = "/usr/bin/cargo";
/// Debian's `rust-lld` (rust-web-llvm, a link to lld-22), which flip-link calls by name:
/// `/usr/bin` comes first in the Debian build's `PATH`.
const DEBIAN_RUST_LLD: &str = "/usr/bin/rust-lld";
/// How long `rustup target add` may try before we fall back to Debian's toolchain.
const RUSTUP_ADD_TIMEOUT: Duration = Duration::from_secs(120);

/// Environment for building ST's C driver for [`TARGET`] with Debian's packages: `cc`
/// compiles with arm-none-eabi-gcc, and bindgen's libclang parses the driver's headers,
/// which include newlib's `<string.h>` and friends (the driver's build script asks gcc for
/// a sysroot, and Debian's gcc has none, so without this path bindgen cannot find them).
/// `firmware/.cargo/config.toml` sets the same BINDGEN_EXTRA_CLANG_ARGS for hand builds.
pub const C_TOOLCHAIN_ENV: [(&str, &str); 3] = [
    ("CC_thumbv6m_none_eabi", "arm-none-eabi-gcc"),
    ("AR_thumbv6m_none_eabi", "arm-none-eabi-ar"),
    (
        "BINDGEN_EXTRA_CLANG_ARGS",
        "-I/usr/lib/arm-none-eabi/include",
    ),
];

/// Environment variable that forces a toolchain: `rustup` or `debian`.
pub const FORCE_VAR: &str = "BUGBOT_FIRMWARE_TOOLCHAIN";

/// Runs `scripts/install-cross-toolchain.sh` for the packages this build needs: Debian's
/// Rust toolchain (`--rust`) and the depth sensor's C toolchain (`--c`). Quiet when they
/// are installed.
pub fn install_packages(root: &Path, rust: bool, c: bool) -> Result<(), String> {
    if !rust && !c {
        return Ok(());
    }
    let script = root.join("scripts").join("install-cross-toolchain.sh");
    let mut cmd = Command::new("bash");
    cmd.arg(&script);
    if rust {
        cmd.arg("--rust");
    }
    if c {
        cmd.arg("--c");
    }
    run_in(root, &mut cmd)
}

/// Which compiler builds the firmware.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Toolchain {
    /// The active rustup toolchain, which has the target's prebuilt core.
    Rustup,
    /// Debian's rustc/cargo 1.96, building core from source.
    Debian,
}

impl fmt::Display for Toolchain {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Toolchain::Rustup => "rustup",
            Toolchain::Debian => "Debian (-Zbuild-std=core)",
        })
    }
}

impl Toolchain {
    /// Picks the toolchain (see the module docs); [`install_packages`] installs Debian's.
    pub fn choose() -> Result<Toolchain, String> {
        let forced = std::env::var(FORCE_VAR).unwrap_or_default();
        let toolchain = match forced.as_str() {
            "rustup" => Toolchain::Rustup,
            "debian" => Toolchain::Debian,
            "" if rustup_has_target() || rustup_add_target() => Toolchain::Rustup,
            "" => Toolchain::Debian,
            other => {
                return Err(format!(
                    "{FORCE_VAR}={other:?}: expected \"rustup\" or \"debian\""
                ))
            }
        };
        Ok(toolchain)
    }

    /// `cargo <subcommand> --release` for the firmware, with this toolchain's environment,
    /// linking through `flip_link` (firmware/.cargo/config.toml names it too, for hand
    /// builds; the path given here does not depend on `PATH`).
    pub fn cargo(self, subcommand: &str, flip_link: &Path) -> Command {
        let mut cmd = match self {
            Toolchain::Rustup => {
                // The rustup proxy, with the inherited RUSTUP_TOOLCHAIN: the same toolchain
                // whose target list we checked. The target comes from firmware/.cargo/config.toml.
                let mut cmd = Command::new("cargo");
                cmd.args([subcommand, "--release"]);
                cmd
            }
            Toolchain::Debian => {
                let mut cmd = Command::new(DEBIAN_CARGO);
                cmd.args([
                    subcommand,
                    "--release",
                    "-Zbuild-std=core",
                    "--target",
                    TARGET,
                ]);
                // What the outer `cargo xtask` (a rustup cargo) leaves in the environment
                // would point the Debian cargo at rustup's binaries and libraries.
                for var in [
                    "RUSTUP_TOOLCHAIN",
                    "RUSTUP_TOOLCHAIN_SOURCE",
                    "RUST_RECURSION_COUNT",
                    "CARGO",
                    "RUSTC",
                    "RUSTDOC",
                    "RUSTC_WRAPPER",
                    "RUSTC_WORKSPACE_WRAPPER",
                    "LD_LIBRARY_PATH",
                ] {
                    cmd.env_remove(var);
                }
                cmd.env("RUSTC", DEBIAN_RUSTC);
                // -Zbuild-std is unstable; Debian ships a stable compiler.
                cmd.env("RUSTC_BOOTSTRAP", "1");
                // Debian's own cargo-clippy, clippy-driver and rust-lld before rustup's
                // proxies in ~/.cargo/bin.
                cmd.env("PATH", debian_path());
                cmd
            }
        };
        cmd.env("CARGO_TARGET_THUMBV6M_NONE_EABI_LINKER", flip_link);
        cmd
    }

    /// What this toolchain needs beyond the packages: Debian's `rust-lld`, which
    /// flip-link calls.
    pub fn check_linker(self) -> Result<(), String> {
        if self == Toolchain::Debian && !Path::new(DEBIAN_RUST_LLD).exists() {
            return Err(format!(
                "{DEBIAN_RUST_LLD} is missing: flip-link links with it on the Debian toolchain \
(scripts/install-cross-toolchain.sh --rust installs it, package rust-web-llvm)"
            ));
        }
        Ok(())
    }
}

/// `--config` for the firmware's build that strips the machine's own directories from the
/// source paths compiled in (panic locations, debug info): the checkout's and cargo's
/// registry sources become relative (`slam-core/src/pose.rs`, `embassy-rp-0.10.0/src/..`).
/// The image then does not depend on where the project or `CARGO_HOME` lies, so its size
/// is the same on every machine, and it is smaller by the prefixes.
pub fn source_path_remaps(root: &Path) -> String {
    let mut prefixes = vec![root.to_path_buf()];
    let cargo_home = std::env::var_os("CARGO_HOME")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cargo")));
    if let Some(sources) = cargo_home.map(|h| h.join("registry").join("src")) {
        if let Ok(entries) = std::fs::read_dir(&sources) {
            let mut registries: Vec<PathBuf> = entries.flatten().map(|e| e.path()).collect();
            registries.sort();
            prefixes.extend(registries);
        }
    }
    remap_config(&prefixes)
}

/// The `--config` value remapping each of `prefixes` to nothing; a directory whose name
/// the TOML string or the flag cannot carry (a quote, a backslash, an `=`, a control
/// character, or not UTF-8) is left as it is.
fn remap_config(prefixes: &[PathBuf]) -> String {
    let flags: Vec<String> = prefixes
        .iter()
        .filter_map(|p| p.to_str())
        .filter(|p| !p.contains(['"', '\\', '=']) && !p.chars().any(char::is_control))
        .map(|p| format!("\"--remap-path-prefix={}/=\"", p.trim_end_matches('/')))
        .collect();
    format!("target.{TARGET}.rustflags=[{}]", flags.join(", "))
}

/// `PATH` with `/usr/bin` first.
fn debian_path() -> std::ffi::OsString {
    let rest = std::env::var_os("PATH").unwrap_or_default();
    let mut dirs = vec![PathBuf::from("/usr/bin")];
    dirs.extend(std::env::split_paths(&rest).filter(|d| d != Path::new("/usr/bin")));
    std::env::join_paths(dirs).unwrap_or(rest)
}

/// Runs `scripts/install-flip-link.sh` (quiet when flip-link is installed) and returns the
/// path of the flip-link binary it prints.
pub fn install_flip_link(root: &Path) -> Result<PathBuf, String> {
    let script = root.join("scripts").join("install-flip-link.sh");
    let out = Command::new("bash")
        .arg(&script)
        .current_dir(root)
        .stderr(Stdio::inherit())
        .output()
        .map_err(|e| format!("cannot run {}: {e}", script.display()))?;
    let path = PathBuf::from(String::from_utf8_lossy(&out.stdout).trim());
    if !out.status.success() || !path.is_file() {
        return Err(format!(
            "{} failed ({}): flip-link, the firmware's linker, is not installed",
            script.display(),
            out.status
        ));
    }
    Ok(path)
}

/// Whether the active rustup toolchain already has the target's standard library.
pub fn rustup_has_target() -> bool {
    let Ok(out) = Command::new("rustup")
        .args(["target", "list", "--installed"])
        .stderr(Stdio::null())
        .output()
    else {
        return false;
    };
    out.status.success()
        && String::from_utf8_lossy(&out.stdout)
            .lines()
            .any(|l| l.trim() == TARGET)
}

/// Tries `rustup target add`, giving up after [`RUSTUP_ADD_TIMEOUT`] (offline machines).
fn rustup_add_target() -> bool {
    eprintln!("firmware: trying `rustup target add {TARGET}`");
    let Ok(mut child) = Command::new("rustup")
        .args(["target", "add", TARGET])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
    else {
        return false;
    };
    let started = Instant::now();
    loop {
        match child.try_wait() {
            Ok(Some(status)) => return status.success() && rustup_has_target(),
            Ok(None) if started.elapsed() < RUSTUP_ADD_TIMEOUT => {
                thread::sleep(Duration::from_millis(200))
            }
            _ => {
                let _ = child.kill();
                let _ = child.wait();
                return false;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn remaps_are_one_flag_a_directory_and_odd_names_are_left_out() {
        let dirs = [
            "/work/main",
            "/root/.cargo/registry/src/index.crates.io-1949cf8c6b5b557f/",
        ]
        .map(PathBuf::from);
        assert_eq!(
            remap_config(&dirs),
            "target.thumbv6m-none-eabi.rustflags=[\"--remap-path-prefix=/work/main/=\", \
\"--remap-path-prefix=/root/.cargo/registry/src/index.crates.io-1949cf8c6b5b557f/=\"]"
        );
        let odd = ["/a\"b", "/a=b", "/a\\b", "/a\nb"].map(PathBuf::from);
        assert_eq!(remap_config(&odd), "target.thumbv6m-none-eabi.rustflags=[]");
    }
}
