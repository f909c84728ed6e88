//! Every program outside the Rust toolchain that the tests call, and the project script
//! that installs it (listed for people in `xtask/README.md`).
//!
//! The scripts run on their own when a command needs their tools (`cargo xtask firmware`
//! runs the cross-toolchain and flip-link ones, `cargo xtask emulate` the Node.js one,
//! `cargo xtask test` the browser one);
//! `cargo xtask tools` checks them all at once and names the script for each one missing.

use std::path::{Path, PathBuf};

/// An external program, and what installs it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Tool {
    /// Program name (looked up on `PATH`), or an absolute path for files that are not.
    pub program: &'static str,
    /// What the tests need it for.
    pub used_for: &'static str,
    /// The script (and its options) that installs it.
    pub installed_by: &'static str,
    /// Needed only on the Debian toolchain path (no rustup target).
    pub debian_only: bool,
}

const fn tool(program: &'static str, used_for: &'static str, installed_by: &'static str) -> Tool {
    Tool {
        program,
        used_for,
        installed_by,
        debian_only: false,
    }
}

const fn debian(program: &'static str, used_for: &'static str) -> Tool {
    Tool {
        program,
        used_for,
        installed_by: "scripts/install-cross-toolchain.sh --rust",
        debian_only: true,
    }
}

/// Every external program the tests call.
pub const TOOLS: &[Tool] = &[
    tool(
        "node",
        "runs the emulator harness (tests/emulator)",
        "scripts/install-node.sh",
    ),
    tool(
        "npm",
        "installs rp2040js from tests/emulator/package-lock.json (`npm ci`)",
        "scripts/install-node.sh",
    ),
    tool(
        "chromium",
        "headless browser for the live page's test (host-sim/tests/page_browser.rs)",
        "scripts/install-browser.sh",
    ),
    tool(
        "flip-link",
        "the firmware's linker wrapper (stack overflow faults)",
        "scripts/install-flip-link.sh",
    ),
    tool(
        "arm-none-eabi-gcc",
        "compiles ST's VL53L5CX driver",
        "scripts/install-cross-toolchain.sh --c",
    ),
    tool(
        "arm-none-eabi-ar",
        "archives ST's VL53L5CX driver",
        "scripts/install-cross-toolchain.sh --c",
    ),
    tool(
        "/usr/lib/arm-none-eabi/include/string.h",
        "newlib's headers, which bindgen reads",
        "scripts/install-cross-toolchain.sh --c",
    ),
    tool(
        "/usr/lib/llvm-14/lib/libclang.so",
        "libclang, which bindgen loads (libclang-dev)",
        "scripts/install-cross-toolchain.sh --c",
    ),
    debian(
        "/usr/bin/rustc",
        "Debian's Rust, when rustup cannot add thumbv6m-none-eabi",
    ),
    debian(
        "/usr/bin/cargo",
        "Debian's cargo, building core with -Zbuild-std",
    ),
    debian(
        "/usr/bin/rust-lld",
        "the linker flip-link calls on the Debian path",
    ),
    debian(
        "/usr/bin/cargo-clippy",
        "lints the firmware on the Debian path",
    ),
];

/// Where `program` is: itself if it is a path, else the first match on `PATH` or in
/// cargo's bin directory (where `cargo install` puts flip-link).
pub fn find(program: &str) -> Option<PathBuf> {
    let path = Path::new(program);
    if path.is_absolute() {
        return path.exists().then(|| path.to_path_buf());
    }
    let cargo_bin = std::env::var_os("CARGO_HOME")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cargo")))
        .map(|d| d.join("bin"));
    std::env::var_os("PATH")
        .iter()
        .flat_map(std::env::split_paths)
        .chain(cargo_bin)
        .map(|dir| dir.join(program))
        .find(|p| p.is_file())
}

/// A line saying which script installs `program`, for an error about it.
pub fn install_hint(program: &str) -> Option<String> {
    let name = Path::new(program)
        .file_name()
        .and_then(|n| n.to_str())
        .unwrap_or(program);
    TOOLS
        .iter()
        .find(|t| {
            t.program == program || t.program.ends_with(&format!("/{name}")) || t.program == name
        })
        .map(|t| {
            format!(
                "{} ({}) is installed by {}",
                t.program, t.used_for, t.installed_by
            )
        })
}

/// `cargo xtask tools`: which tools are installed; fails naming each one missing and its
/// script. The Debian toolchain's are only required when the rustup target is missing.
pub fn check_all() -> Result<(), String> {
    let debian_needed = !crate::firmware::rustup_has_target();
    let mut missing = Vec::new();
    for t in TOOLS {
        let found = find(t.program);
        let required = !t.debian_only || debian_needed;
        let state = match (&found, required) {
            (Some(p), _) => format!("ok       {}", p.display()),
            (None, true) => "MISSING".to_string(),
            (None, false) => "absent (not needed: rustup has the target)".to_string(),
        };
        println!(
            "{:<42} {state}\n{:<42}   {}; {}",
            t.program, "", t.used_for, t.installed_by
        );
        if found.is_none() && required {
            missing.push(format!("{} (run {})", t.program, t.installed_by));
        }
    }
    if missing.is_empty() {
        Ok(())
    } else {
        Err(format!("missing: {}", missing.join(", ")))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_script_named_exists() {
        let root = crate::workspace_root();
        for t in TOOLS {
            let script = t.installed_by.split(' ').next().unwrap_or_default();
            assert!(root.join(script).is_file(), "{} names {script}", t.program);
        }
    }

    #[test]
    fn hints_name_the_script() {
        let hint = install_hint("flip-link").unwrap();
        assert!(hint.contains("scripts/install-flip-link.sh"), "{hint}");
        let hint = install_hint("/root/.cargo/bin/flip-link").unwrap();
        assert!(hint.contains("scripts/install-flip-link.sh"), "{hint}");
        assert!(install_hint("node").unwrap().contains("install-node.sh"));
        assert!(install_hint("chromium")
            .unwrap()
            .contains("install-browser.sh"));
        assert_eq!(install_hint("no-such-program"), None);
    }

    #[test]
    fn finds_programs_on_path_and_absolute_paths() {
        assert!(find("sh").is_some());
        assert!(find("/").is_some());
        assert_eq!(find("/no/such/file"), None);
        assert_eq!(find("no-such-program-bugbot"), None);
    }
}
