// The wheel motors: the firmware's PWM read back as signed duties for the world.

/// PWM slices driving the DRV8833: 5 the left wheel (GP10/11), 6 the right (GP12/13).
const LEFT_SLICE = 5;
const RIGHT_SLICE = 6;

/// Reads the motor PWM slices as wheel duties in -1..1. DRV8833: IN1 PWM with IN2 low
/// drives forward, IN2 PWM with IN1 low reverse (fast decay).
export class Motors {
  /// Switches off rp2040js's PWM edge alarms on `rp`: it simulates every PWM edge with a
  /// clock alarm, which at the motors' 20 kHz would be most of the emulator's work, and
  /// nothing here watches the pins (the DRV8833 is not emulated), so the duty is read from
  /// CC/TOP instead. What the shortcut loses: the wrap interrupt and DREQ never fire (the
  /// firmware uses neither) and a CC/TOP write counts at once instead of at the next wrap.
  constructor(rp) {
    this.rp = rp;
    for (const ch of rp.pwm.channels) {
      ch.alarmA.enable = false;
      ch.alarmB.enable = false;
      ch.alarmBottom.enable = false;
    }
    this.left = 0;
    this.right = 0;
    /// The largest duty either wheel was driven at.
    this.maxAbs = 0;
  }

  /// Reads both duties now.
  read() {
    this.left = this.duty(LEFT_SLICE);
    this.right = this.duty(RIGHT_SLICE);
    this.maxAbs = Math.max(this.maxAbs, Math.abs(this.left), Math.abs(this.right));
    return this;
  }

  duty(slice) {
    const ch = this.rp.pwm.channels[slice];
    if (!(ch.csr & 1)) return 0; // slice disabled: outputs low, coast
    const period = (ch.top & 0xffff) + 1;
    const a = Math.min(ch.cc & 0xffff, period) / period;
    const b = Math.min((ch.cc >>> 16) & 0xffff, period) / period;
    return a - b;
  }
}
