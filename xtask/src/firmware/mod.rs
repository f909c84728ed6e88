//! `cargo xtask firmware [--world FILE] [--check-only] [--no-default-features] [--features
//! LIST]`: builds the RP2040 firmware for a world, writes its UF2 and flat binary images
//! next to the ELF ([`image`]), and checks its flash and RAM budget ([`budget`]).
//!
//! The world is a scenario file (default `host-sim/scenarios/seed-mat.toml`): the
//! firmware's `build.rs` reads the file `BUGBOT_WORLD` names, which this sets, and the
//! grid's size, and so the RAM, comes from it. The file is checked here first, with the
//! same errors, so a bad world fails before the toolchain is set up.
//!
//! Two toolchains can build it, rustup's or Debian's ([`toolchain`];
//! `BUGBOT_FIRMWARE_TOOLCHAIN=rustup|debian` forces one), and both link through flip-link,
//! installed by `scripts/install-flip-link.sh` before every build. The firmware always
//! builds into `firmware/target` (or `BUGBOT_FIRMWARE_TARGET_DIR`), never into the host's
//! target directory. `--check-only` type-checks the firmware (`cargo check`) and writes
//! nothing; [`clippy`] lints it for `cargo xtask lint`.
//!
//! # The depth sensor's C driver
//!
//! The firmware's default `vl53l5cx` feature builds ST's C driver for the VL53L5CX (crate
//! `vl53l5cx-uld`: `cc` compiles it, `bindgen` binds it), with either Rust toolchain. So
//! while the feature is on, `scripts/install-cross-toolchain.sh --c` installs Debian's
//! `gcc-arm-none-eabi`, `libnewlib-arm-none-eabi` and `libclang-dev`, and the build gets
//! [`C_TOOLCHAIN_ENV`] (each variable only where the caller has not set it).
//! `--no-default-features` builds without the sensor (and without the C toolchain); it and
//! `--features` are passed to cargo as they are.
//!
//! # The budget leaves out the sensor's firmware image
//!
//! The flash budget (192 KB) is for *our* firmware. ST's driver carries the sensor's own
//! firmware, an 86,016-byte blob (`VL53L5CX_FIRMWARE`, in `.rodata`) that the driver uploads
//! into the sensor at every boot. It is data we neither write nor can shrink, its size is
//! fixed by ST, and counting it would leave the budget a third of its size for everything
//! else. So the check reads that symbol's size from the ELF symbol table, prints it as its
//! own row, and holds flash *minus* the image to the budget; the images written (UF2, BIN)
//! and the `total` row still contain it, and 2 MB of flash holds it easily. Static RAM is

mod budget;
mod image;
mod toolchain;

use std::fs;
use std::path::PathBuf;
use std::process::Command;

use budget::Usage;
pub use budget::STACK_ROOM;
use image::{Elf, FlashImage, FLASH_BASE, UF2_FAMILY_RP2040};
pub use toolchain::rustup_has_target;
use toolchain::{Toolchain, C_TOOLCHAIN_ENV};

use crate::{run_in, workspace_root};

/// The firmware's target triple.
pub const TARGET: &str = "thumbv6m-none-eabi";
/// The firmware's binary name (`[[bin]]` in `firmware/Cargo.toml`).
const BIN_NAME: &str = "bugbot-firmware";
/// The world a firmware is built for when none is named, from the workspace root.
pub const DEFAULT_WORLD: &str = "host-sim/scenarios/seed-mat.toml";
/// The variable the firmware's `build.rs` reads the world file's path from.
const WORLD_VAR: &str = "BUGBOT_WORLD";
/// The firmware feature that needs the C toolchain, on by default.
const DEPTH_FEATURE: &str = "vl53l5cx";

/// `cargo xtask firmware`'s options.
#[derive(clap::Args, Clone, Debug, Default, PartialEq, Eq)]
pub struct FirmwareArgs {
    /// The world to build for: a scenario file [default: host-sim/scenarios/seed-mat.toml]
    #[arg(long, value_name = "FILE")]
    pub world: Option<PathBuf>,
    /// Type-check only (`cargo check`): no image, no size table.
    #[arg(long)]
    pub check_only: bool,
    /// Build without the default `vl53l5cx` depth sensor (and without its C toolchain).
    #[arg(long)]
    pub no_default_features: bool,
    /// Firmware features to turn on (comma-separated), passed to cargo as given.
    #[arg(long, short = 'F', value_name = "LIST")]
    pub features: Vec<String>,
}

impl FirmwareArgs {
    /// The world file, absolute: `--world` from the current directory, or the seed mat.
    pub fn world_file(&self) -> PathBuf {
        match &self.world {
            Some(p) if p.is_absolute() => p.clone(),
            Some(p) => std::env::current_dir().map_or_else(|_| p.clone(), |d| d.join(p)),
            None => workspace_root().join(DEFAULT_WORLD),
        }
    }

    /// The world checked as the firmware's build checks it, with its grid's size.
    fn robot_world(&self) -> Result<world::RobotWorld, String> {
        let path = self.world_file();
        let bad = |e: String| format!("world {}: {e}", path.display());
        let scenario = world::Scenario::load(&path).map_err(|e| bad(e.to_string()))?;
        world::RobotWorld::of(&scenario).map_err(|e| bad(e.to_string()))
    }

    /// The feature flags, for cargo as given.
    fn cargo_args(&self) -> Vec<String> {
        let mut args = Vec::new();
        if self.no_default_features {
            args.push("--no-default-features".to_string());
        }
        for list in &self.features {
            args.extend(["--features".to_string(), list.clone()]);
        }
        args
    }

    /// Whether the build has the `vl53l5cx` feature (default in `firmware/Cargo.toml`),
    /// and so needs the C toolchain.
    fn depth_sensor(&self) -> bool {
        let named = self
            .features
            .iter()
            .flat_map(|list| list.split([',', ' ']))
            .map(|f| f.rsplit('/').next().unwrap_or(f));
        !self.no_default_features || named.into_iter().any(|f| f == DEPTH_FEATURE)
    }
}

/// A firmware cargo command, ready to run from `firmware/` with the chosen toolchain, the
/// packages it needs installed and flip-link as the linker.
struct FirmwareCargo {
    toolchain: Toolchain,
    cmd: Command,
    target_dir: PathBuf,
}

impl FirmwareCargo {
    fn new(subcommand: &str, args: &FirmwareArgs) -> Result<FirmwareCargo, String> {
        let root = workspace_root();
        let target_dir = std::env::var_os("BUGBOT_FIRMWARE_TARGET_DIR")
            .map(PathBuf::from)
            .unwrap_or_else(|| root.join("firmware").join("target"));

        let toolchain = Toolchain::choose()?;
        let depth = args.depth_sensor();
        toolchain::install_packages(&root, toolchain == Toolchain::Debian, depth)?;
        toolchain.check_linker()?;
        let flip_link = toolchain::install_flip_link(&root)?;
        eprintln!(
            "firmware: {subcommand} with the {toolchain} toolchain, {}, linker {}",
            if depth {
                "with the VL53L5CX driver"
            } else {
                "without the VL53L5CX driver"
            },
            flip_link.display()
        );
        let mut cmd = toolchain.cargo(subcommand, &flip_link);
        cmd.arg("--config")
            .arg(toolchain::source_path_remaps(&root));
        cmd.args(args.cargo_args());
        if depth {
            for (var, value) in C_TOOLCHAIN_ENV {
                if std::env::var_os(var).is_none() {
                    cmd.env(var, value);
                }
            }
        }
        cmd.env(WORLD_VAR, args.world_file());
        cmd.arg("--target-dir").arg(&target_dir);
        Ok(FirmwareCargo {
            toolchain,
            cmd,
            target_dir,
        })
    }

    fn run(mut self) -> Result<(), String> {
        run_in(&workspace_root().join("firmware"), &mut self.cmd)
    }
}

/// `cargo xtask firmware`: builds the firmware, writes its images and checks its budget.
pub fn run(args: &FirmwareArgs) -> Result<(), String> {
    let check_only = args.check_only;
    let robot = args.robot_world()?;
    let build = FirmwareCargo::new(if check_only { "check" } else { "build" }, args)?;
    let (toolchain, target_dir) = (build.toolchain, build.target_dir.clone());
    build.run()?;
    if check_only {
        return Ok(());
    }

    let elf_path = elf_path_in(&target_dir);
    let elf_bytes =
        fs::read(&elf_path).map_err(|e| format!("cannot read {}: {e}", elf_path.display()))?;
    let elf = Elf::parse(&elf_bytes)?;

    let image = FlashImage::from_segments(&elf.segments)?;
    let uf2_path = elf_path.with_extension("uf2");
    let bin_path = elf_path.with_extension("bin");
    image::write(&uf2_path, &image.to_uf2())?;
    image::write(&bin_path, &image.bytes)?;

    let usage = Usage::from_sections(&elf.sections, elf.sensor_image);
    println!();
    println!(
        "world {} ({}): grid {} x {} cells of {} mm, {} bytes of map",
        robot.name,
        args.world_file().display(),
        robot.columns,
        robot.rows,
        robot.config.geometry.cell_mm,
        robot.map_bytes()
    );
    println!("firmware images ({toolchain} toolchain):");
    println!("  ELF  {}", elf_path.display());
    println!(
        "  UF2  {}  ({} blocks, family 0x{UF2_FAMILY_RP2040:08X})",
        uf2_path.display(),
        image.uf2_blocks()
    );
    println!(
        "  BIN  {}  ({} bytes from 0x{FLASH_BASE:08X})",
        bin_path.display(),
        image.bytes.len()
    );
    println!();
    print!("{usage}");
    usage.check()
}

/// Every shipped scenario (`world::shipped::SHIPPED`, which a test holds to the
/// directory), in the order listed there.
pub fn shipped_worlds() -> Vec<PathBuf> {
    let dir = world::shipped::directory();
    world::shipped::SHIPPED
        .iter()
        .map(|name| dir.join(name))
        .collect()
}

/// `cargo xtask test`'s check that the firmware builds for every shipped world within its
/// flash and RAM budget (the grid, and so the RAM, is the world's): a test a world.
/// Returns (passed, failed); leaves the firmware built for the last world.
pub fn worlds_run() -> Result<(u64, u64), String> {
    let (mut passed, mut failed) = (0, 0);
    for world in shipped_worlds() {
        let args = FirmwareArgs {
            world: Some(world.clone()),
            ..FirmwareArgs::default()
        };
        match run(&args) {
            Ok(()) => passed += 1,
            Err(e) => {
                eprintln!("FAILED firmware for {}: {e}", world.display());
                failed += 1;
            }
        }
    }
    println!("firmware for every shipped world: {passed} passed, {failed} failed");
    Ok((passed, failed))
}

/// `cargo clippy --release -- -D warnings` on the firmware for its target, with whichever
/// toolchain builds it (`cargo xtask lint`).
pub fn clippy() -> Result<(), String> {
    let mut lint = FirmwareCargo::new("clippy", &FirmwareArgs::default())?;
    lint.cmd.args(["--", "-D", "warnings"]);
    lint.run()
}

/// The release ELF under a firmware target directory.
fn elf_path_in(target_dir: &std::path::Path) -> PathBuf {
    target_dir.join(TARGET).join("release").join(BIN_NAME)
}

/// The release ELF `cargo xtask firmware` builds (the emulator runs it).
pub fn elf_path() -> PathBuf {
    let target_dir = std::env::var_os("BUGBOT_FIRMWARE_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| workspace_root().join("firmware").join("target"));
    elf_path_in(&target_dir)
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(clap::Parser)]
    struct Cli {
        #[command(flatten)]
        args: FirmwareArgs,
    }

    fn parse(a: &[&str]) -> Result<FirmwareArgs, clap::Error> {
        Cli::try_parse_from(std::iter::once("firmware").chain(a.iter().copied())).map(|c| c.args)
    }

    #[test]
    fn options_pass_feature_flags_through() {
        let default = parse(&[]).unwrap();
        assert!(default.depth_sensor());
        assert!(default.cargo_args().is_empty());

        let without = parse(&["--no-default-features"]).unwrap();
        assert!(!without.depth_sensor());
        assert_eq!(without.cargo_args(), ["--no-default-features"]);

        let back = parse(&[
            "--check-only",
            "--no-default-features",
            "--features",
            "bugbot-firmware/vl53l5cx",
        ])
        .unwrap();
        assert!(back.check_only && back.depth_sensor());
        assert_eq!(
            back.cargo_args(),
            [
                "--no-default-features",
                "--features",
                "bugbot-firmware/vl53l5cx"
            ]
        );
        let eq = parse(&["--no-default-features", "--features=a,vl53l5cx"]).unwrap();
        assert!(eq.depth_sensor());

        assert!(parse(&["--features"]).is_err());
        assert!(parse(&["--release"]).is_err());
    }
}
