// Where the cycles go, for a firmware that is slow or spins. Off unless asked for:
// BUGBOT_EMU_STEP_PROFILE=1 gives the step's cycles by function (`=pc`: by instruction),
// BUGBOT_EMU_PC_SAMPLES=1 samples core 0's PC across the whole run (=N: the N most
// sampled PCs rather than 12).

/// The profilers the environment asks for: `{ stepProfile, pcSamples }`, each null when
/// not asked for.
export function profilersFromEnv(elf, env) {
  const byPc = env.BUGBOT_EMU_STEP_PROFILE === 'pc';
  return {
    stepProfile: env.BUGBOT_EMU_STEP_PROFILE ? functionProfiler(elf, byPc) : null,
    pcSamples: env.BUGBOT_EMU_PC_SAMPLES ? new PcSamples(Math.max(12, Number(env.BUGBOT_EMU_PC_SAMPLES) || 0)) : null,
  };
}

/// The profilers' figures, added to the result under their own keys.
export function profileResult({ stepProfile, pcSamples }, steps) {
  const out = {};
  if (stepProfile) {
    out.step_profile_worst = stepProfile.worst(stepProfile.byPc ? 4000 : 40);
    out.step_profile_second = stepProfile.second(stepProfile.byPc ? 4000 : 40);
    out.step_profile = stepProfile.top(stepProfile.byPc ? 2000 : 40, steps);
  }
  if (pcSamples) out.pc_samples = pcSamples.top(pcSamples.shown);
  return out;
}

/// Cycles by the function holding each PC (from the ELF's function symbols), or by PC.
/// The step meter feeds it: `add` per instruction in the step, `mark` at the step's last
/// instruction so far, `commit` when the step ends.
function functionProfiler(elf, byPc) {
  const fns = elf.symbols.filter((s) => s.type === 2 && s.size > 0)
    .map((s) => ({ lo: s.value & ~1, hi: (s.value & ~1) + s.size, name: s.name }))
    .sort((a, b) => a.lo - b.lo);
  const cycles = new Map();
  // This step's samples so far, and how many of them came before its last instruction
  // (the window stays open after it until the core sleeps).
  let pending = [];
  let marked = 0;
  // The costliest step's cycles by function, and the next costliest's: what sets the
  // worst step apart shows in the difference.
  let worst = new Map();
  let worstTotal = 0;
  let second = new Map();
  let secondTotal = 0;
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
    byPc,
    add(pc, c) { pending.push(byPc ? `0x${pc.toString(16)}` : find(pc), c); },
    mark() { marked = pending.length; },
    commit() {
      const mine = new Map();
      let total = 0;
      for (let i = 0; i < marked; i += 2) {
        cycles.set(pending[i], (cycles.get(pending[i]) || 0) + pending[i + 1]);
        mine.set(pending[i], (mine.get(pending[i]) || 0) + pending[i + 1]);
        total += pending[i + 1];
      }
      if (total > worstTotal) {
        [second, secondTotal] = [worst, worstTotal];
        [worst, worstTotal] = [mine, total];
      } else if (total > secondTotal) {
        [second, secondTotal] = [mine, total];
      }
      pending = [];
      marked = 0;
    },
    /// The costliest step's cycles by function.
    worst(n) { return costliest(worst, n); },
    /// The next costliest step's, likewise.
    second(n) { return costliest(second, n); },
    /// Mean cycles per step by function, the costliest first.
    top(n, steps) {
      return [...cycles].sort((x, y) => y[1] - x[1]).slice(0, n)
        .map(([f, c]) => `${Math.round(c / Math.max(1, steps))} cycles/step ${f}`);
    },
  };
}

/// A step's `n` costliest entries, each as "C cycles WHERE".
function costliest(step, n) {
  return [...step].sort((x, y) => y[1] - x[1]).slice(0, n).map(([f, c]) => `${c} cycles ${f}`);
}

/// Core 0's PC, sampled every 1024th instruction.
class PcSamples {
  /// `shown`: how many of the most sampled PCs the result lists.
  constructor(shown) { this.counts = new Map(); this.shown = shown; }
  /// `instr`: instructions executed so far.
  sample(instr, pc) {
    if ((instr & 0x3ff) === 0) this.counts.set(pc, (this.counts.get(pc) || 0) + 1);
  }
  top(n) {
    return [...this.counts].sort((x, y) => y[1] - x[1]).slice(0, n).map(([pc, k]) => `0x${pc.toString(16)} x${k}`);
  }
}
