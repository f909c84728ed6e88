// The firmware's retained block (firmware/src/retained.rs), read from SRAM as a debugger
// would: at a watchdog reset, and again as the first SLAM step after it begins, to tell
// whether the firmware took up the map and the state it had or started afresh.

const SRAM_BASE = 0x20000000;
/// The block's header, `u32` words in `repr(C)` order, and where the state starts.
const CLOSED = 12, RESUMES = 20, MAP_AT = 28, MAP_CELLS = 32, ROUTE = 36, STATE = 40;
/// `closed` when the state is whole.
const CLOSED_MAGIC = 0xc105ed00;
// A map cell is one byte of log odds (`slam_core::grid::LogOdds`, `i8`).

/// `{ read(rp), compare(before, after) }` for the block in `elf`, or null when the
/// firmware has none.
export function retainedState(elf) {
  const sym = elf.symbols.find((s) => /retained8RETAINED/.test(s.name) && s.size > STATE);
  if (!sym) return null;
  const base = sym.value - SRAM_BASE;
  return {
    /// What the block holds now: its header, the map's cells and the state's bytes.
    read(rp) {
      const word = (o) => rp.sramView.getUint32(base + o, true);
      const mapAt = word(MAP_AT), mapCells = word(MAP_CELLS);
      const mapOk = mapAt >= STATE && mapAt + mapCells <= sym.size;
      const map = mapOk ? Int8Array.from({ length: mapCells }, (_, i) => rp.sramView.getInt8(base + mapAt + i)) : null;
      const route = word(ROUTE);
      return {
        closed: word(CLOSED) === CLOSED_MAGIC,
        resumes: word(RESUMES),
        route: { leg: route >>> 24, done: route & 0xffffff },
        map,
        state: rp.sram.slice(base + STATE, base + sym.size),
      };
    },
    /// The figures of a reset: the map's cells and the state's bytes at the reset
    /// (`before`) against those as the next step began (`after`).
    compare(before, after) {
      const same = (a, b) => a.reduce((n, x, i) => n + (x === b[i] ? 1 : 0), 0);
      const map = before.map && after.map && before.map.length === after.map.length;
      return {
        closed_at_reset: before.closed,
        route_at_reset: before.route,
        state_bytes: before.state.length,
        state_bytes_equal: same(before.state, after.state),
        map_cells: map ? before.map.length : null,
        map_cells_known: map ? before.map.filter((c) => c !== 0).length : null,
        map_cells_equal: map ? same(before.map, after.map) : null,
        resumes_after: after.resumes,
      };
    },
  };
}
