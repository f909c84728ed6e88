// The camera co-processor's link on UART0 RX: every 100 ms a frame of the AprilTags in
// view (COBS + CRC-16/CCITT-FALSE, as wire/src/camera_link documents), fed to the UART
// one byte time apart as the real line would.

/// Simulated time between frames, in nanoseconds.
const FRAME_PERIOD_NS = 100e6;
/// The most tags one frame carries.
const MAX_TAGS = 8;

export function crc16CcittFalse(bytes) {
  let crc = 0xffff;
  for (const b of bytes) {
    crc ^= b << 8;
    for (let i = 0; i < 8; i++) crc = crc & 0x8000 ? ((crc << 1) ^ 0x1021) & 0xffff : (crc << 1) & 0xffff;
  }
  return crc;
}

export function cobsEncode(bytes) {
  const out = [0];
  let codeAt = 0;
  let code = 1;
  for (const b of bytes) {
    if (b === 0) {
      out[codeAt] = code;
      codeAt = out.length;
      out.push(0);
      code = 1;
    } else {
      out.push(b);
      code++;
      if (code === 0xff) {
        out[codeAt] = code;
        codeAt = out.length;
        out.push(0);
        code = 1;
      }
    }
  }
  out[codeAt] = code;
  return out;
}

/// One camera frame on the wire (COBS, then the 0x00 delimiter).
export function cameraFrame(counter, tags) {
  const body = [1, counter & 0xff, (counter >> 8) & 0xff, Math.min(tags.length, MAX_TAGS)];
  for (const t of tags.slice(0, MAX_TAGS)) {
    const cx = Math.max(0, Math.min(32000, Math.round(t.cx_px * 100)));
    const cy = 12000; // host-sim reports no y; the tags hang at the camera's height
    const d = Math.max(0, Math.min(0xffff, Math.round(t.distance_mm)));
    body.push(t.id & 0xff, (t.id >> 8) & 0xff, cx & 0xff, cx >> 8, cy & 0xff, cy >> 8, d & 0xff, d >> 8);
  }
  const crc = crc16CcittFalse(body);
  body.push(crc & 0xff, crc >> 8);
  return [...cobsEncode(body), 0];
}

/// The co-processor sending frames into `uart` (an rp2040js UART).
export class CameraLink {
  /// `readTags()`: the world's tags in view now (host-sim's `tags` reply); `garbage()`:
  /// whether line noise replaces this frame, `silent()`: whether the co-processor sends
  /// nothing this period (fault injection); `later(ns, fn)` schedules on the simulation
  /// clock.
  constructor({ uart, later, readTags, garbage, silent = () => false }) {
    this.uart = uart;
    this.later = later;
    this.readTags = readTags;
    this.garbage = garbage;
    this.silent = silent;
    this.counter = 0;
    /// Frames sent good, frames sent as garbage, periods left silent, bytes queued, tags
    /// in the good frames.
    this.stats = { frames: 0, garbage: 0, silent: 0, bytes: 0, tagsSent: 0 };
    /// Bytes the UART took (the rest were dropped on a full RX FIFO).
    this.uartRxBytes = 0;
    this.rxQueue = [];
    this.rxBusy = false;
  }

  /// Sends the first frame one period from now, and one every period after.
  start() {
    this.later(FRAME_PERIOD_NS, () => this.tick());
  }

  tick() {
    if (this.silent()) {
      this.stats.silent++;
      this.later(FRAME_PERIOD_NS, () => this.tick());
      return;
    }
    const tags = this.readTags() || [];
    let bytes = cameraFrame(this.counter++, tags);
    if (this.garbage()) {
      this.stats.garbage++;
      // Line noise: random bytes, then a frame with a corrupted body (bad CRC).
      const noise = Array.from({ length: 12 }, () => (Math.random() * 256) | 0);
      bytes = [...noise, 0, ...bytes];
      bytes[bytes.length - 4] ^= 0x5a;
    } else {
      this.stats.frames++;
      this.stats.tagsSent += tags.length;
    }
    this.stats.bytes += bytes.length;
    this.rxQueue.push(...bytes);
    if (!this.rxBusy) this.feedNext();
    this.later(FRAME_PERIOD_NS, () => this.tick());
  }

  feedNext() {
    if (!this.rxQueue.length) { this.rxBusy = false; return; }
    this.rxBusy = true;
    const uart = this.uart;
    const byteNs = (10 * 1e9) / (uart.baudRate || 115200);
    this.later(byteNs, () => {
      // The real PL011 drops the byte (overrun) when its 32-entry FIFO is full.
      if (uart.enabled && uart.rxEnabled && !uart.rxFIFO.full) {
        uart.feedByte(this.rxQueue.shift());
        this.uartRxBytes++;
      } else {
        this.rxQueue.shift();
      }
      this.feedNext();
    });
  }
}

/// `[name, passed]` for `harness.mjs --self-test`.
export function selfTests() {
  // The fixture of wire/tests/camera_link.rs: tag 5 at (160, 120) px, 1500 mm; tag 256
  // at (0, 240) px, 0 mm; counter 0x0102; CRC 0x1B95.
  const FRAME = [0x01, 0x02, 0x01, 0x02, 0x05, 0x00, 0x80, 0x3e, 0xe0, 0x2e, 0xdc, 0x05, 0x00, 0x01, 0x00, 0x00, 0xc0, 0x5d, 0x00, 0x00];
  const FRAME_COBS = [0x06, 0x01, 0x02, 0x01, 0x02, 0x05, 0x07, 0x80, 0x3e, 0xe0, 0x2e, 0xdc, 0x05, 0x02, 0x01, 0x01, 0x03, 0xc0, 0x5d, 0x01, 0x03, 0x95, 0x1b];
  const crc = crc16CcittFalse(FRAME);
  const built = cameraFrame(0x0102, [{ id: 5, cx_px: 160, distance_mm: 1500 }]);
  return [
    ['crc check value', crc16CcittFalse([...Buffer.from('123456789')]) === 0x29b1],
    ['fixture crc', crc === 0x1b95],
    ['fixture cobs', JSON.stringify(cobsEncode([...FRAME, crc & 0xff, crc >> 8])) === JSON.stringify(FRAME_COBS)],
    ['frame ends in one delimiter', built.indexOf(0) === built.length - 1],
  ];
}
