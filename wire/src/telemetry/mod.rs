//! The robot's telemetry stream: framed binary messages from the robot to a viewer.
//!
//! The robot sends, on a UART or USB CDC link, a [`Message::Hello`] at start and every
//! few seconds (so a viewer can join late), a [`Message::Tick`] every SLAM tick (preceded
//! by that tick's raw inputs, [`Message::Inputs`], when the schedule records them, and
//! followed by a [`Message::Filter`] when the robot flies the filter), a chunk of the map
//! ([`Message::MapRows`]) every tick, round robin, and a [`Message::Health`] every second. [`Streamer`] decides which, [`encode`] frames one message into the
//! caller's buffer, and [`StreamDecoder`] turns received bytes back into messages.
//!
//! `no_std`, no allocator, no floating point; nothing here panics on any input.
//!
//! # Byte layout
//!
//! One frame on the wire is
//!
//! ```text
//! COBS( VERSION | postcard(Message) | CRC16_LE ) | 0x00
//! ```
//!
//! - `VERSION` is one byte, [`WIRE_VERSION`] (`0xBA`: BugBot telemetry, layout 10). A
//!   receiver drops frames with any other value.
//! - `postcard(Message)` is the [postcard 1.x] encoding of [`Message`]: integers `u16`,
//!   `u32`, `i32` are LEB128 varints (signed ones zigzag-mapped first), `u8` and `i8` are
//!   one raw byte, an enum is its variant index as a varint followed by its fields, a
//!   struct is its fields in order with nothing between them.
//! - `CRC16_LE` is CRC-16/CCITT-FALSE (polynomial `0x1021`, initial value `0xFFFF`, no
//!   reflection, no final XOR; check value `0x29B1` for `"123456789"`) over the
//!   `VERSION` byte and the postcard bytes, sent low byte first.
//! - `COBS` is Consistent Overhead Byte Stuffing: the stuffed frame holds no `0x00`, so
//!   `0x00` ends every frame and a receiver resynchronises at the next one. A block of 254
//!   non-zero bytes is code `0xFF` with no implied zero. Empty frames (`0x00 0x00`) are
//!   ignored, so a sender may send a lone `0x00` first to end a receiver's partial frame.
//!
//! Messages (variant index, then fields in order):
//!
//! | index | message | fields |
//! |---|---|---|
//! | 0 | `Hello` | `width: u16`, `height: u16` (cells), `cell_mm: i32`, `origin_x_mm: i32`, `origin_y_mm: i32`, `free_below: i8`, `occupied_above: i8` (cell units, below), `firmware: u8 major, u8 minor, u8 patch`, `localiser` (varint 0 dead reckoning, 1 two-tag fix, 2 filter), then how the run started: `reset` (varint 0 power-on, 1 watchdog, 2 other), `resumed: bool` (one byte 0 or 1: the map, pose and route were taken up from before the reset), `resumes: u16` (resets resumed from since the last fresh start) |
//! | 1 | `Tick` | `tick: u32`, `time_ms: u32`, `x_um: i32`, `y_um: i32`, `heading_bits: u32` (2^32 per turn, clockwise from +y), `fix` (varint 0 not attempted, 1 taken, 2 rejected followed by varint 0 geometry / 1 gate / 2 too old), `stale: u8` (bit 0 flow, bit 1 gyro, bit 2 depth), `cells_written: u32`, `doubts: u16` (the inputs the core doubts and why, four bits each: gyro in bits 0-3, flow 4-7, depth 8-11; 0 trusted, 1 missing, 2 stuck, 3 impossible, 4 jump, 5 moved while held, 6 more turn or drive than commanded, 7 disagrees with a tag, 8 late, 9 a turn the walls did not make, 10 far less turn or drive than commanded), then the counters as `u32`: ticks, fixes_taken, fixes_rejected_geometry, fixes_rejected_gate, fixes_rejected_too_old, relocalisations, beams_mapped, beams_invalid, flow_stale, gyro_stale, depth_stale, gyro_doubted, flow_doubted, depth_doubted, scans_withheld |
//! | 2 | `MapRows` | `first_row: u16`, `first_column: u16`, `cells`: varint count (at most [`MAX_CHUNK_CELLS`]) then one `i8` per cell |
//! | 3 | `Health` | twelve `u32`: depth_timeouts, depth_bus_errors, flow_no_surface, flow_outliers, flow_bus_errors, gyro_bus_errors, camera_bad_frames, tick_overruns, watchdog_feeds, depth_start_failures, flow_start_failures, gyro_start_failures |
//! | 4 | `Filter` | `tick: u32`, the pose covariance as six `i64` (xx, xy, yy, xh, yh, hh; position in 1/16 mm, heading in 2^-16 rad, so xx / 256 is mm² and hh / 2^32 rad²), the calibration as three `i32` (gyro_scale_ppm, gyro_bias_mdps, flow_scale_ppm), the tag counters as six `u32` (used, unknown_id, behind, too_far, too_old, gate) |
//! | 5 | `Inputs` | `tick: u32`, `time_ms: u32` (as the `Tick` that follows), then the `SensorFrame` the core stepped on: `dt_us: u32`; `flow`: option (postcard's option byte: 0 none, 1 some, then the value) of `forward_counts: i32`, `right_counts: i32` (flow counts); `gyro`: option of `rate_mdps: i32` (clockwise positive); `depth`: option of 8 ranges left to right, each an option of `u16` mm; `depth_age_us: u32`; `depth_doubt: u8` (what the depth task made of the scan against the frames before: 0 none, else a doubt code as in `Tick`); `tags`: varint count (at most `slam_core::MAX_TAGS`, 8) then each `id: u16`, `cx_centipx: i32`, `distance_mm: u32`; `tags_age_us: u32`; `external_pose`: option of `x_um: i32`, `y_um: i32`, `heading_bits: u32`; `commanded`: option of `speed_mm_s: i32`, `turn_mdps: i32` (what the motors were driven with) |
//!
//! An `Inputs` comes just before the `Tick` of the step it fed, when
//! [`Schedule::inputs`] is on. A `Filter` follows each `Tick` of a robot whose `Hello` says it flies the filter, and
//! carries the same `tick`.
//!
//! A `MapRows` chunk's cells run in row-major order from `(first_column, first_row)`,
//! carrying on at column 0 of the next row; row 0 is the grid's lowest y. A cell is its
//! log odds in sixteenths, the byte the robot's grid holds, moved by at most one step
//! only where a threshold lies past a byte's reach, so that its belief survives: it is
//! *free* when below `-free_below`,
//! *occupied* when above `occupied_above` (the `Hello`'s thresholds, in the same units),
//! and unknown otherwise, exactly as the robot's grid classifies it (see [`CellScale`]).
//!
//! # Budget
//!
//! The longest frame is [`MAX_FRAME_LEN`] (213) bytes, a full `Inputs`. On the seed's
//! 46 x 46 grid at 10 Hz with [`Schedule::DEFAULT`]: a `MapRows` of two rows (92 cells)
//! is 101 bytes a tick, an `Inputs` at most 213, a `Tick` at most 132, a `Filter` at most
//! 116, a `Health` at most 66 once a second and a `Hello` at most 37 every 5 s (the tests
//! check each bound). That is at most 10 x (101 + 213 + 132 + 116) + 66 + 8 = 5,694
//! bytes/s, and the whole map refreshes every 2.3 s. The firmware sends two chunks a
//! tick: at most 6,703 bytes/s, 7.3 % of its 921,600 baud 8N1 UART (92,160 bytes/s), of
//! which the inputs are 2,130 bytes/s (2.3 %). Without them (`inputs: false`) a run cannot
//! be replayed, but the stream is a third shorter.
//!
//! # Files
//!
//! `message.rs` the messages, `health.rs` the one list of sensor counters,
//! `core_layout.rs` the core's own types on the wire, `cell_scale.rs` a map cell in one
//! byte, `stream.rs` the sender ([`Streamer`], [`encode`]), `decode.rs` the receiver
//! ([`StreamDecoder`]).
//!
//! [postcard 1.x]: https://postcard.jamesmunns.com/wire-format

mod cell_scale;
mod core_layout;
mod decode;
mod health;
mod message;
mod stream;

pub use crate::framing::{DecoderStats, FrameError};
pub use cell_scale::CellScale;
pub use core_layout::serialize_counters;
pub use decode::{Frames, StreamDecoder};
pub use health::SensorHealth;
pub use message::{
    Boot, CellChunk, FilterState, FirmwareVersion, Hello, Inputs, MapRows, Message, ResetCause,
    Tick, STALE_DEPTH, STALE_FLOW, STALE_GYRO,
};
pub use stream::{encode, EncodeError, Schedule, Streamer};

/// The first byte of every frame: `0xBA`, BugBot telemetry layout 10.
///
/// Bumped whenever the layout changes, so an old viewer drops new frames instead of
/// misreading them. Layout 2 added the start-up failure counts to `Health`; layout 3 the
/// `TooOld` fix rejection and its counter to `Tick`; layout 4 the `Hello`'s localiser and
/// the `Filter` message; layout 5 the `Inputs` message; layout 6 the doubted inputs and
/// their counters to `Tick`, and the `Hello`'s boot (reset cause, resumed or not); layout
/// 7 the commanded motion to `Inputs` (and doubt code 6 to `Tick`); layout 8 whether the
/// `Hello`'s filter matches scans against the map; layout 9 the depth scan's own doubt to
/// `Inputs` (and doubt codes 7 and 8 to `Tick`); layout 10 the counts of pictures
/// repeated, leapt and late to `Tick`'s counters.
pub const WIRE_VERSION: u8 = 0xBA;

/// Most cells one [`MapRows`] carries: two rows of the seed's 46-cell grid fit, and the
/// frame stays under 150 bytes (1.6 ms at 921,600 baud).
pub const MAX_CHUNK_CELLS: usize = 128;

/// Longest postcard encoding of any [`Message`], in bytes: a full [`Inputs`] (index 1; tick,
/// time and `dt_us` 5 each; flow 1 + 5 + 5; gyro 1 + 5; depth 1 + 8 x (1 + 3); depth age
/// 5; depth doubt 1; eight tags, a 1-byte count and 3 + 5 + 5 each; tags age 5; external pose
/// 1 + 5 + 5 + 5; command 1 + 5 + 5). A full [`MapRows`] is shorter: 1 + 3 + 3 + 2 + [`MAX_CHUNK_CELLS`].
pub const MAX_MESSAGE_LEN: usize = 1
    + 5
    + 5
    + 5
    + (1 + 5 + 5)
    + (1 + 5)
    + (1 + slam_core::BEAMS * (1 + 3))
    + 5
    + 1
    + (1 + slam_core::MAX_TAGS * (3 + 5 + 5))
    + 5
    + (1 + 5 + 5 + 5)
    + (1 + 5 + 5);

/// Longest frame before stuffing: version byte, message, CRC.
pub const MAX_RAW_LEN: usize = 1 + MAX_MESSAGE_LEN + 2;

/// Longest frame on the wire, in bytes, delimiter included: COBS adds one byte per 254
/// started, the delimiter one more. Size encode buffers with this.
pub const MAX_FRAME_LEN: usize = MAX_RAW_LEN + MAX_RAW_LEN / 254 + 1 + 1;
