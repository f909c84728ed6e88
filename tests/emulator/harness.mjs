#!/usr/bin/env node
// BugBot's real RP2040 firmware in rp2040js, wired to the simulated world.
//
// The firmware's flat image runs on both emulated cores (chip.mjs, core1.mjs, the run
// loop in scheduler.mjs), with rp2040js's gaps patched to behave as the chip does
// (patches.mjs). The devices are models answering on the firmware's buses: the PMW3901
// flow sensor on SPI0 (CS GP17), the ICM-42688-P gyro on I2C1 @ 0x68, the VL53L5CX on
// I2C0 @ 0x29 (run by core 1, powered through LPn on GP6), the camera co-processor's
// frames on UART0 RX, and the motor PWM read back as wheel duties (devices/). Before every
// sensor read the world is moved to the emulator's time (world.mjs: `host-sim serve`).
//
// A computer is plugged into the USB port (usb-host.mjs, unless `--no-usb`): it enumerates
// the firmware's device and reads its CDC ACM serial port, the telemetry's second copy.
//
// Out come the telemetry from UART1 TX (`--telemetry`, decoded by `host-sim view`) and
// from USB (`--usb-telemetry`, the bytes the host read from the bulk IN endpoint), the
// raw defmt RTT bytes (`--defmt`, decoded by `cargo xtask emulate` against the ELF), the
// world's true pose at each SLAM step (`--truth`) and one JSON object of figures on
// stdout (result.mjs), cycles per step among them (step.mjs).
//
// `node harness.mjs --help` for the command line; `--self-test` runs the checks of the
// camera framing and the fault parsing, one `ok   NAME` or `FAIL NAME` line each.

import fs from 'node:fs';
import path from 'node:path';
import { fileURLToPath } from 'node:url';

import { USAGE, parseArgs } from './args.mjs';
import { bootChip } from './chip.mjs';
import { readElf, flashImage } from './elf.mjs';
import {
  Faults, HANG_KINDS, selfTests as faultTests, WRONG_FLOW_SCALE, WRONG_GYRO_BIAS_MDPS, WRONG_RANGE_MM,
  WRONG_TAG_PX,
} from './faults.mjs';
import { selfTests as core1Tests } from './core1.mjs';
import { selfTests as dividerTests } from './divider.mjs';
import { patchI2c, patchSpiMode, patchUart, patchUsbDevice, usbDeviceSelfTests } from './patches.mjs';
import { profilersFromEnv, profileResult } from './profile.mjs';
import { buildResult } from './result.mjs';
import { RttDrain } from './rtt.mjs';
import { runBothCores, WATCHDOG_RESET } from './scheduler.mjs';
import { round } from './result.mjs';
import { retainedState } from './retained.mjs';
import { stackMeter } from './stacks.mjs';
import { StepMeter, findStep, findFilterCode } from './step.mjs';
import { MatchMeter, findMatcher } from './match.mjs';
import { UsbHost, selfTests as usbTests } from './usb-host.mjs';
import { openWorld } from './world.mjs';
import { CameraLink, selfTests as cameraTests } from './devices/camera.mjs';
import { attachI2cBus } from './devices/i2c-bus.mjs';
import { ICM42688_ADDRESS, Icm42688Model } from './devices/icm42688.mjs';
import { Motors } from './devices/motors.mjs';
import { Pmw3901Model } from './devices/pmw3901.mjs';
import { VL53L5CX_ADDRESS, Vl53l5cxModel } from './vl53l5cx.mjs';

const REPO = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '..', '..');
/// The flow sensor's chip select and the depth sensor's LPn (power) pin.
const FLOW_CS_PIN = 17;
const DEPTH_LPN_PIN = 6;

function main() {
  const args = parseArgs(process.argv.slice(2), REPO);
  if (args.help) return console.log(USAGE);
  if (args.selfTest) {
    return void selfTest().catch((e) => {
      console.error(`harness: ${e.message}`);
      process.exit(2);
    });
  }
  const say = (...m) => { if (!args.quiet) console.error('[harness]', ...m); };

  const elf = readElf(args.elf);
  const rttSym = elf.symbols.find((s) => s.name === '_SEGGER_RTT');
  if (!rttSym) throw new Error('no _SEGGER_RTT symbol in the ELF: is defmt-rtt linked?');
  const step = findStep(args.elf, elf);
  say(`step measurement: ${step.method} ${step.symbol || step.reason || ''}`);

  const image = args.bin ? fs.readFileSync(args.bin) : flashImage(elf);
  const first = bootChip(image);
  const { clock, nowS } = first;
  say(`loaded ${image.length} bytes; SP=0x${(first.core.SP >>> 0).toString(16)} PC=0x${first.core.PC.toString(16)}`);

  const faults = new Faults(args.faults, nowS);
  const world = openWorld(args, REPO);
  // What is wired to the chip now; a watchdog reset boots a new one (`boot` below).
  let board = null;
  // The world moves to the emulator's time, the wheels at their duties now, before each
  // sensor read.
  const advanceWorld = () => {
    board.motors.read();
    world.advance(nowS(), board.motors.left, board.motors.right);
  };

  // The defmt log is written as it comes, so that xtask can follow the run.
  const defmtFd = args.defmt ? fs.openSync(args.defmt, 'w') : null;
  const rtt = new RttDrain(first.rp, rttSym.value, defmtFd);
  const telemetry = [];
  const usbTelemetry = [];
  // The chip's peripherals patched, the device models and the computer on the USB port
  // wired to it: at power-on, and again after each watchdog reset (the parts outside the
  // RP2040 keep running through it, but their models answer the new chip's buses; each
  // part's firmware start-up takes it from where it is, as on the robot).
  const boot = (chip) => {
    const { rp, later } = chip;
    const motors = new Motors(rp);
    if (board) motors.maxAbs = board.motors.maxAbs;
    board = { chip, motors };
    rtt.rp = rp;
    // Both UARTs run BufferedUart; UART1 TX carries the telemetry.
    patchUart(rp, rp.uart[0], later, () => {});
    patchUart(rp, rp.uart[1], later, (byte) => telemetry.push(byte));
    for (const i2c of rp.i2c) patchI2c(i2c);
    board.devices = attachDevices({ rp, later, clock, faults, world, advanceWorld });
    // The computer on the USB port, and what it read from the serial port.
    board.usbHost = args.noUsb ? null : new UsbHost({
      bus: patchUsbDevice(rp),
      later,
      nowS,
      onSerial: (bytes) => { for (const b of bytes) usbTelemetry.push(b); },
      say,
    });
  };
  boot(first);

  // The world's true pose as each step starts (one JSON line per step, `--truth`), for
  // scoring the firmware's pose tick by tick: the step estimates the pose at this instant.
  // A step that never finishes (a hang, a reset) sends no tick: its line is taken back.
  const truthLines = [];
  // The retained block at the last reset, to compare as the next step begins.
  let atReset = null;
  const recordTruth = () => {
    if (atReset) {
      Object.assign(resets[resets.length - 1], retained.compare(atReset, retained.read(board.chip.rp)));
      atReset = null;
    }
    if (!args.truth || args.noWorld) return;
    advanceWorld();
    truthLines.push(JSON.stringify(world.truth()));
  };
  const dropTruth = () => {
    if (args.truth && !args.noWorld) truthLines.pop();
  };
  const profilers = profilersFromEnv(elf, process.env);
  const filter = step.method === 'none' ? null : findFilterCode(args.elf);
  if (filter) say(`filter measurement: ${filter.method}, ${filter.filterRows} rows in the filter's files`);
  const matchMeter = new MatchMeter(findMatcher(elf));
  const onStart = () => {
    matchMeter.stepStarted();
    recordTruth();
  };
  const meter = new StepMeter(step, { onStart, onAbandon: dropTruth, profile: profilers.stepProfile, filter });
  const hardFault = elf.symbols.find((s) => s.name === 'HardFault');
  // A hang fault stops core 0 once: asleep between ticks, or inside a step.
  const hang = faults.any(HANG_KINDS)
    ? (asleep, inStep) => (asleep && faults.once('core0-hang')) || (inStep && faults.once('step-hang'))
    : null;
  const retained = retainedState(elf);
  const stacks = stackMeter(elf);
  const resets = [];

  let run, truth = null;
  const total = { instructions: 0, core1Instructions: 0, cycles: 0, core1Cycles: 0, wallS: 0 };
  try {
    for (;;) {
      const chip = board.chip;
      run = runBothCores({
        chip,
        endNs: args.seconds * 1e9,
        meter,
        matchMeter,
        rtt,
        pcSamples: profilers.pcSamples,
        hardFaultPc: hardFault ? hardFault.value & ~1 : -1,
        maxWallS: args.maxWall ? args.maxWall - total.wallS : 0,
        hang,
      });
      total.instructions += run.instructions;
      total.core1Instructions += run.core1Instructions;
      total.cycles += chip.core.cycles;
      total.core1Cycles += chip.core1.launched ? chip.core1.core.cycles : 0;
      total.wallS += run.wallS;
      if (run.stopReason !== WATCHDOG_RESET) break;
      if (board.usbHost) board.usbHost.endOfRun();
      const reset = {
        at_s: round(nowS(), 4),
        reason: chip.rp.peripherals[0x40058].reason === 2 ? 'force' : 'timer',
        hung_at_s: run.hungAtNs === null ? null : round(run.hungAtNs / 1e9, 4),
      };
      resets.push(reset);
      atReset = retained ? retained.read(chip.rp) : null;
      say(`watchdog reset at ${reset.at_s} s (core 0 hung at ${reset.hung_at_s} s); booting again with SRAM kept`);
      boot(bootChip(image, chip));
    }
    try { advanceWorld(); truth = world.truth(); } catch (e) { say(`truth: ${e.message}`); }
  } finally {
    world.close();
  }
  run = { ...run, ...total };
  const { chip: lastChip, devices, usbHost, motors } = board;

  if (usbHost) usbHost.endOfRun();
  if (args.telemetry) fs.writeFileSync(args.telemetry, Buffer.from(telemetry));
  if (args.usbTelemetry) fs.writeFileSync(args.usbTelemetry, Buffer.from(usbTelemetry));
  if (args.truth) fs.writeFileSync(args.truth, truthLines.map((l) => `${l}\n`).join(''));
  if (defmtFd !== null) fs.closeSync(defmtFd);

  const result = buildResult({
    args, chip: lastChip, run, meter, matchMeter, rtt, world, motors, truth, devices, faults, resets,
    stacks: stacks.read(lastChip.rp),
    telemetryBytes: telemetry.length,
    usb: usbHost ? usbHost.summary() : 'unplugged (--no-usb)',
    profile: profileResult(profilers, meter.cycles.length),
  });
  console.log(args.json ? JSON.stringify(result) : JSON.stringify(result, null, 2));
}

/// The device models on the firmware's buses, each reading the world at the instant the
/// firmware asks and failing as the injected faults say.
function attachDevices({ rp, later, clock, faults, world, advanceWorld }) {
  // ICM-42688-P gyro on I2C1, the bus to itself. While it does not answer, its sample
  // register keeps the last value (a NACKed read latches nothing).
  const imu = new Icm42688Model(() => {
    if (faults.dropped('gyro')) return null;
    return faults.reading('gyro', () => { advanceWorld(); return world.gyro().rate_mdps; }, {
      garbage: (random) => Math.round((random() * 2 - 1) * 2_000_000),
      wrong: (mdps) => mdps + WRONG_GYRO_BIAS_MDPS,
    });
  }, () => clock.nanos);
  const imuBus = attachI2cBus(rp.i2c[1], later, { [ICM42688_ADDRESS]: imu }, () =>
    faults.silent('gyro') ? [ICM42688_ADDRESS] : []);

  // VL53L5CX on I2C0, its ULD run by core 1. LPn low powers the part down: it stops
  // answering and forgets its firmware; high, or an input (the board pulls LPn up), powers
  // it up.
  const depth = new Vl53l5cxModel({
    readBeams: () => faults.reading('depth', () => { advanceWorld(); return world.depth(); }, {
      garbage: (random) => ({ ranges_mm: Array.from({ length: 8 }, () => Math.round(random() * 4000)) }),
      wrong: (beams) => ({
        ...beams,
        ranges_mm: beams.ranges_mm.map((r) => (r === null ? null : r + WRONG_RANGE_MM)),
      }),
    }),
    nowNs: () => clock.nanos,
  });
  rp.gpio[DEPTH_LPN_PIN].addListener((state) => (state === 0 ? depth.powerDown() : depth.powerUp()));
  const depthBus = attachI2cBus(rp.i2c[0], later, { [VL53L5CX_ADDRESS]: depth }, () => {
    if (!depth.present) return [VL53L5CX_ADDRESS];
    if (faults.silent('depth')) return [VL53L5CX_ADDRESS];
    return [];
  });

  // PMW3901 flow sensor on SPI0. Off, it leaves MISO low; under the no-surface fault it
  // sees nothing: no motion, a low SQUAL and the dark flag.
  const spi = rp.spi[0];
  patchSpiMode(spi);
  const flow = new Pmw3901Model(() => {
    const r = faults.reading('flow', () => { advanceWorld(); return world.flow(); }, {
      garbage: (random) => ({
        forward_counts: Math.round((random() * 2 - 1) * 500),
        right_counts: Math.round((random() * 2 - 1) * 500),
        squal: Math.round(random() * 255),
      }),
      wrong: (f) => ({
        ...f,
        forward_counts: f.forward_counts * WRONG_FLOW_SCALE,
        right_counts: f.right_counts * WRONG_FLOW_SCALE,
      }),
    });
    if (faults.hit('flow-no-surface')) return { forward_counts: 0, right_counts: 0, squal: 5, dark: true };
    return r;
  }, () => faults.silent('flow'));
  flow.attach(spi, rp.gpio[FLOW_CS_PIN], later);

  // The camera co-processor on UART0 RX. Its garbage is line noise on the UART.
  const camera = new CameraLink({
    uart: rp.uart[0],
    later,
    readTags: () => faults.reading('camera', () => { advanceWorld(); return world.tags().tags; }, {
      garbage: () => [],
      wrong: (tags) => tags.map((t) => ({ ...t, cx_px: t.cx_px + WRONG_TAG_PX })),
    }),
    garbage: () => faults.active('camera-garbage'),
    silent: () => faults.silent('camera'),
  });
  camera.start();

  return { imu, imuBus, depth, depthBus, flow, camera };
}

/// Every module's self-tests, one line each; exits 1 if any failed.
async function selfTest() {
  let ok = true;
  const usbDevice = await usbDeviceSelfTests();
  const all = [
    ...cameraTests(), ...faultTests(), ...dividerTests(), ...core1Tests(), ...usbTests(), ...usbDevice,
  ];
  for (const [name, pass] of all) {
    console.log(`${pass ? 'ok  ' : 'FAIL'} ${name}`);
    ok &&= pass;
  }
  process.exit(ok ? 0 : 1);
}

try {
  main();
} catch (e) {
  console.error(`harness: ${e.message}`);
  process.exit(2);
}
