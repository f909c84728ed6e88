//! The firmware's flash and static RAM budget: a size table from the ELF's sections, and
//! the check `cargo xtask firmware` fails on.
//!
//! The flash budget leaves out the depth sensor's own firmware image (see the parent
//! module's docs): it is printed as its own row and subtracted before the check.

use std::fmt;

use super::image::{Section, Symbol, FLASH_BASE, FLASH_SIZE, RAM_BASE, RAM_SIZE};

/// Budget: the firmware must stay well inside the chip's 2 MB so the map and logs have
/// room; 192 KB holds the filter and the scan matcher with room for what comes next.
const FLASH_BUDGET: u64 = 192 * 1024;
/// Static RAM, the world's grid included (issue 12: a 6 m room at 5 cm, and more, must
/// fit); the stack has the rest of the chip's 264 KB.
const RAM_BUDGET: u64 = 96 * 1024;
/// What the chip's RAM leaves core 0's stack beside the statics of a world at the RAM
/// budget: the least any world's firmware gives it.
pub const STACK_ROOM: u64 = RAM_SIZE as u64 - RAM_BUDGET;

/// Flash and static RAM use, from the section headers.
pub struct Usage {
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
    pub fn from_sections(sections: &[Section], sensor_image: Option<Symbol>) -> Usage {
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

    pub fn check(&self) -> Result<(), String> {
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
        let big = Usage::from_sections(&[s(".bss", RAM_BASE, 97 * 1024, true)], None);
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

    /// The build with the sensor's driver, in the proportions of the real one with the
    /// scan matcher: 220 KB of flash of which 84 KB is the sensor's image.
    fn with_sensor_image() -> Vec<Section> {
        vec![
            section(".text", FLASH_BASE + 0x100, 130 * 1024, false),
            section(".rodata", FLASH_BASE + 0x4_0000, 90 * 1024, false),
            section(".data", RAM_BASE, 512, false),
            section(".bss", RAM_BASE + 512, 20 * 1024, true),
        ]
    }

    #[test]
    fn usage_leaves_the_sensor_image_out_of_the_flash_budget() {
        let image = Symbol {
            addr: FLASH_BASE + 0x4_0000 + 4096,
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
        sections[0].size = 200 * 1024;
        let image = Symbol {
            addr: FLASH_BASE + 0x4_0000,
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
}
