//! DRV8833 mixing and PWM duty cycles against a recording fake channel.

use std::cell::RefCell;
use std::rc::Rc;

use drivers::motors::{mix, Decay, Error, HBridge, MotorConfig, Motors, PerMille, WheelCommand};
use embedded_hal::pwm::{ErrorKind, ErrorType, SetDutyCycle};

/// A PWM channel that records every duty cycle set (max duty 2000 so the
/// per-mille scaling is visible), and can be made to fail.
#[derive(Clone, Default)]
struct FakePwm {
    log: Rc<RefCell<Vec<u16>>>,
    fail: bool,
}

impl FakePwm {
    fn last(&self) -> Option<u16> {
        self.log.borrow().last().copied()
    }
}

impl ErrorType for FakePwm {
    type Error = ErrorKind;
}

impl SetDutyCycle for FakePwm {
    fn max_duty_cycle(&self) -> u16 {
        2000
    }

    fn set_duty_cycle(&mut self, duty: u16) -> Result<(), ErrorKind> {
        if self.fail {
            return Err(ErrorKind::Other);
        }
        self.log.borrow_mut().push(duty);
        Ok(())
    }
}

type Pins = [FakePwm; 4];

fn motors(config: MotorConfig) -> (Motors<FakePwm, FakePwm, FakePwm, FakePwm>, Pins) {
    let pins: Pins = Default::default();
    let m = Motors::new(
        HBridge::new(pins[0].clone(), pins[1].clone()),
        HBridge::new(pins[2].clone(), pins[3].clone()),
        config,
    )
    .unwrap();
    (m, pins)
}

fn duties(pins: &Pins) -> [Option<u16>; 4] {
    [
        pins[0].last(),
        pins[1].last(),
        pins[2].last(),
        pins[3].last(),
    ]
}

fn pm(v: i32) -> PerMille {
    PerMille::saturating(v)
}

fn wheels(l: i32, r: i32) -> WheelCommand {
    WheelCommand {
        left: pm(l),
        right: pm(r),
    }
}

#[test]
fn per_mille_clamps() {
    assert_eq!(pm(5000), PerMille::MAX);
    assert_eq!(pm(-1001), PerMille::MIN);
    assert_eq!(pm(i32::MIN).get(), -1000);
    assert_eq!(pm(-250).get(), -250);
}

#[test]
fn mixing_and_ratio_keeping_saturation() {
    assert_eq!(mix(pm(500), pm(0)), wheels(500, 500));
    assert_eq!(mix(pm(0), pm(300)), wheels(300, -300));
    // 1500 : 500 scaled to 1000 : 333, ratio 3 kept.
    assert_eq!(mix(pm(1000), pm(500)), wheels(1000, 333));
    assert_eq!(mix(pm(-1000), pm(-1000)), wheels(-1000, 0));
    // 400 : 1200 scaled to 333 : 1000.
    assert_eq!(mix(pm(800), pm(-400)), wheels(333, 1000));
    assert_eq!(mix(PerMille::MAX, PerMille::MIN), wheels(0, 1000));
}

#[test]
fn new_coasts_and_stop_coasts() {
    let (mut m, pins) = motors(MotorConfig::default());
    assert_eq!(duties(&pins), [Some(0); 4]);
    m.drive(pm(500), pm(0)).unwrap();
    m.stop().unwrap();
    assert_eq!(duties(&pins), [Some(0); 4]);
}

#[test]
fn slow_decay_forward_and_reverse() {
    let (mut m, pins) = motors(MotorConfig::default());
    // Left +750: IN1 high, IN2 at (1000 - 750) / 1000 of 2000.
    // Right +250: IN1 high, IN2 at 750 / 1000.
    assert_eq!(m.drive(pm(500), pm(250)).unwrap(), wheels(750, 250));
    assert_eq!(
        duties(&pins),
        [Some(2000), Some(500), Some(2000), Some(1500)]
    );
    // Reverse: IN2 high, IN1 inverted PWM.
    m.drive(pm(-1000), pm(0)).unwrap();
    assert_eq!(duties(&pins), [Some(0), Some(2000), Some(0), Some(2000)]);
}

#[test]
fn fast_decay_forward_and_reverse() {
    let (mut m, pins) = motors(MotorConfig {
        decay: Decay::Fast,
        ..MotorConfig::default()
    });
    m.drive(pm(300), pm(0)).unwrap();
    assert_eq!(duties(&pins), [Some(600), Some(0), Some(600), Some(0)]);
    m.drive(pm(-300), pm(0)).unwrap();
    assert_eq!(duties(&pins), [Some(0), Some(600), Some(0), Some(600)]);
}

#[test]
fn inverted_side_swaps_inputs() {
    let (mut m, pins) = motors(MotorConfig {
        decay: Decay::Fast,
        invert_left: true,
        invert_right: false,
    });
    m.drive(pm(300), pm(0)).unwrap();
    assert_eq!(duties(&pins), [Some(0), Some(600), Some(600), Some(0)]);
}

#[test]
fn brake_sets_all_high() {
    let (mut m, pins) = motors(MotorConfig::default());
    m.brake().unwrap();
    assert_eq!(duties(&pins), [Some(2000); 4]);
    let (left, _right) = m.destroy();
    let (in1, _in2) = left.destroy();
    assert_eq!(in1.last(), Some(2000));
}

#[test]
fn pwm_error_is_mapped() {
    let pins: Pins = Default::default();
    let mut bad = pins[3].clone();
    bad.fail = true;
    let result = Motors::new(
        HBridge::new(pins[0].clone(), pins[1].clone()),
        HBridge::new(pins[2].clone(), bad),
        MotorConfig::default(),
    );
    assert!(matches!(result, Err(Error::Pwm(ErrorKind::Other))));
}
