//! Camera co-processor task (UART0, 115200 baud 8N1, RX on GP1): decodes its tag-detection
//! frames and publishes each picture's tags into [`TagInbox`], the latest picture winning,
//! with the instant its frame began to be sent.
//!
//! The UART is *buffered* (interrupt driven into a ring buffer), not DMA: bytes that arrive
//! while the task is busy are kept, and it is an RX mode the emulator harness
//! (`tests/emulator`, which models the PL011's FIFOs and `UARTDMACR`) runs.
//!
//! Frames are the camera link's COBS + CRC frames (`wire::camera_link`); the decoder
//! resynchronises at the next `0x00` after line noise or a cut frame. Each good frame, even
//! one with no tags, replaces the previous picture: a picture with no tags in view is news
//! too (the tags left the view), and the SLAM tick treats an empty list as "no fix".

use embassy_rp::uart::{self, BufferedUart};
use embassy_time::{Duration, Instant};
use embedded_io_async::Read;
use slam_core::{TagDetection, TagDetections};
use static_cell::ConstStaticCell;
use wire::camera_link::{FrameDecoder, FrameRepr};

use crate::board::{CameraLinkPins, CAMERA_BAUD};
use crate::health::HEALTH;
use crate::inputs::{TagInbox, TagPicture};
use crate::Irqs;

/// Receive buffer, in bytes: a few frames of detections at 115200 baud between polls.
const RX_BUFFER_BYTES: usize = 256;
/// Transmit buffer, in bytes: commands to the co-processor are short (none yet).
const TX_BUFFER_BYTES: usize = 32;
/// Bytes taken from the ring buffer per read.
const READ_CHUNK_BYTES: usize = 64;

static RX_BUFFER: ConstStaticCell<[u8; RX_BUFFER_BYTES]> =
    ConstStaticCell::new([0; RX_BUFFER_BYTES]);
static TX_BUFFER: ConstStaticCell<[u8; TX_BUFFER_BYTES]> =
    ConstStaticCell::new([0; TX_BUFFER_BYTES]);

/// Runs the camera link for good. A UART error (overrun, framing, break) is counted as a
/// bad frame; the decoder then drops the cut frame at the next delimiter by itself.
#[embassy_executor::task]
pub async fn camera_task(pins: CameraLinkPins, irqs: Irqs, tags: &'static TagInbox) -> ! {
    let mut config = uart::Config::default();
    config.baudrate = CAMERA_BAUD;
    let mut uart = BufferedUart::new(
        pins.uart,
        pins.tx,
        pins.rx,
        irqs,
        TX_BUFFER.take(),
        RX_BUFFER.take(),
        config,
    );
    let mut decoder = FrameDecoder::new();
    let mut rejected_seen = 0u32;
    let mut chunk = [0u8; READ_CHUNK_BYTES];
    loop {
        let n = match uart.read(&mut chunk).await {
            Ok(n) => n,
            Err(e) => {
                defmt::warn!("camera: UART receive error {}", e);
                HEALTH.camera_bad_frames.bump();
                continue;
            }
        };
        // The read wakes on the RX interrupt, so this is within a few character times of
        // the chunk's last byte: when every frame that ends in the chunk arrived.
        let received = Instant::now();
        for frame in decoder.feed(chunk.get(..n).unwrap_or(&[])) {
            HEALTH.camera_frames.bump();
            tags.signal(TagPicture {
                tags: to_core(&frame),
                sent: sent_at(received, &frame),
            });
        }
        // The decoder counts rejects by kind; the health struct wants the total.
        let rejected = decoder.stats().bad_frames.total();
        HEALTH
            .camera_bad_frames
            .add(rejected.wrapping_sub(rejected_seen));
        rejected_seen = rejected;
    }
}

/// A character's time on the line, nanoseconds: 8N1 is ten bits.
const CHARACTER_NS: u32 = (10_000_000_000 / CAMERA_BAUD as u64) as u32;

/// When the co-processor began sending `frame`, whose last byte had arrived by
/// `received`: its bytes took a character time each. The co-processor sends a picture's
/// frame once it has found the tags, so this is the picture's moment less that work, which
/// the link does not report. The arrival is a frame's time on the line later, and in a
/// turn that is more heading than a filter the tags have made sure of allows.
fn sent_at(received: Instant, frame: &FrameRepr) -> Instant {
    let characters = u32::try_from(frame.wire_len()).unwrap_or(u32::MAX);
    let on_line_us = characters.saturating_mul(CHARACTER_NS) / 1_000;
    received
        .checked_sub(Duration::from_micros(u64::from(on_line_us)))
        .unwrap_or(received)
}

/// The core's view of one picture: id, centre column in centipixels, distance in
/// millimetres. The link's ranges are already checked (`cx <= 32000`), so no conversion
/// can fail; detections past the core's capacity are dropped and counted.
fn to_core(frame: &FrameRepr) -> TagDetections {
    let mut out = TagDetections::default();
    for d in frame.detections() {
        let detection = TagDetection {
            id: d.tag_id(),
            cx_centipx: i32::from(d.cx_centipx()),
            distance_mm: u32::from(d.distance_mm()),
        };
        if out.push(detection).is_err() {
            HEALTH.camera_tags_dropped.bump();
        }
    }
    out
}
