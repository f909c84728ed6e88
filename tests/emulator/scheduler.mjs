// Both cores side by side under one simulation clock. Each core has its own time, and the
// core that is behind runs its next instruction; the clock (timers, device models)
// follows the slower of the cores that are awake. A core asleep (WFE/WFI) follows the
// clock, and with both asleep the clock jumps to the next alarm.

/// Runs `chip` (from `bootChip`) until `endNs` of simulated time, a HardFault or
/// breakpoint, a watchdog reset (stop reason `WATCHDOG_RESET`: the caller boots the chip
/// again), both cores asleep with nothing pending, or `maxWallS` seconds of wall time
/// (0: no limit). `meter` measures the step on core 0, `matchMeter` the scan matches, `rtt` is drained as the run goes,
/// `pcSamples` (or null) samples core 0's PC. `hang` (or null) is asked before each of
/// core 0's instructions: `hang(asleep, inStep)` true stops core 0 for good (a hung core:
/// no instruction, no interrupt; its peripherals and core 1 run on). Returns
/// `{ stopReason, instructions, core1Instructions, wallS, hungAtNs }`.
export function runBothCores({ chip, endNs, meter, matchMeter, rtt, pcSamples, hardFaultPc, maxWallS, hang = null }) {
  const { clock, rp, core: c0, core1 } = chip;
  // Core 0 as the loop sees it: hung, it sleeps and never wakes.
  let hungAtNs = null;
  const core = {
    get waiting() { return hungAtNs !== null || c0.waiting; },
  };
  let stopReason = null;
  rp.onBreak = (code) => { stopReason = `breakpoint/udf ${code} at PC 0x${c0.PC.toString(16)}`; };
  let asleepWithNothing = false;
  const wallStart = process.hrtime.bigint();
  let instr = 0;
  let cycleNs = 1e9 / rp.clkSys;
  const c1 = core1.core;
  let instr1 = 0;
  let t0 = 0, t1 = 0;
  const c1Awake = () => core1.launched && !c1.waiting;
  while (clock.nanos < endNs && !stopReason) {
    if (chip.watchdogFired()) { stopReason = WATCHDOG_RESET; break; }
    if (hang && hungAtNs === null && hang(c0.waiting, meter.open)) {
      hungAtNs = clock.nanos;
      meter.abandon();
      matchMeter.abandon();
    }
    if (core.waiting) {
      meter.close();
      if (!c1Awake()) {
        rtt.drain();
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
      if ((++instr1 & 0xffff) === 0) rtt.drain();
      const until = core.waiting ? t1 : Math.min(t0, t1);
      if (until > clock.nanos) clock.tick(until - clock.nanos);
      continue;
    }
    if (t0 < clock.nanos) t0 = clock.nanos;
    const pc = c0.PC;
    const inside = meter.before(pc, c0);
    matchMeter.before(pc, c0);
    if (pc === hardFaultPc) { stopReason = 'HardFault'; break; }
    if (pcSamples) pcSamples.sample(instr, pc);
    const before = c0.cycles;
    const c = c0.executeInstruction();
    if (meter.open) meter.after(pc, c0, before, inside);
    matchMeter.after(c0, before);
    t0 += c * cycleNs;
    const until = c1Awake() ? Math.min(t0, t1) : t0;
    if (until > clock.nanos) clock.tick(until - clock.nanos);
    if ((++instr & 0xffff) === 0) {
      rtt.drain();
      cycleNs = 1e9 / rp.clkSys;
      if (maxWallS && (instr & 0xfffff) === 0) {
        const wall = Number(process.hrtime.bigint() - wallStart) / 1e9;
        if (wall > maxWallS) { stopReason = `wall-clock limit ${maxWallS} s`; break; }
      }
    }
  }
  if (stopReason === WATCHDOG_RESET) {
    meter.abandon();
    matchMeter.abandon();
  } else meter.close();
  rtt.drain();
  return {
    stopReason: stopReason || (asleepWithNothing ? 'core asleep with no alarm pending' : 'time'),
    instructions: instr,
    core1Instructions: instr1,
    wallS: Number(process.hrtime.bigint() - wallStart) / 1e9,
    hungAtNs,
  };
}

/// The stop reason of a run the watchdog ended by resetting the chip.
export const WATCHDOG_RESET = 'watchdog reset';
