//! PMW3901 optical flow task (SPI0 with DMA): adds each motion read to [`FlowInbox`]; the
//! SLAM tick takes the sum.

use embassy_rp::gpio::{Level, Output};
use embassy_rp::spi::{self, Phase, Polarity, Spi};

use crate::board::{FlowSensorPins, FLOW_SPI_HZ};
use crate::inputs::FlowInbox;
use crate::Irqs;

/// Runs the flow sensor.
///
/// Placeholder until the `drivers` crate's PMW3901 driver lands: the bus is up and CS is
/// high (deselected), nothing is published, so every tick's flow is stale.
///
/// Wiring the driver: `drivers::flow::Pmw3901` wants an `embedded-hal-async` `SpiDevice`:
/// wrap `spi` and `cs` in an exclusive device (`embedded-hal-bus`'s `ExclusiveDevice`, or
/// `embassy-embedded-hal`'s `SpiDevice` over a `Mutex` if the bus is ever shared), then
/// `init(&mut embassy_time::Delay)` and `read()` at 100 Hz or faster (a `Ticker`); add
/// each good reading, in robot frame (`forward_counts`, `right_counts`), with
/// `motion.add(..)`. Low-quality reads are skipped, so a tick without a good read is stale.
#[embassy_executor::task]
pub async fn flow_task(pins: FlowSensorPins, irqs: Irqs, motion: &'static FlowInbox) -> ! {
    let mut config = spi::Config::default();
    config.frequency = FLOW_SPI_HZ;
    // SPI mode 3: clock idles high, data captured on the rising (second) edge.
    config.polarity = Polarity::IdleHigh;
    config.phase = Phase::CaptureOnSecondTransition;
    let _spi = Spi::new(
        pins.spi,
        pins.sck,
        pins.mosi,
        pins.miso,
        pins.tx_dma,
        pins.rx_dma,
        irqs,
        config,
    );
    let _cs = Output::new(pins.cs, Level::High);
    let _ = motion;
    defmt::warn!("flow: PMW3901 driver not wired; flow input stays stale");
    super::park().await
}
