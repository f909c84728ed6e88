// The firmware's ELF, read in plain JS: its symbols (for `_SEGGER_RTT`, `HardFault` and
// the step function) and its loadable segments (the flash image when no `.bin` is given).

import fs from 'node:fs';

/// Start of the RP2040's XIP flash in the address map.
export const FLASH_BASE = 0x10000000;
/// Size of the flash window the image may occupy.
const FLASH_WINDOW = 0x1000000;
const SHT_SYMTAB = 2;
const PT_LOAD = 1;

/// `{ symbols: [{ name, value, size, type }], segments: [{ paddr, data }] }` of a 32-bit
/// little-endian ELF. `type` is the symbol's ELF type: 1 object, 2 function.
export function readElf(file) {
  const b = fs.readFileSync(file);
  if (b.readUInt32BE(0) !== 0x7f454c46 || b[4] !== 1 || b[5] !== 1) {
    throw new Error(`${file}: not a 32-bit little-endian ELF`);
  }
  const shoff = b.readUInt32LE(0x20);
  const shentsize = b.readUInt16LE(0x2e);
  const shnum = b.readUInt16LE(0x30);
  const sections = [];
  for (let i = 0; i < shnum; i++) {
    const o = shoff + i * shentsize;
    sections.push({
      type: b.readUInt32LE(o + 4),
      addr: b.readUInt32LE(o + 12),
      offset: b.readUInt32LE(o + 16),
      size: b.readUInt32LE(o + 20),
      link: b.readUInt32LE(o + 24),
    });
  }
  // Loadable segments by load (physical) address.
  const segments = [];
  const phoff = b.readUInt32LE(0x1c);
  const phentsize = b.readUInt16LE(0x2a);
  const phnum = b.readUInt16LE(0x2c);
  for (let i = 0; i < phnum; i++) {
    const o = phoff + i * phentsize;
    if (b.readUInt32LE(o) !== PT_LOAD) continue;
    const offset = b.readUInt32LE(o + 4);
    const paddr = b.readUInt32LE(o + 12);
    const filesz = b.readUInt32LE(o + 16);
    if (filesz) segments.push({ paddr, data: b.subarray(offset, offset + filesz) });
  }
  const symbols = [];
  for (const s of sections) {
    if (s.type !== SHT_SYMTAB) continue;
    const strtab = sections[s.link];
    for (let o = s.offset; o + 16 <= s.offset + s.size; o += 16) {
      const nameOff = b.readUInt32LE(o);
      let end = strtab.offset + nameOff;
      while (b[end] !== 0) end++;
      symbols.push({
        name: b.toString('latin1', strtab.offset + nameOff, end),
        value: b.readUInt32LE(o + 4),
        size: b.readUInt32LE(o + 8),
        type: b[o + 12] & 0xf,
      });
    }
  }
  return { symbols, segments };
}

/// The flash contents from 0x10000000, gaps erased (0xFF), as `cargo xtask firmware`
/// writes the `.bin`.
export function flashImage(elf) {
  const inFlash = elf.segments.filter((s) => s.paddr >= FLASH_BASE && s.paddr < FLASH_BASE + FLASH_WINDOW);
  const end = Math.max(...inFlash.map((s) => s.paddr - FLASH_BASE + s.data.length));
  const image = Buffer.alloc(end, 0xff);
  for (const s of inFlash) s.data.copy(image, s.paddr - FLASH_BASE);
  return image;
}
