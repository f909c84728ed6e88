// The SIO's hardware divider, one per core.
//
// On the RP2040 each core has its own divider (datasheet 2.3.1.5), so core 1's divides
// never disturb core 0's. rp2040js keeps one divider in its single SIO; core1.mjs answers
// the divider's registers of each core's SIO view from one of these instead.
//
// As on the chip: writing a dividend or divisor starts a division (signed or unsigned by
// the register written) and sets DIRTY; reading QUOTIENT clears DIRTY; writing QUOTIENT or
// REMAINDER stores the value and sets READY and DIRTY (how an interrupt handler puts back
// the state it saved). The chip's result is valid 8 cycles after the last operand write and
// the writes do not stall the core: code using it waits those cycles itself (embassy-rp's
// `intrinsics` run 8 cycles of branches), so no cycles are charged here and READY reads 1
// at once.

export const DIV_UDIVIDEND = 0x060;
export const DIV_UDIVISOR = 0x064;
export const DIV_SDIVIDEND = 0x068;
export const DIV_SDIVISOR = 0x06c;
export const DIV_QUOTIENT = 0x070;
export const DIV_REMAINDER = 0x074;
export const DIV_CSR = 0x078;
const CSR_READY = 1 << 0;
const CSR_DIRTY = 1 << 1;

/// One core's divider: its operands, results and CSR, all as unsigned 32-bit words.
export class Divider {
  constructor() {
    this.dividend = 0;
    this.divisor = 0;
    this.quotient = 0;
    this.remainder = 0;
    this.csr = CSR_READY;
  }

  /// Whether `offset` (from the SIO's base) is one of the divider's registers.
  static owns(offset) {
    return offset >= DIV_UDIVIDEND && offset <= DIV_CSR;
  }

  readUint32(offset) {
    switch (offset) {
      case DIV_UDIVIDEND:
      case DIV_SDIVIDEND:
        return this.dividend;
      case DIV_UDIVISOR:
      case DIV_SDIVISOR:
        return this.divisor;
      case DIV_QUOTIENT:
        this.csr &= ~CSR_DIRTY;
        return this.quotient;
      case DIV_REMAINDER:
        return this.remainder;
      default:
        return this.csr;
    }
  }

  writeUint32(offset, value) {
    const word = value >>> 0;
    switch (offset) {
      case DIV_UDIVIDEND: this.dividend = word; this.divide(false); return;
      case DIV_SDIVIDEND: this.dividend = word; this.divide(true); return;
      case DIV_UDIVISOR: this.divisor = word; this.divide(false); return;
      case DIV_SDIVISOR: this.divisor = word; this.divide(true); return;
      case DIV_QUOTIENT: this.quotient = word; this.csr = CSR_READY | CSR_DIRTY; return;
      case DIV_REMAINDER: this.remainder = word; this.csr = CSR_READY | CSR_DIRTY; return;
      default: return; // CSR is read-only
    }
  }

  /// The division the chip starts on an operand write. By zero it answers as the chip
  /// does: the remainder is the dividend, the quotient all ones (1 for a negative signed
  /// dividend).
  divide(signed) {
    const n = signed ? this.dividend | 0 : this.dividend;
    const d = signed ? this.divisor | 0 : this.divisor;
    if (d === 0) {
      this.quotient = signed && n < 0 ? 1 : 0xffffffff;
      this.remainder = this.dividend;
    } else {
      this.quotient = Math.trunc(n / d) >>> 0;
      this.remainder = (n % d) >>> 0;
    }
    this.csr = CSR_READY | CSR_DIRTY;
  }
}

/// The divider's own checks, one `[name, pass]` each: signed and unsigned results, the
/// chip's answer to a zero divisor, and DIRTY as the firmware's save and restore read it.
export function selfTests() {
  const div = new Divider();
  const run = (dividendAt, divisorAt, n, d) => {
    div.writeUint32(dividendAt, n);
    div.writeUint32(divisorAt, d);
    return [div.readUint32(DIV_QUOTIENT), div.readUint32(DIV_REMAINDER)];
  };
  const unsigned = run(DIV_UDIVIDEND, DIV_UDIVISOR, 0xfffffff0, 7);
  const signed = run(DIV_SDIVIDEND, DIV_SDIVISOR, -100, 7);
  const byZero = run(DIV_SDIVIDEND, DIV_SDIVISOR, -5, 0);
  div.writeUint32(DIV_UDIVIDEND, 9);
  const dirtyAfterWrite = div.readUint32(DIV_CSR) === (CSR_READY | CSR_DIRTY);
  div.readUint32(DIV_QUOTIENT);
  const cleanAfterRead = div.readUint32(DIV_CSR) === CSR_READY;
  div.writeUint32(DIV_REMAINDER, 3);
  div.writeUint32(DIV_QUOTIENT, 0xfffffff2);
  const restored = div.readUint32(DIV_CSR) === (CSR_READY | CSR_DIRTY)
    && div.readUint32(DIV_QUOTIENT) === 0xfffffff2 && div.readUint32(DIV_REMAINDER) === 3;
  return [
    ['divider unsigned', unsigned[0] === Math.floor(0xfffffff0 / 7) && unsigned[1] === 0xfffffff0 % 7],
    ['divider signed truncates toward zero', signed[0] === (-14 >>> 0) && signed[1] === (-2 >>> 0)],
    ['divider by zero as the chip', byZero[0] === 1 && byZero[1] === (-5 >>> 0)],
    ['divider DIRTY set by a write, cleared by reading the quotient', dirtyAfterWrite && cleanAfterRead],
    ['divider state restored through QUOTIENT and REMAINDER', restored],
  ];
}
