// The RP2040's second core, which rp2040js 1.4.1 does not emulate.
//
// rp2040js builds one `CortexM0Core`, and its SIO answers CPUID with 0 and has no
// inter-core FIFO (FIFO_ST, FIFO_WR and FIFO_RD read as invalid). The firmware starts its
// depth sensor's blocking driver on core 1 (`embassy_rp::multicore::spawn_core1`), so
// without a second core that task never runs. This module adds one:
//
// - a second `CortexM0Core` whose bus is the same chip seen from core 1: the same SRAM,
//   flash and peripherals, but its own PPB (NVIC, SysTick, VTOR: each core has its own on
//   the chip) and an SIO whose CPUID reads 1 and whose FIFO ends are swapped;
// - the two inter-core FIFOs (8 words each way), their status bits (VLD, RDY and the
//   sticky WOF/ROE errors) and their interrupts, SIO_IRQ_PROC0 (15) to core 0 and
//   SIO_IRQ_PROC1 (16) to core 1, raised while the reading core's FIFO holds data;
// - core 1's boot ROM: after reset it waits on its FIFO for the launch sequence
//   (0, 0, 1, VTOR, SP, entry), echoing each word back and starting over on a mismatch
//   or a 0; once the sequence is complete it sets VTOR, SP and PC and runs;
// - SEV: on the chip it sets the event register of both cores, waking a core asleep in
//   WFE. rp2040js only logs it; `sev()` does what the chip does;
// - a hardware divider per core (divider.mjs), as on the chip, where rp2040js has one, so
//   that code dividing on it (embassy-rp's `intrinsics`) on both cores gets its own results.
//
// Not modelled: peripheral interrupts on core 1 (the chip routes every IRQ to both NVICs;
// the firmware enables none on core 1 but its FIFO's, and GPIO interrupts are per core
// through PROCn_INTE anyway), core 1's interpolators (shared with core 0's here; the
// firmware uses none), bus contention between cores.

import { RP2040 } from './node_modules/rp2040js/dist/esm/rp2040.js';
import { CortexM0Core } from './node_modules/rp2040js/dist/esm/cortex-m0-core.js';
import { RPPPB } from './node_modules/rp2040js/dist/esm/peripherals/ppb.js';
import { Divider } from './divider.mjs';

const CPUID = 0x000;
const FIFO_ST = 0x050;
const FIFO_WR = 0x054;
const FIFO_RD = 0x058;
const FIFO_DEPTH = 8;
const FIFO_ST_VLD = 1 << 0;
const FIFO_ST_RDY = 1 << 1;
const FIFO_ST_WOF = 1 << 2;
const FIFO_ST_ROE = 1 << 3;
const SIO_IRQ_PROC = [15, 16];
const WFE = 0xbf20;

/// Adds core 1 to `rp`. Returns `{ core, launched, launchWords, fifoWords, sev }`; the
/// caller's main loop runs `core` beside `rp.core` once `launched` is true.
export function addCore1(rp) {
  const core0 = rp.core;
  // The bus as core 1 sees it: everything of `rp` by delegation, but its own core, PPB
  // and SIO view. rp2040js's memory map dispatches through `this.ppb` and `this.sio`.
  const rp1 = Object.create(rp);
  const core1 = new CortexM0Core(rp1);
  rp1.core = core1;
  rp1.ppb = new RPPPB(rp1, 'PPB (core 1)');
  for (const ppb of [rp.ppb, rp1.ppb]) addMpuRegisters(ppb);
  const cores = [core0, core1];

  const state = {
    core: core1,
    launched: false,
    launchWords: 0,
    fifoWords: [0, 0],
    sev,
  };

  // fifos[n]: the words waiting for core n to read.
  const fifos = [[], []];
  const sticky = [0, 0];
  const updateIrqs = () => {
    for (const n of [0, 1]) cores[n].setInterrupt(SIO_IRQ_PROC[n], fifos[n].length > 0 || sticky[n] !== 0);
  };

  // Core 1's boot ROM, before launch: how far into the sequence it is, and the three
  // words it keeps. A 0 (re)starts the sequence (the second 0 moves it on), any word out
  // of place sends it back to the start; every word is echoed, so core 0 sees the
  // mismatch and starts again.
  let at = 0;
  const kept = [];
  const bootRomReceive = (word) => {
    if (word === 0) at = at === 1 ? 2 : 1;
    else if (at === 2 && word === 1) at = 3;
    else if (at >= 3) kept[at++ - 3] = word;
    else at = 0;
    // The echo: core 1's write into core 0's FIFO.
    fifos[0].push(word);
    state.launchWords++;
    if (at === 6) {
      const [vtor, sp, entry] = kept;
      core1.VTOR = vtor;
      core1.SP = sp;
      core1.PC = entry & ~1;
      core1.waiting = false;
      state.launched = true;
    }
  };

  const write = (n, word) => {
    const other = 1 - n;
    if (n === 0 && !state.launched) {
      bootRomReceive(word >>> 0);
    } else if (fifos[other].length >= FIFO_DEPTH) {
      sticky[n] |= FIFO_ST_WOF; // the write is lost, as on the chip
    } else {
      fifos[other].push(word >>> 0);
      state.fifoWords[n]++;
    }
    updateIrqs();
  };
  const read = (n) => {
    if (!fifos[n].length) {
      sticky[n] |= FIFO_ST_ROE;
      updateIrqs();
      return 0;
    }
    const word = fifos[n].shift();
    updateIrqs();
    return word;
  };
  const status = (n) => {
    const other = 1 - n;
    const txRoom = n === 0 && !state.launched ? true : fifos[other].length < FIFO_DEPTH;
    return (fifos[n].length ? FIFO_ST_VLD : 0) | (txRoom ? FIFO_ST_RDY : 0) | sticky[n];
  };

  // Each core's view of the SIO: the shared block (GPIO, spinlocks), by delegation so
  // that rp2040js's GPIO pins still find its output registers, with the per-core
  // registers (CPUID, the FIFO ends, the divider) answered here.
  const sio = rp.sio;
  const dividers = [new Divider(), new Divider()];
  const view = (n) => {
    const v = Object.create(sio);
    v.readUint32 = (offset) => {
      if (Divider.owns(offset)) return dividers[n].readUint32(offset);
      switch (offset) {
        case CPUID: return n;
        case FIFO_ST: return status(n);
        case FIFO_RD: return read(n);
        default: return sio.readUint32(offset);
      }
    };
    v.writeUint32 = (offset, value) => {
      if (Divider.owns(offset)) return dividers[n].writeUint32(offset, value);
      switch (offset) {
        case FIFO_WR: write(n, value); return;
        case FIFO_ST: sticky[n] = 0; updateIrqs(); return; // any write clears WOF and ROE
        default: sio.writeUint32(offset, value);
      }
    };
    return v;
  };
  rp.sio = view(0);
  rp1.sio = view(1);

  // SEV: set both cores' event registers; a core asleep in WFE wakes (one asleep in WFI
  // does not: WFI waits for an interrupt only).
  function sev() {
    for (const c of cores) {
      if (c.waiting && rp.readUint16(c.PC - 2) === WFE) c.waiting = false;
      else c.eventRegistered = true;
    }
  }
  // Core 1 starts in the boot ROM's wait loop.
  core1.waiting = true;
  return state;
}

/// rp2040js has no MPU: its registers read as unimplemented (all ones), and embassy-rp's
/// stack guard (`install_stack_guard`, run on core 1 at launch) traps with UDF when
/// MPU_CTRL reads non-zero. The Cortex-M0+ MPU of the RP2040 has 8 regions (MPU_TYPE
/// 0x800) and resets with CTRL = 0. The registers are stored; the protection itself is
/// not enforced (a stack overflow into the guard region goes unnoticed here, where the
/// chip would fault).
function addMpuRegisters(ppb) {
  const MPU_TYPE = 0xd90, MPU_CTRL = 0xd94, MPU_RNR = 0xd98, MPU_RBAR = 0xd9c, MPU_RASR = 0xda0;
  const regions = Array.from({ length: 8 }, () => ({ rbar: 0, rasr: 0 }));
  let ctrl = 0, rnr = 0;
  const read = ppb.readUint32.bind(ppb);
  const write = ppb.writeUint32.bind(ppb);
  ppb.readUint32 = (offset) => {
    switch (offset) {
      case MPU_TYPE: return 0x800;
      case MPU_CTRL: return ctrl;
      case MPU_RNR: return rnr;
      case MPU_RBAR: return (regions[rnr].rbar & ~0x1f) | rnr;
      case MPU_RASR: return regions[rnr].rasr;
      default: return read(offset);
    }
  };
  ppb.writeUint32 = (offset, value) => {
    switch (offset) {
      case MPU_CTRL: ctrl = value & 7; return;
      case MPU_RNR: rnr = value & 7; return;
      case MPU_RBAR:
        // VALID (bit 4) selects the region in bits 3:0 and updates RNR.
        if (value & 0x10) rnr = value & 7;
        regions[rnr].rbar = value >>> 0;
        return;
      case MPU_RASR: regions[rnr].rasr = value >>> 0; return;
      default: write(offset, value);
    }
  };
}

/// Core 1's own checks, one `[name, pass]` each: the two cores dividing interleaved, each
/// operand write of one core between the other's, each get their own results (on the chip
/// each core has its own divider; one shared divider would hand core 0 core 1's quotient).
export function selfTests() {
  const rp = new RP2040();
  const core1 = addCore1(rp);
  const buses = [rp, core1.core.rp2040];
  const SIO = 0xd0000000;
  const write = (n, offset, value) => buses[n].writeUint32(SIO + offset, value);
  const read = (n, offset) => buses[n].readUint32(SIO + offset) >>> 0;
  write(0, 0x068, -1000); // core 0: SDIVIDEND
  write(1, 0x060, 77); // core 1: UDIVIDEND
  write(0, 0x06c, 7); // core 0: SDIVISOR
  write(1, 0x064, 5); // core 1: UDIVISOR
  const q1 = read(1, 0x070);
  const q0 = read(0, 0x070);
  const r0 = read(0, 0x074);
  const r1 = read(1, 0x074);
  return [
    ['core 0 and core 1 divide interleaved, each on its own divider',
      q0 === (-142 >>> 0) && r0 === (-6 >>> 0) && q1 === 15 && r1 === 2],
    ['each core reads its own CPUID', read(0, 0x000) === 0 && read(1, 0x000) === 1],
  ];
}
