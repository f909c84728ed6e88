// The firmware's defmt log: RTT up-channel 0, drained from SRAM as a debug probe would.
// The bytes are kept raw; xtask decodes them against the ELF's defmt table. With a sink
// (a file descriptor) each drain also appends them there, so the log can be followed
// while the run goes on.

import fs from 'node:fs';

const SRAM_BASE = 0x20000000;
/// Offset of up-channel 0 in the control block: id[16], max_up u32, max_down u32.
const UP0 = 24;
// Fields of an up-channel descriptor: name, buf, size, write, read, flags (u32 each).
const BUF = 4, SIZE = 8, WRITE = 12, READ = 16;

export class RttDrain {
  /// `controlBlock`: the address of the `_SEGGER_RTT` symbol.
  constructor(rp, controlBlock, sink = null) {
    this.rp = rp;
    this.chan = controlBlock + UP0;
    /// Every byte drained so far.
    this.bytes = [];
    this.sink = sink;
  }

  /// Takes what the firmware has written since the last drain and advances the read
  /// pointer, or defmt-rtt drops data once its buffer is full.
  drain() {
    const rp = this.rp;
    const chan = this.chan;
    const size = rp.readUint32(chan + SIZE);
    if (!size) return; // .data not copied yet
    const buf = rp.readUint32(chan + BUF);
    const write = rp.readUint32(chan + WRITE);
    let read = rp.readUint32(chan + READ);
    if (write === read || write >= size || read >= size) return;
    const first = this.bytes.length;
    while (read !== write) {
      this.bytes.push(rp.sram[buf - SRAM_BASE + read]);
      read = read + 1 === size ? 0 : read + 1;
    }
    rp.sramView.setUint32(chan + READ - SRAM_BASE, read, true);
    if (this.sink !== null) fs.writeSync(this.sink, Buffer.from(this.bytes.slice(first)));
  }
}
