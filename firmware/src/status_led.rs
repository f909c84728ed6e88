//! Status LED task: a 1 Hz heartbeat on GP25 shows the executor is running.

use embassy_rp::gpio::{Level, Output};
use embassy_rp::peripherals::PIN_25;
use embassy_rp::Peri;
use embassy_time::{Duration, Ticker};

/// Half the heartbeat period.
const HALF_PERIOD: Duration = Duration::from_millis(500);

/// Blinks the status LED.
#[embassy_executor::task]
pub async fn status_led_task(pin: Peri<'static, PIN_25>) -> ! {
    let mut led = Output::new(pin, Level::Low);
    let mut ticker = Ticker::every(HALF_PERIOD);
    loop {
        led.toggle();
        ticker.next().await;
    }
}
