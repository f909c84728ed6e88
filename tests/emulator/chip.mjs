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

/// A chip running `image` (flash contents from 0x10000000). Returns `{ clock, rp, core,
/// core1, messages, later, nowS }`: `core` is core 0, `core1` what `addCore1` returns,
/// `messages` rp2040js's log messages counted once per text, `later(ns, fn)` runs `fn`
/// `ns` of simulated time from now, `nowS()` is simulated seconds since reset.
export function bootChip(image) {
  const clock = new SimulationClock(NOMINAL_CLK_HZ);
  const rp = new RP2040(clock);
  const core = rp.core;
  rp.flash.set(image, 0);
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
  const messages = new Map();
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
  return { clock, rp, core, core1, messages, later, nowS };
}
