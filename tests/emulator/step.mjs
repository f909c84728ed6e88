// Cycles per SLAM step: `core.cycles` across `Slam::step` on core 0, whether the step is
// its own function or inlined into the SLAM task; and the filter's share of them, by the
// source file each instruction came from (`findFilterCode`).

import { spawnSync, execFileSync } from 'node:child_process';
import { round } from './result.mjs';

/// Cycles a step may take for the map, the pose and the filter (issue 10's target).
const STEP_BUDGET_CYCLES = 40000;
/// Cycles per microsecond at the nominal 125 MHz.
const CYCLES_PER_US = 125;

/// Where to measure Slam::step. A real function symbol if the step was not inlined
/// (entry to return); otherwise the inlined copy's address ranges from DWARF (first to
/// last instruction inside them per tick). Needs `llvm-dwarfdump` for the second case.
export function findStep(elfPath, elf) {
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

/// Where the filter's code lies: the instructions whose DWARF line-table row names a file
/// under `src/estimator/` (slam-core's filter, inlined or not). Returns
/// `{ classify(pc), method }`: `classify` gives 'filter', 'project' (any other file of
/// ours) or 'library' (Rust's `core`, compiler builtins, registry crates). Null when
/// `llvm-dwarfdump` is missing.
export function findFilterCode(elfPath) {
  const tool = ['llvm-dwarfdump', 'llvm-dwarfdump-22', 'llvm-dwarfdump-14'].find(
    (t) => spawnSync(t, ['--version'], { stdio: 'ignore' }).status === 0,
  );
  if (!tool) return null;
  const out = execFileSync(tool, ['--debug-line', elfPath], { maxBuffer: 1 << 30 }).toString();
  // Rows as [address, kind]: kind 0 library, 1 project, 2 filter, -1 end of a sequence.
  const rows = [];
  let dirs = [];
  let files = [];
  let pending = null;
  const kindOf = (path) => {
    if (/(^|\/)library\/|\/rustc\/|\.cargo\/registry\//.test(path)) return 0;
    return /(^|\/)src\/estimator\//.test(path) ? 2 : 1;
  };
  for (const line of out.split('\n')) {
    let m;
    if (line.startsWith('debug_line[')) { dirs = []; files = []; continue; }
    if ((m = /^include_directories\[\s*(\d+)\] = "(.*)"/.exec(line))) { dirs[Number(m[1])] = m[2]; continue; }
    if ((m = /^file_names\[\s*(\d+)\]:/.exec(line))) { pending = { i: Number(m[1]) }; continue; }
    if (pending && (m = /^\s+name: "(.*)"/.exec(line))) { pending.name = m[1]; continue; }
    if (pending && (m = /^\s+dir_index: (\d+)/.exec(line))) {
      const dir = dirs[Number(m[1])];
      files[pending.i] = kindOf(dir ? `${dir}/${pending.name || ''}` : pending.name || '');
      pending = null;
      continue;
    }
    if ((m = /^0x([0-9a-f]+)\s+\d+\s+\d+\s+(\d+)\s.*?(end_sequence)?\s*$/.exec(line))) {
      rows.push([parseInt(m[1], 16), m[3] ? -1 : files[Number(m[2])] ?? 1]);
    }
  }
  rows.sort((a, b) => a[0] - b[0]);
  const addr = rows.map((r) => r[0]);
  const kind = rows.map((r) => r[1]);
  const names = ['library', 'project', 'filter'];
  const cache = new Map();
  return {
    method: `by source file: src/estimator/ and the library code it calls (${tool} --debug-line)`,
    filterRows: kind.filter((k) => k === 2).length,
    classify(pc) {
      let k = cache.get(pc);
      if (k !== undefined) return k;
      let a = 0, b = addr.length - 1, at = -1;
      while (a <= b) {
        const mid = (a + b) >> 1;
        if (addr[mid] <= pc) { at = mid; a = mid + 1; } else b = mid - 1;
      }
      k = at < 0 || kind[at] < 0 ? 'library' : names[kind[at]];
      cache.set(pc, k);
      return k;
    },
  };
}

/// Measures each step as a window of core 0's cycles: opened at the step's first
/// instruction, closed at the function's return (a real function) or when core 0 next
/// sleeps (inlined: the window ends at the last instruction seen inside the step's
/// ranges). Cycles spent in interrupt handlers inside the window are not the step's.
export class StepMeter {
  /// `step`: what `findStep` found. `onStart()`: called as each step begins, before its
  /// first instruction runs; `onAbandon()` when one never finishes. `profile`: a `functionProfiler`, or null. `filter`: what
  /// `findFilterCode` found, or null: each instruction of the step is the filter's when
  /// it comes from the filter's files, or from library code (builtins, `core`) reached
  /// from them; an instruction from any other file of ours ends the filter's part.
  constructor(step, { onStart, onAbandon = () => {}, profile, filter = null }) {
    this.step = step;
    this.isFunction = step.method === 'function';
    this.ranges = step.ranges || [];
    // The address span to test first: the function's entry, the inlined ranges' hull, or
    // an empty span when there is nothing to measure.
    this.lo = step.method === 'inlined-ranges' ? step.lo : this.isFunction ? step.entry : 1;
    this.hi = step.method === 'inlined-ranges' ? step.hi : this.isFunction ? step.entry + 2 : 0;
    this.onStart = onStart;
    this.onAbandon = onAbandon;
    this.profile = profile;
    this.open = false;
    this.start = 0;
    this.end = 0;
    this.isr = 0;
    this.isrAtEnd = 0;
    this.fnReturn = -1;
    this.fnSp = 0;
    /// Each step's cycles, and the interrupt cycles left out of each.
    this.cycles = [];
    this.isrCycles = [];
    this.filter = filter;
    this.inFilter = false;
    this.filterNow = 0;
    this.filterAtEnd = 0;
    /// Each step's cycles in the filter.
    this.filterCycles = [];
  }

  inRanges(pc) {
    const ranges = this.ranges;
    for (let i = 0; i < ranges.length; i++) if (pc >= ranges[i][0] && pc < ranges[i][1]) return true;
    return false;
  }

  openWindow(core) {
    this.open = true;
    this.start = core.cycles;
    this.isr = 0;
    this.inFilter = false;
    this.filterNow = 0;
    this.filterAtEnd = 0;
    this.onStart();
  }

  /// Before core 0 executes the instruction at `pc`. Returns whether `pc` is inside an
  /// inlined step's ranges (pass it on to `after`).
  before(pc, core) {
    if (pc < this.lo || pc >= this.hi) return false;
    if (this.isFunction) {
      if (this.fnReturn < 0) {
        this.fnReturn = core.LR & ~1;
        this.fnSp = core.SP;
        this.openWindow(core);
      }
      return false;
    }
    if (!this.inRanges(pc)) return false;
    if (!this.open) this.openWindow(core);
    return true;
  }

  /// After core 0 executed the instruction at `pc`, which started at `cyclesBefore`;
  /// only while the window is open.
  after(pc, core, cyclesBefore, inside) {
    if (core.IPSR !== 0) this.isr += core.cycles - cyclesBefore;
    else {
      if (this.profile) this.profile.add(pc, core.cycles - cyclesBefore);
      if (this.filter) {
        const k = this.filter.classify(pc);
        if (k !== 'library') this.inFilter = k === 'filter';
        if (this.inFilter) this.filterNow += core.cycles - cyclesBefore;
      }
    }
    if (inside) {
      this.end = core.cycles;
      this.isrAtEnd = this.isr;
      this.filterAtEnd = this.filterNow;
      if (this.profile) this.profile.mark();
    }
    if (this.fnReturn >= 0 && core.PC === this.fnReturn && core.SP >= this.fnSp && core.IPSR === 0) {
      this.end = core.cycles;
      this.isrAtEnd = this.isr;
      this.filterAtEnd = this.filterNow;
      this.fnReturn = -1;
      this.close();
    }
  }

  /// Drops the step in progress, if any, unmeasured: the core stopped inside it (a hang,
  /// a reset) and it never finished. `onAbandon()` is called if there was one.
  abandon() {
    this.fnReturn = -1;
    if (!this.open) return;
    this.open = false;
    this.onAbandon();
  }

  /// Ends the step in progress, if any.
  close() {
    if (!this.open) return;
    this.open = false;
    this.cycles.push(this.end - this.start - this.isrAtEnd);
    this.filterCycles.push(this.filterAtEnd);
    if (this.profile) this.profile.commit();
    this.isrCycles.push(this.isrAtEnd);
  }

  /// The result's step figures, in its key order.
  summary() {
    const step = this.step;
    const sorted = [...this.cycles].sort((x, y) => x - y);
    const pick = (q) => (sorted.length ? sorted[Math.min(sorted.length - 1, Math.floor(q * sorted.length))] : null);
    const max = sorted.length ? sorted[sorted.length - 1] : null;
    return {
      ticks_seen: this.cycles.length,
      step_measure: step.method === 'none' ? step.reason : `${step.method}: ${step.symbol}`,
      step_cycles_min: sorted.length ? sorted[0] : null,
      step_cycles_median: pick(0.5),
      step_cycles_p99: pick(0.99),
      step_cycles_max: max,
      step_cycles_over_budget: sorted.filter((c) => c > STEP_BUDGET_CYCLES).length,
      step_us_max_at_125mhz: sorted.length ? round(max / CYCLES_PER_US, 1) : null,
      step_isr_cycles_excluded_max: this.isrCycles.length ? Math.max(...this.isrCycles) : 0,
      // The five costliest steps, each as "tick N: C cycles" (N counts from 0).
      step_cycles_costliest: this.cycles
        .map((c, i) => [c, i])
        .sort((x, y) => y[0] - x[0])
        .slice(0, 5)
        .map(([c, i]) => `tick ${i}: ${c} cycles`),
      ...this.filterSummary(),
    };
  }

  /// The filter's part of the steps: its cycles per step (median, p99, max), its share of
  /// all step cycles, and its cycles in the costliest step.
  filterSummary() {
    if (!this.filter) return { filter_measure: 'llvm-dwarfdump is missing: not measured' };
    const sorted = [...this.filterCycles].sort((x, y) => x - y);
    const pick = (q) => (sorted.length ? sorted[Math.min(sorted.length - 1, Math.floor(q * sorted.length))] : null);
    const total = this.cycles.reduce((a, c) => a + c, 0);
    const filterTotal = this.filterCycles.reduce((a, c) => a + c, 0);
    let worst = -1;
    this.cycles.forEach((c, i) => { if (worst < 0 || c > this.cycles[worst]) worst = i; });
    return {
      filter_measure: this.filter.method,
      filter_cycles_median: pick(0.5),
      filter_cycles_p99: pick(0.99),
      filter_cycles_max: sorted.length ? sorted[sorted.length - 1] : null,
      filter_share_pct: total > 0 ? round((100 * filterTotal) / total, 1) : null,
      filter_cycles_in_worst_step: worst >= 0 ? this.filterCycles[worst] : null,
    };
  }
}
