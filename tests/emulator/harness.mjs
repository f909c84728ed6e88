#!/usr/bin/env node
// BugBot's real RP2040 firmware in rp2040js 1.4.1, wired to the simulated world.
//
// What it does, in order:
// - loads the firmware's flat image (`.bin`, from 0x10000000) into flash and starts the
//   core from the vector table at 0x10000100 (boot2 and the boot ROM are skipped);
// - covers the rp2040js gaps the firmware runs into (I2C interrupt mask, UART DMA control,
//   RX DMA request and TX interrupt, SPI mode), each patch saying what the real chip does;
// - runs both cores (core 1 is added by core1.mjs: rp2040js has one) under a
//   `SimulationClock`: the core that is behind executes its next instruction and the clock
//   follows the slower awake core; with both asleep (WFE/WFI) it jumps to the next alarm;
// - drains the defmt RTT up-channel from SRAM at the `_SEGGER_RTT` symbol into a file
//   (`cargo xtask emulate` decodes it against the ELF), and captures UART1 TX (telemetry)
//   into another (`host-sim view` decodes it);
// - models the devices: PMW3901 flow (SPI0, CS GP17), ICM-42688-P gyro (I2C1 @ 0x68),
//   the VL53L5CX (I2C0 @ 0x29, vl53l5cx.mjs: answers ST's ULD, firmware upload and all), the
//   camera co-processor's frames on UART0 RX (every 100 ms), and reads the motor PWM
//   slices back as wheel duties;
// - asks `host-sim serve` (JSON lines over two FIFOs, synchronously) to move the world to
//   the emulator's time before every sensor read;
// - measures `core.cycles` per SLAM step (Slam::step, inlined or not: see `findStep`).
//
// Usage: node harness.mjs --bin FW.bin --elf FW.elf --scenario FILE [--seconds N]
//          [--seed N] [--host-sim BIN | --no-world] [--telemetry FILE] [--defmt FILE]
//          [--truth FILE]
//          [--fault NAME@T+S]... [--max-wall S] [--json] [--quiet]
//        node harness.mjs --self-test

import { spawn, spawnSync, execFileSync } from 'node:child_process';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { fileURLToPath } from 'node:url';

// The package's `exports` map hides its subpaths, so import by path (EMULATOR.md).
import { RP2040 } from './node_modules/rp2040js/dist/esm/rp2040.js';
import { SimulationClock } from './node_modules/rp2040js/dist/esm/clock/simulation-clock.js';
import { addCore1 } from './core1.mjs';
import { Vl53l5cxModel } from './vl53l5cx.mjs';

const HERE = path.dirname(fileURLToPath(import.meta.url));
const REPO = path.resolve(HERE, '..', '..');

const FLASH_BASE = 0x10000000;
const SRAM_BASE = 0x20000000;
const VECTOR_TABLE = 0x10000100;
/// The RP2040's nominal system clock, hertz: the load figure's denominator.
const NOMINAL_CLK_HZ = 125e6;

// ---------------------------------------------------------------------------------------
// Command line

function parseArgs(argv) {
  const a = {
    bin: null,
    elf: null,
    scenario: path.join(REPO, 'host-sim/scenarios/seed-mat.toml'),
    seconds: 10,
    seed: 1,
    hostSim: null,
    noWorld: false,
    telemetry: null,
    defmt: null,
    truth: null,
    faults: [],
    maxWall: 0,
    json: false,
    quiet: false,
    selfTest: false,
  };
  for (let i = 0; i < argv.length; i++) {
    const k = argv[i];
    const v = () => {
      if (i + 1 >= argv.length) throw new Error(`${k} needs a value`);
      return argv[++i];
    };
    switch (k) {
      case '--bin': a.bin = v(); break;
      case '--elf': a.elf = v(); break;
      case '--scenario': a.scenario = v(); break;
      case '--seconds': a.seconds = Number(v()); break;
      case '--seed': a.seed = Number(v()); break;
      case '--host-sim': a.hostSim = v(); break;
      case '--no-world': a.noWorld = true; break;
      case '--telemetry': a.telemetry = v(); break;
      case '--defmt': a.defmt = v(); break;
      case '--truth': a.truth = v(); break;
      case '--fault': a.faults.push(parseFault(v())); break;
      case '--max-wall': a.maxWall = Number(v()); break;
      case '--json': a.json = true; break;
      case '--quiet': a.quiet = true; break;
      case '--self-test': a.selfTest = true; break;
      default: throw new Error(`unknown argument ${k}`);
    }
  }
  if (!a.selfTest && !a.elf) throw new Error('--elf is required (--bin is optional)');
  if (!(a.seconds > 0)) throw new Error('--seconds must be positive');
  return a;
}

const FAULT_KINDS = ['depth-nack', 'camera-garbage', 'flow-no-surface', 'gyro-nack'];

/// `NAME@T+S`: fault NAME from S simulated seconds after reset on (`NAME@S` too);
/// `NAME@T+S/D`: the same, ending D seconds later (the sensor recovers).
function parseFault(text) {
  const m = /^([a-z-]+)@(?:T\+)?([0-9.]+)s?(?:\/([0-9.]+)s?)?$/.exec(text);
  if (!m || !FAULT_KINDS.includes(m[1])) {
    throw new Error(
      `bad --fault ${text}: want one of ${FAULT_KINDS.join(', ')} as NAME@T+SECONDS[/DURATION]`,
    );
  }
  const at_s = Number(m[2]);
  const until_s = m[3] === undefined ? Infinity : at_s + Number(m[3]);
  return { kind: m[1], at_s, until_s, events: 0 };
}

// ---------------------------------------------------------------------------------------
// ELF: symbol table (for _SEGGER_RTT and the step function) in plain JS

function readElf(file) {
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
  // Loadable segments by load (physical) address: the flash image when no .bin is given.
  const segments = [];
  const phoff = b.readUInt32LE(0x1c);
  const phentsize = b.readUInt16LE(0x2a);
  const phnum = b.readUInt16LE(0x2c);
  for (let i = 0; i < phnum; i++) {
    const o = phoff + i * phentsize;
    if (b.readUInt32LE(o) !== 1) continue; // PT_LOAD
    const offset = b.readUInt32LE(o + 4);
    const paddr = b.readUInt32LE(o + 12);
    const filesz = b.readUInt32LE(o + 16);
    if (filesz) segments.push({ paddr, data: b.subarray(offset, offset + filesz) });
  }
  const symbols = [];
  for (const s of sections) {
    if (s.type !== 2) continue; // SHT_SYMTAB
    const strtab = sections[s.link];
    for (let o = s.offset; o + 16 <= s.offset + s.size; o += 16) {
      const nameOff = b.readUInt32LE(o);
      let end = strtab.offset + nameOff;
      while (b[end] !== 0) end++;
      symbols.push({
        name: b.toString('latin1', strtab.offset + nameOff, end),
        value: b.readUInt32LE(o + 4),
        size: b.readUInt32LE(o + 8),
        type: b[o + 12] & 0xf, // 1 object, 2 func
      });
    }
  }
  return { symbols, segments };
}

/// The flash contents from 0x10000000, gaps erased (0xFF), as `cargo xtask firmware`
/// writes the `.bin`.
function flashImage(elf) {
  const inFlash = elf.segments.filter((s) => s.paddr >= FLASH_BASE && s.paddr < FLASH_BASE + 0x1000000);
  const end = Math.max(...inFlash.map((s) => s.paddr - FLASH_BASE + s.data.length));
  const image = Buffer.alloc(end, 0xff);
  for (const s of inFlash) s.data.copy(image, s.paddr - FLASH_BASE);
  return image;
}

/// Where to measure Slam::step. A real function symbol if the step was not inlined
/// (entry to return); otherwise the inlined copy's address ranges from DWARF (first to
/// last instruction inside them per tick). Needs `llvm-dwarfdump` for the second case.
function findStep(elfPath, elf) {
  const fn = elf.symbols.find(
    (s) => s.type === 2 && /slam_core.*Slam.*4step17h/.test(s.name) && s.size > 0,
  );
  if (fn) {
    return { method: 'function', symbol: fn.name, entry: fn.value & ~1, ranges: null };
  }
  const tool = ['llvm-dwarfdump', 'llvm-dwarfdump-22', 'llvm-dwarfdump-14'].find(
    (t) => spawnSync(t, ['--version'], { stdio: 'ignore' }).status === 0,
  );
  if (!tool) return { method: 'none', reason: 'Slam::step is inlined and llvm-dwarfdump is missing' };
  const out = execFileSync(tool, ['--debug-info', elfPath], { maxBuffer: 1 << 30 }).toString();
  const lines = out.split('\n');
  for (let i = 0; i < lines.length; i++) {
    if (!/DW_TAG_inlined_subroutine/.test(lines[i])) continue;
    const origin = lines[i + 1] || '';
    if (!/DW_AT_abstract_origin.*slam_core4slam.*Slam\$LT\$.*\$GT\$4step17h/.test(origin)) continue;
    const ranges = [];
    let callLine = null;
    for (let j = i + 2; j < Math.min(lines.length, i + 80); j++) {
      const l = lines[j];
      let m;
      if ((m = /\[0x([0-9a-f]+), 0x([0-9a-f]+)\)/.exec(l))) ranges.push([parseInt(m[1], 16), parseInt(m[2], 16)]);
      else if ((m = /DW_AT_low_pc\s*\(0x([0-9a-f]+)\)/.exec(l))) ranges.push([parseInt(m[1], 16), null]);
      else if ((m = /DW_AT_high_pc\s*\(0x([0-9a-f]+)\)/.exec(l)) && ranges.length) ranges[ranges.length - 1][1] = parseInt(m[1], 16);
      if ((m = /DW_AT_call_line\s*\((\d+)\)/.exec(l))) callLine = Number(m[1]);
      if (/DW_AT_call_column/.test(l) || /^0x[0-9a-f]+:/.test(l.trim())) break;
    }
    const good = ranges.filter((r) => r[1] !== null);
    if (good.length) {
      return {
        method: 'inlined-ranges',
        symbol: 'slam_core::slam::Slam::step (inlined into slam_task, call line ' + callLine + ')',
        ranges: good,
        lo: Math.min(...good.map((r) => r[0])),
        hi: Math.max(...good.map((r) => r[1])),
      };
    }
  }
  return { method: 'none', reason: 'no Slam::step symbol and no inlined copy in DWARF' };
}

// ---------------------------------------------------------------------------------------
// Camera frames: COBS + CRC-16/CCITT-FALSE, as drivers/src/camera_link documents

function crc16CcittFalse(bytes) {
  let crc = 0xffff;
  for (const b of bytes) {
    crc ^= b << 8;
    for (let i = 0; i < 8; i++) crc = crc & 0x8000 ? ((crc << 1) ^ 0x1021) & 0xffff : (crc << 1) & 0xffff;
  }
  return crc;
}

function cobsEncode(bytes) {
  const out = [0];
  let codeAt = 0;
  let code = 1;
  for (const b of bytes) {
    if (b === 0) {
      out[codeAt] = code;
      codeAt = out.length;
      out.push(0);
      code = 1;
    } else {
      out.push(b);
      code++;
      if (code === 0xff) {
        out[codeAt] = code;
        codeAt = out.length;
        out.push(0);
        code = 1;
      }
    }
  }
  out[codeAt] = code;
  return out;
}

/// One camera frame on the wire (COBS, then the 0x00 delimiter).
function cameraFrame(counter, tags) {
  const body = [1, counter & 0xff, (counter >> 8) & 0xff, Math.min(tags.length, 8)];
  for (const t of tags.slice(0, 8)) {
    const cx = Math.max(0, Math.min(32000, Math.round(t.cx_px * 100)));
    const cy = 12000; // host-sim reports no y; the tags hang at the camera's height
    const d = Math.max(0, Math.min(0xffff, Math.round(t.distance_mm)));
    body.push(t.id & 0xff, (t.id >> 8) & 0xff, cx & 0xff, cx >> 8, cy & 0xff, cy >> 8, d & 0xff, d >> 8);
  }
  const crc = crc16CcittFalse(body);
  body.push(crc & 0xff, crc >> 8);
  return [...cobsEncode(body), 0];
}

function selfTest() {
  // The fixture of drivers/tests/camera_link.rs: tag 5 at (160, 120) px, 1500 mm; tag 256
  // at (0, 240) px, 0 mm; counter 0x0102; CRC 0x1B95.
  const FRAME = [0x01, 0x02, 0x01, 0x02, 0x05, 0x00, 0x80, 0x3e, 0xe0, 0x2e, 0xdc, 0x05, 0x00, 0x01, 0x00, 0x00, 0xc0, 0x5d, 0x00, 0x00];
  const FRAME_COBS = [0x06, 0x01, 0x02, 0x01, 0x02, 0x05, 0x07, 0x80, 0x3e, 0xe0, 0x2e, 0xdc, 0x05, 0x02, 0x01, 0x01, 0x03, 0xc0, 0x5d, 0x01, 0x03, 0x95, 0x1b];
  const checks = [];
  checks.push(['crc check value', crc16CcittFalse([...Buffer.from('123456789')]) === 0x29b1]);
  checks.push(['fixture crc', crc16CcittFalse(FRAME) === 0x1b95]);
  const crc = crc16CcittFalse(FRAME);
  checks.push(['fixture cobs', JSON.stringify(cobsEncode([...FRAME, crc & 0xff, crc >> 8])) === JSON.stringify(FRAME_COBS)]);
  const built = cameraFrame(0x0102, [{ id: 5, cx_px: 160, distance_mm: 1500 }]);
  checks.push(['frame ends in one delimiter', built.indexOf(0) === built.length - 1]);
  checks.push(['fault parse', parseFault('depth-nack@T+3').at_s === 3]);
  checks.push(['fault duration', parseFault('flow-no-surface@T+5/3').until_s === 8]);
  let ok = true;
  for (const [name, pass] of checks) {
    console.log(`${pass ? 'ok  ' : 'FAIL'} ${name}`);
    ok &&= pass;
  }
  process.exit(ok ? 0 : 1);
}

// ---------------------------------------------------------------------------------------
// The world: `host-sim serve` over two FIFOs, synchronous request/reply

class HostWorld {
  constructor(bin, scenario, seed, log) {
    this.dir = fs.mkdtempSync(path.join(os.tmpdir(), 'bugbot-emu-'));
    this.toSim = path.join(this.dir, 'to-sim');
    this.fromSim = path.join(this.dir, 'from-sim');
    execFileSync('mkfifo', [this.toSim, this.fromSim]);
    // The shell opens both FIFOs before exec; opening our ends below unblocks it. Using
    // FIFOs instead of pipes lets the emulator loop block on each reply, so the world is
    // read at exactly the simulated instant the firmware asks.
    this.child = spawn(
      'sh',
      ['-c', 'exec "$0" "$@" <"$TO_SIM" >"$FROM_SIM"', bin, 'serve', scenario, '--seed', String(seed)],
      { stdio: ['ignore', 'ignore', 'inherit'], env: { ...process.env, TO_SIM: this.toSim, FROM_SIM: this.fromSim } },
    );
    this.out = fs.openSync(this.toSim, 'w');
    this.in = fs.openSync(this.fromSim, 'r');
    this.pending = Buffer.alloc(0);
    this.requests = 0;
    this.t_s = 0;
    this.log = log;
  }

  request(obj) {
    fs.writeSync(this.out, JSON.stringify(obj) + '\n');
    this.requests++;
    const chunk = Buffer.alloc(65536);
    for (;;) {
      const nl = this.pending.indexOf(10);
      if (nl >= 0) {
        const line = this.pending.subarray(0, nl).toString();
        this.pending = this.pending.subarray(nl + 1);
        const reply = JSON.parse(line);
        if (reply.error) throw new Error(`host-sim: ${reply.error} (request ${JSON.stringify(obj)})`);
        return reply;
      }
      const n = fs.readSync(this.in, chunk, 0, chunk.length, null);
      if (n === 0) throw new Error('host-sim serve closed its output (is `serve` in host-sim\'s CLI?)');
      this.pending = Buffer.concat([this.pending, chunk.subarray(0, n)]);
    }
  }

  advance(t_s, left, right) {
    if (t_s <= this.t_s) return null;
    this.t_s = t_s;
    return this.request({ cmd: 'advance', t_s, left, right });
  }
  flow() { return this.request({ cmd: 'flow' }); }
  gyro() { return this.request({ cmd: 'gyro' }); }
  depth() { return this.request({ cmd: 'depth' }); }
  tags() { return this.request({ cmd: 'tags' }); }
  truth() { return this.request({ cmd: 'truth' }); }

  close() {
    try { fs.closeSync(this.out); } catch {}
    try { fs.closeSync(this.in); } catch {}
    try { this.child.kill(); } catch {}
    fs.rmSync(this.dir, { recursive: true, force: true });
  }
}

/// No world: the robot stands on a good surface in front of nothing. Lets the firmware
/// boot and tick without host-sim (plumbing tests, or before `serve` exists).
class StillWorld {
  constructor() { this.requests = 0; this.t_s = 0; this.n = 0; }
  advance(t_s) { this.t_s = Math.max(this.t_s, t_s); return null; }
  flow() { return { forward_counts: 0, right_counts: 0, squal: 120 }; }
  // Alternating +-1 count of noise: the firmware's bias calibration wants a little spread.
  gyro() { this.n++; return { rate_mdps: this.n & 1 ? 30 : -30 }; }
  depth() { return { ranges_mm: Array(8).fill(null) }; }
  tags() { return { tags: [] }; }
  truth() { return null; }
  close() {}
}

// ---------------------------------------------------------------------------------------
// The emulator

function main() {
  const args = parseArgs(process.argv.slice(2));
  if (args.selfTest) return selfTest();
  const say = (...m) => { if (!args.quiet) console.error('[harness]', ...m); };

  const elf = readElf(args.elf);
  const rttSym = elf.symbols.find((s) => s.name === '_SEGGER_RTT');
  if (!rttSym) throw new Error('no _SEGGER_RTT symbol in the ELF: is defmt-rtt linked?');
  const step = findStep(args.elf, elf);
  say(`step measurement: ${step.method} ${step.symbol || step.reason || ''}`);

  const clock = new SimulationClock(NOMINAL_CLK_HZ);
  const rp = new RP2040(clock);
  const core = rp.core;
  const image = args.bin ? fs.readFileSync(args.bin) : flashImage(elf);
  rp.flash.set(image, 0);
  core.VTOR = VECTOR_TABLE;
  core.SP = rp.readUint32(VECTOR_TABLE);
  core.PC = rp.readUint32(VECTOR_TABLE + 4) & ~1;
  say(`loaded ${image.length} bytes; SP=0x${(core.SP >>> 0).toString(16)} PC=0x${core.PC.toString(16)}`);

  // Core 1 (see core1.mjs): a second core on the same bus, its FIFOs and boot ROM.
  const core1 = addCore1(rp);

  // rp2040js logs SEV and does nothing else. On the RP2040 SEV sets the event register of
  // both cores, so a WFE falls through or wakes; embassy's thread-mode pender relies on
  // that (a task woken from thread mode or from the other core would otherwise sleep until
  // some unrelated interrupt). The logger hook does it; other messages are counted, once
  // per text, for the report.
  const emuMessages = new Map();
  const note = (level) => (component, message) => {
    const key = `${level} [${component}] ${message}`;
    emuMessages.set(key, (emuMessages.get(key) || 0) + 1);
  };
  rp.logger = {
    debug() {},
    info(component, message) {
      if (message === 'SEV') core1.sev();
      else note('info')(component, message);
    },
    warn: note('warn'),
    error: note('error'),
  };

  let stopReason = null;
  rp.onBreak = (code) => { stopReason = `breakpoint/udf ${code} at PC 0x${core.PC.toString(16)}`; };

  // Scheduling helper: run `fn` `ns` nanoseconds of simulated time from now.
  const later = (ns, fn) => clock.createAlarm(fn).schedule(Math.max(0, ns));
  const now_s = () => clock.nanos / 1e9;
  const faultOn = (kind) =>
    args.faults.find((f) => f.kind === kind && now_s() >= f.at_s && now_s() < f.until_s);

  // ---- World
  let world;
  if (args.noWorld) {
    world = new StillWorld();
  } else {
    const bin = args.hostSim || path.join(REPO, 'target/release/host-sim');
    if (!fs.existsSync(bin)) throw new Error(`no host-sim at ${bin}: build it or pass --no-world`);
    world = new HostWorld(bin, args.scenario, args.seed, say);
  }

  // ---- Motors: PWM slices 5 (left, GP10/11) and 6 (right, GP12/13) read back as duty.
  // DRV8833: IN1 PWM with IN2 low drives forward, IN2 PWM with IN1 low reverse (fast decay).
  const pwmDuty = (slice) => {
    const ch = rp.pwm.channels[slice];
    if (!(ch.csr & 1)) return 0; // slice disabled: outputs low, coast
    const period = (ch.top & 0xffff) + 1;
    const a = Math.min(ch.cc & 0xffff, period) / period;
    const b = Math.min((ch.cc >>> 16) & 0xffff, period) / period;
    return a - b;
  };
  // rp2040js simulates every PWM edge with clock alarms: two slices at 20 kHz cost about
  // 120 000 callbacks per simulated second and made the emulator slower than real time.
  // Nothing here watches the pins (the DRV8833 is not emulated), so the edge alarms are
  // switched off and the duty is read from CC/TOP. Cost of the shortcut: the wrap
  // interrupt and DREQ never fire (the firmware uses neither) and a CC/TOP write counts
  // at once instead of at the next wrap (50 us later on the chip).
  for (const ch of rp.pwm.channels) {
    ch.alarmA.enable = false;
    ch.alarmB.enable = false;
    ch.alarmBottom.enable = false;
  }
  const duties = { left: 0, right: 0, maxAbs: 0 };
  const advanceWorld = () => {
    duties.left = pwmDuty(5);
    duties.right = pwmDuty(6);
    duties.maxAbs = Math.max(duties.maxAbs, Math.abs(duties.left), Math.abs(duties.right));
    world.advance(now_s(), duties.left, duties.right);
  };

  // ---- defmt RTT up-channel 0, drained from SRAM. Layout (SEGGER RTT): id[16],
  // max_up u32, max_down u32, then per up buffer: name, buf, size, write, read, flags.
  const rttBytes = [];
  const rttChan = rttSym.value + 24;
  const drainRtt = () => {
    const size = rp.readUint32(rttChan + 8);
    if (!size) return; // .data not copied yet
    const buf = rp.readUint32(rttChan + 4);
    const write = rp.readUint32(rttChan + 12);
    let read = rp.readUint32(rttChan + 16);
    if (write === read || write >= size || read >= size) return;
    while (read !== write) {
      rttBytes.push(rp.sram[buf - SRAM_BASE + read]);
      read = read + 1 === size ? 0 : read + 1;
    }
    // Advance the read pointer, or defmt-rtt drops data once its buffer is full.
    rp.sramView.setUint32(rttChan + 16 - SRAM_BASE, read, true);
  };

  // ---- UART patches (both UARTs: the firmware uses BufferedUart on each).
  const telemetry = [];
  const uartStats = [{ rx: 0, tx: 0 }, { rx: 0, tx: 0 }];
  for (const n of [0, 1]) patchUart(rp, rp.uart[n], later, (byte) => {
    uartStats[n].tx++;
    if (n === 1) telemetry.push(byte);
  });

  // ---- I2C: interrupt mask patch and device models.
  for (const i2c of rp.i2c) patchI2c(i2c);
  const imu = new Icm42688Model(() => {
    if (faultOn('gyro-nack')) return null;
    advanceWorld();
    return world.gyro().rate_mdps;
  }, () => clock.nanos);
  const imuBus = attachI2cBus(rp.i2c[1], later, { 0x68: imu }, () => (faultOn('gyro-nack') ? [0x68] : []));
  // VL53L5CX on I2C0 (0x29), its ULD run by core 1. LPn (GP6) low powers the part down:
  // it stops answering and forgets its firmware; high, or an input (the board pulls LPn
  // up), powers it up.
  const depth = new Vl53l5cxModel({
    readBeams: () => { advanceWorld(); return world.depth(); },
    nowNs: () => clock.nanos,
  });
  rp.gpio[6].addListener((state) => (state === 0 ? depth.powerDown() : depth.powerUp()));
  const depthFault = args.faults.find((f) => f.kind === 'depth-nack');
  const depthBus = attachI2cBus(rp.i2c[0], later, { 0x29: depth }, () => {
    if (!depth.present) return [0x29];
    if (faultOn('depth-nack')) { depthFault.events++; return [0x29]; }
    return [];
  });

  // ---- SPI0: PMW3901.
  const spi = rp.spi[0];
  // rp2040js's `spiMode` getter swaps modes 2 and 3. The real SSP: CPOL = SSPCR0.SPO
  // (bit 6), CPHA = SSPCR0.SPH (bit 7), mode = CPOL * 2 + CPHA.
  Object.defineProperty(spi, 'spiMode', {
    get() { return ((this.control0 >> 6) & 1) * 2 + ((this.control0 >> 7) & 1); },
  });
  const flowFault = args.faults.find((f) => f.kind === 'flow-no-surface');
  const flow = new Pmw3901Model(() => {
    advanceWorld();
    const r = world.flow();
    if (faultOn('flow-no-surface')) {
      flowFault.events++;
      return { forward_counts: 0, right_counts: 0, squal: 5, dark: true };
    }
    return r;
  });
  const cs = rp.gpio[17];
  cs.addListener((v) => { if (v === 1) flow.deselect(); else if (v === 0) flow.select(); });
  spi.onTransmit = (value) => {
    // A byte takes 8 SCK periods; completing it later keeps DMA reads longer than the
    // 8-entry RX FIFO from overrunning (an instant device would).
    const hz = spi.clockFrequency || 2e6;
    const selected = cs.value === 0;
    const modeOk = spi.spiMode === 3;
    if (selected && !modeOk) flow.modeErrors++;
    const rx = selected && modeOk ? flow.transfer(value) : 0xff;
    later((8 * 1e9) / hz, () => spi.completeTransmit(rx));
  };

  // ---- UART0 RX: camera co-processor frames every 100 ms, built from `tags`.
  const camFault = args.faults.find((f) => f.kind === 'camera-garbage');
  let camCounter = 0;
  const cam = { frames: 0, garbage: 0, bytes: 0, tagsSent: 0 };
  const rxQueue = [];
  let rxBusy = false;
  const uart0 = rp.uart[0];
  const feedNext = () => {
    if (!rxQueue.length) { rxBusy = false; return; }
    rxBusy = true;
    const byteNs = (10 * 1e9) / (uart0.baudRate || 115200);
    later(byteNs, () => {
      // The real PL011 drops the byte (overrun) when its 32-entry FIFO is full.
      if (uart0.enabled && uart0.rxEnabled && !uart0.rxFIFO.full) {
        uart0.feedByte(rxQueue.shift());
        uartStats[0].rx++;
      } else {
        rxQueue.shift();
      }
      feedNext();
    });
  };
  const cameraTick = () => {
    advanceWorld();
    const tags = world.tags().tags || [];
    let bytes = cameraFrame(camCounter++, tags);
    if (faultOn('camera-garbage')) {
      camFault.events++;
      cam.garbage++;
      // Line noise: random bytes, then a frame with a corrupted body (bad CRC).
      const noise = Array.from({ length: 12 }, () => (Math.random() * 256) | 0);
      bytes = [...noise, 0, ...bytes];
      bytes[bytes.length - 4] ^= 0x5a;
    } else {
      cam.frames++;
      cam.tagsSent += tags.length;
    }
    cam.bytes += bytes.length;
    rxQueue.push(...bytes);
    if (!rxBusy) feedNext();
    later(100e6, cameraTick);
  };
  later(100e6, cameraTick);

  // ---- Step measurement.
  const stepCycles = [];
  const stepIsrCycles = [];
  let winOpen = false, winStart = 0, winEnd = 0, winIsr = 0, winIsrAtEnd = 0;
  const ranges = step.ranges || [];
  const inStep = (pc) => {
    for (let i = 0; i < ranges.length; i++) if (pc >= ranges[i][0] && pc < ranges[i][1]) return true;
    return false;
  };
  // The world's true pose as each step starts (one JSON line per step, `--truth`), for
  // scoring the firmware's pose tick by tick: the step estimates the pose at this instant.
  const truthLines = [];
  const recordTruth = () => {
    if (!args.truth || args.noWorld) return;
    advanceWorld();
    truthLines.push(JSON.stringify(world.truth()));
  };
  const closeWindow = () => {
    if (!winOpen) return;
    winOpen = false;
    // Interrupts taken between the step's first and last instruction are not the step's.
    stepCycles.push(winEnd - winStart - winIsrAtEnd);
    if (stepProfile) stepProfile.commit();
    stepIsrCycles.push(winIsrAtEnd);
  };
  const lo = step.method === 'inlined-ranges' ? step.lo : step.method === 'function' ? step.entry : 1;
  const hi = step.method === 'inlined-ranges' ? step.hi : step.method === 'function' ? step.entry + 2 : 0;
  let fnReturn = -1, fnSp = 0;

  // ---- Main loop.
  const endNs = args.seconds * 1e9;
  const wallStart = process.hrtime.bigint();
  let instr = 0;
  let cycleNs = 1e9 / rp.clkSys;
  const hardFault = elf.symbols.find((s) => s.name === 'HardFault');
  const hardFaultPc = hardFault ? hardFault.value & ~1 : -1;
  // BUGBOT_EMU_PC_SAMPLES=1: where the core spends its time (for a firmware that spins).
  const pcSamples = process.env.BUGBOT_EMU_PC_SAMPLES ? new Map() : null;
  // BUGBOT_EMU_STEP_PROFILE=1: the step's cycles by function (where a slow step spends them).
  const stepProfile = process.env.BUGBOT_EMU_STEP_PROFILE ? functionProfiler(elf) : null;
  let asleepWithNothing = false;
  // Two cores run side by side: each has its own time, and the core that is behind runs
  // its next instruction; the clock (timers, device models) follows the slower of the
  // cores that are awake. A core asleep (WFE/WFI) follows the clock.
  const c1 = core1.core;
  let instr1 = 0;
  let t0 = 0, t1 = 0;
  const c1Awake = () => core1.launched && !c1.waiting;
  while (clock.nanos < endNs && !stopReason) {
    if (core.waiting) {
      closeWindow();
      if (!c1Awake()) {
        drainRtt();
        const next = clock.nanosToNextAlarm;
        if (!clock.nextAlarm) { asleepWithNothing = true; break; }
        clock.tick(Math.min(Math.max(next, 0), endNs - clock.nanos));
        continue;
      }
    }
    if (c1Awake() && (core.waiting || t1 < t0)) {
      if (t1 < clock.nanos) t1 = clock.nanos;
      if (c1.PC === hardFaultPc) { stopReason = 'HardFault on core 1'; break; }
      t1 += c1.executeInstruction() * cycleNs;
      if ((++instr1 & 0xffff) === 0) drainRtt();
      const until = core.waiting ? t1 : Math.min(t0, t1);
      if (until > clock.nanos) clock.tick(until - clock.nanos);
      continue;
    }
    if (t0 < clock.nanos) t0 = clock.nanos;
    const pc = core.PC;
    let inside = false;
    if (pc >= lo && pc < hi) {
      if (step.method === 'function') {
        if (fnReturn < 0) { fnReturn = core.LR & ~1; fnSp = core.SP; winOpen = true; winStart = core.cycles; winIsr = 0; recordTruth(); }
      } else if (inStep(pc)) {
        inside = true;
        if (!winOpen) { winOpen = true; winStart = core.cycles; winIsr = 0; recordTruth(); }
      }
    }
    if (pc === hardFaultPc) { stopReason = 'HardFault'; break; }
    if (pcSamples && (instr & 0x3ff) === 0) pcSamples.set(pc, (pcSamples.get(pc) || 0) + 1);
    const before = core.cycles;
    const c = core.executeInstruction();
    if (winOpen) {
      if (core.IPSR !== 0) winIsr += core.cycles - before;
      else if (stepProfile) stepProfile.add(pc, core.cycles - before);
      if (inside) { winEnd = core.cycles; winIsrAtEnd = winIsr; if (stepProfile) stepProfile.mark(); }
      if (fnReturn >= 0 && core.PC === fnReturn && core.SP >= fnSp && core.IPSR === 0) {
        winEnd = core.cycles; winIsrAtEnd = winIsr; fnReturn = -1; closeWindow();
      }
    }
    t0 += c * cycleNs;
    const until = c1Awake() ? Math.min(t0, t1) : t0;
    if (until > clock.nanos) clock.tick(until - clock.nanos);
    if ((++instr & 0xffff) === 0) {
      drainRtt();
      cycleNs = 1e9 / rp.clkSys;
      if (args.maxWall && (instr & 0xfffff) === 0) {
        const wall = Number(process.hrtime.bigint() - wallStart) / 1e9;
        if (wall > args.maxWall) { stopReason = `wall-clock limit ${args.maxWall} s`; break; }
      }
    }
  }
  closeWindow();
  drainRtt();
  const wallS = Number(process.hrtime.bigint() - wallStart) / 1e9;
  const simS = clock.nanos / 1e9;

  let truth = null;
  try { advanceWorld(); truth = world.truth(); } catch (e) { say(`truth: ${e.message}`); }
  world.close();

  // ---- Outputs.
  if (args.telemetry) fs.writeFileSync(args.telemetry, Buffer.from(telemetry));
  if (args.truth) fs.writeFileSync(args.truth, truthLines.map((l) => `${l}\n`).join(''));
  const defmtFile = args.defmt || (args.telemetry ? args.telemetry.replace(/(\.bin)?$/, '.defmt') : null);
  if (defmtFile) fs.writeFileSync(defmtFile, Buffer.from(rttBytes));

  const STEP_BUDGET_CYCLES = 20000;
  const sorted = [...stepCycles].sort((x, y) => x - y);
  const pick = (q) => (sorted.length ? sorted[Math.min(sorted.length - 1, Math.floor(q * sorted.length))] : null);
  const result = {
    sim_seconds: round(simS, 3),
    wall_seconds: round(wallS, 3),
    sim_per_wall: round(simS / wallS, 2),
    stop_reason: stopReason || (asleepWithNothing ? 'core asleep with no alarm pending' : 'time'),
    instructions: instr,
    cycles: core.cycles,
    cpu_load_pct: round((100 * core.cycles) / (simS * NOMINAL_CLK_HZ), 2),
    clk_sys_hz: rp.clkSys,
    ticks_seen: stepCycles.length,
    step_measure: step.method === 'none' ? step.reason : `${step.method}: ${step.symbol}`,
    step_cycles_min: sorted.length ? sorted[0] : null,
    step_cycles_median: pick(0.5),
    step_cycles_p99: pick(0.99),
    step_cycles_max: sorted.length ? sorted[sorted.length - 1] : null,
    // Steps over the 20,000-cycle budget (0.16 ms at 125 MHz) for the map and pose update.
    step_cycles_over_budget: sorted.filter((c) => c > STEP_BUDGET_CYCLES).length,
    step_us_max_at_125mhz: sorted.length ? round(sorted[sorted.length - 1] / 125, 1) : null,
    step_isr_cycles_excluded_max: stepIsrCycles.length ? Math.max(...stepIsrCycles) : 0,
    defmt_bytes: rttBytes.length,
    telemetry_bytes: telemetry.length,
    world: args.noWorld ? 'still (no host-sim)' : 'host-sim serve',
    world_requests: world.requests,
    max_wheel_duty: round(duties.maxAbs, 3),
    truth,
    devices: {
      flow: { reads: flow.bursts, register_reads: flow.regReads, writes: flow.writes, resets: flow.resets, spi_mode_errors: flow.modeErrors },
      imu: { samples: imu.samples, resets: imu.resets, nacks: imuBus.nacks },
      depth: { transactions: depthBus.transactions, nacks: depthBus.nacks, ...depth.stats() },
      camera: cam,
      uart0_rx_bytes: uartStats[0].rx,
      uart_tx_overflows: [rp.uart[0].txOverflows || 0, rp.uart[1].txOverflows || 0],
      core1: core1.launched
        ? { launched: true, instructions: instr1, cycles: core1.core.cycles, load_pct: round((100 * core1.core.cycles) / (simS * NOMINAL_CLK_HZ), 2), fifo_words: core1.fifoWords }
        : { launched: false, launch_words: core1.launchWords },
    },
    faults_injected: args.faults.map((f) => ({
      fault: `${f.kind}@T+${f.at_s}${Number.isFinite(f.until_s) ? `/${f.until_s - f.at_s}` : ''}`,
      events: f.events,
    })),
    emulator_messages: [...emuMessages].slice(0, 20).map(([k, n]) => `${n}x ${k}`),
  };
  if (stepProfile) result.step_profile_worst = stepProfile.worst(process.env.BUGBOT_EMU_STEP_PROFILE === 'pc' ? 4000 : 15);
  if (stepProfile) result.step_profile = stepProfile.top(process.env.BUGBOT_EMU_STEP_PROFILE === 'pc' ? 2000 : 15, stepCycles.length);
  if (pcSamples) {
    result.pc_samples = [...pcSamples].sort((x, y) => y[1] - x[1]).slice(0, 12).map(([pc, n]) => `0x${pc.toString(16)} x${n}`);
  }
  if (args.json) {
    console.log(JSON.stringify(result));
  } else {
    console.log(JSON.stringify(result, null, 2));
  }
}

/// Cycles by the function holding each PC (from the ELF's function symbols).
function functionProfiler(elf) {
  const fns = elf.symbols.filter((s) => s.type === 2 && s.size > 0)
    .map((s) => ({ lo: s.value & ~1, hi: (s.value & ~1) + s.size, name: s.name }))
    .sort((a, b) => a.lo - b.lo);
  const cycles = new Map();
  // This step's samples so far, and how many of them came before its last instruction
  // (the window stays open after it until the core sleeps).
  let pending = [];
  let marked = 0;
  let worst = new Map();
  let worstTotal = 0;
  const find = (pc) => {
    let a = 0, b = fns.length - 1;
    while (a <= b) {
      const m = (a + b) >> 1;
      if (pc < fns[m].lo) b = m - 1;
      else if (pc >= fns[m].hi) a = m + 1;
      else return fns[m].name;
    }
    return `0x${pc.toString(16)}`;
  };
  return {
    add(pc, c) { pending.push(process.env.BUGBOT_EMU_STEP_PROFILE === 'pc' ? `0x${pc.toString(16)}` : find(pc), c); },
    mark() { marked = pending.length; },
    commit() {
      const mine = new Map();
      let total = 0;
      for (let i = 0; i < marked; i += 2) {
        cycles.set(pending[i], (cycles.get(pending[i]) || 0) + pending[i + 1]);
        mine.set(pending[i], (mine.get(pending[i]) || 0) + pending[i + 1]);
        total += pending[i + 1];
      }
      if (total > worstTotal) { worstTotal = total; worst = mine; }
      pending = [];
      marked = 0;
    },
    /// The costliest step's cycles by function.
    worst(n) {
      return [...worst].sort((x, y) => y[1] - x[1]).slice(0, n).map(([f, c]) => `${c} cycles ${f}`);
    },
    top(n, steps) {
      return [...cycles].sort((x, y) => y[1] - x[1]).slice(0, n)
        .map(([f, c]) => `${Math.round(c / Math.max(1, steps))} cycles/step ${f}`);
    },
  };
}

function round(x, n) {
  const f = 10 ** n;
  return Math.round(x * f) / f;
}

// ---------------------------------------------------------------------------------------
// Peripheral patches

/// UART: gives UARTDMACR storage, raises the RX DMA request, and models the TX FIFO so
/// the TX interrupt fires on a transition as on the chip.
function patchUart(rp, uart, later, onByteOut) {
  const UARTDR = 0x0, UARTFR = 0x18, UARTIFLS = 0x34, UARTDMACR = 0x48;
  const TXINTR = 1 << 5;
  const RXDMAE = 1 << 0;
  const TXDMAE = 1 << 1;
  let dmacr = 0;
  let ifls = 0x12;
  const txFifo = [];
  let shifting = false;
  const fifoDepth = () => (uart.fifosEnabled ? 32 : 1);
  // TXIFLSEL: 0 = 1/8, 1 = 1/4, 2 = 1/2, 3 = 3/4, 4 = 7/8 of 32 entries.
  const txLevel = () => [4, 8, 16, 24, 28][ifls & 7] ?? 16;

  // rp2040js sets the TX interrupt on every check, so a TX-masked BufferedUart ISR never
  // stops. The PL011 raises TXRIS only when the TX FIFO level falls through the trigger
  // level (or, FIFOs off, when the holding register empties), and clears it on a write
  // that lifts the level back above it, or through UARTICR.
  uart.checkInterrupts = function () {
    rp.setInterrupt(this.irq, !!(this.interruptStatus & this.interruptMask));
    // The PL011 requests RX DMA while its RX FIFO holds data and UARTDMACR.RXDMAE is set;
    // rp2040js never raises it, so async DMA reads of late bytes time out.
    if (dmacr & RXDMAE && !this.rxFIFO.empty) rp.dma.setDREQ(this.dreq.rx);
    else rp.dma.clearDREQ(this.dreq.rx);
    // rp2040js holds the TX DMA request high whenever the UART is enabled, so a DMA write
    // (the firmware's telemetry UartTx) floods a full FIFO and bytes are lost. The PL011
    // requests TX DMA only with UARTDMACR.TXDMAE set and room in the TX FIFO.
    if (dmacr & TXDMAE && this.enabled && txFifo.length < fifoDepth()) rp.dma.setDREQ(this.dreq.tx);
    else rp.dma.clearDREQ(this.dreq.tx);
  };

  const shiftNext = () => {
    if (!txFifo.length) { shifting = false; return; }
    shifting = true;
    const bits = (uart.wordLength || 8) + 2;
    later((bits * 1e9) / (uart.baudRate || 115200), () => {
      const level = txFifo.length;
      onByteOut(txFifo.shift());
      uart.checkInterrupts(); // room again: the TX DMA request may rise
      const lvl = fifoDepth() === 1 ? 0 : txLevel();
      if ((level > lvl && txFifo.length <= lvl) || txFifo.length === 0) {
        uart.interruptStatus |= TXINTR;
        uart.checkInterrupts();
      }
      shiftNext();
    });
  };

  const origRead = uart.readUint32.bind(uart);
  const origWrite = uart.writeUint32.bind(uart);
  uart.readUint32 = (offset) => {
    switch (offset) {
      // rp2040js reports TX FIFO always empty: the PL011 has TXFF (bit 5), TXFE (bit 7)
      // and BUSY (bit 3) from the real FIFO and shifter.
      case UARTFR: {
        const base = origRead(offset) & ~((1 << 7) | (1 << 5) | (1 << 3));
        return base | (txFifo.length >= fifoDepth() ? 1 << 5 : 0) | (txFifo.length === 0 ? 1 << 7 : 0) |
          (shifting ? 1 << 3 : 0);
      }
      case UARTIFLS: return ifls;
      // Unimplemented in rp2040js (reads 0xFFFFFFFF, so BufferedUart's ISR believes RX
      // DMA is on and returns at once, forever). The PL011 stores TXDMAE/RXDMAE/DMAONERR.
      case UARTDMACR: return dmacr;
      default: return origRead(offset);
    }
  };
  uart.writeUint32 = (offset, value) => {
    switch (offset) {
      case UARTDR:
        if (!uart.enabled || !uart.txEnabled) return;
        if (txFifo.length < fifoDepth()) txFifo.push(value & 0xff);
        else uart.txOverflows = (uart.txOverflows || 0) + 1; // the PL011 drops it too
        uart.checkInterrupts();
        if (txFifo.length > (fifoDepth() === 1 ? 0 : txLevel())) {
          uart.interruptStatus &= ~TXINTR;
          uart.checkInterrupts();
        }
        if (!shifting) shiftNext();
        return;
      case UARTIFLS: ifls = value & 0x3f; return;
      case UARTDMACR: dmacr = value & 0x7; uart.checkInterrupts(); return;
      default: origWrite(offset, value); uart.checkInterrupts();
    }
  };
  // checkInterrupts of rp2040js's UARTIMSC/UARTICR paths now goes through the override.
}

/// I2C: rp2040js ignores writes to IC_INTR_MASK (0x30), so the I2C interrupt never fires
/// and async transfers hang. The DW_apb_i2c stores the mask (13 bits) and drives the
/// interrupt line with RAW_INTR_STAT & INTR_MASK.
///
/// After a transmit abort (a NACK) the DW_apb_i2c flushes its TX FIFO, which leaves it
/// empty, so TX_EMPTY (RAW_INTR_STAT bit 4) is raised at once; rp2040js flushes the FIFO
/// but never raises the flag, and embassy-rp's blocking write, which waits for TX_EMPTY
/// before it looks for the abort, then spins for ever on the first NACK.
function patchI2c(i2c) {
  const TX_EMPTY = 1 << 4;
  const origAbort = i2c.abort.bind(i2c);
  i2c.abort = (reason) => {
    origAbort(reason);
    i2c.setInterrupts(TX_EMPTY);
  };
  const IC_INTR_MASK = 0x30;
  const origWrite = i2c.writeUint32.bind(i2c);
  i2c.writeUint32 = (offset, value) => {
    if (offset === IC_INTR_MASK) {
      i2c.intEnable = value & 0x1fff;
      i2c.checkInterrupts();
      return;
    }
    origWrite(offset, value);
  };
}

/// Routes one I2C block's bus events to the device models by address, completing each
/// step after one bus byte time (9 SCL periods) as a clock-stretching device would.
/// `nacking()` returns addresses that must not answer right now (fault injection).
function attachI2cBus(i2c, later, devices, nacking) {
  const stats = { transactions: 0, nacks: 0 };
  let dev = null;
  const byteNs = () => (9 * 1e9) / 400e3;
  i2c.onStart = () => later(1e9 / 400e3, () => i2c.completeStart());
  i2c.onConnect = (address, mode) => {
    stats.transactions++;
    const d = devices[address];
    const ack = !!d && !nacking().includes(address);
    dev = ack ? d : null;
    if (!ack) stats.nacks++;
    if (dev) dev.connect(mode === 1 ? 'read' : 'write');
    later(byteNs(), () => i2c.completeConnect(ack));
  };
  i2c.onWriteByte = (value) => {
    if (dev) dev.write(value);
    later(byteNs(), () => i2c.completeWrite(!!dev));
  };
  i2c.onReadByte = () => {
    const v = dev ? dev.read() : 0xff;
    later(byteNs(), () => i2c.completeRead(v));
  };
  i2c.onStop = () => {
    if (dev) dev.stop();
    dev = null;
    later(1e9 / 400e3, () => i2c.completeStop());
  };
  return stats;
}

// ---------------------------------------------------------------------------------------
// Device models

/// ICM-42688-P, user bank 0, as drivers/src/imu uses it: WHO_AM_I, soft reset with the
/// reset-done flag, PWR_MGMT0 (gyro on after its start-up time), GYRO_CONFIG0 (full
/// scale), GYRO_DATA_Z1/Z0 big-endian with auto-increment.
class Icm42688Model {
  constructor(sampleMdps, nowNs) {
    this.sampleMdps = sampleMdps;
    this.nowNs = nowNs;
    this.samples = 0;
    this.resets = 0;
    this.reset();
    this.regs[0x2d] = 0x10; // power-on reset also reports reset-done
  }
  reset() {
    this.regs = new Uint8Array(256);
    this.regs[0x75] = 0x47;
    this.regs[0x4f] = 0x06; // GYRO_CONFIG0 reset: 2000 dps, 1 kHz
    this.gyroOnAtNs = Infinity;
    this.ptr = 0;
    this.first = false;
    this.sample = null;
  }
  connect(mode) {
    this.first = mode === 'write';
    if (mode === 'read' && (this.ptr === 0x29 || this.ptr === 0x2a)) this.latchSample();
  }
  latchSample() {
    let counts = -32768; // INVALID_SAMPLE until the gyro has started
    if (this.nowNs() >= this.gyroOnAtNs) {
      const rate = this.sampleMdps();
      if (rate === null) return;
      const lsbPerDps = [16.4, 32.8, 65.5, 131, 262, 524.3, 1048.6, 2097.2][(this.regs[0x4f] >> 5) & 7];
      // The chip's Z axis points out of its top face (right-handed); BugBot's rate is
      // positive clockwise from above, and the driver negates for a face-up chip.
      counts = Math.max(-32767, Math.min(32767, Math.round((-rate * lsbPerDps) / 1000)));
      this.samples++;
    }
    this.regs[0x29] = (counts >> 8) & 0xff;
    this.regs[0x2a] = counts & 0xff;
  }
  write(v) {
    if (this.first) { this.ptr = v; this.first = false; return; }
    const reg = this.ptr++ & 0xff;
    if (reg === 0x11 && v & 1) {
      this.reset();
      this.resets++;
      this.regs[0x2d] = 0x10; // INT_STATUS.RESET_DONE
      return;
    }
    this.regs[reg] = v;
    if (reg === 0x4e) {
      // Gyro low-noise mode (bits 3:2 = 0b11): data valid after the 30 ms start-up.
      this.gyroOnAtNs = ((v >> 2) & 3) === 3 ? this.nowNs() + 30e6 : Infinity;
    }
  }
  read() {
    const reg = this.ptr++ & 0xff;
    const v = this.regs[reg];
    if (reg === 0x2d) this.regs[0x2d] = 0; // INT_STATUS clears on read
    return v;
  }
  stop() {}
}

/// PMW3901 on SPI, as drivers/src/flow uses it: `[addr]` then data for reads,
/// `[addr | 0x80, value]` for writes, chip select framing each transaction. The motion
/// burst (0x16) returns 12 bytes built from the world's flow at the moment it is asked.
class Pmw3901Model {
  constructor(readFlow) {
    this.readFlow = readFlow;
    this.bursts = 0;
    this.regReads = 0;
    this.writes = 0;
    this.resets = 0;
    this.modeErrors = 0;
    this.regs = new Uint8Array(128);
    this.regs[0x00] = 0x49;
    this.regs[0x5f] = 0xb6;
    this.deselect();
  }
  select() { this.addr = null; this.out = []; this.writeReg = null; }
  deselect() { this.addr = null; this.out = []; this.writeReg = null; }
  transfer(mosi) {
    if (this.writeReg !== null) {
      this.writes++;
      if (this.writeReg === 0x3a && mosi === 0x5a) this.resets++;
      this.regs[this.writeReg] = mosi;
      this.writeReg = null;
      return 0;
    }
    if (this.addr === null) {
      this.addr = mosi;
      if (mosi & 0x80) { this.writeReg = mosi & 0x7f; return 0; }
      if (mosi === 0x16) {
        this.bursts++;
        this.out = this.burst();
      } else {
        this.regReads++;
        const v = this.regs[mosi & 0x7f];
        this.out = [v];
        if (mosi === 0x02) this.out = [0x00];
      }
      return 0;
    }
    return this.out.length ? this.out.shift() : 0;
  }
  burst() {
    const f = this.readFlow();
    const clamp = (x) => Math.max(-32768, Math.min(32767, Math.round(x || 0)));
    // Default axis map: delta_x is robot right, delta_y robot forward.
    const dx = clamp(f.right_counts);
    const dy = clamp(f.forward_counts);
    const squal = Math.max(0, Math.min(255, Math.round(f.squal ?? 0)));
    const dark = f.dark || squal < 0x19;
    const motion = dx !== 0 || dy !== 0 ? 0x80 : 0x00;
    return [
      motion, 0x3f, dx & 0xff, (dx >> 8) & 0xff, dy & 0xff, (dy >> 8) & 0xff,
      squal, 0x40, 0x80, 0x10, dark ? 0x1f : 0x01, 0x00,
    ];
  }
}

try {
  main();
} catch (e) {
  console.error(`harness: ${e.message}`);
  process.exit(2);
}
