// PixArt PMW3901 optical flow sensor as an SPI device model, as drivers/src/flow uses it,
// and its wiring to an rp2040js SPI block and chip-select pin.

const REG_PRODUCT_ID = 0x00;
const REG_MOTION = 0x02;
const REG_MOTION_BURST = 0x16;
const REG_POWER_UP_RESET = 0x3a;
const REG_INVERSE_PRODUCT_ID = 0x5f;
const POWER_UP_RESET_VALUE = 0x5a;
/// SQUAL below which the sensor sees no surface.
const SQUAL_MIN = 0x19;
/// The SPI mode the PMW3901 speaks (CPOL 1, CPHA 1).
const SPI_MODE = 3;

/// `[addr]` then data for reads, `[addr | 0x80, value]` for writes, chip select framing
/// each transaction. The motion burst (0x16) returns 12 bytes built from the world's flow
/// at the moment it is asked.
export class Pmw3901Model {
  /// `readFlow()`: `{ forward_counts, right_counts, squal, dark? }` at this instant;
  /// `absent()`: whether the sensor is not answering (MISO stays low, writes are lost).
  constructor(readFlow, absent = () => false) {
    this.readFlow = readFlow;
    this.absent = absent;
    this.bursts = 0;
    this.regReads = 0;
    this.writes = 0;
    this.resets = 0;
    this.modeErrors = 0;
    this.regs = new Uint8Array(128);
    this.regs[REG_PRODUCT_ID] = 0x49;
    this.regs[REG_INVERSE_PRODUCT_ID] = 0xb6;
    this.deselect();
  }

  select() { this.addr = null; this.out = []; this.writeReg = null; }
  deselect() { this.addr = null; this.out = []; this.writeReg = null; }

  transfer(mosi) {
    if (this.absent()) return 0;
    if (this.writeReg !== null) {
      this.writes++;
      if (this.writeReg === REG_POWER_UP_RESET && mosi === POWER_UP_RESET_VALUE) this.resets++;
      this.regs[this.writeReg] = mosi;
      this.writeReg = null;
      return 0;
    }
    if (this.addr === null) {
      this.addr = mosi;
      if (mosi & 0x80) { this.writeReg = mosi & 0x7f; return 0; }
      if (mosi === REG_MOTION_BURST) {
        this.bursts++;
        this.out = this.burst();
      } else {
        this.regReads++;
        const v = this.regs[mosi & 0x7f];
        this.out = [v];
        if (mosi === REG_MOTION) this.out = [0x00];
      }
      return 0;
    }
    return this.out.length ? this.out.shift() : 0;
  }

  burst() {
    const f = this.readFlow();
    const clamp = (x) => Math.max(-32768, Math.min(32767, Math.round(x || 0)));
    // Default axis map: delta_x is robot right, delta_y robot forward.
    const dx = clamp(f.right_counts);
    const dy = clamp(f.forward_counts);
    const squal = Math.max(0, Math.min(255, Math.round(f.squal ?? 0)));
    const dark = f.dark || squal < SQUAL_MIN;
    const motion = dx !== 0 || dy !== 0 ? 0x80 : 0x00;
    return [
      motion, 0x3f, dx & 0xff, (dx >> 8) & 0xff, dy & 0xff, (dy >> 8) & 0xff,
      squal, 0x40, 0x80, 0x10, dark ? 0x1f : 0x01, 0x00,
    ];
  }

  /// Puts the model on `spi` (an rp2040js SPI block, its mode already patched: see
  /// `patchSpiMode`) behind the chip-select pin `cs`. A transfer in the wrong SPI mode
  /// reads 0xFF and counts a mode error.
  attach(spi, cs, later) {
    cs.addListener((v) => { if (v === 1) this.deselect(); else if (v === 0) this.select(); });
    spi.onTransmit = (value) => {
      // A byte takes 8 SCK periods; completing it later keeps DMA reads longer than the
      // 8-entry RX FIFO from overrunning (an instant device would).
      const hz = spi.clockFrequency || 2e6;
      const selected = cs.value === 0;
      const modeOk = spi.spiMode === SPI_MODE;
      if (selected && !modeOk) this.modeErrors++;
      const rx = selected && modeOk ? this.transfer(value) : 0xff;
      later((8 * 1e9) / hz, () => spi.completeTransmit(rx));
    };
  }
}
