#!/usr/bin/env node
// ST VL53L5CX 8x8 multizone time-of-flight sensor as an I2C device model for the rp2040js
// harness, at the level of its registers and memory, so that ST's Ultra Lite Driver (ULD,
// through the `vl53l5cx-uld` crate) runs against it unchanged: `init` (software reboot,
// 84 KB firmware upload, MCU boot, NVM read, default configuration), the DCI
// command/answer protocol behind every setting, `start_ranging`, `check_data_ready`,
// `get_ranging_data` and `stop_ranging`.
//
// What the part looks like from the bus (everything here was read off the ULD's C source,
// what it writes and which answers it accepts; nothing of ST's code or data is copied):
// - Address 0x29 (7-bit). Every transfer starts with a 16-bit big-endian register index;
//   reads are that index written, then a repeated start and the data. The index
//   auto-increments.
// - Index 0x7FFF selects the page on every page. Page 0: ids (0x00 = 0xF0, 0x01 = 0x02),
//   the GO2 status bytes of the MCU (0x06, 0x07), power mode (0x09), MCU run control
//   (0x0B), MCU stop (0x14/0x15), software reset (0x4002) and start-up registers the ULD
//   only writes. Page 1: 0x21 bit 4, "firmware memory access granted". Page 2: the ranging
//   results from 0x0000 and the UI command area 0x2C00..0x2FFF. Pages 9, 10, 11: windows
//   on the MCU's RAM, where the firmware image is written (32 + 32 + 20 KB).
// - Commands go to the end of the UI area, so their last byte is 0x2FFF. The last 4 bytes
//   are [tag, code, length]: code 1 writes, code 2 reads, code 3 starts ranging; length
//   counts the command's bytes before that word. Before it: block headers, each a
//   big-endian word (idx << 16 | size << 4 | type) naming an address in the firmware's
//   configuration memory ("DCI") and a byte count (type 1..12: size elements of type
//   bytes; otherwise size bytes), followed for writes by the data, then a 0x0000000F
//   terminator word. All data is big-endian per 32-bit word (the ULD word-swaps its
//   little-endian structs both ways). A read's answer lands at 0x2C04 in the same block
//   format; the status word at 0x2C00 tells the ULD the command is done.
// - A ranging frame at page 2, 0x0000: a status word [stream count, 0x05, 0x05, 0x10]
//   (what `check_data_ready` tests), then 8 bytes holding the frame id, then the blocks of
//   the output list the ULD sent (the list's START marker first, data-less), each header +
//   data, then 12 bytes ending in the frame id again, which the ULD compares with the
//   first to detect a frame torn by an update during the read.
//
// Where the model simplifies, the comments say what the real part does. In short: no
// ranging physics (every zone of a column reports the column's beam; the other outputs are
// plausible constants), the MCU firmware is stored but not run (its effects are modelled),
// boot times are assumed, and the meaning of status bytes the ULD only compares is
// inferred from those comparisons.
//
// Usage (tests/emulator/devices/i2c-bus.mjs is the bus it plugs into):
//   const m = new Vl53l5cxModel({ readBeams, nowNs });
//   m.connect('write' | 'read'); m.write(byte); m.read(); m.stop();   // bus events
//   m.powerDown(); m.powerUp();                                         // LPn low / high
//   m.present                                                           // false: NACK
//   m.stats()                                                           // counters
// Self-test, no Rust needed: node tests/emulator/vl53l5cx.mjs --self-test

import { fileURLToPath } from 'node:url';

// ---------------------------------------------------------------------------------------
// Facts about the part and its firmware, as the ULD uses them

export const VL53L5CX_ADDRESS = 0x29;

const PAGE_SELECT = 0x7fff;
const PAGE_SYSTEM = 0;
const PAGE_FW_ACCESS = 1;
const PAGE_UI = 2;
const FW_PAGES = [9, 10, 11];
const PAGE_BYTES = 0x8000;

// Page 0.
const REG_DEVICE_ID = 0x0000; // 0xF0
const REG_REVISION_ID = 0x0001; // 0x02 (the VL53L8CX answers 0x0C)
const REG_I2C_ADDRESS = 0x0004;
const REG_GO2_STATUS0 = 0x0006; // bit 0: MCU running and awake; bit 7: MCU has stopped
const REG_GO2_STATUS1 = 0x0007; // why it stopped: 0x84/0x85 = on the host's request
const REG_POWER = 0x0009; // 0x04 wake-up (HP idle), 0x02 sleep (LP idle), 0x05 ranging
const REG_MCU_RUN = 0x000b; // 0 holds the MCU in reset, 1 starts it from RAM
const REG_MCU_STOP = 0x0014; // 1 stops the MCU, with REG_MCU_STOP_KEY = 0x16
const REG_MCU_STOP_KEY = 0x0015;
const REG_SOFT_RESET = 0x4002; // 1 then 0: software reset of the MCU
// Page-0 registers the ULD writes during its start-up sequences without reading them back
// (analogue, clock and boot-address set-up). Stored, with no modelled effect.
const PAGE0_WRITE_ONLY = new Set([
  0x000a, 0x000c, 0x000e, 0x000f, 0x0101, 0x0102, 0x0103, 0x010a, 0x0114, 0x0115, 0x0116,
  0x0117, 0x0219, 0x021a, 0x021b, 0x400f,
]);

// Page 1 and page 2 registers of the firmware-access handshake.
const REG_FW_ACCESS_STATUS = 0x0021; // page 1, bit 4
const REG_FW_ACCESS_REQUEST = 0x0003; // page 2, 0x0D asks for access

// UI command area (page 2).
const UI_STATUS = 0x2c00;
const UI_START = 0x2c04;
const UI_END = 0x2fff;
const UI_LAST_WORD = UI_END - 3;
const CMD_WRITE = 1;
const CMD_READ = 2;
const CMD_START = 3;
const CMD_DONE = 0x03; // status byte 1 when the firmware has handled a command
const TERMINATOR = [0x00, 0x00, 0x00, 0x0f];

// DCI (the firmware's configuration memory), the addresses this model gives meaning to.
const DCI_RANGE_INFO = 0x5440; // written by the firmware at start: u16 frame size at +8
const DCI_ZONE_CONFIG = 0x5450; // bytes 0, 1: zones across, zones down
const DCI_FREQ_HZ = 0x5458; // byte 1: frames per second
const DCI_RANGING_MODE = 0xad30; // byte 1: 1 continuous, 3 autonomous
const DCI_OUTPUT_CONFIG = 0xd968; // u32: frame size the ULD will read; u32: list length
const DCI_OUTPUT_ENABLES = 0xd970; // 4 x u32: bit i enables output list entry i
const DCI_OUTPUT_LIST = 0xd980; // 128 x u32 block headers: what each frame carries
const OUTPUT_LIST_ENTRIES = 128;

// Output blocks, by their idx in the frame. The single-target layout (the crate's default)
// and the multi-target one (the `targets-N` features) use different addresses.
const OUTPUTS = new Map([
  [0x54b4, 'metadata'],
  [0x54c0, 'common'],
  [0x54d0, 'ambient'],
  [0x55d0, 'spads'],
  [0xdb84, 'nb_targets'], [0x57d0, 'nb_targets'],
  [0xdbc4, 'signal'], [0x5890, 'signal'],
  [0xdec4, 'sigma'], [0x6490, 'sigma'],
  [0xdf44, 'distance'], [0x6690, 'distance'],
  [0xe044, 'reflectance'], [0x6a90, 'reflectance'],
  [0xe084, 'status'], [0x6b90, 'status'],
  [0xd858, 'motion'], [0xcc50, 'motion'],
]);
const PER_ZONE = new Set(['ambient', 'spads', 'nb_targets']);
const PER_TARGET = new Set(['signal', 'sigma', 'distance', 'reflectance', 'status']);

// Frame layout around the blocks (see the header comment).
const FRAME_HEAD_BYTES = 12; // status word, reserved word, frame id word
const FRAME_TAIL_BYTES = 12; // two reserved words, frame id word
const FRAME_READY = [0x05, 0x05, 0x10]; // status word bytes 1..3 of a ready frame

// Ranging.
const MAX_RANGE_MM = 4000;
const MAX_HZ = { 16: 60, 64: 15 }; // by zone count
const TARGET_STATUS_VALID = 5;
const TARGET_STATUS_NONE = 0; // the ULD itself turns this into 255 when nb_targets is on
const SILICON_TEMP_C = 25;

// Boot times, assumed (the ULD waits 100 ms after the software reset before its first
// poll and polls the firmware boot every ms, so any value under those works the same).
const ROM_BOOT_NS = 1e6;
const FW_BOOT_NS = 5e6;

// The firmware image of ST's ULD 2.0.0 (the one `vl53l5cx-uld-sys` 0.1.0 ships, "MM1.8"):
// 0x15000 bytes, CRC-32 0x4DDD48A0. A different image (another ULD version) or bytes lost
// or changed on the bus shows as an error; pass `firmwareCrc32: null` to skip the check.
export const ULD_FIRMWARE_BYTES = 0x15000;
export const ULD_FIRMWARE_CRC32 = 0x4ddd48a0;

const MAX_ERROR_MESSAGES = 8;

// ---------------------------------------------------------------------------------------
// Helpers

/// Reverses the bytes of every 32-bit word: the ULD's wire order <-> little-endian memory.
/// Bytes after the last whole word are copied unchanged.
export function swapWords(src) {
  const out = new Uint8Array(src.length);
  const whole = src.length & ~3;
  for (let i = 0; i < whole; i += 4) {
    out[i] = src[i + 3];
    out[i + 1] = src[i + 2];
    out[i + 2] = src[i + 1];
    out[i + 3] = src[i];
  }
  for (let i = whole; i < src.length; i++) out[i] = src[i];
  return out;
}

let crcTable = null;
/// CRC-32 (IEEE 802.3, as zlib's crc32).
export function crc32(bytes) {
  if (!crcTable) {
    crcTable = new Uint32Array(256);
    for (let n = 0; n < 256; n++) {
      let c = n;
      for (let k = 0; k < 8; k++) c = c & 1 ? 0xedb88320 ^ (c >>> 1) : c >>> 1;
      crcTable[n] = c >>> 0;
    }
  }
  let c = 0xffffffff;
  for (const b of bytes) c = crcTable[(c ^ b) & 0xff] ^ (c >>> 8);
  return (c ^ 0xffffffff) >>> 0;
}

/// A block header word's fields.
function blockHeader(word) {
  const type = word & 0xf;
  const size = (word >>> 4) & 0xfff;
  const idx = word >>> 16;
  const bytes = type >= 1 && type <= 12 ? type * size : size;
  return { word: word >>> 0, idx, type, size, bytes };
}

const hex = (v, w = 4) => `0x${v.toString(16).padStart(w, '0')}`;

// ---------------------------------------------------------------------------------------
// The model

export class Vl53l5cxModel {
  /// `readBeams()` -> `{ranges_mm: [8 x mm or null]}`, the robot's beams left to right;
  /// `nowNs()` -> simulated time in ns. `poweredAtStart`: LPn high before the harness says
  /// anything (breakout boards pull it up). `firmwareCrc32`: the image expected at MCU
  /// start (null: any).
  constructor({ readBeams, nowNs, poweredAtStart = true, firmwareCrc32 = ULD_FIRMWARE_CRC32 } = {}) {
    this.readBeams = readBeams ?? (() => ({ ranges_mm: new Array(8).fill(null) }));
    this.nowNs = nowNs ?? (() => 0);
    this.expectedFirmwareCrc32 = firmwareCrc32;
    // Counters for the harness report.
    this.uploads = 0; // firmware images the MCU was started from
    this.upload_bytes = 0; // bytes written to the firmware pages
    this.producedFrames = 0; // see the `frames` getter
    this.frames_read = 0; // frames whose last byte the host read
    this.resets = 0; // LPn power-downs (firmware and configuration lost)
    this.reboots = 0; // MCU software reset pulses (two per ULD init)
    this.dci_commands = 0; // UI commands handled
    this.errors = 0; // anything the model did not expect
    this.error_messages = [];
    this.firmwareCrc32 = null; // CRC of the last image the MCU started from
    this.corruptFramesPending = 0;
    this.powerOnReset(poweredAtStart);
  }

  // ---- Bus side

  /// False while LPn is low: the part does not acknowledge its address.
  get present() {
    return this.mcu !== 'off';
  }

  /// START or repeated START addressed to the part.
  connect(mode) {
    this.endWrite();
    if (!this.present) {
      this.error('addressed while LPn is low (the part would not acknowledge)');
      this.tx = null;
      return;
    }
    this.tx = { mode, count: 0, indexHigh: 0 };
    if (mode === 'read' && this.page === PAGE_UI && this.index < UI_STATUS) this.syncFrames();
  }

  write(byte) {
    const tx = this.tx;
    if (!tx || tx.mode !== 'write') {
      if (tx) this.error('byte written in a read transfer');
      return;
    }
    byte &= 0xff;
    if (tx.count === 0) tx.indexHigh = byte;
    else if (tx.count === 1) this.index = (tx.indexHigh << 8) | byte;
    else this.writeByte(byte, tx.count === 2);
    tx.count++;
  }

  read() {
    const tx = this.tx;
    if (!tx || tx.mode !== 'read') {
      if (tx) this.error('byte read in a write transfer');
      return 0xff;
    }
    tx.count++;
    return this.readByte();
  }

  stop() {
    this.endWrite();
    this.tx = null;
  }

  /// LPn low. Modelled as losing the firmware and the configuration: the harness uses LPn as
  /// the sensor's reset. ST documents LPn as an I2C enable (the `vl53l5cx-uld` crate says it
  /// does not drop the firmware); the ULD cannot tell the difference, as its `init` always
  /// reboots the MCU and uploads the firmware again.
  powerDown() {
    if (!this.present) return;
    this.syncFrames();
    this.resets++;
    this.powerOnReset(false);
  }

  /// LPn high: the part answers again, its boot ROM starting.
  powerUp() {
    if (this.present) return;
    this.powerOnReset(true);
  }

  /// Test hook: the next `count` frames carry a footer id that does not match the header
  /// id, as a frame overwritten while the host reads it would; the ULD reports them as
  /// corrupted (status 2).
  corruptNextFrames(count = 1) {
    this.corruptFramesPending += count;
  }

  /// Frames produced so far, counted up to the current time (without touching the results
  /// area, so a report taken during a read cannot tear the frame being read).
  get frames() {
    const r = this.ranging;
    if (!r) return this.producedFrames;
    const due = Math.floor((this.nowNs() - r.t0) / r.periodNs);
    return this.producedFrames + Math.max(0, due - r.produced);
  }

  stats() {
    return {
      uploads: this.uploads,
      upload_bytes: this.upload_bytes,
      frames: this.frames,
      frames_read: this.frames_read,
      resets: this.resets,
      reboots: this.reboots,
      dci_commands: this.dci_commands,
      ranging: !!this.ranging,
      firmware_crc32: this.firmwareCrc32 === null ? null : hex(this.firmwareCrc32, 8),
      errors: this.errors,
      error_messages: [...this.error_messages],
    };
  }

  // ---- State

  powerOnReset(powered) {
    this.pages = new Map();
    this.page = PAGE_SYSTEM;
    this.index = 0;
    this.tx = null;
    this.commandPending = false;
    const sys = this.mem(PAGE_SYSTEM);
    sys[REG_DEVICE_ID] = 0xf0;
    sys[REG_REVISION_ID] = 0x02;
    sys[REG_I2C_ADDRESS] = VL53L5CX_ADDRESS;
    sys[REG_POWER] = 0x04;
    sys[REG_MCU_RUN] = 0x01;
    this.i2cAddress = VL53L5CX_ADDRESS;
    this.mcu = powered ? 'rom' : 'off';
    this.bootDoneNs = this.nowNs() + ROM_BOOT_NS;
    this.mcuHalted = false;
    this.softResetArmed = false;
    // The host's access to the firmware pages, granted by 0x0D in page 2 register 3. It
    // survives the MCU's software reset: the ULD's init grants it, pulses the reset again
    // and only then uploads.
    this.fwAccess = false;
    this.clearMcuRam();
  }

  /// What the MCU loses on a reset: its RAM (firmware image, DCI memory, the UI and results
  /// areas) and anything it was doing.
  clearMcuRam() {
    this.fwImage = new Uint8Array(FW_PAGES.length * PAGE_BYTES);
    this.fwWritten = new Uint8Array(this.fwImage.length);
    this.fwUnique = 0;
    this.fwEnd = 0;
    this.dci = null;
    this.ranging = null;
    this.frame = null;
    this.pages.delete(PAGE_UI);
  }

  mem(page) {
    let m = this.pages.get(page);
    if (!m) {
      m = new Uint8Array(PAGE_BYTES);
      this.pages.set(page, m);
    }
    return m;
  }

  error(message) {
    this.errors++;
    if (this.error_messages.length < MAX_ERROR_MESSAGES) this.error_messages.push(message);
  }

  firmwareRunning() {
    return this.mcu === 'fw' && this.nowNs() >= this.bootDoneNs && !this.mcuHalted;
  }

  // ---- Register writes

  endWrite() {
    const tx = this.tx;
    if (!tx || tx.mode !== 'write') return;
    if (tx.count === 1) this.error('write transfer with a one-byte register index');
    // The firmware acts on a command once the host has written its last byte.
    if (this.commandPending) this.runCommand();
  }

  writeByte(v, first) {
    const idx = this.index;
    this.index = (idx + 1) & 0xffff;
    // The page register answers at 0x7FFF on every page. A burst that runs through 0x7FFF
    // (the ULD's firmware upload ends each 32 KB page there) writes memory: the part's
    // behaviour there is undocumented, and the ULD selects the next page right after, so
    // either reading gives the same result.
    if (idx === PAGE_SELECT && first) {
      this.page = v;
      return;
    }
    if (idx >= PAGE_BYTES) {
      this.error(`write beyond the page, index ${hex(idx)}`);
      return;
    }
    if (FW_PAGES.includes(this.page)) {
      this.writeFirmware(idx, v);
      return;
    }
    const mem = this.mem(this.page);
    mem[idx] = v;
    if (this.page === PAGE_SYSTEM) this.writeSystem(idx, v);
    else if (this.page === PAGE_FW_ACCESS) {
      if (idx !== 0x0020) this.error(`write to page 1 register ${hex(idx)}`);
    } else if (this.page === PAGE_UI) {
      if (idx === REG_FW_ACCESS_REQUEST) {
        if (v === 0x0d) this.fwAccess = true;
      } else if (idx >= UI_START && idx <= UI_END) {
        if (idx === UI_END) this.commandPending = true;
      } else {
        this.error(`write to page 2 at ${hex(idx)}, outside the UI command area`);
      }
    } else {
      this.error(`write to page ${this.page} at ${hex(idx)}`);
    }
  }

  writeSystem(idx, v) {
    switch (idx) {
      case REG_I2C_ADDRESS:
        // `set_i2c_address`: the part answers at the new address from the next transfer.
        this.i2cAddress = v & 0x7f;
        if (this.i2cAddress !== VL53L5CX_ADDRESS) {
          this.error(`I2C address moved to ${hex(this.i2cAddress, 2)}; the model answers at 0x29 only`);
        }
        return;
      case REG_POWER:
        if (![0x02, 0x04, 0x05].includes(v)) this.error(`power mode register set to ${hex(v, 2)}`);
        return;
      case REG_MCU_RUN:
        if (v === 0x00) {
          this.mcu = this.mcu === 'off' ? 'off' : 'held';
          this.ranging = null;
        } else if (v === 0x01 && this.mcu === 'held') {
          this.startMcu();
        }
        return;
      case REG_MCU_STOP:
        if (v & 1) {
          if (this.mem(PAGE_SYSTEM)[REG_MCU_STOP_KEY] !== 0x16) {
            this.error('MCU stop requested without the 0x16 key');
            return;
          }
          // The firmware stops ranging and reports "stopped by the host" in GO2 status 1.
          this.syncFrames();
          this.ranging = null;
          this.mcuHalted = true;
        } else {
          // The MCU resumes; ST's ULD restores this at the end of `stop_ranging`.
          this.mcuHalted = false;
        }
        return;
      case REG_MCU_STOP_KEY:
        return;
      case REG_SOFT_RESET:
        // A pulse (1 then 0) resets the MCU to its boot ROM: the uploaded firmware and the
        // configuration are gone. The ULD's init pulses it twice (before and after granting
        // itself firmware access), so `reboots` counts two per init.
        if (v === 1) this.softResetArmed = true;
        else if (v === 0 && this.softResetArmed) {
          this.softResetArmed = false;
          this.reboots++;
          this.clearMcuRam();
          this.mcu = 'rom';
          this.mcuHalted = false;
          this.bootDoneNs = this.nowNs() + ROM_BOOT_NS;
        }
        return;
      default:
        if (!PAGE0_WRITE_ONLY.has(idx)) this.error(`write to page 0 register ${hex(idx)}`);
    }
  }

  writeFirmware(idx, v) {
    const offset = (this.page - FW_PAGES[0]) * PAGE_BYTES + idx;
    if (!this.fwAccess) this.error('firmware page written before access was granted');
    this.fwImage[offset] = v;
    if (!this.fwWritten[offset]) {
      this.fwWritten[offset] = 1;
      this.fwUnique++;
    }
    this.fwEnd = Math.max(this.fwEnd, offset + 1);
    this.upload_bytes++;
  }

  /// REG_MCU_RUN 0 -> 1: the MCU starts from RAM. With a whole image it boots the firmware
  /// (modelled from here on); with none, or a gappy one, it would run garbage: the model
  /// then never reports a boot and answers no command (the ULD times out).
  startMcu() {
    const complete = this.fwEnd > 2 * PAGE_BYTES && this.fwUnique === this.fwEnd;
    if (!complete) {
      this.error(
        `MCU started without a whole firmware image (${this.fwUnique} bytes written, up to ${this.fwEnd})`,
      );
      this.mcu = 'dead';
      return;
    }
    this.firmwareCrc32 = crc32(this.fwImage.subarray(0, this.fwEnd));
    const expected = this.expectedFirmwareCrc32;
    if (expected !== null && this.firmwareCrc32 !== expected) {
      this.error(
        `firmware image of ${this.fwEnd} bytes has CRC ${hex(this.firmwareCrc32, 8)}, not ${hex(expected, 8)}` +
          ' (bytes lost or changed on the bus, or another ULD version)',
      );
    }
    this.uploads++;
    this.mcu = 'fw';
    this.bootDoneNs = this.nowNs() + FW_BOOT_NS;
    this.dci = new Uint8Array(0x10000);
    // The firmware fills its configuration memory at boot. The ULD overwrites almost all of
    // it with its default configuration, reads the NVM calibration blocks and the glare
    // filter (0xE108) before writing them, and does not check their contents: the model
    // leaves them zero, a unit with zero offsets.
    this.mem(PAGE_UI).fill(0);
  }

  // ---- Register reads

  readByte() {
    const idx = this.index;
    this.index = (idx + 1) & 0xffff;
    if (idx === PAGE_SELECT) return this.page;
    if (idx >= PAGE_BYTES) {
      this.error(`read beyond the page, index ${hex(idx)}`);
      return 0;
    }
    switch (this.page) {
      case PAGE_SYSTEM:
        return this.readSystem(idx);
      case PAGE_FW_ACCESS:
        if (idx === REG_FW_ACCESS_STATUS) return this.fwAccess ? 0x10 : 0x00;
        break;
      case PAGE_UI:
        if (idx >= UI_STATUS && idx <= UI_END) return this.mem(PAGE_UI)[idx];
        return this.readResults(idx);
      default:
        break;
    }
    this.error(`read of page ${this.page} at ${hex(idx)}`);
    return this.pages.get(this.page)?.[idx] ?? 0;
  }

  readSystem(idx) {
    const sys = this.mem(PAGE_SYSTEM);
    switch (idx) {
      case REG_DEVICE_ID:
      case REG_REVISION_ID:
      case REG_POWER:
        return sys[idx];
      case REG_GO2_STATUS0: {
        const booted = (this.mcu === 'rom' || this.mcu === 'fw') && this.nowNs() >= this.bootDoneNs;
        const awake = sys[REG_POWER] !== 0x02;
        return (booted && awake ? 0x01 : 0x00) | (this.mcuHalted ? 0x80 : 0x00);
      }
      case REG_GO2_STATUS1:
        return this.mcuHalted ? 0x84 : 0x00;
      default:
        this.error(`read of page 0 register ${hex(idx)}`);
        return sys[idx];
    }
  }

  readResults(idx) {
    const f = this.frame;
    const mem = this.mem(PAGE_UI);
    if (idx < 4) return mem[idx];
    if (!f || idx >= f.size) {
      this.error(`read of the results area at ${hex(idx)}, outside the current frame`);
      return mem[idx];
    }
    if (f.pending) this.fillFrame();
    if (idx === f.size - 1 && !f.read) {
      f.read = true;
      this.frames_read++;
    }
    return mem[idx];
  }

  // ---- UI commands

  runCommand() {
    this.commandPending = false;
    const ui = this.mem(PAGE_UI);
    if (!this.firmwareRunning() || this.mem(PAGE_SYSTEM)[REG_POWER] === 0x02) {
      this.error('UI command while the firmware is not running: no answer');
      return;
    }
    this.dci_commands++;
    const [tag, code] = [ui[UI_LAST_WORD], ui[UI_LAST_WORD + 1]];
    const length = (ui[UI_LAST_WORD + 2] << 8) | ui[UI_LAST_WORD + 3];
    let ok;
    if (code === CMD_START) ok = length === 0 && this.startRanging();
    else if (code === CMD_WRITE || code === CMD_READ) ok = this.runBlocks(ui, code, tag, length);
    else ok = false;
    if (!ok) this.error(`UI command tag ${tag} code ${code} length ${length} not understood`);
    // The status word: the ULD waits for byte 1 = 3 (done), byte 0 = 2 after its NVM read
    // (whose tag is 2) and treats byte 2 >= 0x7F as an MCU error. The model echoes the tag
    // in byte 0; the real part's bytes 0 and 3 are not documented.
    ui.set([tag, CMD_DONE, ok ? 0x00 : 0x7f, 0x00], UI_STATUS);
  }

  /// Code 1 (write the blocks' data) or 2 (answer the blocks at UI_START).
  runBlocks(ui, code, tag, length) {
    const start = UI_LAST_WORD - length;
    const terminator = UI_LAST_WORD - 4;
    if (start < UI_START || length < 4) return false;
    if (TERMINATOR.some((b, k) => ui[terminator + k] !== b)) return false;
    const requests = [];
    let p = start;
    while (p < terminator) {
      const h = blockHeader(new DataView(ui.buffer).getUint32(p, false));
      if (h.idx + h.bytes > 0x10000) return false;
      if (code === CMD_WRITE) {
        if (p + 4 + h.bytes > terminator) return false;
        this.dci.set(swapWords(ui.subarray(p + 4, p + 4 + h.bytes)), h.idx);
        p += 4 + h.bytes;
      } else {
        requests.push(h);
        p += 4;
      }
    }
    if (p !== terminator) return false;
    if (code === CMD_READ) {
      // The answer: each requested block, header then data, then the terminator and a last
      // word like a command's (tag, code, length).
      const answer = [];
      for (const h of requests) {
        answer.push((h.word >>> 24) & 0xff, (h.word >>> 16) & 0xff, (h.word >>> 8) & 0xff, h.word & 0xff);
        answer.push(...swapWords(this.dci.subarray(h.idx, h.idx + h.bytes)));
      }
      answer.push(...TERMINATOR);
      const n = answer.length;
      answer.push(tag, code, (n >> 8) & 0xff, n & 0xff);
      if (UI_START + answer.length > UI_END + 1) return false;
      ui.set(answer, UI_START);
    }
    return true;
  }

  /// Code 3: lay the frame out from the output list and enables the ULD wrote, tell the
  /// ULD the frame size (it checks it against its own sum) and start the frame clock.
  startRanging() {
    const d = this.dci;
    const dv = new DataView(d.buffer);
    const across = d[DCI_ZONE_CONFIG];
    const down = d[DCI_ZONE_CONFIG + 1];
    const zones = across * down;
    if (!(zones in MAX_HZ)) {
      this.error(`zone configuration ${across} x ${down}`);
      return false;
    }
    const blocks = [];
    let offset = FRAME_HEAD_BYTES;
    for (let i = 0; i < OUTPUT_LIST_ENTRIES; i++) {
      const word = dv.getUint32(DCI_OUTPUT_LIST + 4 * i, true);
      const enabled = (dv.getUint32(DCI_OUTPUT_ENABLES + 4 * (i >> 5), true) >>> (i & 31)) & 1;
      if (word === 0 || !enabled) continue;
      const h = blockHeader(word);
      const kind = OUTPUTS.get(h.idx) ?? (h.type === 0xd ? 'start' : 'unknown');
      this.checkBlock(h, kind, zones);
      blocks.push({ ...h, kind, offset });
      offset += 4 + h.bytes;
    }
    const size = offset + FRAME_TAIL_BYTES;
    if (size > UI_STATUS) {
      this.error(`frame of ${size} bytes would overrun the UI area`);
      return false;
    }
    const expected = dv.getUint32(DCI_OUTPUT_CONFIG, true);
    if (expected !== size) {
      this.error(`the ULD expects ${expected}-byte frames; its output list gives ${size}`);
    }
    d.fill(0, DCI_RANGE_INFO, DCI_RANGE_INFO + 12);
    dv.setUint16(DCI_RANGE_INFO + 8, size, true);

    let hz = d[DCI_FREQ_HZ + 1];
    if (hz === 0) {
      this.error('ranging frequency 0 Hz');
      return false;
    }
    if (hz > MAX_HZ[zones]) {
      // The firmware enforces the limit (how, ST does not say): the model clamps.
      this.error(`${hz} Hz is above the part's ${MAX_HZ[zones]} Hz for ${zones} zones`);
      hz = MAX_HZ[zones];
    }
    // Continuous and autonomous modes (DCI_RANGING_MODE) both produce a frame per period;
    // the integration time of autonomous mode only matters to the real part's power and
    // signal.
    this.ranging = {
      t0: this.nowNs(),
      periodNs: 1e9 / hz,
      produced: 0,
      layout: { blocks, size, zones, across },
    };
    // No frame is ready until the first of this session (an old status word would look
    // ready to the ULD, which restarts its stream count at 255).
    this.frame = null;
    this.mem(PAGE_UI).fill(0, 0, 4);
    return true;
  }

  checkBlock(h, kind, zones) {
    if (kind === 'unknown') this.error(`output block idx ${hex(h.idx)} unknown to the model: sent as zeros`);
    const perZoneWrong = PER_ZONE.has(kind) && h.size !== zones;
    const perTargetWrong = PER_TARGET.has(kind) && (h.size === 0 || h.size % zones !== 0);
    if (perZoneWrong || perTargetWrong) this.error(`${kind} block of ${h.size} entries for ${zones} zones`);
    if ((PER_ZONE.has(kind) || PER_TARGET.has(kind)) && ![1, 2, 4].includes(h.type)) {
      this.error(`${kind} block with ${h.type}-byte entries`);
    }
  }

  // ---- Frames

  /// Brings the frame clock up to now: a frame every period since the start; frames nobody
  /// read are overwritten by the newest, whose stream count is visible at once (its
  /// contents are filled when the host first reads past the status word).
  syncFrames() {
    const r = this.ranging;
    if (!r) return;
    const due = Math.floor((this.nowNs() - r.t0) / r.periodNs);
    if (due <= r.produced) return;
    this.producedFrames += due - r.produced;
    r.produced = due;
    // Stream counts run 0..254: the ULD treats 255 as "no frame yet".
    const streamCount = (due - 1) % 255;
    this.frame = {
      id: due & 0xffff,
      streamCount,
      size: r.layout.size,
      layout: r.layout,
      pending: true, // contents not filled yet
      read: false, // last byte not read yet
    };
    this.mem(PAGE_UI).set([streamCount, ...FRAME_READY], 0);
  }

  fillFrame() {
    const f = this.frame;
    const { blocks, size, zones, across } = f.layout;
    f.pending = false;
    const targets = this.zoneTargets(zones, across);
    // Built as the ULD sees it after its word swap (little-endian), then swapped to wire.
    const frame = new Uint8Array(size);
    const dv = new DataView(frame.buffer);
    const corrupt = this.corruptFramesPending > 0;
    if (corrupt) this.corruptFramesPending--;
    dv.setUint16(8, f.id, false);
    dv.setUint16(size - 4, corrupt ? f.id ^ 0xffff : f.id, false);
    for (const b of blocks) {
      dv.setUint32(b.offset, b.word, true);
      this.fillBlock(dv, b, targets, zones);
    }
    const wire = swapWords(frame);
    wire.set([f.streamCount, ...FRAME_READY], 0);
    this.mem(PAGE_UI).set(wire, 0);
  }

  /// Each zone's target in mm, or null: every zone of a column reports the beam(s) of that
  /// column (beam b is sensor column 7 - b, the sensor seeing the scene mirrored), the
  /// nearest when a column covers two beams (4x4). The real part ranges each zone's own
  /// cone; `drivers::depth::reduce` reads the middle rows, so filling every row gives it
  /// back exactly the beams.
  zoneTargets(zones, across) {
    let beams;
    try {
      beams = this.readBeams();
    } catch (e) {
      this.error(`readBeams threw: ${e.message}`);
    }
    let ranges = beams?.ranges_mm;
    if (!Array.isArray(ranges) || ranges.length !== 8) {
      this.error('readBeams gave no 8 ranges_mm: frame without targets');
      ranges = new Array(8).fill(null);
    }
    const valid = (mm) =>
      typeof mm === 'number' && mm > 0 && mm <= MAX_RANGE_MM ? Math.round(mm) : null;
    const column = [];
    for (let c = 0; c < across; c++) {
      let nearest = null;
      for (let b = 0; b < 8; b++) {
        const sensorColumn = Math.floor(((7 - b) * across) / 8);
        const mm = valid(ranges[b]);
        if (sensorColumn === c && mm !== null && (nearest === null || mm < nearest)) nearest = mm;
      }
      column.push(nearest);
    }
    return Array.from({ length: zones }, (_, z) => column[z % across]);
  }

  /// One output block's data. Values besides distance, status and target count are plausible
  /// constants, not physics, in the units the ULD divides out (kcps/SPAD x 2048, mm x 128,
  /// % x 2, mm x 4).
  fillBlock(dv, b, targets, zones) {
    const base = b.offset + 4;
    if (b.kind === 'metadata') {
      if (b.bytes >= 9) dv.setInt8(base + 8, SILICON_TEMP_C);
      return;
    }
    if (!PER_ZONE.has(b.kind) && !PER_TARGET.has(b.kind)) return; // common, motion: zeros
    if (![1, 2, 4].includes(b.type)) return;
    const perZone = PER_ZONE.has(b.kind) ? 1 : Math.max(1, Math.floor(b.size / zones));
    for (let e = 0; e < b.size; e++) {
      const zone = Math.floor(e / perZone);
      const mm = e % perZone === 0 ? targets[zone] ?? null : null;
      let v = 0;
      switch (b.kind) {
        case 'ambient': v = 2 * 2048; break; // 2 kcps/SPAD of ambient light
        case 'spads': v = (16 * 1024) / zones; break;
        case 'nb_targets': v = targets[zone] === null || targets[zone] === undefined ? 0 : 1; break;
        case 'signal': v = mm === null ? 0 : Math.round(2048 * Math.min(2000, 2e7 / (mm * mm))); break;
        case 'sigma': v = mm === null ? 0 : Math.round(128 * (1 + mm / 1000)); break;
        case 'distance': v = mm === null ? 0 : mm * 4; break;
        case 'reflectance': v = mm === null ? 0 : 2 * 50; break;
        case 'status': v = mm === null ? TARGET_STATUS_NONE : TARGET_STATUS_VALID; break;
        default: break;
      }
      const at = base + e * b.type;
      if (b.type === 1) dv.setUint8(at, v);
      else if (b.type === 2) dv.setUint16(at, v, true);
      else dv.setUint32(at, v, true);
    }
  }
}

// ---------------------------------------------------------------------------------------
// Self-test: a small host that speaks the ULD's protocol byte for byte (written from the
// same facts, not from ST's code), against the model. `node vl53l5cx.mjs --self-test`.

function selfTest() {
  const checks = [];
  const check = (name, ok, detail = '') => {
    checks.push([name, !!ok]);
    if (!ok) console.error(`FAILED ${name} ${detail}`);
  };
  let now = 0;
  let beams = new Array(8).fill(null);
  let beamCalls = 0;
  const image = new Uint8Array(ULD_FIRMWARE_BYTES);
  let seed = 12345;
  for (let i = 0; i < image.length; i++) {
    seed = (seed * 1103515245 + 12345) >>> 0;
    image[i] = seed >>> 24;
  }
  const m = new Vl53l5cxModel({
    readBeams: () => {
      beamCalls++;
      return { ranges_mm: beams };
    },
    nowNs: () => now,
    firmwareCrc32: crc32(image),
  });

  // Bus primitives, each byte taking 9 SCL periods at 400 kHz.
  const byteNs = 22500;
  const wr = (index, bytes) => {
    m.connect('write');
    m.write(index >> 8);
    m.write(index & 0xff);
    for (const b of bytes) m.write(b);
    m.stop();
    now += (3 + bytes.length) * byteNs;
  };
  const rd = (index, n) => {
    m.connect('write');
    m.write(index >> 8);
    m.write(index & 0xff);
    m.connect('read');
    const out = Array.from({ length: n }, () => m.read());
    m.stop();
    now += (4 + n) * byteNs;
    return out;
  };
  const wait = (ms) => { now += ms * 1e6; };
  const poll = (index, pos, mask, value) => {
    for (let t = 0; t < 200; t++) {
      const s = rd(index, pos + 1);
      wait(10);
      if ((s[pos] & mask) === value) return true;
    }
    return false;
  };
  const pollUi = (pos, value) => {
    for (let t = 0; t < 200; t++) {
      const s = rd(UI_STATUS, 4);
      wait(10);
      if (s[2] >= 0x7f) return false;
      if (s[pos] === value) return true;
    }
    return false;
  };
  const header = (idx, bytes, type = 0) => {
    const size = type ? bytes / type : bytes;
    return [idx >> 8, idx & 0xff, (size >> 4) & 0xff, ((size & 0xf) << 4) | type];
  };
  const dciWrite = (idx, native) => {
    const n = native.length;
    const last = [0x05, CMD_WRITE, (n + 8) >> 8, (n + 8) & 0xff];
    const cmd = [...header(idx, n), ...swapWords(native), ...TERMINATOR, ...last];
    wr(UI_END + 1 - cmd.length, cmd);
    return pollUi(1, CMD_DONE);
  };
  const dciRead = (idx, n) => {
    wr(UI_END - 11, [...header(idx, n), ...TERMINATOR, 0x00, CMD_READ, 0x00, 0x08]);
    if (!pollUi(1, CMD_DONE)) return null;
    const answer = rd(UI_START, n + 12);
    const native = swapWords(Uint8Array.from(answer)).slice(4, 4 + n);
    return { header: answer.slice(0, 4), native };
  };
  const u32s = (...words) => {
    const out = new Uint8Array(4 * words.length);
    words.forEach((w, i) => new DataView(out.buffer).setUint32(4 * i, w >>> 0, true));
    return out;
  };

  // Identity, page register, LPn.
  check('present at power-up', m.present);
  wr(PAGE_SELECT, [0]);
  check('device and revision id', rd(0, 1)[0] === 0xf0 && rd(1, 1)[0] === 0x02);
  wr(PAGE_SELECT, [2]);
  check('page register reads back', rd(PAGE_SELECT, 1)[0] === 2);
  m.powerDown();
  check('absent while LPn is low', !m.present && m.resets === 1);
  m.powerUp();
  check('present again', m.present);

  // Software reset, boot ROM, firmware access, upload, MCU start.
  wr(PAGE_SELECT, [0]);
  wr(REG_SOFT_RESET, [1]);
  wr(REG_SOFT_RESET, [0]);
  check('boot ROM not up at once', rd(REG_GO2_STATUS0, 1)[0] === 0);
  wait(100);
  check('boot ROM up', poll(REG_GO2_STATUS0, 0, 0xff, 0x01));
  wr(PAGE_SELECT, [2]);
  wr(REG_FW_ACCESS_REQUEST, [0x0d]);
  wr(PAGE_SELECT, [1]);
  check('firmware access granted', poll(REG_FW_ACCESS_STATUS, 0, 0x10, 0x10));
  for (const [k, page] of FW_PAGES.entries()) {
    wr(PAGE_SELECT, [page]);
    wr(0, image.subarray(k * PAGE_BYTES, Math.min(image.length, (k + 1) * PAGE_BYTES)));
  }
  wr(PAGE_SELECT, [0]);
  wr(REG_MCU_RUN, [0]);
  wr(REG_MCU_RUN, [1]);
  check('firmware boots', poll(REG_GO2_STATUS0, 0, 0x81, 0x01));
  check('upload counted', m.uploads === 1 && m.upload_bytes === ULD_FIRMWARE_BYTES);
  check('upload CRC', m.firmwareCrc32 === crc32(image));
  wr(PAGE_SELECT, [2]);

  // A multi-block read (like the ULD's NVM request): tag 2 in status byte 0, the blocks
  // echoed at UI_START with their data.
  const nvm = [...header(0x5400, 4), ...header(0x9e38, 256, 4), ...TERMINATOR, 0x02, CMD_READ, 0, 12];
  wr(UI_END + 1 - nvm.length, nvm);
  check('multi-block read done', pollUi(0, 2));
  const nvmAnswer = rd(UI_START, 4 + 4 + 4 + 256 + 4);
  check('multi-block answer layout',
    nvmAnswer.slice(0, 4).join() === header(0x5400, 4).join() &&
    nvmAnswer.slice(8, 12).join() === header(0x9e38, 256, 4).join() &&
    nvmAnswer.slice(268, 272).join() === TERMINATOR.join());

  // DCI round trip: what is written reads back, byte for byte on the wire and word-swapped
  // in the firmware's memory.
  const zone8x8 = Uint8Array.from([8, 8, 0, 0, 4, 4, 0, 0]);
  check('DCI write', dciWrite(DCI_ZONE_CONFIG, zone8x8));
  const back = dciRead(DCI_ZONE_CONFIG, 8);
  check('DCI read back', back && back.native.join() === zone8x8.join());
  check('DCI answer header', back && back.header.join() === header(DCI_ZONE_CONFIG, 8).join());
  check('DCI memory is little-endian', m.dci[DCI_ZONE_CONFIG] === 8 && m.dci[DCI_ZONE_CONFIG + 5] === 4);
  dciWrite(DCI_RANGING_MODE, Uint8Array.from([0, 1, 0, 3, 0, 0, 0, 0]));

  // Ranging sessions. The output list as the ULD builds it: fixed entries whose sizes follow
  // the zone count (and targets per zone), the frame size the ULD reads summed its way.
  const session = ({ across, targets, enables0, seconds, hz, beamsAt, label }) => {
    const zones = across * across;
    dciWrite(DCI_ZONE_CONFIG, Uint8Array.from([across, across, 0, 0, 8 / across, 8 / across, 0, 0]));
    dciWrite(DCI_FREQ_HZ, Uint8Array.from([0, hz, 0, 0]));
    const one = targets === 1;
    const list = [
      0x0000000d, 0x54b400c0, 0x54c00040,
      (0x54d0 << 16) | (zones << 4) | 4,
      (0x55d0 << 16) | (zones << 4) | 4,
      ((one ? 0xdb84 : 0x57d0) << 16) | (zones << 4) | 1,
      ((one ? 0xdbc4 : 0x5890) << 16) | ((zones * targets) << 4) | 4,
      ((one ? 0xdec4 : 0x6490) << 16) | ((zones * targets) << 4) | 2,
      ((one ? 0xdf44 : 0x6690) << 16) | ((zones * targets) << 4) | 2,
      ((one ? 0xe044 : 0x6a90) << 16) | ((zones * targets) << 4) | 1,
      ((one ? 0xe084 : 0x6b90) << 16) | ((zones * targets) << 4) | 1,
      (one ? 0xd85808c0 : 0xcc5008c0),
    ];
    let size = 24;
    list.forEach((w, i) => {
      if (!((enables0 >>> i) & 1)) return;
      size += 4 + blockHeader(w >>> 0).bytes;
    });
    dciWrite(DCI_OUTPUT_LIST, u32s(...list));
    dciWrite(DCI_OUTPUT_CONFIG, u32s(size, list.length + 1));
    dciWrite(DCI_OUTPUT_ENABLES, u32s(enables0, 0, 0, 0xc0000000));
    wr(UI_LAST_WORD, [0x00, CMD_START, 0x00, 0x00]);
    check(`${label}: start done`, pollUi(1, CMD_DONE));
    const info = dciRead(DCI_RANGE_INFO, 12);
    const agreed = info && new DataView(info.native.buffer).getUint16(8, true) === size;
    check(`${label}: frame size agreed`, agreed, `${size}`);

    let streamCount = 255;
    let decoded = 0;
    let matched = 0;
    let corrupted = 0;
    const t0 = now;
    const beamCallsBefore = beamCalls;
    while (now - t0 < seconds * 1e9) {
      wait(5);
      beams = beamsAt(decoded);
      // check_data_ready's test.
      const s = rd(0, 4);
      const fresh = s[0] !== streamCount && s[0] !== 255;
      if (!fresh || s[1] !== 0x05 || (s[2] & 0x05) !== 0x05 || (s[3] & 0x10) !== 0x10) continue;
      const raw = rd(0, size);
      streamCount = raw[0];
      const f = swapWords(Uint8Array.from(raw));
      const dv = new DataView(f.buffer);
      const out = {};
      for (let i = 16; i < size; i += 4) {
        const h = blockHeader(dv.getUint32(i, true));
        if (OUTPUTS.has(h.idx)) out[OUTPUTS.get(h.idx)] = { at: i + 4, ...h };
        i += h.bytes;
      }
      if (dv.getUint16(8, false) !== dv.getUint16(size - 4, false)) {
        corrupted++;
        continue;
      }
      decoded++;
      // Decode as the ULD, reduce as drivers::depth::reduce (the middle rows).
      const zoneOf = (z) => z * targets;
      const columnOf = (beam) => Math.floor(((7 - beam) * across) / 8);
      const got = [];
      for (let b = 0; b < 8; b++) {
        const col = columnOf(b);
        let best = null;
        for (const row of [across / 2 - 1, across / 2]) {
          const z = row * across + col;
          const nb = out.nb_targets ? dv.getUint8(out.nb_targets.at + z) : 1;
          const status = nb === 0 ? 255 : dv.getUint8(out.status.at + zoneOf(z));
          const mm = Math.trunc(dv.getInt16(out.distance.at + 2 * zoneOf(z), true) / 4);
          if (![5, 6, 9].includes(status) || mm <= 0) continue;
          best = best === null ? mm : Math.min(best, mm);
        }
        got.push(best);
      }
      // What the beams sent should give: the nearest in range of the beams sharing a column.
      const sent = beamsAt(decoded - 1);
      const inRange = (mm) => typeof mm === 'number' && mm > 0 && mm <= MAX_RANGE_MM;
      const want = sent.map((_, b) => {
        const same = sent.filter((mm, k) => columnOf(k) === columnOf(b) && inRange(mm)).map(Math.round);
        return same.length ? Math.min(...same) : null;
      });
      if (got.join() === want.join()) matched++;
      else console.error(`${label}: frame ${decoded} gave ${got.join()} for ${want.join()}`);
      if (decoded === 3) m.corruptNextFrames(1);
    }
    const read = decoded + corrupted;
    check(`${label}: frame rate`, Math.abs(read - hz * seconds) <= 1, `${read} in ${seconds} s`);
    check(`${label}: every frame matched its beams`, decoded > 0 && matched === decoded, `${matched}/${decoded}`);
    check(`${label}: corrupted frame detected`, corrupted === 1);
    check(`${label}: one readBeams call per frame read`, beamCalls - beamCallsBefore === read);
    return decoded;
  };
  const pattern = (k) => [300 + k, null, 4500, 1200, 4000, 50, 2500.4, 999];
  const all = 0x7ff; // START .. target status, as the ULD enables them by default
  session({ across: 8, targets: 1, enables0: all, seconds: 1, hz: 15, beamsAt: pattern, label: '8x8' });

  // Stop: the MCU stop handshake, then no more frames.
  wr(PAGE_SELECT, [0]);
  wr(REG_MCU_STOP_KEY, [0x16]);
  wr(REG_MCU_STOP, [0x01]);
  check('MCU stopped', poll(REG_GO2_STATUS0, 0, 0x80, 0x80) && rd(REG_GO2_STATUS1, 1)[0] === 0x84);
  wr(REG_MCU_STOP, [0x00]);
  wr(REG_MCU_STOP_KEY, [0x00]);
  wr(REG_POWER, [0x04]);
  wr(PAGE_SELECT, [2]);
  const framesAtStop = m.frames;
  wait(500);
  check('no frames after stop', m.frames === framesAtStop);

  // Other output configurations: 4x4 at 60 Hz, two targets per zone with motion and no
  // ambient, reflectance or target count.
  const reversed = (k) => pattern(k).reverse();
  session({ across: 4, targets: 1, enables0: all, seconds: 0.5, hz: 60, beamsAt: reversed, label: '4x4' });
  const fewer = (all & ~(8 | 32 | 512)) | 2048; // no ambient, target count, reflectance; motion
  session({ across: 8, targets: 2, enables0: fewer, seconds: 1, hz: 10, beamsAt: pattern, label: '8x8 two targets' });

  check('no unexpected bus traffic', m.errors === 0, JSON.stringify(m.error_messages));

  // LPn low drops the firmware: commands go unanswered until the next upload.
  m.powerDown();
  m.powerUp();
  wait(10);
  wr(PAGE_SELECT, [2]);
  wr(UI_LAST_WORD, [0x00, CMD_START, 0x00, 0x00]);
  check('no firmware after LPn cycle', rd(UI_STATUS, 4)[1] !== CMD_DONE && m.errors === 1);

  const failed = checks.filter(([, ok]) => !ok).length;
  console.log(`vl53l5cx model self-test: ${checks.length - failed} passed, ${failed} failed`);
  return failed === 0;
}

if (process.argv[1] && fileURLToPath(import.meta.url) === process.argv[1]) {
  if (process.argv.includes('--self-test')) process.exit(selfTest() ? 0 : 1);
  console.error('usage: node vl53l5cx.mjs --self-test');
  process.exit(2);
}
