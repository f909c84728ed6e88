// TDK ICM-42688-P gyro as an I2C device model (address 0x68), user bank 0 only, as
// drivers/src/imu uses it.

export const ICM42688_ADDRESS = 0x68;

const REG_GYRO_DATA_Z1 = 0x29;
const REG_GYRO_DATA_Z0 = 0x2a;
const REG_INT_STATUS = 0x2d;
const REG_DEVICE_CONFIG = 0x11;
const REG_PWR_MGMT0 = 0x4e;
const REG_GYRO_CONFIG0 = 0x4f;
const REG_WHO_AM_I = 0x75;
const INT_STATUS_RESET_DONE = 0x10;
/// Gyro start-up time after PWR_MGMT0 turns it on, in nanoseconds.
const GYRO_START_NS = 30e6;

/// WHO_AM_I, soft reset with the reset-done flag, PWR_MGMT0 (gyro on after its start-up
/// time), GYRO_CONFIG0 (full scale), GYRO_DATA_Z1/Z0 big-endian with auto-increment.
export class Icm42688Model {
  /// `sampleMdps()`: the world's yaw rate now, in millidegrees per second, positive
  /// clockwise from above; `null` leaves the last sample in place. `nowNs()`: simulated
  /// time in nanoseconds.
  constructor(sampleMdps, nowNs) {
    this.sampleMdps = sampleMdps;
    this.nowNs = nowNs;
    this.samples = 0;
    this.resets = 0;
    this.reset();
    this.regs[REG_INT_STATUS] = INT_STATUS_RESET_DONE; // power-on reset reports it too
  }

  reset() {
    this.regs = new Uint8Array(256);
    this.regs[REG_WHO_AM_I] = 0x47;
    this.regs[REG_GYRO_CONFIG0] = 0x06; // reset value: 2000 dps, 1 kHz
    this.gyroOnAtNs = Infinity;
    this.ptr = 0;
    this.first = false;
  }

  connect(mode) {
    this.first = mode === 'write';
    if (mode === 'read' && (this.ptr === REG_GYRO_DATA_Z1 || this.ptr === REG_GYRO_DATA_Z0)) this.latchSample();
  }

  latchSample() {
    let counts = -32768; // INVALID_SAMPLE until the gyro has started
    if (this.nowNs() >= this.gyroOnAtNs) {
      const rate = this.sampleMdps();
      if (rate === null) return;
      const lsbPerDps = [16.4, 32.8, 65.5, 131, 262, 524.3, 1048.6, 2097.2][(this.regs[REG_GYRO_CONFIG0] >> 5) & 7];
      // The chip's Z axis points out of its top face (right-handed); BugBot's rate is
      // positive clockwise from above, and the driver negates for a face-up chip.
      counts = Math.max(-32767, Math.min(32767, Math.round((-rate * lsbPerDps) / 1000)));
      this.samples++;
    }
    this.regs[REG_GYRO_DATA_Z1] = (counts >> 8) & 0xff;
    this.regs[REG_GYRO_DATA_Z0] = counts & 0xff;
  }

  write(v) {
    if (this.first) { this.ptr = v; this.first = false; return; }
    const reg = this.ptr++ & 0xff;
    if (reg === REG_DEVICE_CONFIG && v & 1) {
      this.reset();
      this.resets++;
      this.regs[REG_INT_STATUS] = INT_STATUS_RESET_DONE;
      return;
    }
    this.regs[reg] = v;
    if (reg === REG_PWR_MGMT0) {
      // Gyro low-noise mode (bits 3:2 = 0b11): data valid after the start-up time.
      this.gyroOnAtNs = ((v >> 2) & 3) === 3 ? this.nowNs() + GYRO_START_NS : Infinity;
    }
  }

  read() {
    const reg = this.ptr++ & 0xff;
    const v = this.regs[reg];
    if (reg === REG_INT_STATUS) this.regs[REG_INT_STATUS] = 0; // clears on read
    return v;
  }

  stop() {}
}
