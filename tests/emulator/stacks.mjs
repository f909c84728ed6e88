// How deep each core's stack went, read from SRAM after the run as a debugger would.
//
// Both stacks start zeroed: core 1's is a zero-initialised static (`CORE1_STACK`, embassy's
// `Stack`, its bytes first), and core 0's lies below the statics (flip-link's layout, from
// `_stack_start` down to `_stack_end`), where nothing but the stack writes. The lowest
// non-zero byte in each is how far down the stack was written: a floor on its depth, as a
// frame whose lowest bytes only ever held zeros reads shallower than it was. A watchdog
// reset keeps SRAM, so the figure covers every boot of the run.

const SRAM_BASE = 0x20000000;

/// `{ read(rp) }` giving `{ core0, core1 }`, each `{ peak_bytes, size_bytes }` (or null
/// when the ELF does not say where that stack lies).
export function stackMeter(elf) {
  const symbol = (test) => elf.symbols.find(test);
  const top = symbol((s) => s.name === '_stack_start');
  const bottom = symbol((s) => s.name === '_stack_end');
  const core1 = symbol((s) => /CORE1_STACK/.test(s.name) && s.size > 0);
  // The stack itself: the symbol is a `StaticCell` holding the 32-byte-aligned `Stack`
  // first and its taken flag after, padded to the next 32.
  const core1Bytes = core1 ? core1.size - 32 : 0;
  const regions = {
    core0: top && bottom && top.value > bottom.value ? { from: bottom.value, to: top.value } : null,
    core1: core1 && core1Bytes > 0 ? { from: core1.value, to: core1.value + core1Bytes } : null,
  };
  return {
    read(rp) {
      const depth = (region) => {
        if (!region) return null;
        const [from, to] = [region.from - SRAM_BASE, region.to - SRAM_BASE];
        let lowest = to;
        for (let a = from; a < to; a += 1) {
          if (rp.sram[a] !== 0) {
            lowest = a;
            break;
          }
        }
        return { peak_bytes: to - lowest, size_bytes: to - from };
      };
      return { core0: depth(regions.core0), core1: depth(regions.core1) };
    },
  };
}
