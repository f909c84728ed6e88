// The emulated RP2040: rp2040js's chip under a simulation clock, with core 1 added and
// the firmware's flash image loaded, started as the boot ROM would leave it.

// The package's `exports` map hides its subpaths, so they are imported by path.
import { RP2040 } from './node_modules/rp2040js/dist/esm/rp2040.js';
import { SimulationClock } from './node_modules/rp2040js/dist/esm/clock/simulation-clock.js';
import { addCore1 } from './core1.mjs';

/// The RP2040's nominal system clock, hertz: the load figures' denominator.
export const NOMINAL_CLK_HZ = 125e6;
/// Where boot2 leaves the vector table (boot2 and the boot ROM are skipped).
const VECTOR_TABLE = 0x10000100;

/// Watchdog register block, and VREG_AND_CHIP_RESET's CHIP_RESET.
const WATCHDOG_BLOCK = 0x40058, TIMER_BLOCK = 0x40054;
const CHIP_RESET_BLOCK = 0x40064, CHIP_RESET = 0x08, HAD_POR = 1 << 8;

/// A chip running `image` (flash contents from 0x10000000). Returns `{ clock, rp, core,
/// core1, messages, later, nowS, watchdogFired }`: `core` is core 0, `core1` what
/// `addCore1` returns, `messages` rp2040js's log messages counted once per text,
/// `later(ns, fn)` runs `fn` `ns` of simulated time from now, `nowS()` is simulated
/// seconds since the first power-on, `watchdogFired()` whether the watchdog has reset
/// the chip (the run loop stops then, and the harness boots it again with `after`).
///
/// `after` (or null, at power-on): the chip this one restarts, after its watchdog fired.
/// rp2040js counts the watchdog down and reports its firing but leaves the reset to its
/// embedder, so it is done here as the RP2040 does it (datasheet 4.7, "Watchdog", and
/// 2.13, "Power-On State Machine"): with the reset triggers embassy-rp selects in
/// PSM_WDSEL, everything but the oscillators restarts, both processors and every
/// peripheral, the watchdog itself included, on the same clock; SRAM is not cleared, the
/// watchdog's REASON says TIMER (or FORCE) and its scratch registers keep their values,
/// and CHIP_RESET keeps the power-on flag of the last chip-level reset. The old chip's
/// pending alarms are dropped: its peripherals and the device models wired to it are gone.
export function bootChip(image, after = null) {
  const clock = after ? after.clock : new SimulationClock(NOMINAL_CLK_HZ);
  if (after) clock.nextAlarm = null;
  const rp = new RP2040(clock);
  const core = rp.core;
  rp.flash.set(image, 0);
  const watchdog = rp.peripherals[WATCHDOG_BLOCK];
  if (after) {
    const old = after.rp.peripherals[WATCHDOG_BLOCK];
    rp.sram.set(after.rp.sram);
    watchdog.scratchData.set(old.scratchData);
    watchdog.reason = old.reason;
    // The TIMER restarts from 0 with the chip; rp2040js's reads the shared clock as it is.
    const timer = rp.peripherals[TIMER_BLOCK];
    const bootNs = clock.nanos;
    timer.clock = {
      get nanos() { return clock.nanos - bootNs; },
      get micros() { return (clock.nanos - bootNs) / 1000; },
      createAlarm: (callback) => clock.createAlarm(callback),
    };
  }
  let fired = false;
  // The chip resets here: the watchdog stops with it. (Left running, rp2040js's periodic
  // alarm finds its counter at 0 and fires again at the same instant, for ever.)
  watchdog.onWatchdogTrigger = () => {
    fired = true;
    watchdog.alarm.enable = false;
    watchdog.timer.enable = false;
  };
  // rp2040js leaves VREG_AND_CHIP_RESET unimplemented (reads 0): CHIP_RESET.HAD_POR says
  // the last chip-level reset was the power-on, which a watchdog reset does not change.
  const chipReset = rp.peripherals[CHIP_RESET_BLOCK];
  const chipResetRead = chipReset.readUint32.bind(chipReset);
  chipReset.readUint32 = (offset) => (offset === CHIP_RESET ? HAD_POR : chipResetRead(offset));
  core.VTOR = VECTOR_TABLE;
  core.SP = rp.readUint32(VECTOR_TABLE);
  core.PC = rp.readUint32(VECTOR_TABLE + 4) & ~1;

  // Core 1 (see core1.mjs): a second core on the same bus, its FIFOs and boot ROM.
  const core1 = addCore1(rp);

  // rp2040js logs SEV and does nothing else. On the RP2040 SEV sets the event register of
  // both cores, so a WFE falls through or wakes; embassy's thread-mode pender relies on
  // that (a task woken from thread mode or from the other core would otherwise sleep until
  // some unrelated interrupt). The logger hook does it; other messages are counted, once
  // per text, for the report.
  const messages = after ? after.messages : new Map();
  const note = (level) => (component, message) => {
    const key = `${level} [${component}] ${message}`;
    messages.set(key, (messages.get(key) || 0) + 1);
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

  const later = (ns, fn) => clock.createAlarm(fn).schedule(Math.max(0, ns));
  const nowS = () => clock.nanos / 1e9;
  return { clock, rp, core, core1, messages, later, nowS, watchdogFired: () => fired };
}
