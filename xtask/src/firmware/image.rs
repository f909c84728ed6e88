//! The firmware's ELF, and the images written next to it: UF2 for the RP2040's USB boot
//! ROM, and the flat binary the emulator loads.

use std::fs;
use std::path::Path;

use object::elf;
use object::read::elf::{ElfFile32, FileHeader, ProgramHeader, SectionHeader, Sym};
use object::Endianness;

/// The symbol of the VL53L5CX's own firmware image, left out of the flash budget (see the
/// module docs).
pub const SENSOR_IMAGE_SYMBOL: &str = "VL53L5CX_FIRMWARE";

/// RP2040 flash as the CPU sees it (XIP): the UF2 and flat image start here.
pub const FLASH_BASE: u32 = 0x1000_0000;
/// Flash size on the board (2 MB).
pub const FLASH_SIZE: u32 = 2 * 1024 * 1024;
/// RP2040 SRAM.
pub const RAM_BASE: u32 = 0x2000_0000;
pub const RAM_SIZE: u32 = 264 * 1024;

/// UF2: family of the RP2040 boot ROM.
pub const UF2_FAMILY_RP2040: u32 = 0xE48B_FF56;
/// UF2 payload per block, as the RP2040 boot ROM requires.
const UF2_PAYLOAD: u32 = 256;

pub fn write(path: &Path, bytes: &[u8]) -> Result<(), String> {
    fs::write(path, bytes).map_err(|e| format!("cannot write {}: {e}", path.display()))
}

/// A loadable piece of the ELF, placed where it lives in flash.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Segment {
    /// Load (physical) address: `.data` runs from RAM but is stored in flash.
    pub paddr: u32,
    pub data: Vec<u8>,
}

/// An allocated section, for the size table.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Section {
    pub name: String,
    /// Run (virtual) address.
    pub addr: u32,
    pub size: u32,
    /// `NOBITS` (`.bss`, `.uninit`): takes RAM, no flash.
    pub nobits: bool,
}

/// A symbol's place in memory.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Symbol {
    pub addr: u32,
    pub size: u32,
}

/// What the size check and the image writers need from the ELF.
pub struct Elf {
    pub segments: Vec<Segment>,
    pub sections: Vec<Section>,
    /// [`SENSOR_IMAGE_SYMBOL`], when the build has the sensor's driver.
    pub sensor_image: Option<Symbol>,
}

impl Elf {
    pub fn parse(bytes: &[u8]) -> Result<Elf, String> {
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
pub struct FlashImage {
    pub bytes: Vec<u8>,
    /// Which bytes some segment wrote: UF2 skips pages no segment touches.
    pub written: Vec<bool>,
}

impl FlashImage {
    pub fn from_segments(segments: &[Segment]) -> Result<FlashImage, String> {
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

    pub fn uf2_blocks(&self) -> usize {
        self.pages().len()
    }

    /// The image as UF2: one 512-byte block per 256-byte page, family id set.
    pub fn to_uf2(&self) -> Vec<u8> {
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
}
