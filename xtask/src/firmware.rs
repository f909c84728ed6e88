//! `cargo xtask firmware [--check-only] [--no-default-features] [--features LIST]`: builds
//! the RP2040 firmware, writes its UF2 and flat binary images next to the ELF, and checks
//! its flash and RAM budget.
//!
//! Two toolchains can build it:
//!
//! - **rustup**, when the active toolchain has `thumbv6m-none-eabi` (or `rustup target add`
//!   gets it): plain `cargo build --release` in `firmware/`, as on any developer's machine.
//! - **Debian** otherwise (machines without access to rustup's servers):
//!   `scripts/install-cross-toolchain.sh --rust` installs Debian's Rust 1.96 with its library
//!   source, and core is built from source with `-Zbuild-std=core`.
//!
//! `BUGBOT_FIRMWARE_TOOLCHAIN=rustup|debian` forces one path. The firmware always builds
//! into `firmware/target` (or `BUGBOT_FIRMWARE_TARGET_DIR`), never into the host's target
//! directory. `--check-only` type-checks the firmware (`cargo check`) and writes nothing.
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
//! The flash budget (128 KB) is for *our* firmware. ST's driver carries the sensor's own
//! firmware, an 86,016-byte blob (`VL53L5CX_FIRMWARE`, in `.rodata`) that the driver uploads
//! into the sensor at every boot. It is data we neither write nor can shrink, its size is
//! fixed by ST, and counting it would leave the budget a third of its size for everything
//! else. So the check reads that symbol's size from the ELF symbol table, prints it as its
//! own row, and holds flash *minus* the image to the budget; the images written (UF2, BIN)
//! and the `total` row still contain it, and 2 MB of flash holds it easily. Static RAM is
//! unaffected: the image is never copied to RAM.

use std::fmt;
use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::thread;
use std::time::{Duration, Instant};

use object::elf;
use object::read::elf::{ElfFile32, FileHeader, ProgramHeader, SectionHeader, Sym};
use object::Endianness;

use crate::{run_in, workspace_root};

/// The firmware's target triple.
const TARGET: &str = "thumbv6m-none-eabi";
/// The firmware's binary name (`[[bin]]` in `firmware/Cargo.toml`).
const BIN_NAME: &str = "bugbot-firmware";
/// Debian's compiler and cargo, installed by `scripts/install-cross-toolchain.sh`.
const DEBIAN_RUSTC: &str = "/usr/bin/rustc";
const DEBIAN_CARGO: &str = "/usr/bin/cargo";
/// Linkers Debian provides, best first: `rust-lld` (rust-web-llvm, a link to lld-22), then
/// lld-22's own `ld.lld`. Set explicitly so the build does not depend on `PATH`.
const DEBIAN_LINKERS: [&str; 2] = ["/usr/bin/rust-lld", "/usr/lib/llvm-22/bin/ld.lld"];
/// How long `rustup target add` may try before we fall back to Debian's toolchain.
const RUSTUP_ADD_TIMEOUT: Duration = Duration::from_secs(120);

/// The firmware feature that needs the C toolchain, on by default.
const DEPTH_FEATURE: &str = "vl53l5cx";
/// Environment for building ST's C driver for [`TARGET`] with Debian's packages: `cc`
/// compiles with arm-none-eabi-gcc, and bindgen's libclang parses the driver's headers,
/// which include newlib's `<string.h>` and friends (the driver's build script asks gcc for
/// a sysroot, and Debian's gcc has none, so without this path bindgen cannot find them).
/// `firmware/.cargo/config.toml` sets the same BINDGEN_EXTRA_CLANG_ARGS for hand builds.
const C_TOOLCHAIN_ENV: [(&str, &str); 3] = [
    ("CC_thumbv6m_none_eabi", "arm-none-eabi-gcc"),
    ("AR_thumbv6m_none_eabi", "arm-none-eabi-ar"),
    (
        "BINDGEN_EXTRA_CLANG_ARGS",
        "-I/usr/lib/arm-none-eabi/include",
    ),
];
/// The symbol of the VL53L5CX's own firmware image, left out of the flash budget (see the
/// module docs).
const SENSOR_IMAGE_SYMBOL: &str = "VL53L5CX_FIRMWARE";

/// RP2040 flash as the CPU sees it (XIP): the UF2 and flat image start here.
const FLASH_BASE: u32 = 0x1000_0000;
/// Flash size on the board (2 MB).
const FLASH_SIZE: u32 = 2 * 1024 * 1024;
/// RP2040 SRAM.
const RAM_BASE: u32 = 0x2000_0000;
const RAM_SIZE: u32 = 264 * 1024;
/// Budget: the firmware must stay well inside the chip so the map and logs have room.
const FLASH_BUDGET: u64 = 128 * 1024;
const RAM_BUDGET: u64 = 48 * 1024;

/// UF2: family of the RP2040 boot ROM.
const UF2_FAMILY_RP2040: u32 = 0xE48B_FF56;
/// UF2 payload per block, as the RP2040 boot ROM requires.
const UF2_PAYLOAD: u32 = 256;

/// Entry point from `main.rs`.
pub fn run(args: &[String]) -> Result<(), String> {
    let Some(opts) = Options::parse(args)? else {
        println!(
            "usage: cargo xtask firmware [--check-only] [--no-default-features] [--features LIST]"
        );
        println!("  builds firmware/ for {TARGET}, writes .uf2 and .bin next to the ELF,");
        println!("  prints flash and RAM use; --check-only runs `cargo check` only;");
        println!("  --no-default-features builds without the `{DEPTH_FEATURE}` depth sensor");
        return Ok(());
    };
    let check_only = opts.check_only;

    let root = workspace_root();
    let firmware_dir = root.join("firmware");
    let target_dir = std::env::var_os("BUGBOT_FIRMWARE_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| firmware_dir.join("target"));

    let toolchain = Toolchain::choose()?;
    let depth = opts.depth_sensor();
    install_packages(&root, toolchain == Toolchain::Debian, depth)?;
    eprintln!(
        "firmware: building with the {toolchain} toolchain, {}",
        if depth {
            "with the VL53L5CX driver"
        } else {
            "without the VL53L5CX driver"
        }
    );
    let mut cmd = toolchain.cargo(if check_only { "check" } else { "build" });
    cmd.args(&opts.cargo_args);
    if depth {
        for (var, value) in C_TOOLCHAIN_ENV {
            if std::env::var_os(var).is_none() {
                cmd.env(var, value);
            }
        }
    }
    cmd.arg("--target-dir").arg(&target_dir);
    run_in(&firmware_dir, &mut cmd)?;
    if check_only {
        return Ok(());
    }

    let elf_path = target_dir.join(TARGET).join("release").join(BIN_NAME);
    let elf_bytes =
        fs::read(&elf_path).map_err(|e| format!("cannot read {}: {e}", elf_path.display()))?;
    let elf = Elf::parse(&elf_bytes)?;

    let image = FlashImage::from_segments(&elf.segments)?;
    let uf2_path = elf_path.with_extension("uf2");
    let bin_path = elf_path.with_extension("bin");
    write(&uf2_path, &image.to_uf2())?;
    write(&bin_path, &image.bytes)?;

    let usage = Usage::from_sections(&elf.sections, elf.sensor_image);
    println!();
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

/// What `cargo xtask firmware` was asked for.
#[derive(Debug, Default, PartialEq, Eq)]
struct Options {
    check_only: bool,
    no_default_features: bool,
    /// Features named with `--features`, without any `crate/` prefix.
    features: Vec<String>,
    /// The feature flags, for cargo as given.
    cargo_args: Vec<String>,
}

impl Options {
    /// `None` for `--help`.
    fn parse(args: &[String]) -> Result<Option<Options>, String> {
        let mut opts = Options::default();
        let mut args = args.iter();
        while let Some(arg) = args.next() {
            let list = match arg.as_str() {
                "--check-only" => {
                    opts.check_only = true;
                    continue;
                }
                "--no-default-features" => {
                    opts.no_default_features = true;
                    opts.cargo_args.push(arg.clone());
                    continue;
                }
                "-h" | "--help" => return Ok(None),
                "--features" | "-F" => args
                    .next()
                    .ok_or_else(|| format!("firmware: {arg} needs a feature list"))?,
                other => match other.strip_prefix("--features=") {
                    Some(list) => list,
                    None => return Err(format!("firmware: unknown argument {other:?}")),
                },
            };
            opts.features.extend(
                list.split([',', ' '])
                    .filter(|f| !f.is_empty())
                    .map(|f| f.rsplit('/').next().unwrap_or(f).to_string()),
            );
            opts.cargo_args
                .extend(["--features".to_string(), list.to_string()]);
        }
        Ok(Some(opts))
    }

    /// Whether the build has the `vl53l5cx` feature (default in `firmware/Cargo.toml`),
    /// and so needs the C toolchain.
    fn depth_sensor(&self) -> bool {
        !self.no_default_features || self.features.iter().any(|f| f == DEPTH_FEATURE)
    }
}

/// Runs `scripts/install-cross-toolchain.sh` for the packages this build needs: Debian's
/// Rust toolchain (`--rust`) and the depth sensor's C toolchain (`--c`). Quiet when they
/// are installed.
fn install_packages(root: &Path, rust: bool, c: bool) -> Result<(), String> {
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
enum Toolchain {
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
    fn choose() -> Result<Toolchain, String> {
        let forced = std::env::var("BUGBOT_FIRMWARE_TOOLCHAIN").unwrap_or_default();
        let toolchain = match forced.as_str() {
            "rustup" => Toolchain::Rustup,
            "debian" => Toolchain::Debian,
            "" if rustup_has_target() || rustup_add_target() => Toolchain::Rustup,
            "" => Toolchain::Debian,
            other => {
                return Err(format!(
                    "BUGBOT_FIRMWARE_TOOLCHAIN={other:?}: expected \"rustup\" or \"debian\""
                ))
            }
        };
        Ok(toolchain)
    }

    /// `cargo <subcommand> --release` for the firmware, with this toolchain's environment.
    fn cargo(self, subcommand: &str) -> Command {
        match self {
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
                    "LD_LIBRARY_PATH",
                ] {
                    cmd.env_remove(var);
                }
                cmd.env("RUSTC", DEBIAN_RUSTC);
                // -Zbuild-std is unstable; Debian ships a stable compiler.
                cmd.env("RUSTC_BOOTSTRAP", "1");
                if let Some(linker) = DEBIAN_LINKERS.iter().find(|p| Path::new(p).exists()) {
                    cmd.env("CARGO_TARGET_THUMBV6M_NONE_EABI_LINKER", linker);
                }
                cmd
            }
        }
    }
}

/// Whether the active rustup toolchain already has the target's standard library.
fn rustup_has_target() -> bool {
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

fn write(path: &Path, bytes: &[u8]) -> Result<(), String> {
    fs::write(path, bytes).map_err(|e| format!("cannot write {}: {e}", path.display()))
}

/// A loadable piece of the ELF, placed where it lives in flash.
#[derive(Clone, Debug, PartialEq, Eq)]
struct Segment {
    /// Load (physical) address: `.data` runs from RAM but is stored in flash.
    paddr: u32,
    data: Vec<u8>,
}

/// An allocated section, for the size table.
#[derive(Clone, Debug, PartialEq, Eq)]
struct Section {
    name: String,
    /// Run (virtual) address.
    addr: u32,
    size: u32,
    /// `NOBITS` (`.bss`, `.uninit`): takes RAM, no flash.
    nobits: bool,
}

/// A symbol's place in memory.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Symbol {
    addr: u32,
    size: u32,
}

/// What the size check and the image writers need from the ELF.
struct Elf {
    segments: Vec<Segment>,
    sections: Vec<Section>,
    /// [`SENSOR_IMAGE_SYMBOL`], when the build has the sensor's driver.
    sensor_image: Option<Symbol>,
}

impl Elf {
    fn parse(bytes: &[u8]) -> Result<Elf, String> {
        let file = ElfFile32::<Endianness>::parse(bytes).map_err(|e| format!("not an ELF: {e}"))?;
        let endian = file.endian();
        let header = file.elf_header();

        let mut segments = Vec::new();
        for ph in header
            .program_headers(endian, bytes)
            .map_err(|e| e.to_string())?
        {
            if ph.p_type(endian) != elf::PT_LOAD || ph.p_filesz(endian) == 0 {
                continue;
            }
            let data = ph
                .data(endian, bytes)
                .map_err(|()| "a program header points outside the file".to_string())?;
            segments.push(Segment {
                paddr: ph.p_paddr(endian),
                data: data.to_vec(),
            });
        }

        let table = header.sections(endian, bytes).map_err(|e| e.to_string())?;
        let mut sections = Vec::new();
        for sh in table.iter() {
            let flags = sh.sh_flags(endian);
            if flags & elf::SHF_ALLOC == 0 || sh.sh_size(endian) == 0 {
                continue;
            }
            let name = table
                .section_name(endian, sh)
                .map(|n| String::from_utf8_lossy(n).into_owned())
                .unwrap_or_else(|_| "?".into());
            sections.push(Section {
                name,
                addr: sh.sh_addr(endian),
                size: sh.sh_size(endian),
                nobits: sh.sh_type(endian) == elf::SHT_NOBITS,
            });
        }
        let symbols = table
            .symbols(endian, bytes, elf::SHT_SYMTAB)
            .map_err(|e| e.to_string())?;
        let sensor_image = symbols
            .iter()
            .find(|sym| {
                sym.st_size(endian) > 0
                    && sym.name(endian, symbols.strings()) == Ok(SENSOR_IMAGE_SYMBOL.as_bytes())
            })
            .map(|sym| Symbol {
                addr: sym.st_value(endian),
                size: sym.st_size(endian),
            });
        Ok(Elf {
            segments,
            sections,
            sensor_image,
        })
    }
}

/// The flash contents from [`FLASH_BASE`] to the end of the last segment; gaps are 0xFF,
/// the value of erased flash.
#[derive(Debug, PartialEq, Eq)]
struct FlashImage {
    bytes: Vec<u8>,
    /// Which bytes some segment wrote: UF2 skips pages no segment touches.
    written: Vec<bool>,
}

impl FlashImage {
    fn from_segments(segments: &[Segment]) -> Result<FlashImage, String> {
        let mut end = 0u32;
        for s in segments {
            let len = u32::try_from(s.data.len()).map_err(|_| "segment too large".to_string())?;
            let seg_end = s
                .paddr
                .checked_add(len)
                .ok_or("segment wraps the address space")?;
            if s.paddr < FLASH_BASE || seg_end > FLASH_BASE + FLASH_SIZE {
                return Err(format!(
                    "segment 0x{:08X}..0x{seg_end:08X} is outside flash 0x{FLASH_BASE:08X}..0x{:08X}",
                    s.paddr,
                    FLASH_BASE + FLASH_SIZE
                ));
            }
            end = end.max(seg_end - FLASH_BASE);
        }
        if end == 0 {
            return Err("the ELF has nothing to put in flash".into());
        }
        let mut bytes = vec![0xFF; end as usize];
        let mut written = vec![false; end as usize];
        for s in segments {
            let start = (s.paddr - FLASH_BASE) as usize;
            let range = start..start + s.data.len();
            if written[range.clone()].iter().any(|&w| w) {
                return Err(format!("segments overlap at 0x{:08X}", s.paddr));
            }
            bytes[range.clone()].copy_from_slice(&s.data);
            written[range].fill(true);
        }
        Ok(FlashImage { bytes, written })
    }

    /// Offsets of the 256-byte pages that hold data.
    fn pages(&self) -> Vec<usize> {
        self.written
            .chunks(UF2_PAYLOAD as usize)
            .enumerate()
            .filter(|(_, page)| page.iter().any(|&w| w))
            .map(|(i, _)| i * UF2_PAYLOAD as usize)
            .collect()
    }

    fn uf2_blocks(&self) -> usize {
        self.pages().len()
    }

    /// The image as UF2: one 512-byte block per 256-byte page, family id set.
    fn to_uf2(&self) -> Vec<u8> {
        const MAGIC_START0: u32 = 0x0A32_4655;
        const MAGIC_START1: u32 = 0x9E5D_5157;
        const MAGIC_END: u32 = 0x0AB1_6F30;
        const FLAG_FAMILY_ID_PRESENT: u32 = 0x0000_2000;
        const DATA_FIELD: usize = 476;

        let pages = self.pages();
        let total = pages.len() as u32;
        let mut out = Vec::with_capacity(pages.len() * 512);
        for (number, &offset) in pages.iter().enumerate() {
            let end = (offset + UF2_PAYLOAD as usize).min(self.bytes.len());
            let mut payload = [0xFFu8; DATA_FIELD];
            payload[..end - offset].copy_from_slice(&self.bytes[offset..end]);
            for word in [
                MAGIC_START0,
                MAGIC_START1,
                FLAG_FAMILY_ID_PRESENT,
                FLASH_BASE + offset as u32,
                UF2_PAYLOAD,
                number as u32,
                total,
                UF2_FAMILY_RP2040,
            ] {
                out.extend_from_slice(&word.to_le_bytes());
            }
            // Bytes past the payload are unused by the boot ROM; zero them as the spec asks.
            payload[UF2_PAYLOAD as usize..].fill(0);
            out.extend_from_slice(&payload);
            out.extend_from_slice(&MAGIC_END.to_le_bytes());
        }
        out
    }
}

/// Flash and static RAM use, from the section headers.
struct Usage {
    /// (section, flash bytes, RAM bytes), in ELF order.
    rows: Vec<(String, u64, u64)>,
    /// Everything in flash, the sensor's image included.
    flash: u64,
    ram: u64,
    /// Flash bytes of the sensor's firmware image (0 without the driver), left out of the
    /// budget (see the module docs).
    excluded: u64,
}

/// Width of the table's first column: fits "ToF sensor image (excluded)".
const NAME_WIDTH: usize = 28;

impl Usage {
    /// Flash: every allocated section stored in flash, plus the load image of initialised
    /// RAM (`.data`). RAM: every allocated section that runs from RAM (`.data`, `.bss`,
    /// `.uninit`); the stack is not a section, so it is not counted. `sensor_image` is
    /// excluded from the budget when it lies inside a section stored in flash (the only
    /// place the driver puts it); anywhere else it is counted like everything else.
    fn from_sections(sections: &[Section], sensor_image: Option<Symbol>) -> Usage {
        let in_flash = |a: u32| (FLASH_BASE..FLASH_BASE + FLASH_SIZE).contains(&a);
        let in_ram = |a: u32| (RAM_BASE..RAM_BASE + RAM_SIZE).contains(&a);
        let mut rows = Vec::new();
        let mut excluded = 0;
        for s in sections {
            let size = s.size as u64;
            let (flash, ram) = if in_flash(s.addr) {
                (size, 0)
            } else if in_ram(s.addr) {
                (if s.nobits { 0 } else { size }, size)
            } else {
                continue;
            };
            if let Some(image) = sensor_image {
                let (start, end) = (image.addr as u64, image.addr as u64 + image.size as u64);
                let section_end = s.addr as u64 + size;
                if in_flash(s.addr) && !s.nobits && s.addr as u64 <= start && end <= section_end {
                    excluded = image.size as u64;
                }
            }
            rows.push((s.name.clone(), flash, ram));
        }
        let flash = rows.iter().map(|r| r.1).sum();
        let ram = rows.iter().map(|r| r.2).sum();
        Usage {
            rows,
            flash,
            ram,
            excluded,
        }
    }

    /// The flash held to the budget: everything but the sensor's image.
    fn counted_flash(&self) -> u64 {
        self.flash - self.excluded
    }

    fn check(&self) -> Result<(), String> {
        let mut over = Vec::new();
        if self.counted_flash() > FLASH_BUDGET {
            over.push(format!(
                "flash {} bytes (not counting the {}-byte ToF sensor image) exceeds the {} KB budget",
                self.counted_flash(),
                self.excluded,
                FLASH_BUDGET / 1024
            ));
        }
        if self.ram > RAM_BUDGET {
            over.push(format!(
                "static RAM {} bytes exceeds the {} KB budget",
                self.ram,
                RAM_BUDGET / 1024
            ));
        }
        if over.is_empty() {
            Ok(())
        } else {
            Err(format!("firmware over budget: {}", over.join("; ")))
        }
    }
}

impl fmt::Display for Usage {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        const W: usize = NAME_WIDTH;
        writeln!(f, "  {:<W$} {:>10} {:>10}", "section", "flash", "RAM")?;
        for (name, flash, ram) in &self.rows {
            writeln!(f, "  {name:<W$} {flash:>10} {ram:>10}")?;
        }
        writeln!(f, "  {:<W$} {:>10} {:>10}", "total", self.flash, self.ram)?;
        if self.excluded > 0 {
            let minus = format!("-{}", self.excluded);
            writeln!(
                f,
                "  {:<W$} {minus:>10} {:>10}",
                "ToF sensor image (excluded)", "-"
            )?;
            writeln!(
                f,
                "  {:<W$} {:>10} {:>10}",
                "counted",
                self.counted_flash(),
                self.ram
            )?;
        }
        writeln!(
            f,
            "  {:<W$} {:>10} {:>10}",
            "budget", FLASH_BUDGET, RAM_BUDGET
        )?;
        writeln!(
            f,
            "  {:<W$} {:>9.1}% {:>9.1}%",
            "used",
            100.0 * self.counted_flash() as f64 / FLASH_BUDGET as f64,
            100.0 * self.ram as f64 / RAM_BUDGET as f64
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn word(block: &[u8], index: usize) -> u32 {
        u32::from_le_bytes(block[index * 4..index * 4 + 4].try_into().unwrap())
    }

    #[test]
    fn image_places_segments_by_load_address_and_fills_gaps() {
        let image = FlashImage::from_segments(&[
            Segment {
                paddr: FLASH_BASE + 4,
                data: vec![1, 2],
            },
            Segment {
                paddr: FLASH_BASE,
                data: vec![9],
            },
        ])
        .unwrap();
        assert_eq!(image.bytes, vec![9, 0xFF, 0xFF, 0xFF, 1, 2]);
    }

    #[test]
    fn image_rejects_ram_and_overlaps() {
        let ram = Segment {
            paddr: RAM_BASE,
            data: vec![0],
        };
        assert!(FlashImage::from_segments(&[ram]).is_err());
        let a = Segment {
            paddr: FLASH_BASE,
            data: vec![0; 8],
        };
        let b = Segment {
            paddr: FLASH_BASE + 4,
            data: vec![0; 8],
        };
        assert!(FlashImage::from_segments(&[a, b]).is_err());
    }

    #[test]
    fn uf2_blocks_cover_only_written_pages() {
        let image = FlashImage::from_segments(&[
            Segment {
                paddr: FLASH_BASE,
                data: vec![0xAB; 300],
            },
            Segment {
                paddr: FLASH_BASE + 0x1000,
                data: vec![0xCD; 4],
            },
        ])
        .unwrap();
        let uf2 = image.to_uf2();
        assert_eq!(uf2.len(), 3 * 512);
        let blocks: Vec<&[u8]> = uf2.chunks(512).collect();
        let addresses: Vec<u32> = blocks.iter().map(|b| word(b, 3)).collect();
        assert_eq!(
            addresses,
            [FLASH_BASE, FLASH_BASE + 0x100, FLASH_BASE + 0x1000]
        );
        for (n, b) in blocks.iter().enumerate() {
            assert_eq!(word(b, 0), 0x0A32_4655);
            assert_eq!(word(b, 1), 0x9E5D_5157);
            assert_eq!(word(b, 2), 0x2000);
            assert_eq!(word(b, 4), 256);
            assert_eq!(word(b, 5), n as u32);
            assert_eq!(word(b, 6), 3);
            assert_eq!(word(b, 7), UF2_FAMILY_RP2040);
            assert_eq!(word(b, 127), 0x0AB1_6F30);
        }
        assert_eq!(blocks[1][32..32 + 44], [0xAB; 44]);
        assert_eq!(blocks[1][32 + 44], 0xFF);
        assert_eq!(blocks[2][32..36], [0xCD; 4]);
    }

    #[test]
    fn usage_counts_data_in_both_and_bss_in_ram_only() {
        let s = |name: &str, addr, size, nobits| Section {
            name: name.into(),
            addr,
            size,
            nobits,
        };
        let usage = Usage::from_sections(
            &[
                s(".text", FLASH_BASE + 0x100, 1000, false),
                s(".data", RAM_BASE, 100, false),
                s(".bss", RAM_BASE + 100, 50, true),
                s(".defmt", 0, 10, false),
            ],
            None,
        );
        assert_eq!((usage.flash, usage.ram, usage.excluded), (1100, 150, 0));
        assert!(usage.check().is_ok());
        let big = Usage::from_sections(&[s(".bss", RAM_BASE, 64 * 1024, true)], None);
        assert!(big.check().unwrap_err().contains("static RAM"));
    }

    fn section(name: &str, addr: u32, size: u32, nobits: bool) -> Section {
        Section {
            name: name.into(),
            addr,
            size,
            nobits,
        }
    }

    /// The build with the sensor's driver, in the proportions of the real one: 150 KB of
    /// flash of which 84 KB is the sensor's image.
    fn with_sensor_image() -> Vec<Section> {
        vec![
            section(".text", FLASH_BASE + 0x100, 60 * 1024, false),
            section(".rodata", FLASH_BASE + 0x2_0000, 90 * 1024, false),
            section(".data", RAM_BASE, 512, false),
            section(".bss", RAM_BASE + 512, 20 * 1024, true),
        ]
    }

    #[test]
    fn usage_leaves_the_sensor_image_out_of_the_flash_budget() {
        let image = Symbol {
            addr: FLASH_BASE + 0x2_0000 + 4096,
            size: 86_016,
        };
        let sections = with_sensor_image();
        let without = Usage::from_sections(&sections, None);
        assert!(without.flash > FLASH_BUDGET);
        assert!(without.check().unwrap_err().contains("flash"));

        let usage = Usage::from_sections(&sections, Some(image));
        assert_eq!(
            usage.flash, without.flash,
            "the total still holds the image"
        );
        assert_eq!(usage.excluded, 86_016);
        assert_eq!(usage.counted_flash(), usage.flash - 86_016);
        assert_eq!(usage.ram, without.ram, "RAM is unaffected");
        assert!(usage.check().is_ok());

        let table = usage.to_string();
        let row = table
            .lines()
            .find(|l| l.contains("ToF sensor image (excluded)"))
            .expect("a row for the image");
        assert!(row.contains("-86016"), "{row}");
        assert!(
            table.contains(&format!(" {} ", usage.counted_flash())),
            "{table}"
        );
        assert!(!without.to_string().contains("ToF"));
    }

    #[test]
    fn usage_still_fails_when_the_rest_exceeds_the_budget() {
        let mut sections = with_sensor_image();
        sections[0].size = 130 * 1024;
        let image = Symbol {
            addr: FLASH_BASE + 0x2_0000,
            size: 86_016,
        };
        let usage = Usage::from_sections(&sections, Some(image));
        let err = usage.check().unwrap_err();
        assert!(
            err.contains("not counting the 86016-byte ToF sensor image"),
            "{err}"
        );
    }

    #[test]
    fn usage_excludes_only_an_image_stored_in_flash() {
        let sections = with_sensor_image();
        // Outside every section, or in RAM: counted as usual.
        for addr in [FLASH_BASE + 0x10_0000, RAM_BASE + 512] {
            let usage = Usage::from_sections(&sections, Some(Symbol { addr, size: 8 }));
            assert_eq!(usage.excluded, 0, "0x{addr:08X}");
        }
    }

    #[test]
    fn options_pass_feature_flags_through() {
        let args = |a: &[&str]| a.iter().map(|s| s.to_string()).collect::<Vec<_>>();
        let default = Options::parse(&[]).unwrap().unwrap();
        assert!(default.depth_sensor());
        assert!(default.cargo_args.is_empty());

        let without = Options::parse(&args(&["--no-default-features"]))
            .unwrap()
            .unwrap();
        assert!(!without.depth_sensor());
        assert_eq!(without.cargo_args, ["--no-default-features"]);

        let back = Options::parse(&args(&[
            "--check-only",
            "--no-default-features",
            "--features",
            "bugbot-firmware/vl53l5cx",
        ]))
        .unwrap()
        .unwrap();
        assert!(back.check_only && back.depth_sensor());
        assert_eq!(
            back.cargo_args,
            [
                "--no-default-features",
                "--features",
                "bugbot-firmware/vl53l5cx"
            ]
        );
        let eq = Options::parse(&args(&["--no-default-features", "--features=a,vl53l5cx"]))
            .unwrap()
            .unwrap();
        assert!(eq.depth_sensor());

        assert!(Options::parse(&args(&["--help"])).unwrap().is_none());
        assert!(Options::parse(&args(&["--features"])).is_err());
        assert!(Options::parse(&args(&["--release"])).is_err());
    }
}
