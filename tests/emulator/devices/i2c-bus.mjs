// An rp2040js I2C block's bus events routed to device models by address.

/// Fast-mode bus speed the devices answer at, in hertz.
const SCL_HZ = 400e3;

/// Routes `i2c`'s bus events to `devices` (address -> model with `connect(mode)`,
/// `write(byte)`, `read()`, `stop()`), completing each step after one bus byte time
/// (9 SCL periods) as a clock-stretching device would. `nacking()` returns the addresses
/// that must not answer right now (fault injection, a powered-down part). Returns the
/// bus's counters, `{ transactions, nacks }`, kept up to date.
export function attachI2cBus(i2c, later, devices, nacking) {
  const stats = { transactions: 0, nacks: 0 };
  let dev = null;
  const byteNs = () => (9 * 1e9) / SCL_HZ;
  i2c.onStart = () => later(1e9 / SCL_HZ, () => i2c.completeStart());
  i2c.onConnect = (address, mode) => {
    stats.transactions++;
    const d = devices[address];
    const ack = !!d && !nacking().includes(address);
    dev = ack ? d : null;
    if (!ack) stats.nacks++;
    if (dev) dev.connect(mode === 1 ? 'read' : 'write');
    later(byteNs(), () => i2c.completeConnect(ack));
  };
  i2c.onWriteByte = (value) => {
    if (dev) dev.write(value);
    later(byteNs(), () => i2c.completeWrite(!!dev));
  };
  i2c.onReadByte = () => {
    const v = dev ? dev.read() : 0xff;
    later(byteNs(), () => i2c.completeRead(v));
  };
  i2c.onStop = () => {
    if (dev) dev.stop();
    dev = null;
    later(1e9 / SCL_HZ, () => i2c.completeStop());
  };
  return stats;
}
