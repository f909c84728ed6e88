// Cycles per scan match on core 0. The firmware searches each tick's match in pieces
// after its step, yielding to the other tasks between them, so a match is not one window
// of time: it is the calls into the matcher's entry points (`Matcher::start`, `search`,
// `finish` and the filter's `apply_match`), each timed from entry to return less the
// interrupt cycles inside it, summed from one step's start to the next.

import { round } from './result.mjs';

/// Cycles a match may take (issue 11's target).
const MATCH_BUDGET_CYCLES = 2500000;

/// The entry addresses of the matcher's functions in `elf`, or none for a firmware built
/// without the matcher.
export function findMatcher(elf) {
  const entry = /slam_core.*(7Matcher(5start|6search|6finish)|11apply_match)17h/;
  return elf.symbols
    .filter((s) => s.type === 2 && s.size > 0 && entry.test(s.name))
    .map((s) => s.value & ~1);
}

export class MatchMeter {
  /// `entries`: what `findMatcher` found.
  constructor(entries) {
    this.entries = new Set(entries);
    this.lo = entries.length ? Math.min(...entries) : 1;
    this.hi = entries.length ? Math.max(...entries) + 1 : 0;
    this.ret = -1;
    this.sp = 0;
    this.start = 0;
    this.isr = 0;
    this.tick = 0;
    /// Each tick's match cycles, for the ticks that matched.
    this.cycles = [];
  }

  /// Before core 0 executes the instruction at `pc`.
  before(pc, core) {
    if (this.ret >= 0 || pc < this.lo || pc >= this.hi || !this.entries.has(pc)) return;
    this.ret = core.LR & ~1;
    this.sp = core.SP;
    this.start = core.cycles;
    this.isr = 0;
  }

  /// After core 0 executed the instruction at `pc`, which started at `cyclesBefore`.
  after(core, cyclesBefore) {
    if (this.ret < 0) return;
    if (core.IPSR !== 0) {
      this.isr += core.cycles - cyclesBefore;
      return;
    }
    if (core.PC === this.ret && core.SP >= this.sp) {
      this.tick += core.cycles - this.start - this.isr;
      this.ret = -1;
    }
  }

  /// A step begins: the match before it, if any, is complete.
  stepStarted() {
    if (this.tick > 0) this.cycles.push(this.tick);
    this.tick = 0;
  }

  /// The core stopped (a reset): a call in progress never returns.
  abandon() {
    this.ret = -1;
    this.tick = 0;
  }

  /// The result's match figures.
  summary() {
    this.stepStarted();
    const sorted = [...this.cycles].sort((x, y) => x - y);
    const pick = (q) => (sorted.length ? sorted[Math.min(sorted.length - 1, Math.floor(q * sorted.length))] : null);
    const total = sorted.reduce((a, c) => a + c, 0);
    return {
      matches: sorted.length,
      match_cycles_median: pick(0.5),
      match_cycles_p99: pick(0.99),
      match_cycles_max: sorted.length ? sorted[sorted.length - 1] : null,
      match_cycles_mean: sorted.length ? round(total / sorted.length, 0) : null,
      match_cycles_over_budget: sorted.filter((c) => c > MATCH_BUDGET_CYCLES).length,
    };
  }
}
