// Where rp2040js 1.4.1 differs from the RP2040 in ways the firmware runs into, patched to
// behave as the chip does. Each patch says what the real part does.

/// UART (PL011): gives UARTDMACR storage, raises the RX DMA request, and models the TX
/// FIFO so the TX interrupt fires on a transition as on the chip. `onByteOut(byte)` is
/// called as each byte leaves the shifter, one frame time after the last.
export function patchUart(rp, uart, later, onByteOut) {
  const UARTDR = 0x0, UARTFR = 0x18, UARTIFLS = 0x34, UARTDMACR = 0x48;
  const TXINTR = 1 << 5;
  const RXDMAE = 1 << 0;
  const TXDMAE = 1 << 1;
  let dmacr = 0;
  let ifls = 0x12;
  const txFifo = [];
  let shifting = false;
  const fifoDepth = () => (uart.fifosEnabled ? 32 : 1);
  // TXIFLSEL: 0 = 1/8, 1 = 1/4, 2 = 1/2, 3 = 3/4, 4 = 7/8 of 32 entries.
  const txLevel = () => [4, 8, 16, 24, 28][ifls & 7] ?? 16;

  // rp2040js sets the TX interrupt on every check, so a TX-masked BufferedUart ISR never
  // stops. The PL011 raises TXRIS only when the TX FIFO level falls through the trigger
  // level (or, FIFOs off, when the holding register empties), and clears it on a write
  // that lifts the level back above it, or through UARTICR.
  uart.checkInterrupts = function () {
    rp.setInterrupt(this.irq, !!(this.interruptStatus & this.interruptMask));
    // The PL011 requests RX DMA while its RX FIFO holds data and UARTDMACR.RXDMAE is set;
    // rp2040js never raises it, so async DMA reads of late bytes time out.
    if (dmacr & RXDMAE && !this.rxFIFO.empty) rp.dma.setDREQ(this.dreq.rx);
    else rp.dma.clearDREQ(this.dreq.rx);
    // rp2040js holds the TX DMA request high whenever the UART is enabled, so a DMA write
    // (the firmware's telemetry UartTx) floods a full FIFO and bytes are lost. The PL011
    // requests TX DMA only with UARTDMACR.TXDMAE set and room in the TX FIFO.
    if (dmacr & TXDMAE && this.enabled && txFifo.length < fifoDepth()) rp.dma.setDREQ(this.dreq.tx);
    else rp.dma.clearDREQ(this.dreq.tx);
  };

  const shiftNext = () => {
    if (!txFifo.length) { shifting = false; return; }
    shifting = true;
    const bits = (uart.wordLength || 8) + 2;
    later((bits * 1e9) / (uart.baudRate || 115200), () => {
      const level = txFifo.length;
      onByteOut(txFifo.shift());
      uart.checkInterrupts(); // room again: the TX DMA request may rise
      const lvl = fifoDepth() === 1 ? 0 : txLevel();
      if ((level > lvl && txFifo.length <= lvl) || txFifo.length === 0) {
        uart.interruptStatus |= TXINTR;
        uart.checkInterrupts();
      }
      shiftNext();
    });
  };

  const origRead = uart.readUint32.bind(uart);
  const origWrite = uart.writeUint32.bind(uart);
  uart.readUint32 = (offset) => {
    switch (offset) {
      // rp2040js reports TX FIFO always empty: the PL011 has TXFF (bit 5), TXFE (bit 7)
      // and BUSY (bit 3) from the real FIFO and shifter.
      case UARTFR: {
        const base = origRead(offset) & ~((1 << 7) | (1 << 5) | (1 << 3));
        return base | (txFifo.length >= fifoDepth() ? 1 << 5 : 0) | (txFifo.length === 0 ? 1 << 7 : 0) |
          (shifting ? 1 << 3 : 0);
      }
      case UARTIFLS: return ifls;
      // Unimplemented in rp2040js (reads 0xFFFFFFFF, so BufferedUart's ISR believes RX
      // DMA is on and returns at once, forever). The PL011 stores TXDMAE/RXDMAE/DMAONERR.
      case UARTDMACR: return dmacr;
      default: return origRead(offset);
    }
  };
  uart.writeUint32 = (offset, value) => {
    switch (offset) {
      case UARTDR:
        if (!uart.enabled || !uart.txEnabled) return;
        if (txFifo.length < fifoDepth()) txFifo.push(value & 0xff);
        else uart.txOverflows = (uart.txOverflows || 0) + 1; // the PL011 drops it too
        uart.checkInterrupts();
        if (txFifo.length > (fifoDepth() === 1 ? 0 : txLevel())) {
          uart.interruptStatus &= ~TXINTR;
          uart.checkInterrupts();
        }
        if (!shifting) shiftNext();
        return;
      case UARTIFLS: ifls = value & 0x3f; return;
      case UARTDMACR: dmacr = value & 0x7; uart.checkInterrupts(); return;
      // rp2040js's UARTIMSC/UARTICR paths call checkInterrupts, now the override above.
      default: origWrite(offset, value); uart.checkInterrupts();
    }
  };
}

/// I2C (DW_apb_i2c): rp2040js ignores writes to IC_INTR_MASK (0x30), so the I2C interrupt
/// never fires and async transfers hang. The DW_apb_i2c stores the mask (13 bits) and
/// drives the interrupt line with RAW_INTR_STAT & INTR_MASK.
///
/// After a transmit abort (a NACK) the DW_apb_i2c flushes its TX FIFO, which leaves it
/// empty, so TX_EMPTY (RAW_INTR_STAT bit 4) is raised at once; rp2040js flushes the FIFO
/// but never raises the flag, and embassy-rp's blocking write, which waits for TX_EMPTY
/// before it looks for the abort, then spins for ever on the first NACK.
export function patchI2c(i2c) {
  const TX_EMPTY = 1 << 4;
  const origAbort = i2c.abort.bind(i2c);
  i2c.abort = (reason) => {
    origAbort(reason);
    i2c.setInterrupts(TX_EMPTY);
  };
  const IC_INTR_MASK = 0x30;
  const origWrite = i2c.writeUint32.bind(i2c);
  i2c.writeUint32 = (offset, value) => {
    if (offset === IC_INTR_MASK) {
      i2c.intEnable = value & 0x1fff;
      i2c.checkInterrupts();
      return;
    }
    origWrite(offset, value);
  };
}

/// SPI (PL022): rp2040js's `spiMode` getter swaps modes 2 and 3. The real SSP: CPOL =
/// SSPCR0.SPO (bit 6), CPHA = SSPCR0.SPH (bit 7), mode = CPOL * 2 + CPHA.
export function patchSpiMode(spi) {
  Object.defineProperty(spi, 'spiMode', {
    get() { return ((this.control0 >> 6) & 1) * 2 + ((this.control0 >> 7) & 1); },
  });
}

/// USB device controller: the chip's side of each bus transaction, for a host model
/// (usb-host.mjs) to drive. rp2040js 1.4.1's device mode hands an IN buffer to its host
/// hook and clears AVAILABLE the moment the firmware arms it, and clears AVAILABLE on an
/// armed OUT buffer before any data came, so embassy-rp's control `data_out` reads an
/// empty buffer. The RP2040 keeps a buffer's AVAILABLE set until a host transaction uses
/// it: an IN token takes an armed IN buffer (AVAILABLE and FULL cleared), an OUT or the
/// status stage fills an armed OUT buffer (LENGTH and FULL set, AVAILABLE cleared), and
/// either raises the endpoint's BUFF_STATUS bit; with no buffer armed the endpoint NAKs.
/// A token to another device address is ignored (the host times out). EP0 sends STALL
/// only with both its buffer's STALL bit and EP_STALL_ARM set; a SETUP clears
/// EP_STALL_ARM. Double buffering is not modelled (embassy-rp does not use it) and is
/// reported if the firmware ever asks for it. Returns the bus: `setup(packet, address)`,
/// `transferIn(ep, address)`, `transferOut(ep, address, data)` (each returns `{ status:
/// 'ack' | 'nak' | 'stall' | 'timeout', data, pid }`), `reset()`, and hooks the host
/// sets: `onAttach(attached)` when the pull-up (SIE_CTRL.PULLUP_EN) changes, `onArmed(ep,
/// out)` when the firmware makes a buffer AVAILABLE, `onStall(ep, out)` when it sets STALL.
export function patchUsbDevice(rp) {
  const usb = rp.usbCtrl;
  const dpram = rp.usbDPRAM;
  const view = rp.usbDPRAMView;
  const SIE_CTRL = 0x4c, PULLUP_EN = 1 << 16;
  const SIE_SETUP_REC = 1 << 17, SIE_BUS_RESET = 1 << 19;
  const AVAILABLE = 1 << 10, STALL = 1 << 11, DATA1 = 1 << 13, FULL = 1 << 15, LEN = 0x3ff;
  const EP_ENABLE = 1 << 31, EP_DOUBLE_BUF = 1 << 30;
  const bus = {
    onAttach() {},
    onArmed() {},
    onStall() {},
    /// Firmware requests the model cannot serve (double buffering), once each.
    unsupported: new Set(),
  };
  const bufCtrl = (ep, out) => 0x80 + ep * 8 + (out ? 4 : 0);
  // EP1..15 control registers: 0x08 + (ep - 1) * 8, IN then OUT. EP0's buffer is 0x100.
  const epCtrl = (ep, out) => (ep === 0 ? EP_ENABLE | 0x100 : view.getUint32(0x08 + (ep - 1) * 8 + (out ? 4 : 0), true));
  const addressed = (address) => (usb.addrEndp & 0x7f) === address;
  const bufferDone = (ep, out) => {
    usb.buffStatus |= 1 << (ep * 2 + (out ? 1 : 0));
    usb.buffStatusUpdated();
  };
  const stalled = (ep, out, bc) => bc & STALL && (ep !== 0 || usb.epStallArm & (out ? 2 : 1));

  let pullup = false;
  const origWrite = usb.writeUint32.bind(usb);
  usb.writeUint32 = (offset, value) => {
    origWrite(offset, value);
    if (offset !== SIE_CTRL || usb.hostMode) return;
    const now = !!(usb.sieCtrl & PULLUP_EN);
    if (now !== pullup) {
      pullup = now;
      bus.onAttach(now);
    }
  };
  usb.DPRAMUpdated = (offset, value) => {
    if (usb.hostMode || offset < 0x80 || offset > 0xfc) return;
    const ep = (offset - 0x80) >> 3, out = !!(offset & 4);
    if (value & (AVAILABLE << 16) || epCtrl(ep, out) & EP_DOUBLE_BUF) bus.unsupported.add(`double-buffered EP${ep} ${out ? 'OUT' : 'IN'}`);
    if (value & STALL) bus.onStall(ep, out);
    if (value & AVAILABLE) bus.onArmed(ep, out);
  };

  bus.deviceAddress = () => usb.addrEndp & 0x7f;
  bus.reset = () => {
    usb.sieStatus |= SIE_BUS_RESET;
    usb.sieStatusUpdated();
  };
  bus.setup = (packet, address) => {
    if (!pullup || !addressed(address)) return { status: 'timeout' };
    dpram.set(packet, 0);
    usb.epStallArm &= ~3;
    usb.sieStatus |= SIE_SETUP_REC;
    usb.sieStatusUpdated();
    return { status: 'ack' };
  };
  bus.transferIn = (ep, address) => {
    if (!pullup || !addressed(address) || !(epCtrl(ep, false) & EP_ENABLE)) return { status: 'timeout' };
    const at = bufCtrl(ep, false);
    const bc = view.getUint32(at, true);
    if (stalled(ep, false, bc)) return { status: 'stall' };
    if (!(bc & AVAILABLE) || !(bc & FULL)) return { status: 'nak' };
    const start = epCtrl(ep, false) & 0xffc0;
    const data = dpram.slice(start, start + (bc & LEN));
    view.setUint32(at, bc & ~(AVAILABLE | FULL), true);
    bufferDone(ep, false);
    return { status: 'ack', data, pid: bc & DATA1 ? 1 : 0 };
  };
  bus.transferOut = (ep, address, data) => {
    if (!pullup || !addressed(address) || !(epCtrl(ep, true) & EP_ENABLE)) return { status: 'timeout' };
    const at = bufCtrl(ep, true);
    const bc = view.getUint32(at, true);
    if (stalled(ep, true, bc)) return { status: 'stall' };
    if (!(bc & AVAILABLE)) return { status: 'nak' };
    // More than the buffer's LENGTH is an RX overflow on the chip: the data is not taken.
    if (data.length > (bc & LEN)) return { status: 'timeout', overflow: true };
    dpram.set(data, epCtrl(ep, true) & 0xffc0);
    view.setUint32(at, (bc & ~(AVAILABLE | LEN)) | FULL | data.length, true);
    bufferDone(ep, true);
    return { status: 'ack', pid: bc & DATA1 ? 1 : 0 };
  };
  return bus;
}

/// `patchUsbDevice` on a bare chip, the firmware's register writes made by hand: a
/// buffer is only used once armed, stays armed until a transaction uses it, and EP0
/// STALLs only while EP_STALL_ARM is set.
export async function usbDeviceSelfTests() {
  const { RP2040 } = await import('./node_modules/rp2040js/dist/esm/rp2040.js');
  const { SimulationClock } = await import('./node_modules/rp2040js/dist/esm/clock/simulation-clock.js');
  const rp = new RP2040(new SimulationClock());
  const bus = patchUsbDevice(rp);
  const USB = 0x50110000, DPRAM = 0x50100000;
  const attached = [];
  bus.onAttach = (a) => attached.push(a);
  const armed = [];
  bus.onArmed = (ep, out) => armed.push(`${ep}${out ? 'out' : 'in'}`);
  rp.writeUint32(USB + 0x40, 1); // MAIN_CTRL: controller on, device mode
  rp.writeUint32(USB + 0x4c, 1 << 16); // SIE_CTRL: pull-up
  const before = bus.transferIn(0, 0).status;
  rp.writeUint32(DPRAM + 0x100, 0x04030201);
  rp.writeUint32(DPRAM + 0x80, (1 << 15) | (1 << 13) | 3); // EP0 IN: FULL, DATA1, 3 bytes
  const notYet = bus.transferIn(0, 0).status;
  rp.writeUint32(DPRAM + 0x80, (1 << 15) | (1 << 13) | (1 << 10) | 3); // ... AVAILABLE
  const taken = bus.transferIn(0, 0);
  const again = bus.transferIn(0, 0).status;
  const inDone = rp.usbCtrl.buffStatus & 1;
  rp.writeUint32(DPRAM + 0x84, (1 << 10) | 64); // EP0 OUT armed for 64 bytes
  const stillArmed = rp.readUint32(DPRAM + 0x84) & (1 << 10);
  const wrongAddress = bus.transferOut(0, 5, Uint8Array.from([9])).status;
  const given = bus.transferOut(0, 0, Uint8Array.from([7, 8])).status;
  const outBc = rp.readUint32(DPRAM + 0x84);
  rp.writeUint32(DPRAM + 0x80, 1 << 11); // EP0 IN STALL without EP_STALL_ARM
  const unarmedStall = bus.transferIn(0, 0).status;
  rp.writeUint32(USB + 0x68, 1); // EP_STALL_ARM EP0 IN
  const stall = bus.transferIn(0, 0).status;
  bus.setup(new Uint8Array(8), 0);
  const afterSetup = bus.transferIn(0, 0).status;
  return [
    ['usb device: attach on the pull-up', attached.join() === 'true'],
    ['usb device: NAK until a buffer is armed', before === 'nak' && notYet === 'nak'],
    ['usb device: an armed IN buffer is taken once', taken.status === 'ack' && taken.data.join() === '1,2,3' && taken.pid === 1 && again === 'nak' && inDone === 1],
    ['usb device: an OUT buffer stays armed until data comes', stillArmed !== 0 && armed.join() === '0in,0out'],
    ['usb device: a token to another address is ignored', wrongAddress === 'timeout'],
    ['usb device: OUT data fills the buffer', given === 'ack' && (outBc & 0x3ff) === 2 && outBc & (1 << 15) && !(outBc & (1 << 10)) && rp.usbDPRAM[0x100] === 7],
    ['usb device: EP0 stalls only with EP_STALL_ARM, until the next SETUP', unarmedStall === 'nak' && stall === 'stall' && afterSetup === 'nak'],
  ];
}
