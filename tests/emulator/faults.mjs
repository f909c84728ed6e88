// Fault injection: `--fault SENSOR-KIND@T+S[/D]` turns one sensor bad for a stretch of
// simulated time, so `cargo xtask test` can check that the firmware notices, counts and
// recovers. The sensors and kinds are host-sim's (`host_sim::fault`), acted out on the
// device models' buses:
//
// | kind | depth (I2C) | flow (SPI) | gyro (I2C) | camera (UART) |
// |---|---|---|---|---|
// | off | NACKs | MISO reads 0 | NACKs | silent |
// | stuck | the last ranges again | the last counts again | the last rate again | the last tags again |
// | garbage | random ranges | random counts and SQUAL | random rates | line noise, bad CRC |
// | wrong | ranges 150 mm long | counts x 1.3 | rate 3 dps off | centres 40 px off |
// | slow | readings 300 ms old | the same | the same | the same |
// | intermittent | `off` in half the 100 ms windows | the same | the same | the same |
//
// `depth-nack` and `gyro-nack` are the older names of `depth-off` and `gyro-off`;
// `flow-no-surface` (a dark floor: no motion, low SQUAL) is a flow fault of its own.

/// The sensors, as host-sim names them.
export const SENSORS = ['depth', 'flow', 'gyro', 'camera'];
/// The ways each fails, as host-sim names them.
export const KINDS = ['off', 'stuck', 'garbage', 'wrong', 'slow', 'intermittent'];
/// Names kept from before the matrix, and what they mean now.
const ALIASES = { 'depth-nack': 'depth-off', 'gyro-nack': 'gyro-off' };
/// The hangs of core 0: `core0-hang` stops core 0 at its first sleep (every task waiting,
/// between two SLAM ticks) from S seconds on, `step-hang` inside its first SLAM step from S
/// seconds on. A hang strikes once and lasts until the watchdog resets the chip (a
/// duration is ignored).
export const HANG_KINDS = ['core0-hang', 'step-hang'];
/// Faults that are not one sensor failing one of the common ways.
const EXTRA = ['flow-no-surface', ...HANG_KINDS];
/// Every name `--fault` takes.
export const FAULT_KINDS = [
  ...SENSORS.flatMap((s) => KINDS.map((k) => `${s}-${k}`)), ...EXTRA, ...Object.keys(ALIASES),
];

/// How old a `slow` sensor's readings are, in seconds.
export const SLOW_S = 0.3;
/// A `wrong` depth sensor's range offset, millimetres.
export const WRONG_RANGE_MM = 150;
/// A `wrong` flow sensor's scale.
export const WRONG_FLOW_SCALE = 1.3;
/// A `wrong` gyro's bias jump, millidegrees a second.
export const WRONG_GYRO_BIAS_MDPS = 3000;
/// A `wrong` camera's shift of each tag's centre, pixels.
export const WRONG_TAG_PX = 40;
/// The length of an `intermittent` sensor's windows, seconds.
const WINDOW_S = 0.1;

/// `NAME@T+S`: fault NAME from S simulated seconds after reset on (`NAME@S` too);
/// `NAME@T+S/D`: the same, ending D seconds later (the sensor recovers).
export function parseFault(text) {
  const m = /^([a-z0-9-]+)@(?:T\+)?([0-9.]+)s?(?:\/([0-9.]+)s?)?$/.exec(text);
  if (!m || !FAULT_KINDS.includes(m[1])) {
    throw new Error(
      `bad --fault ${text}: want SENSOR-KIND@T+SECONDS[/DURATION], SENSOR one of ` +
        `${SENSORS.join(', ')} and KIND one of ${KINDS.join(', ')} (or ${[...EXTRA, ...Object.keys(ALIASES)].join(', ')})`,
    );
  }
  const at_s = Number(m[2]);
  const until_s = m[3] === undefined ? Infinity : at_s + Number(m[3]);
  return { name: m[1], kind: ALIASES[m[1]] ?? m[1], at_s, until_s, events: 0 };
}

/// A 32-bit integer hash (lowbias32), for windows and garbage that repeat run to run.
function hash32(x) {
  x = (x ^ (x >>> 16)) >>> 0;
  x = Math.imul(x, 0x7feb352d) >>> 0;
  x = (x ^ (x >>> 15)) >>> 0;
  x = Math.imul(x, 0x846ca68b) >>> 0;
  return (x ^ (x >>> 16)) >>> 0;
}

/// The faults of one run, asked by the device models at the simulated instant they act.
export class Faults {
  /// `faults`: parsed by `parseFault`; `nowS()`: simulated seconds since reset.
  constructor(faults, nowS) {
    this.faults = faults;
    this.nowS = nowS;
    /// Per sensor: the last reading given while no fault was in force, and recent readings.
    this.lastGood = {};
    this.recent = {};
    this.draws = 0;
  }

  /// The fault of `kind` (`SENSOR-KIND`) in force now, if any.
  find(kind) {
    const t = this.nowS();
    return this.faults.find((f) => f.kind === kind && t >= f.at_s && t < f.until_s);
  }

  /// Whether a fault of `kind` is in force now.
  active(kind) {
    return this.find(kind) !== undefined;
  }

  /// `active(kind)`, counting an event if so.
  hit(kind) {
    const f = this.find(kind);
    if (f) f.events++;
    return f !== undefined;
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

  /// The kind of fault `sensor` suffers now (`off`, `stuck`, ...), or null.
  kindOf(sensor) {
    const t = this.nowS();
    const f = this.faults.find((x) => x.kind.startsWith(`${sensor}-`) && t >= x.at_s && t < x.until_s);
    return f ? f.kind.slice(sensor.length + 1) : null;
  }

  /// Whether `sensor` gives no answer now: `off`, or `intermittent` in a dropped window.
  dropped(sensor) {
    const kind = this.kindOf(sensor);
    return kind === 'off' ||
      (kind === 'intermittent' &&
        hash32(Math.floor(this.nowS() / WINDOW_S) * 4 + SENSORS.indexOf(sensor)) % 2 === 1);
  }

  /// `dropped(sensor)`, counting an event if so.
  silent(sensor) {
    return this.dropped(sensor) && this.hit(`${sensor}-${this.kindOf(sensor)}`);
  }

  /// A uniform draw in [0, 1) that repeats run to run.
  random() {
    return hash32(0x9e3779b9 + this.draws++) / 2 ** 32;
  }

  /// What `sensor` reports now, given `read()` for the world's true reading: itself, or
  /// the stuck, garbage, wrong or slow reading its fault makes of it. `garbage(random)`
  /// and `wrong(reading)` are the sensor's own versions of those.
  reading(sensor, read, { garbage, wrong }) {
    const now = this.nowS();
    const fresh = read();
    const recent = (this.recent[sensor] ??= []);
    recent.push([now, fresh]);
    while (recent.length > 1 && recent[1][0] <= now - SLOW_S) recent.shift();
    const kind = this.kindOf(sensor);
    if (kind === null || kind === 'off' || kind === 'intermittent') {
      this.lastGood[sensor] = fresh;
      return fresh;
    }
    this.hit(`${sensor}-${kind}`);
    switch (kind) {
      case 'stuck': return this.lastGood[sensor] ?? fresh;
      case 'garbage': return garbage(() => this.random());
      case 'wrong': return wrong(fresh);
      case 'slow': return recent[0][1];
      default: return fresh;
    }
  }

  /// Each fault as given and the events injected, for the result.
  report() {
    return this.faults.map((f) => ({
      fault: `${f.name}@T+${f.at_s}${Number.isFinite(f.until_s) ? `/${f.until_s - f.at_s}` : ''}`,
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
  let noKind = false;
  try { parseFault('gyro-sideways@3'); } catch { noKind = true; }

  // One sensor through every reading kind: the world's reading is the time in tenths.
  const clock = { now: 0 };
  const run = (name) => {
    const f = new Faults([parseFault(`gyro-${name}@T+1/1`)], () => clock.now);
    const out = [];
    for (let i = 0; i <= 25; i++) {
      clock.now = i / 10;
      out.push(f.reading('gyro', () => i, { garbage: () => -1, wrong: (r) => r + 1000 }));
    }
    return { out, f };
  };
  const stuck = run('stuck').out;
  const slow = run('slow').out;
  const wrong = run('wrong').out;
  const garbage = run('garbage');
  const off = new Faults([parseFault('gyro-nack@T+1/1')], () => clock.now);
  clock.now = 1.5;
  const offNow = off.silent('gyro') && !off.silent('depth');
  const flaky = new Faults([parseFault('depth-intermittent@T+0/10')], () => clock.now);
  let dropped = 0;
  for (let i = 0; i < 100; i++) { clock.now = i / 10; dropped += flaky.silent('depth') ? 1 : 0; }
  const hang = new Faults([parseFault('core0-hang@T+2')], () => t.now);
  t.now = 1;
  const hangEarly = hang.once('core0-hang');
  t.now = 2.5;
  const hangStrikes = hang.once('core0-hang');
  const hangAgain = hang.once('core0-hang');
  return [
    ['fault parse', parseFault('depth-nack@T+3').at_s === 3],
    ['fault duration', parseFault('flow-no-surface@T+5/3').until_s === 8],
    ['fault of no known kind refused', refused && noKind],
    ['fault every sensor and kind named', FAULT_KINDS.length === 29 && parseFault('camera-slow@2').kind === 'camera-slow'],
    ['hang strikes once', !hangEarly && hangStrikes && !hangAgain && hang.any(['core0-hang']) && !faults.any(['core0-hang'])],
    ['fault window', !atFour && atFive && !atEight && faults.faults[0].events === 1],
    ['fault report', JSON.stringify(faults.report()) ===
      '[{"fault":"flow-no-surface@T+5/3","events":1},{"fault":"flow-no-surface@T+9","events":0}]'],
    ['fault stuck holds the last good reading', stuck[12] === 9 && stuck[19] === 9 && stuck[20] === 20],
    ['fault slow gives the reading 0.3 s old', slow[15] === 12 && slow[21] === 21],
    ['fault wrong and garbage', wrong[15] === 1015 && wrong[9] === 9 && garbage.out[15] === -1 && garbage.f.faults[0].events === 10],
    ['fault off silences its sensor only', offNow && off.faults[0].events === 1],
    ['fault intermittent drops some windows, not all', dropped > 25 && dropped < 75],
  ];
}
