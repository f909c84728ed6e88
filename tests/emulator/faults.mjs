// Fault injection: `--fault NAME@T+S[/D]` turns a device bad for a stretch of simulated
// time, so `cargo xtask test` can check that the firmware notices, counts and recovers.

/// The faults a device model knows how to inject, and the hangs of core 0: `core0-hang`
/// stops core 0 at its first sleep (every task waiting, between two SLAM ticks) from S
/// seconds on, `step-hang` inside its first SLAM step from S seconds on. A hang strikes
/// once and lasts until the watchdog resets the chip (a duration is ignored).
export const FAULT_KINDS = ['depth-nack', 'camera-garbage', 'flow-no-surface', 'gyro-nack', 'core0-hang', 'step-hang'];

/// The kinds that hang core 0.
export const HANG_KINDS = ['core0-hang', 'step-hang'];

/// `NAME@T+S`: fault NAME from S simulated seconds after reset on (`NAME@S` too);
/// `NAME@T+S/D`: the same, ending D seconds later (the sensor recovers).
export function parseFault(text) {
  const m = /^([a-z0-9-]+)@(?:T\+)?([0-9.]+)s?(?:\/([0-9.]+)s?)?$/.exec(text);
  if (!m || !FAULT_KINDS.includes(m[1])) {
    throw new Error(
      `bad --fault ${text}: want one of ${FAULT_KINDS.join(', ')} as NAME@T+SECONDS[/DURATION]`,
    );
  }
  const at_s = Number(m[2]);
  const until_s = m[3] === undefined ? Infinity : at_s + Number(m[3]);
  return { kind: m[1], at_s, until_s, events: 0 };
}

/// The faults of one run, asked by the device models at the simulated instant they act.
export class Faults {
  /// `faults`: parsed by `parseFault`; `nowS()`: simulated seconds since reset.
  constructor(faults, nowS) {
    this.faults = faults;
    this.nowS = nowS;
  }

  /// Whether a fault of `kind` is in force now.
  active(kind) {
    const t = this.nowS();
    return this.faults.some((f) => f.kind === kind && t >= f.at_s && t < f.until_s);
  }

  /// `active(kind)`, counting an event if so. Events are credited to the first fault of
  /// that kind on the command line.
  hit(kind) {
    if (!this.active(kind)) return false;
    this.faults.find((f) => f.kind === kind).events++;
    return true;
  }

  /// Whether a fault of `kind` is in force now and has not struck yet; if so it strikes
  /// (one event) and never again.
  once(kind) {
    const t = this.nowS();
    const f = this.faults.find((x) => x.kind === kind && t >= x.at_s && t < x.until_s && x.events === 0);
    if (!f) return false;
    f.events++;
    return true;
  }

  /// Whether any fault of one of `kinds` was given.
  any(kinds) {
    return this.faults.some((f) => kinds.includes(f.kind));
  }

  /// Each fault as given and the events injected, for the result.
  report() {
    return this.faults.map((f) => ({
      fault: `${f.kind}@T+${f.at_s}${Number.isFinite(f.until_s) ? `/${f.until_s - f.at_s}` : ''}`,
      events: f.events,
    }));
  }
}

/// `[name, passed]` for `harness.mjs --self-test`.
export function selfTests() {
  const t = { now: 0 };
  const faults = new Faults([parseFault('flow-no-surface@T+5/3'), parseFault('flow-no-surface@9')], () => t.now);
  const atFour = faults.hit('flow-no-surface');
  t.now = 5;
  const atFive = faults.hit('flow-no-surface');
  t.now = 8;
  const atEight = faults.active('flow-no-surface');
  let refused = false;
  try { parseFault('bogus@3'); } catch { refused = true; }
  const hang = new Faults([parseFault('core0-hang@T+2')], () => t.now);
  t.now = 1;
  const hangEarly = hang.once('core0-hang');
  t.now = 2.5;
  const hangStrikes = hang.once('core0-hang');
  const hangAgain = hang.once('core0-hang');
  return [
    ['fault parse', parseFault('depth-nack@T+3').at_s === 3],
    ['fault duration', parseFault('flow-no-surface@T+5/3').until_s === 8],
    ['fault of no known kind refused', refused],
    ['fault window', !atFour && atFive && !atEight && faults.faults[0].events === 1],
    ['hang strikes once', !hangEarly && hangStrikes && !hangAgain && hang.any(['core0-hang']) && !faults.any(['core0-hang'])],
    ['fault report', JSON.stringify(faults.report()) ===
      '[{"fault":"flow-no-surface@T+5/3","events":1},{"fault":"flow-no-surface@T+9","events":0}]'],
  ];
}
