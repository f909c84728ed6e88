//! Motor task: owns the DRV8833's two PWM slices.

use embassy_rp::pwm::{self, Pwm};

use crate::board::{MotorPins, MOTOR_PWM_TOP};

/// Holds both motors in coast (both DRV8833 inputs low) at a 20 kHz PWM carrier.
///
/// Nothing commands motion yet. Wiring `drivers::motors::Motors`: `split()` each `Pwm`
/// into its A/B `PwmOutput`s (they implement `SetDutyCycle`), build the two `HBridge`s and
/// `Motors`, and give this task a `Signal` of drive commands (latest wins) with a timeout
/// that calls `stop()` (coast) when commands stop arriving.
#[embassy_executor::task]
pub async fn motor_task(pins: MotorPins) -> ! {
    let mut config = pwm::Config::default();
    config.top = MOTOR_PWM_TOP;
    // Compare 0 on both channels: both inputs low, the bridge coasts.
    config.compare_a = 0;
    config.compare_b = 0;
    let _left = Pwm::new_output_ab(
        pins.left_slice,
        pins.left_in1,
        pins.left_in2,
        config.clone(),
    );
    let _right = Pwm::new_output_ab(pins.right_slice, pins.right_in1, pins.right_in2, config);
    defmt::info!("motors: coasting (no motion commands yet)");
    crate::sensors::park().await
}
