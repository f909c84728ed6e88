//! Telemetry task (UART1 for now, USB CDC later): sends each SLAM tick's report to the host.

use embassy_rp::uart::{self, BufferedUart};
use static_cell::ConstStaticCell;

use crate::board::{TelemetryLinkPins, TELEMETRY_BAUD};
use crate::slam_task::ReportReceiver;
use crate::Irqs;

/// Transmit buffer, in bytes: room for a report frame and a map slice per tick.
const TX_BUFFER_BYTES: usize = 512;
/// Receive buffer, in bytes: host commands are short.
const RX_BUFFER_BYTES: usize = 64;

static TX_BUFFER: ConstStaticCell<[u8; TX_BUFFER_BYTES]> =
    ConstStaticCell::new([0; TX_BUFFER_BYTES]);
static RX_BUFFER: ConstStaticCell<[u8; RX_BUFFER_BYTES]> =
    ConstStaticCell::new([0; RX_BUFFER_BYTES]);

/// Runs the telemetry link.
///
/// Until the project's telemetry framing exists this only follows the reports (so the
/// seam is exercised) and sends nothing; defmt carries the once-a-second log meanwhile.
///
/// Wiring the framing: for each report, `emit` a telemetry frame (pose, fix outcome,
/// staleness, counters) into a stack buffer and `write_all` it to `uart`; send the map in
/// row slices spread over ticks so one tick never blocks on the whole grid. A full TX
/// buffer must drop a frame (and count it), never stall the SLAM loop: the loop does not
/// wait on this task.
#[embassy_executor::task]
pub async fn telemetry_task(pins: TelemetryLinkPins, irqs: Irqs, mut reports: ReportReceiver) -> ! {
    let mut config = uart::Config::default();
    config.baudrate = TELEMETRY_BAUD;
    let _uart = BufferedUart::new(
        pins.uart,
        pins.tx,
        pins.rx,
        irqs,
        TX_BUFFER.take(),
        RX_BUFFER.take(),
        config,
    );
    loop {
        let _report = reports.changed().await;
    }
}
