//! DRV8833-style dual H-bridge: two PWM inputs per motor.
//!
//! # Decay
//!
//! Each bridge has inputs IN1 and IN2 (both PWM here):
//!
//! | IN1 | IN2 | bridge |
//! | --- | --- | --- |
//! | 0 | 0 | coast (outputs off, fast decay) |
//! | PWM | 0 | forward, fast decay in the off time |
//! | 1 | PWM inverted | forward, slow decay (brake) in the off time |
//! | 1 | 1 | brake |
//!
//! [`Decay::Fast`] lets the current fall quickly through the body diodes:
//! the motor freewheels in the off time, so speed is less linear in duty at
//! low speeds. [`Decay::Slow`] shorts the windings in the off time: speed is
//! close to proportional to duty and the robot stops sharply when duty
//! drops, which suits odometry; it is the default. Reverse swaps IN1/IN2.
//!
//! # Mixing
//!
//! `left = forward + turn`, `right = forward - turn`, so a positive turn
//! turns clockwise seen from above (to the right), matching BugBot's
//! clockwise-positive heading. When either side would pass 1000 per mille
//! both are scaled down by the same factor, so the turn ratio (and thus the
//! path curvature) is kept rather than clipping one side.

use embedded_hal::pwm::SetDutyCycle;

/// Failure of a PWM channel.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Error<E> {
    /// The PWM peripheral refused a duty cycle.
    Pwm(E),
}

impl<E> From<E> for Error<E> {
    fn from(e: E) -> Self {
        Error::Pwm(e)
    }
}

/// A command in per mille of full scale, always within -1000..=1000.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PerMille(i16);

impl PerMille {
    /// Full scale.
    pub const MAX: PerMille = PerMille(1000);
    /// Full scale reversed.
    pub const MIN: PerMille = PerMille(-1000);
    /// Zero.
    pub const ZERO: PerMille = PerMille(0);

    /// Clamp any value into -1000..=1000.
    pub const fn saturating(value: i32) -> Self {
        let v = if value > 1000 {
            1000
        } else if value < -1000 {
            -1000
        } else {
            value
        };
        PerMille(v as i16)
    }

    /// The value, -1000..=1000.
    pub const fn get(self) -> i16 {
        self.0
    }
}

/// What the bridge does in the PWM off time; see the module doc.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Decay {
    /// Outputs off in the off time: freewheel.
    Fast,
    /// Windings shorted in the off time: brake. Default.
    #[default]
    Slow,
}

/// Bridge options.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MotorConfig {
    /// Decay mode for both bridges.
    pub decay: Decay,
    /// Swap the left motor's direction (wired or mounted mirrored).
    pub invert_left: bool,
    /// Swap the right motor's direction.
    pub invert_right: bool,
}

/// Wheel commands after mixing, per mille.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct WheelCommand {
    /// Left wheel, positive drives the robot forward.
    pub left: PerMille,
    /// Right wheel, positive drives the robot forward.
    pub right: PerMille,
}

/// Differential mix with ratio-keeping saturation; see the module doc.
pub fn mix(forward: PerMille, turn: PerMille) -> WheelCommand {
    let f = i32::from(forward.get());
    let t = i32::from(turn.get());
    let (mut left, mut right) = (f + t, f - t);
    let peak = left.abs().max(right.abs());
    if peak > 1000 {
        left = left * 1000 / peak;
        right = right * 1000 / peak;
    }
    WheelCommand {
        left: PerMille::saturating(left),
        right: PerMille::saturating(right),
    }
}

/// One DRV8833 bridge: IN1 and IN2 on two PWM channels.
#[derive(Debug)]
pub struct HBridge<IN1, IN2> {
    in1: IN1,
    in2: IN2,
}

impl<IN1, IN2, E> HBridge<IN1, IN2>
where
    IN1: SetDutyCycle<Error = E>,
    IN2: SetDutyCycle<Error = E>,
{
    /// A bridge on two channels; call [`HBridge::coast`] to put it in a
    /// known state.
    pub fn new(in1: IN1, in2: IN2) -> Self {
        HBridge { in1, in2 }
    }

    /// Drive at `speed` (positive = IN1 side high = forward) with `decay`.
    pub fn set(&mut self, speed: PerMille, decay: Decay) -> Result<(), Error<E>> {
        let magnitude = speed.get().unsigned_abs();
        let ahead = speed.get() >= 0;
        match (decay, ahead) {
            (Decay::Fast, true) => {
                self.in2.set_duty_cycle_fully_off()?;
                self.in1.set_duty_cycle_fraction(magnitude, 1000)?;
            }
            (Decay::Fast, false) => {
                self.in1.set_duty_cycle_fully_off()?;
                self.in2.set_duty_cycle_fraction(magnitude, 1000)?;
            }
            (Decay::Slow, true) => {
                self.in1.set_duty_cycle_fully_on()?;
                self.in2.set_duty_cycle_fraction(1000 - magnitude, 1000)?;
            }
            (Decay::Slow, false) => {
                self.in2.set_duty_cycle_fully_on()?;
                self.in1.set_duty_cycle_fraction(1000 - magnitude, 1000)?;
            }
        }
        Ok(())
    }

    /// Both inputs low: outputs off, the motor freewheels.
    pub fn coast(&mut self) -> Result<(), Error<E>> {
        self.in1.set_duty_cycle_fully_off()?;
        self.in2.set_duty_cycle_fully_off()?;
        Ok(())
    }

    /// Both inputs high: windings shorted, the motor brakes.
    pub fn brake(&mut self) -> Result<(), Error<E>> {
        self.in1.set_duty_cycle_fully_on()?;
        self.in2.set_duty_cycle_fully_on()?;
        Ok(())
    }

    /// Give the channels back.
    pub fn destroy(self) -> (IN1, IN2) {
        (self.in1, self.in2)
    }
}

/// BugBot's two drive motors.
#[derive(Debug)]
pub struct Motors<L1, L2, R1, R2> {
    left: HBridge<L1, L2>,
    right: HBridge<R1, R2>,
    config: MotorConfig,
}

impl<L1, L2, R1, R2, E> Motors<L1, L2, R1, R2>
where
    L1: SetDutyCycle<Error = E>,
    L2: SetDutyCycle<Error = E>,
    R1: SetDutyCycle<Error = E>,
    R2: SetDutyCycle<Error = E>,
{
    /// Both bridges, coasting. Fails if a channel refuses the stop.
    pub fn new(
        left: HBridge<L1, L2>,
        right: HBridge<R1, R2>,
        config: MotorConfig,
    ) -> Result<Self, Error<E>> {
        let mut motors = Motors {
            left,
            right,
            config,
        };
        motors.stop()?;
        Ok(motors)
    }

    /// Drive with `forward` and `turn` (positive = clockwise from above),
    /// both per mille; returns the mixed wheel commands that were applied.
    pub fn drive(&mut self, forward: PerMille, turn: PerMille) -> Result<WheelCommand, Error<E>> {
        let command = mix(forward, turn);
        let orient = |v: PerMille, invert: bool| {
            if invert {
                PerMille::saturating(-i32::from(v.get()))
            } else {
                v
            }
        };
        self.left.set(
            orient(command.left, self.config.invert_left),
            self.config.decay,
        )?;
        self.right.set(
            orient(command.right, self.config.invert_right),
            self.config.decay,
        )?;
        Ok(command)
    }

    /// Coast both motors (outputs off).
    pub fn stop(&mut self) -> Result<(), Error<E>> {
        self.left.coast()?;
        self.right.coast()
    }

    /// Brake both motors (windings shorted).
    pub fn brake(&mut self) -> Result<(), Error<E>> {
        self.left.brake()?;
        self.right.brake()
    }

    /// Give the bridges back, without stopping them.
    pub fn destroy(self) -> (HBridge<L1, L2>, HBridge<R1, R2>) {
        (self.left, self.right)
    }
}
