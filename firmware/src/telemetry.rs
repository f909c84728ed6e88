//! Telemetry task: moves the SLAM loop's encoded frames ([`TELEMETRY_FRAMES`]) out on
//! UART1 TX (GP8) at 921600 baud 8N1, by DMA (channel 2, UART1 TX DREQ), and offers a copy
//! of each to the USB serial port ([`crate::usb`]).
//!
//! The frames are the telemetry stream (`wire::telemetry`: postcard body,
//! CRC-16, COBS, `0x00` after every frame); what goes out when is set by
//! [`crate::slam_task::TELEMETRY_SCHEDULE`]. This task never waits on the SLAM loop and
//! the loop never waits on it: frames queue in a bounded channel and the loop drops (and
//! counts) what does not fit. A lone `0x00` goes out first so a receiver that was
//! listening before reset drops its partial frame.
//!
//! UART1 is the link that must not miss frames (the emulator harness and the radio read
//! it); USB is best effort: [`usb::offer`] never waits, so a PC that is absent or not
//! reading costs a frame copy at most, never UART time.

use embassy_rp::uart::{self, UartTx};
use embassy_time::{with_timeout, Duration};

use crate::board::{TelemetryLinkPins, TELEMETRY_BAUD};
use crate::health::HEALTH;
use crate::slam_task::TELEMETRY_FRAMES;
use crate::{usb, Irqs};

/// Longest one frame may take to leave: 142 bytes take 1.5 ms at 921600 baud.
const WRITE_TIMEOUT: Duration = Duration::from_millis(50);

/// Runs the telemetry link for good.
#[embassy_executor::task]
pub async fn telemetry_task(pins: TelemetryLinkPins, irqs: Irqs) -> ! {
    let mut config = uart::Config::default();
    config.baudrate = TELEMETRY_BAUD;
    let mut uart = UartTx::new(pins.uart, pins.tx, pins.tx_dma, irqs, config);
    send(&mut uart, &[0]).await;
    loop {
        let frame = TELEMETRY_FRAMES.receive().await;
        usb::offer(&frame);
        send(&mut uart, frame.as_bytes()).await;
    }
}

/// Writes `bytes`, counting a failure or a timeout.
async fn send(uart: &mut UartTx<'static, uart::Async>, bytes: &[u8]) {
    match with_timeout(WRITE_TIMEOUT, uart.write(bytes)).await {
        Ok(Ok(())) => {}
        Ok(Err(e)) => {
            defmt::warn!("telemetry: UART write failed: {}", e);
            HEALTH.telemetry_errors.bump();
        }
        Err(_) => HEALTH.telemetry_errors.bump(),
    }
}
