// The computer at the other end of the firmware's USB cable: it enumerates the device as
// an operating system does (the requests and waits of USB 2.0 chapter 9, in Linux's
// order), opens its CDC ACM serial port as a terminal or `host-sim view /dev/ttyACM0`
// does (line coding, then DTR and RTS), and from then on reads the bulk IN endpoint
// without pause, as the kernel's cdc-acm driver keeps a read queued while the port is
// open. The chip's side of each transaction is `patchUsbDevice` (patches.mjs).
//
// Every transaction takes its time on the 12 Mbit/s bus; the host retries a NAKed
// endpoint when the firmware next arms it. Start-of-frame packets are not modelled: the
// host keeps the bus busy, so the device never sees it idle and never suspends (the
// firmware's driver enables no SOF interrupt). A request that does not finish names itself
// and its stage in `error` (a STALL, a timeout, or no answer within
// `ENUMERATION_TIMEOUT_S` of the attach).

/// Wait after the device attaches before the reset (USB 2.0 7.1.7.3, TATTDB), ns.
const DEBOUNCE_NS = 100e6;
/// Bus reset held (TDRST, 10 ms minimum) and the recovery after it (TRSTRCY), ns.
const RESET_NS = 10e6;
const RESET_RECOVERY_NS = 10e6;
/// The device's time to take its new address after SET_ADDRESS (TRSTRCY, 9.2.6.3), ns.
const SET_ADDRESS_RECOVERY_NS = 2e6;
/// The gap between one control request and the next, ns.
const REQUEST_GAP_NS = 100e3;
/// How long after the attach the device must be configured and its port open, simulated s.
export const ENUMERATION_TIMEOUT_S = 1;
/// The address the host gives the device.
const DEVICE_ADDRESS = 1;
/// The line coding the host sets: 921600 baud, 1 stop bit, no parity, 8 data bits (the
/// telemetry UART's; the firmware ignores it).
const LINE_CODING = [0x00, 0x10, 0x0e, 0x00, 0, 0, 8];
/// SET_CONTROL_LINE_STATE's value: DTR and RTS, as a terminal opening the port sends.
const DTR_RTS = 0x3;

/// A full-speed transaction's time on the bus: token, data with its PID and CRC,
/// handshake and gaps (about 13 bytes), at 12 Mbit/s.
const transactionNs = (bytes) => ((bytes + 13) * 8 * 1e9) / 12e6;

const GET_DESCRIPTOR = 6, SET_ADDRESS = 5, SET_CONFIGURATION = 9;
const SET_LINE_CODING = 0x20, GET_LINE_CODING = 0x21, SET_CONTROL_LINE_STATE = 0x22;
const DEVICE = 1, CONFIGURATION = 2, STRING = 3, DEVICE_QUALIFIER = 6;
const hex = (n, digits) => n.toString(16).padStart(digits, '0');

/// An 8-byte SETUP packet.
function setupPacket(bmRequestType, bRequest, wValue, wIndex, wLength) {
  return Uint8Array.from([bmRequestType, bRequest, wValue & 0xff, wValue >> 8, wIndex & 0xff, wIndex >> 8, wLength & 0xff, wLength >> 8]);
}

/// The host. `bus`: what `patchUsbDevice` returned; `later(ns, fn)`, `nowS()`: the
/// chip's clock; `onSerial(bytes)`: each bulk IN packet's bytes; `say(...)`: progress.
export class UsbHost {
  constructor({ bus, later, nowS, onSerial, say }) {
    Object.assign(this, { bus, later, nowS, onSerial, say });
    this.address = 0;
    this.attachedS = null;
    this.configuredS = null;
    this.openS = null;
    this.device = null;
    this.configuration = null;
    this.strings = {};
    this.lineCoding = null;
    this.requests = [];
    this.error = null;
    this.request = null;
    this.waiting = [new Map(), new Map()]; // per direction (0 IN, 1 OUT): ep -> handler
    this.stats = { packets: 0, bytes: 0, zero_length_packets: 0, naks: 0, toggle_errors: 0 };
    this.bulkIn = -1;
    this.bulkToggle = 0;
    bus.onAttach = (attached) => this.attach(attached);
    bus.onArmed = (ep, out) => this.armed(ep, out ? 1 : 0);
    bus.onStall = (ep, out) => this.armed(ep, out ? 1 : 0);
  }

  /// The device pulled D+ up (or let go): debounce, then reset and enumerate.
  attach(attached) {
    if (!attached) {
      if (!this.error && this.openS === null) this.fail('the device detached during enumeration');
      return;
    }
    if (this.attachedS !== null) return;
    this.attachedS = this.nowS();
    this.later(ENUMERATION_TIMEOUT_S * 1e9, () => {
      if (this.openS === null && !this.error) this.fail(`port not open ${ENUMERATION_TIMEOUT_S} s after the attach: ${this.stuck()}`);
    });
    this.later(DEBOUNCE_NS, () => {
      this.bus.reset();
      this.later(RESET_NS + RESET_RECOVERY_NS, () => this.enumerate());
    });
  }

  /// The run ended: an enumeration still under way is named as it stands.
  endOfRun() {
    if (this.error || this.openS !== null) return;
    this.fail(this.attachedS === null
      ? 'the device never attached (SIE_CTRL.PULLUP_EN never set)'
      : `port not open by the end of the run, ${(this.nowS() - this.attachedS).toFixed(3)} s after the attach: ${this.stuck()}`);
  }

  /// Where enumeration stands, for an error.
  stuck() {
    const r = this.request;
    if (!r) return `no request in progress after ${this.requests.at(-1) || 'the reset'}`;
    return `${r.name} waiting in its ${r.stage} stage since ${r.stageS.toFixed(3)} s (EP0 ${r.stage === 'data OUT' || r.stage === 'status OUT' ? 'OUT' : 'IN'} never armed)`;
  }

  fail(why) {
    if (this.error) return;
    this.error = why;
    this.request = null;
    this.waiting[0].clear();
    this.waiting[1].clear();
    this.say(`usb: ${why}`);
  }

  /// Linux's enumeration, then the port opened: each step starts when the last is done.
  enumerate() {
    const steps = [
      () => this.getDescriptor(DEVICE, 0, 0, 64, (d) => { this.device = parseDevice(d); }),
      () => this.control('SET_ADDRESS(1)', setupPacket(0x00, SET_ADDRESS, DEVICE_ADDRESS, 0, 0), null, () => {
        this.address = DEVICE_ADDRESS;
        return SET_ADDRESS_RECOVERY_NS;
      }),
      () => this.getDescriptor(DEVICE, 0, 0, 18, (d) => { this.device = parseDevice(d); }),
      // USB 2.0 9.6.2 has a full-speed-only device STALL this; embassy-usb answers it.
      // Either is taken, as Linux takes either.
      () => this.getDescriptor(DEVICE_QUALIFIER, 0, 0, 10, () => {}, { mayStall: true }),
      () => this.getDescriptor(CONFIGURATION, 0, 0, 9, (d) => { this.configuration = parseConfiguration(d); }),
      () => this.getDescriptor(CONFIGURATION, 0, 0, this.configuration.totalLength, (d) => { this.configuration = parseConfiguration(d); }),
      () => this.getDescriptor(STRING, 0, 0, 255, () => {}),
      ...['manufacturer', 'product', 'serial'].map((key) => () => {
        const index = this.device[`i_${key}`];
        if (!index) return this.next();
        return this.getDescriptor(STRING, index, 0x0409, 255, (d) => { this.strings[key] = parseString(d); });
      }),
      () => this.control(`SET_CONFIGURATION(${this.configuration.value})`, setupPacket(0x00, SET_CONFIGURATION, this.configuration.value, 0, 0), null, () => {
        this.configuredS = this.nowS();
        this.bulkToggle = 0;
      }),
      () => this.cdcRequest('SET_LINE_CODING', 0x21, SET_LINE_CODING, 0, Uint8Array.from(LINE_CODING)),
      () => this.cdcRequest('GET_LINE_CODING', 0xa1, GET_LINE_CODING, 0, 7, (d) => { this.lineCoding = parseLineCoding(d); }),
      () => this.cdcRequest('SET_CONTROL_LINE_STATE(DTR, RTS)', 0x21, SET_CONTROL_LINE_STATE, DTR_RTS, null),
      () => this.openPort(),
    ];
    this.steps = steps;
    this.next();
  }

  /// Runs the next enumeration step.
  next() {
    const step = this.steps.shift();
    if (step && !this.error) step();
  }

  getDescriptor(type, index, langId, length, use, options = {}) {
    const names = { [DEVICE]: 'Device', [CONFIGURATION]: 'Configuration', [STRING]: `String ${index}`, [DEVICE_QUALIFIER]: 'Device qualifier' };
    const name = `GET_DESCRIPTOR(${names[type]}, ${length})`;
    this.control(name, setupPacket(0x80, GET_DESCRIPTOR, (type << 8) | index, langId, length), length, (data) => {
      if (data === null) return undefined; // stalled, and allowed to
      if (data.length < 2 || data[1] !== type) {
        this.fail(`${name}: the device answered with ${data.length} bytes of descriptor type ${data[1]}`);
        return undefined;
      }
      try { use(data); } catch (e) { this.fail(`${name}: ${e.message}`); }
      return undefined;
    }, options);
  }

  /// A CDC class request to the communication interface.
  cdcRequest(name, bmRequestType, bRequest, wValue, data, use = () => {}) {
    const cdc = this.cdc();
    if (!cdc) return this.fail('the configuration has no CDC ACM function (communication interface class 2/2 and a data interface with bulk IN)');
    const length = typeof data === 'number' ? data : data ? data.length : 0;
    return this.control(name, setupPacket(bmRequestType, bRequest, wValue, cdc.comm_interface, length), data, (d) => use(d));
  }

  /// The CDC ACM function's interfaces and endpoints, from the configuration.
  cdc() {
    return this.configuration ? findCdc(this.configuration) : null;
  }

  /// One control transfer: SETUP, the data stage (`data`: a byte count to read, bytes to
  /// write, or null), the status stage. `done(data)` runs at the end and may return a
  /// wait before the next step, ns.
  control(name, packet, data, done, { mayStall = false } = {}) {
    const r = { name, stage: 'SETUP', stageS: this.nowS(), toggle: 1 };
    this.request = r;
    const stage = (s) => { r.stage = s; r.stageS = this.nowS(); };
    const finish = (result) => {
      this.request = null;
      this.requests.push(name);
      const wait = done(result);
      if (!this.error) this.later(wait || REQUEST_GAP_NS, () => this.next());
    };
    const stalled = (what) => {
      if (mayStall) {
        this.request = null;
        this.requests.push(`${name}: STALL`);
        this.later(REQUEST_GAP_NS, () => this.next());
      } else {
        this.fail(`${name}: STALL in its ${what} stage`);
      }
    };
    const toggle = (pid, what) => {
      if (pid !== r.toggle) this.fail(`${name}: ${what} came with DATA${pid}, DATA${r.toggle} expected`);
      r.toggle ^= 1;
    };
    // The status stage is always DATA1, in the direction opposite the data.
    const statusIn = () => {
      stage('status IN');
      r.toggle = 1;
      this.transact(0, 0, null, (res) => {
        if (res.status === 'stall') return stalled('status');
        if (res.data.length) return this.fail(`${name}: ${res.data.length} bytes in the status stage`);
        toggle(res.pid, 'the status stage');
        if (!this.error) finish(new Uint8Array(0));
      });
    };
    const statusOut = (got) => {
      stage('status OUT');
      r.toggle = 1;
      this.transact(0, 1, new Uint8Array(0), (res) => {
        if (res.status === 'stall') return stalled('status');
        toggle(res.pid, 'the status stage');
        if (!this.error) finish(got);
      });
    };
    this.later(transactionNs(8), () => {
      const res = this.bus.setup(packet, this.address);
      if (res.status !== 'ack') return this.fail(`${name}: the SETUP to address ${this.address} timed out (the device's address is ${this.bus.deviceAddress?.() ?? '?'})`);
      if (typeof data === 'number' && data > 0) {
        stage('data IN');
        const got = [];
        const maxPacket = this.device?.max_packet_size_0 || 64;
        const read = () => this.transact(0, 0, null, (res) => {
          if (res.status === 'stall') return stalled('data');
          toggle(res.pid, 'a data packet');
          if (this.error) return;
          got.push(...res.data);
          if (res.data.length < maxPacket || got.length >= data) statusOut(Uint8Array.from(got.slice(0, data)));
          else read();
        });
        read();
      } else if (data instanceof Uint8Array && data.length) {
        stage('data OUT');
        this.transact(0, 1, data, (res) => {
          if (res.status === 'stall') return stalled('data');
          toggle(res.pid, 'the data packet');
          if (!this.error) statusIn();
        });
      } else {
        statusIn();
      }
    });
  }

  /// Waits for an endpoint to take (OUT, `dir` 1) or give (IN, 0) a packet, then calls
  /// `then(result)`: tried after one transaction time, again whenever the firmware arms a
  /// buffer there; a timeout fails the enumeration.
  transact(ep, dir, data, then) {
    const handler = { ep, dir, data, then, scheduled: false };
    this.waiting[dir].set(ep, handler);
    this.schedule(handler);
  }

  schedule(handler) {
    if (handler.scheduled) return;
    handler.scheduled = true;
    this.later(transactionNs(handler.data ? handler.data.length : 64), () => {
      handler.scheduled = false;
      if (this.waiting[handler.dir].get(handler.ep) !== handler) return;
      const res = handler.dir === 0
        ? this.bus.transferIn(handler.ep, this.address)
        : this.bus.transferOut(handler.ep, this.address, handler.data);
      if (res.status === 'nak') { this.stats.naks++; return; }
      this.waiting[handler.dir].delete(handler.ep);
      if (res.status === 'timeout') {
        const what = this.request ? `${this.request.name} in its ${this.request.stage} stage` : `EP${handler.ep} ${handler.dir ? 'OUT' : 'IN'}`;
        return this.fail(`${what}: no answer${res.overflow ? ' (more data than the buffer takes)' : ''}`);
      }
      handler.then(res);
    });
  }

  /// The firmware armed (or stalled) a buffer: a waiting transaction there is tried.
  armed(ep, dir) {
    const handler = this.waiting[dir].get(ep);
    if (handler) this.schedule(handler);
  }

  /// The port is open: read the bulk IN endpoint for good.
  openPort() {
    const cdc = this.cdc();
    this.bulkIn = cdc.bulk_in & 0x0f;
    this.openS = this.nowS();
    this.say(`usb: enumerated and port open at ${this.nowS().toFixed(3)} s: ${describe(this.summary())}`);
    const read = () => this.transact(this.bulkIn, 0, null, (res) => {
      if (res.status === 'stall') return this.fail(`bulk IN EP${this.bulkIn} stalled`);
      // A packet with the wrong toggle is a retry of the last one: a host drops it.
      if (res.pid !== this.bulkToggle) this.stats.toggle_errors++;
      else {
        this.bulkToggle ^= 1;
        this.stats.packets++;
        this.stats.bytes += res.data.length;
        if (!res.data.length) this.stats.zero_length_packets++;
        this.onSerial(res.data);
      }
      read();
    });
    read();
  }

  /// What the harness reports: the descriptors seen, the requests made, the stream's
  /// packet counts and the error, if any.
  summary() {
    const d = this.device;
    return {
      attached_s: this.attachedS,
      configured_s: this.configuredS,
      port_open_s: this.openS,
      device: d && {
        vid_pid: `${hex(d.vid, 4)}:${hex(d.pid, 4)}`,
        usb: d.usb,
        class: `${hex(d.class, 2)}/${hex(d.subclass, 2)}/${hex(d.protocol, 2)}`,
        max_packet_size_0: d.max_packet_size_0,
        configurations: d.configurations,
        ...this.strings,
      },
      configuration: this.configuration && {
        value: this.configuration.value,
        total_length: this.configuration.totalLength,
        max_power_ma: this.configuration.maxPowerMa,
        interfaces: this.configuration.interfaces.map((i) => ({
          number: i.number,
          class: `${hex(i.class, 2)}/${hex(i.subclass, 2)}/${hex(i.protocol, 2)}`,
          endpoints: i.endpoints.map((e) => `0x${hex(e.address, 2)} ${e.type} ${e.maxPacket}`),
        })),
      },
      cdc: this.cdc(),
      line_coding: this.lineCoding,
      requests: this.requests,
      ...this.stats,
      unsupported: [...this.bus.unsupported],
      error: this.error,
    };
  }
}

/// One line for the log: VID:PID, strings, the CDC function's endpoints.
export function describe(s) {
  const d = s.device || {};
  const cdc = s.cdc;
  const ports = cdc ? `CDC ACM: interfaces ${cdc.comm_interface} and ${cdc.data_interface}, bulk IN 0x${hex(cdc.bulk_in, 2)}, bulk OUT 0x${hex(cdc.bulk_out, 2)}` : 'no CDC ACM function';
  return `${d.vid_pid} "${d.manufacturer ?? ''}" "${d.product ?? ''}" serial ${d.serial ?? '-'}, class ${d.class}, ${ports}`;
}

/// The standard device descriptor (USB 2.0 table 9-8).
export function parseDevice(d) {
  if (d.length < 18) throw new Error(`a device descriptor of ${d.length} bytes`);
  const u16 = (i) => d[i] | (d[i + 1] << 8);
  return {
    usb: `${(u16(2) >> 8).toString(16)}.${hex(u16(2) & 0xff, 2)}`,
    class: d[4], subclass: d[5], protocol: d[6],
    max_packet_size_0: d[7],
    vid: u16(8), pid: u16(10),
    i_manufacturer: d[14], i_product: d[15], i_serial: d[16],
    configurations: d[17],
  };
}

/// A configuration descriptor and what follows it (interface association, interface,
/// class-specific and endpoint descriptors), as far as `d` goes.
export function parseConfiguration(d) {
  if (d.length < 9 || d[1] !== CONFIGURATION) throw new Error('not a configuration descriptor');
  const c = { totalLength: d[2] | (d[3] << 8), interfaceCount: d[4], value: d[5], maxPowerMa: d[8] * 2, interfaces: [], associations: [] };
  let i = d[0];
  while (i + 2 <= d.length) {
    const len = d[i], type = d[i + 1];
    if (len < 2 || i + len > d.length) throw new Error(`a descriptor of length ${len} at byte ${i}`);
    if (type === 4 && len >= 9) c.interfaces.push({ number: d[i + 2], alternate: d[i + 3], class: d[i + 5], subclass: d[i + 6], protocol: d[i + 7], endpoints: [] });
    if (type === 0x0b && len >= 8) c.associations.push({ first: d[i + 2], count: d[i + 3], class: d[i + 4] });
    if (type === 5 && len >= 7 && c.interfaces.length) {
      const types = ['control', 'isochronous', 'bulk', 'interrupt'];
      c.interfaces.at(-1).endpoints.push({ address: d[i + 2], type: types[d[i + 3] & 3], maxPacket: d[i + 4] | (d[i + 5] << 8), interval: d[i + 6] });
    }
    i += len;
  }
  return c;
}

/// The CDC ACM function: a communication interface (class 2, subclass 2) and the data
/// interface (class 10) with a bulk IN and a bulk OUT endpoint; null if there is none.
export function findCdc(c) {
  const comm = c.interfaces.find((i) => i.class === 2 && i.subclass === 2);
  const data = c.interfaces.find((i) => i.class === 10 && i.endpoints.some((e) => e.type === 'bulk' && e.address & 0x80));
  if (!comm || !data) return null;
  const notify = comm.endpoints.find((e) => e.type === 'interrupt');
  return {
    comm_interface: comm.number,
    data_interface: data.number,
    notify: notify ? notify.address : null,
    bulk_in: data.endpoints.find((e) => e.type === 'bulk' && e.address & 0x80).address,
    bulk_out: data.endpoints.find((e) => e.type === 'bulk' && !(e.address & 0x80))?.address ?? null,
  };
}

/// A string descriptor's UTF-16LE text.
export function parseString(d) {
  return Buffer.from(d.slice(2, d[0] & ~1)).toString('utf16le');
}

/// CDC's line coding (PSTN 6.3.11): baud, stop bits, parity, data bits.
export function parseLineCoding(d) {
  if (d.length < 7) throw new Error(`a line coding of ${d.length} bytes`);
  return { baud: (d[0] | (d[1] << 8) | (d[2] << 16) | (d[3] << 24)) >>> 0, stop_bits: ['1', '1.5', '2'][d[4]] ?? d[4], parity: d[5], data_bits: d[6] };
}

/// The descriptor parsing against embassy-usb's CDC ACM layout (IAD, communication
/// interface with its functional descriptors and notification endpoint, data interface).
export function selfTests() {
  const device = [18, 1, 0x00, 0x02, 0xef, 0x02, 0x01, 64, 0x09, 0x12, 0x01, 0x00, 0x10, 0x00, 1, 2, 3, 1];
  const config = [
    9, 2, 75, 0, 2, 1, 0, 0x80, 50,
    8, 0x0b, 0, 2, 2, 2, 0, 0,
    9, 4, 0, 0, 1, 2, 2, 0, 0,
    5, 0x24, 0x00, 0x10, 0x01,
    4, 0x24, 0x02, 0x02,
    5, 0x24, 0x06, 0, 1,
    5, 0x24, 0x01, 0x00, 1,
    7, 5, 0x83, 3, 8, 0, 255,
    9, 4, 1, 0, 2, 10, 0, 0, 0,
    7, 5, 0x02, 2, 64, 0, 0,
    7, 5, 0x82, 2, 64, 0, 0,
  ];
  const d = parseDevice(device);
  const c = parseConfiguration(config);
  const cdc = findCdc(c);
  let threw = false;
  try { parseConfiguration([9, 2, 20, 0, 1, 1, 0, 0x80, 50, 9, 4]); } catch { threw = true; }
  return [
    ['usb device descriptor', d.vid === 0x1209 && d.pid === 0x0001 && d.usb === '2.00' && d.max_packet_size_0 === 64 && d.i_serial === 3],
    ['usb configuration descriptor', c.totalLength === 75 && c.value === 1 && c.maxPowerMa === 100 && c.interfaces.length === 2 && c.associations.length === 1],
    ['usb cdc acm endpoints', cdc && cdc.comm_interface === 0 && cdc.data_interface === 1 && cdc.notify === 0x83 && cdc.bulk_in === 0x82 && cdc.bulk_out === 0x02],
    ['usb truncated descriptor refused', threw],
    ['usb string descriptor', parseString([10, 3, 0x42, 0, 0x75, 0, 0x67, 0, 0x42, 0]) === 'BugB'],
    ['usb line coding', parseLineCoding(LINE_CODING).baud === 921600 && parseLineCoding(LINE_CODING).data_bits === 8],
    ['usb setup packet', setupPacket(0x80, 6, 0x0200, 0, 255).join(',') === '128,6,0,2,0,0,255,0'],
  ];
}
