//! Camera co-processor task (UART0): parses its tag-detection frames and publishes each
//! picture's tags into [`TagInbox`].

use embassy_rp::uart::{self, BufferedUart};
use static_cell::ConstStaticCell;

use crate::board::{CameraLinkPins, CAMERA_BAUD};
use crate::inputs::TagInbox;
use crate::Irqs;

/// Receive buffer, in bytes: a few frames of detections at 115200 baud between polls.
const RX_BUFFER_BYTES: usize = 256;
/// Transmit buffer, in bytes: commands to the co-processor are short.
const TX_BUFFER_BYTES: usize = 32;

static RX_BUFFER: ConstStaticCell<[u8; RX_BUFFER_BYTES]> =
    ConstStaticCell::new([0; RX_BUFFER_BYTES]);
static TX_BUFFER: ConstStaticCell<[u8; TX_BUFFER_BYTES]> =
    ConstStaticCell::new([0; TX_BUFFER_BYTES]);

/// Runs the camera link.
///
/// Placeholder until the camera link's frame parser lands: the UART is up (buffered and
/// interrupt driven, so bytes arriving between reads are kept), nothing is published, so
/// every tick has no tags.
///
/// Wiring the parser: read bytes from `uart` (`embedded-io-async` `Read`), feed them to
/// `drivers::camera_link`'s decoder (COBS framing, CRC, checked `Packet`/`Repr`), and for
/// each complete picture `tags.signal(detections)`; a bad frame is counted and skipped.
#[embassy_executor::task]
pub async fn camera_task(pins: CameraLinkPins, irqs: Irqs, tags: &'static TagInbox) -> ! {
    let mut config = uart::Config::default();
    config.baudrate = CAMERA_BAUD;
    let _uart = BufferedUart::new(
        pins.uart,
        pins.tx,
        pins.rx,
        irqs,
        TX_BUFFER.take(),
        RX_BUFFER.take(),
        config,
    );
    let _ = tags;
    defmt::warn!("camera: link parser not wired; no tags");
    super::park().await
}
