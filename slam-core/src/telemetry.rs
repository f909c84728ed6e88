//! The robot's telemetry stream: framed binary messages from the robot to a viewer.
//!
//! The robot sends, on a UART or USB CDC link, a [`Message::Hello`] at start and every
//! few seconds (so a viewer can join late), a [`Message::Tick`] every SLAM tick, a chunk
//! of the map ([`Message::MapRows`]) every tick, round robin, and a [`Message::Health`]
//! every second. [`Streamer`] decides which, [`encode`] frames one message into the
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
//! - `VERSION` is one byte, [`WIRE_VERSION`] (`0xB3`: BugBot telemetry, layout 3). A
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
//! | 0 | `Hello` | `width: u16`, `height: u16` (cells), `cell_mm: i32`, `origin_x_mm: i32`, `origin_y_mm: i32`, `free_below: i8`, `occupied_above: i8` (cell units, below), `firmware: u8 major, u8 minor, u8 patch` |
//! | 1 | `Tick` | `tick: u32`, `time_ms: u32`, `x_um: i32`, `y_um: i32`, `heading_bits: u32` (2^32 per turn, clockwise from +y), `fix` (varint 0 not attempted, 1 taken, 2 rejected followed by varint 0 geometry / 1 gate / 2 too old), `stale: u8` (bit 0 flow, bit 1 gyro, bit 2 depth), `cells_written: u32`, then the counters as `u32`: ticks, fixes_taken, fixes_rejected_geometry, fixes_rejected_gate, fixes_rejected_too_old, relocalisations, beams_mapped, beams_invalid, flow_stale, gyro_stale, depth_stale |
//! | 2 | `MapRows` | `first_row: u16`, `first_column: u16`, `cells`: varint count (at most [`MAX_CHUNK_CELLS`]) then one `i8` per cell |
//! | 3 | `Health` | twelve `u32`: depth_timeouts, depth_bus_errors, flow_no_surface, flow_outliers, flow_bus_errors, gyro_bus_errors, camera_bad_frames, tick_overruns, watchdog_feeds, depth_start_failures, flow_start_failures, gyro_start_failures |
//!
//! A `MapRows` chunk's cells run in row-major order from `(first_column, first_row)`,
//! carrying on at column 0 of the next row; row 0 is the grid's lowest y. A cell is its
//! Q8 log odds divided by 16 (`>> 4`), saturated to `[-128, 127]`, and then moved by at
//! most one step so that its belief survives: it is *free* when below `-free_below`,
//! *occupied* when above `occupied_above` (the `Hello`'s thresholds, in the same units),
//! and unknown otherwise, exactly as the robot's grid classifies it (see [`CellScale`]).
//!
//! # Budget
//!
//! The longest frame is [`MAX_FRAME_LEN`] (142) bytes. On the seed's 46 x 46 grid at
//! 10 Hz with [`Schedule::DEFAULT`]: a `MapRows` of two rows (92 cells) is 101 bytes a
//! tick, a `Tick` at most 96 (about 36 on the seed route), a `Health` at most 66 once a
//! second and a `Hello` at most 33 every 5 s. That is at most 10 x (101 + 96) + 66 + 7 =
//! 2,043 bytes/s (about 1,400 on the seed route), 18 % of a 115,200 baud 8N1 UART
//! (11,520 bytes/s) and nothing for USB; the whole map refreshes every 2.3 s.
//!
//! [postcard 1.x]: https://postcard.jamesmunns.com/wire-format

use crate::framing::{cobs_decode_in_place, cobs_encode, cobs_len, Collected, FrameCollector};
use crate::grid::{Evidence, GridMap, LogOdds, Occupancy};
use crate::pose::Pose;
use crate::slam::{Counters, Staleness, StepReport};
use crate::tagfix::FixOutcome;
use crate::Angle;
use core::fmt;
use serde::de::{self, SeqAccess, Visitor};
use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// The first byte of every frame: `0xB3`, BugBot telemetry layout 3.
///
/// Bumped whenever the layout changes, so an old viewer drops new frames instead of
/// misreading them. Layout 2 added the start-up failure counts to `Health`; layout 3 the
/// `TooOld` fix rejection and its counter to `Tick`.
pub const WIRE_VERSION: u8 = 0xB3;

/// Most cells one [`MapRows`] carries: two rows of the seed's 46-cell grid fit, and the
/// frame stays under 150 bytes (13 ms at 115,200 baud).
pub const MAX_CHUNK_CELLS: usize = 128;

/// Longest postcard encoding of any [`Message`], in bytes (a full [`MapRows`]: index 1,
/// two 3-byte `u16` varints, a 2-byte count and 128 cells).
pub const MAX_MESSAGE_LEN: usize = 1 + 3 + 3 + 2 + MAX_CHUNK_CELLS;

/// Longest frame before stuffing: version byte, message, CRC.
pub const MAX_RAW_LEN: usize = 1 + MAX_MESSAGE_LEN + 2;

/// Longest frame on the wire, in bytes, delimiter included: COBS adds one byte per 254
/// started, the delimiter one more. Size encode buffers with this.
pub const MAX_FRAME_LEN: usize = MAX_RAW_LEN + MAX_RAW_LEN / 254 + 1 + 1;

/// The firmware's version, sent in every [`Hello`].
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FirmwareVersion {
    /// Incompatible changes.
    pub major: u8,
    /// Added features.
    pub minor: u8,
    /// Fixes.
    pub patch: u8,
}

/// What a viewer needs before it can draw anything: the grid and who sent it.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Hello {
    /// Columns in the grid.
    pub width: u16,
    /// Rows in the grid.
    pub height: u16,
    /// Side of a cell, millimetres.
    pub cell_mm: i32,
    /// Map x of the grid's lower-left corner, millimetres.
    pub origin_x_mm: i32,
    /// Map y of the grid's lower-left corner, millimetres.
    pub origin_y_mm: i32,
    /// A cell below `-free_below` is free, in cell units (log odds / 16).
    pub free_below: i8,
    /// A cell above `occupied_above` is occupied, in cell units (log odds / 16).
    pub occupied_above: i8,
    /// Which firmware is talking.
    pub firmware: FirmwareVersion,
}

impl Hello {
    /// The `Hello` describing `map`. Dimensions past `u16::MAX` saturate (no such grid
    /// fits in an RP2040's 264 KB anyway).
    pub fn new<const W: usize, const H: usize>(
        map: &GridMap<W, H>,
        firmware: FirmwareVersion,
    ) -> Hello {
        let g = map.geometry();
        let scale = CellScale::new(map.evidence());
        Hello {
            width: u16::try_from(W).unwrap_or(u16::MAX),
            height: u16::try_from(H).unwrap_or(u16::MAX),
            cell_mm: g.cell_mm,
            origin_x_mm: g.origin_x_mm,
            origin_y_mm: g.origin_y_mm,
            free_below: scale.free_below,
            occupied_above: scale.occupied_above,
            firmware,
        }
    }

    /// The thresholds to classify this grid's cells with.
    pub fn scale(&self) -> CellScale {
        CellScale {
            free_below: self.free_below,
            occupied_above: self.occupied_above,
        }
    }
}

/// One SLAM tick: the pose, the fix and the running totals.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Tick {
    /// Steps run, this one included (the core's `counters.ticks`).
    pub tick: u32,
    /// Time of the tick since start, milliseconds (wraps after 49 days).
    pub time_ms: u32,
    /// Pose x, micrometres.
    pub x_um: i32,
    /// Pose y, micrometres.
    pub y_um: i32,
    /// Heading as a binary angle: 2^32 per turn, clockwise from +y.
    pub heading_bits: u32,
    /// Whether a tag fix was taken, rejected or not tried.
    pub fix: FixOutcome,
    /// Inputs missing this tick: bit 0 flow, bit 1 gyro, bit 2 depth ([`Tick::staleness`]).
    pub stale: u8,
    /// Grid cells written this tick.
    pub cells_written: u32,
    /// The core's totals since start.
    pub counters: Counters,
}

/// Bit of [`Tick::stale`]: no flow reading this tick.
pub const STALE_FLOW: u8 = 1 << 0;
/// Bit of [`Tick::stale`]: no gyro reading this tick.
pub const STALE_GYRO: u8 = 1 << 1;
/// Bit of [`Tick::stale`]: no depth scan this tick.
pub const STALE_DEPTH: u8 = 1 << 2;

impl Tick {
    /// The `Tick` for a step's report, at `time_ms` since start.
    pub fn new(time_ms: u32, report: &StepReport) -> Tick {
        let s = &report.stale;
        Tick {
            tick: report.counters.ticks,
            time_ms,
            x_um: report.pose.x_um,
            y_um: report.pose.y_um,
            heading_bits: report.pose.heading.bits(),
            fix: report.fix,
            stale: (u8::from(s.flow) * STALE_FLOW)
                | (u8::from(s.gyro) * STALE_GYRO)
                | (u8::from(s.depth) * STALE_DEPTH),
            cells_written: report.cells_written,
            counters: report.counters,
        }
    }

    /// The pose this tick mapped at.
    pub fn pose(&self) -> Pose {
        Pose {
            x_um: self.x_um,
            y_um: self.y_um,
            heading: Angle::from_bits(self.heading_bits),
        }
    }

    /// The stale bits as the core's flags; unknown bits are ignored.
    pub fn staleness(&self) -> Staleness {
        Staleness {
            flow: self.stale & STALE_FLOW != 0,
            gyro: self.stale & STALE_GYRO != 0,
            depth: self.stale & STALE_DEPTH != 0,
        }
    }
}

/// Per-sensor fault counters since start, filled in by the firmware's tasks.
///
/// All wrap at `u32::MAX`. A counter that climbs says which wire to check.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SensorHealth {
    /// Depth scans that did not arrive in time.
    pub depth_timeouts: u32,
    /// I2C errors talking to the depth sensor.
    pub depth_bus_errors: u32,
    /// Flow readings dropped because the surface quality was too low.
    pub flow_no_surface: u32,
    /// Flow readings dropped as implausible.
    pub flow_outliers: u32,
    /// SPI errors talking to the flow sensor.
    pub flow_bus_errors: u32,
    /// SPI errors talking to the gyro.
    pub gyro_bus_errors: u32,
    /// Camera link frames that failed COBS, CRC or parsing.
    pub camera_bad_frames: u32,
    /// Ticks whose step started late or ran past the next tick.
    pub tick_overruns: u32,
    /// Times the watchdog was fed.
    pub watchdog_feeds: u32,
    /// Depth sensor start-ups that failed (power-up, firmware upload or configuration);
    /// each is retried after a back-off. Climbing with no depth scans ever arriving: the
    /// sensor never started.
    pub depth_start_failures: u32,
    /// Flow sensor start-ups that failed; each is retried after a back-off.
    pub flow_start_failures: u32,
    /// Gyro start-ups that failed; each is retried after a back-off.
    pub gyro_start_failures: u32,
}

/// A run of map cells, in cell units; see the module doc for the scale.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MapRows {
    /// Row of the first cell (0 is the lowest y).
    pub first_row: u16,
    /// Column of the first cell; the run carries on at column 0 of the next row.
    pub first_column: u16,
    /// The cells, row-major.
    pub cells: CellChunk,
}

/// Up to [`MAX_CHUNK_CELLS`] cells: a fixed array and a length, so no allocator.
#[derive(Clone, Copy)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CellChunk {
    len: u8,
    cells: [i8; MAX_CHUNK_CELLS],
}

impl CellChunk {
    /// No cells.
    pub const fn new() -> CellChunk {
        CellChunk {
            len: 0,
            cells: [0; MAX_CHUNK_CELLS],
        }
    }

    /// A chunk holding `cells`, or `None` if there are more than [`MAX_CHUNK_CELLS`].
    pub fn from_slice(cells: &[i8]) -> Option<CellChunk> {
        let mut chunk = CellChunk::new();
        chunk.cells.get_mut(..cells.len())?.copy_from_slice(cells);
        chunk.len = u8::try_from(cells.len()).ok()?;
        Some(chunk)
    }

    /// Appends a cell; `Err` when full.
    pub fn push(&mut self, cell: i8) -> Result<(), Full> {
        let slot = self.cells.get_mut(self.len as usize).ok_or(Full)?;
        *slot = cell;
        self.len += 1;
        Ok(())
    }

    /// The cells held.
    pub fn as_slice(&self) -> &[i8] {
        self.cells.get(..self.len as usize).unwrap_or(&[])
    }

    /// How many cells are held.
    pub fn len(&self) -> usize {
        self.len as usize
    }

    /// Whether no cells are held.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
}

impl Default for CellChunk {
    fn default() -> Self {
        CellChunk::new()
    }
}

impl PartialEq for CellChunk {
    fn eq(&self, other: &Self) -> bool {
        self.as_slice() == other.as_slice()
    }
}

impl Eq for CellChunk {}

impl fmt::Debug for CellChunk {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_list().entries(self.as_slice()).finish()
    }
}

/// A fixed-capacity container had no room.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Full;

impl Serialize for CellChunk {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeSeq;
        let mut seq = serializer.serialize_seq(Some(self.len()))?;
        for cell in self.as_slice() {
            seq.serialize_element(cell)?;
        }
        seq.end()
    }
}

impl<'de> Deserialize<'de> for CellChunk {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct ChunkVisitor;
        impl<'de> Visitor<'de> for ChunkVisitor {
            type Value = CellChunk;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                write!(f, "at most {MAX_CHUNK_CELLS} cells")
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<CellChunk, A::Error> {
                // postcard gives the count up front: refuse an impossible one before reading.
                if seq.size_hint().is_some_and(|n| n > MAX_CHUNK_CELLS) {
                    return Err(de::Error::invalid_length(
                        seq.size_hint().unwrap_or(0),
                        &self,
                    ));
                }
                let mut chunk = CellChunk::new();
                while let Some(cell) = seq.next_element::<i8>()? {
                    chunk
                        .push(cell)
                        .map_err(|Full| de::Error::invalid_length(MAX_CHUNK_CELLS + 1, &self))?;
                }
                Ok(chunk)
            }
        }
        deserializer.deserialize_seq(ChunkVisitor)
    }
}

/// Everything the robot sends.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Message {
    /// The grid and the firmware (variant 0).
    Hello(Hello),
    /// One tick (variant 1).
    Tick(Tick),
    /// A chunk of the map (variant 2).
    MapRows(MapRows),
    /// Sensor fault counters (variant 3).
    Health(SensorHealth),
}

/// How a map cell is squeezed into one byte without changing what it means.
///
/// A cell is sent as its Q8 log odds `>> 4` (1/16 of a log-odds unit per step, so the
/// seed's clamp of +-8.0 just fits in an `i8` after saturating), nudged by one step where
/// the shift alone would move it across a belief threshold: the viewer's map then agrees
/// with the robot's belief for belief.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CellScale {
    /// A cell below `-free_below` is free, cell units (0 to 127).
    pub free_below: i8,
    /// A cell above `occupied_above` is occupied, cell units (0 to 126).
    pub occupied_above: i8,
}

impl CellScale {
    /// The thresholds for a grid using `evidence`, shifted to cell units and kept where
    /// both beliefs stay reachable in an `i8`.
    pub fn new(evidence: &Evidence) -> CellScale {
        let shift = |t: LogOdds| (t >> 4).clamp(0, 126) as i8;
        CellScale {
            free_below: shift(evidence.free_below),
            occupied_above: shift(evidence.occupied_above),
        }
    }

    /// The byte sent for a cell of `log_odds` that the robot believes is `belief`.
    pub fn encode(&self, log_odds: LogOdds, belief: Occupancy) -> i8 {
        // In i16 so that no threshold, however set, can overflow.
        let shifted = (log_odds >> 4).clamp(i8::MIN as i16, i8::MAX as i16);
        let free = (self.free_below as i16).clamp(0, 127);
        let occupied = (self.occupied_above as i16).clamp(0, 126);
        let cell = match belief {
            Occupancy::Free => shifted.min(-free - 1),
            Occupancy::Occupied => shifted.max(occupied + 1),
            Occupancy::Unknown => shifted.clamp(-free, occupied),
        };
        cell.clamp(i8::MIN as i16, i8::MAX as i16) as i8
    }

    /// What a received cell byte means.
    pub fn belief(&self, cell: i8) -> Occupancy {
        if (cell as i16) < -(self.free_below as i16) {
            Occupancy::Free
        } else if cell > self.occupied_above {
            Occupancy::Occupied
        } else {
            Occupancy::Unknown
        }
    }
}

/// When each kind of message goes out, in ticks.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Schedule {
    /// A `Hello` on the first tick and then every this many ticks (0: only the first).
    pub hello_every_ticks: u32,
    /// A `Health` every this many ticks, starting with the first (0: never).
    pub health_every_ticks: u32,
    /// `MapRows` chunks per tick.
    pub map_chunks_per_tick: u8,
}

impl Schedule {
    /// At 10 Hz: a `Hello` every 5 s, a `Health` every second, one chunk a tick.
    pub const DEFAULT: Schedule = Schedule {
        hello_every_ticks: 50,
        health_every_ticks: 10,
        map_chunks_per_tick: 1,
    };
}

impl Default for Schedule {
    fn default() -> Self {
        Schedule::DEFAULT
    }
}

/// The sending side's state: which tick this is and where the map sweep has got to.
///
/// The firmware and the simulator both call [`Streamer::tick`] once per step, so the
/// simulator's recorded stream is the one the robot sends.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Streamer {
    schedule: Schedule,
    firmware: FirmwareVersion,
    ticks_sent: u32,
    next_column: u16,
    next_row: u16,
}

impl Streamer {
    /// A stream starting with a `Hello` and the map's first row.
    pub const fn new(schedule: Schedule, firmware: FirmwareVersion) -> Streamer {
        Streamer {
            schedule,
            firmware,
            ticks_sent: 0,
            next_column: 0,
            next_row: 0,
        }
    }

    /// Hands `send` this tick's messages, in order: a `Hello` when due, the `Tick`, the
    /// map chunks, and `health` when due. `time_ms` is the tick's time since start.
    pub fn tick<const W: usize, const H: usize>(
        &mut self,
        time_ms: u32,
        report: &StepReport,
        map: &GridMap<W, H>,
        health: &SensorHealth,
        mut send: impl FnMut(&Message),
    ) {
        let n = self.ticks_sent;
        self.ticks_sent = n.wrapping_add(1);
        let due = |every: u32| n.checked_rem(every) == Some(0);
        if n == 0 || due(self.schedule.hello_every_ticks) {
            send(&Message::Hello(Hello::new(map, self.firmware)));
        }
        send(&Message::Tick(Tick::new(time_ms, report)));
        for _ in 0..self.schedule.map_chunks_per_tick {
            if let Some(rows) = self.next_map_rows(map) {
                send(&Message::MapRows(rows));
            }
        }
        if due(self.schedule.health_every_ticks) {
            send(&Message::Health(*health));
        }
    }

    /// Hands `send` the whole map from row 0, so a viewer holds the final map when the run
    /// stops (the sweep otherwise lags by up to its period).
    pub fn send_whole_map<const W: usize, const H: usize>(
        &mut self,
        map: &GridMap<W, H>,
        mut send: impl FnMut(&Message),
    ) {
        self.next_column = 0;
        self.next_row = 0;
        while let Some(rows) = self.next_map_rows(map) {
            send(&Message::MapRows(rows));
            if self.next_row == 0 && self.next_column == 0 {
                break;
            }
        }
    }

    /// The next chunk of the sweep: as many whole rows as fit in [`MAX_CHUNK_CELLS`], or
    /// for grids wider than that, the next piece of a row. `None` for an empty grid.
    pub fn next_map_rows<const W: usize, const H: usize>(
        &mut self,
        map: &GridMap<W, H>,
    ) -> Option<MapRows> {
        let rows = map.rows();
        let scale = CellScale::new(map.evidence());
        let (mut column, mut row) = (self.next_column as usize, self.next_row as usize);
        if column >= W || row >= H {
            (column, row) = (0, 0);
        }
        let mut chunk = CellChunk::new();
        let (first_column, first_row) = (column, row);
        while let Some(&l) = rows.get(row).and_then(|r| r.get(column)) {
            let belief = map.occupancy(column as i32, row as i32);
            if chunk.push(scale.encode(l, belief)).is_err() {
                break;
            }
            column += 1;
            if column == W {
                // Whole rows only, unless a row alone is too wide for a chunk.
                if chunk.len() + W > MAX_CHUNK_CELLS {
                    column = 0;
                    row += 1;
                    break;
                }
                column = 0;
                row += 1;
            }
        }
        if chunk.is_empty() {
            return None;
        }
        if row >= H {
            row = 0;
        }
        self.next_column = u16::try_from(column).unwrap_or(0);
        self.next_row = u16::try_from(row).unwrap_or(0);
        Some(MapRows {
            first_row: u16::try_from(first_row).ok()?,
            first_column: u16::try_from(first_column).ok()?,
            cells: chunk,
        })
    }
}

/// Why a message could not be framed.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum EncodeError {
    /// The caller's buffer is shorter than the frame; `needed` bytes would do
    /// ([`MAX_FRAME_LEN`] always does).
    BufferTooSmall {
        /// The frame's length, delimiter included.
        needed: usize,
    },
    /// postcard refused the message (cannot happen for messages built by this module).
    Body,
}

/// Frames `message` into `out` and returns the frame's length, delimiter included.
///
/// Needs at most [`MAX_FRAME_LEN`] bytes of `out`; on [`EncodeError`] `out` may hold
/// part of a frame and must not be sent.
pub fn encode(message: &Message, out: &mut [u8]) -> Result<usize, EncodeError> {
    let mut raw = [0u8; MAX_RAW_LEN];
    let (version, rest) = raw.split_at_mut(1);
    version.copy_from_slice(&[WIRE_VERSION]);
    let body_area = rest.get_mut(..MAX_MESSAGE_LEN).ok_or(EncodeError::Body)?;
    let body_len = postcard::to_slice(message, body_area)
        .map_err(|_| EncodeError::Body)?
        .len();
    let raw_len = 1 + body_len;
    let crc = crc16(raw.get(..raw_len).ok_or(EncodeError::Body)?);
    raw.get_mut(raw_len..raw_len + 2)
        .ok_or(EncodeError::Body)?
        .copy_from_slice(&crc.to_le_bytes());
    let raw = raw.get(..raw_len + 2).ok_or(EncodeError::Body)?;
    let needed = cobs_len(raw) + 1;
    if out.len() < needed {
        return Err(EncodeError::BufferTooSmall { needed });
    }
    let n = cobs_encode(raw, out).map_err(|_| EncodeError::BufferTooSmall { needed })?;
    *out.get_mut(n)
        .ok_or(EncodeError::BufferTooSmall { needed })? = 0;
    Ok(n + 1)
}

pub use crate::framing::crc16;

/// Why a received frame was dropped.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FrameError {
    /// More than [`MAX_FRAME_LEN`] bytes before a delimiter.
    Overlong,
    /// The COBS codes do not add up.
    Cobs,
    /// Too short to hold a version byte and a CRC.
    TooShort,
    /// The CRC does not match: a flipped bit, a dropped byte, or two frames run together.
    Crc,
    /// Not [`WIRE_VERSION`]: another firmware's layout.
    Version,
    /// The CRC was good but the body is not a [`Message`] (or has bytes left over).
    Body,
}

/// Frames decoded and dropped, by kind. Counters wrap.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DecoderStats {
    /// Good frames returned.
    pub frames_ok: u32,
    /// [`FrameError::Overlong`] frames.
    pub overlong: u32,
    /// [`FrameError::Cobs`] frames.
    pub bad_cobs: u32,
    /// [`FrameError::TooShort`] frames.
    pub too_short: u32,
    /// [`FrameError::Crc`] frames.
    pub bad_crc: u32,
    /// [`FrameError::Version`] frames.
    pub bad_version: u32,
    /// [`FrameError::Body`] frames.
    pub bad_body: u32,
}

impl DecoderStats {
    fn count(&mut self, error: FrameError) {
        let counter = match error {
            FrameError::Overlong => &mut self.overlong,
            FrameError::Cobs => &mut self.bad_cobs,
            FrameError::TooShort => &mut self.too_short,
            FrameError::Crc => &mut self.bad_crc,
            FrameError::Version => &mut self.bad_version,
            FrameError::Body => &mut self.bad_body,
        };
        *counter = counter.wrapping_add(1);
    }

    /// Dropped frames of every kind.
    pub fn bad_frames(&self) -> u32 {
        self.overlong
            .wrapping_add(self.bad_cobs)
            .wrapping_add(self.too_short)
            .wrapping_add(self.bad_crc)
            .wrapping_add(self.bad_version)
            .wrapping_add(self.bad_body)
    }
}

/// Bytes in, messages out, with a fixed buffer of one frame.
///
/// Bytes gather until a `0x00`; then the frame is un-stuffed, checked and parsed. A bad
/// frame (garbage, a dropped byte, a viewer joining mid-frame) is counted and the decoder
/// starts over at the next `0x00`. Empty frames are skipped silently.
#[derive(Clone, Debug)]
pub struct StreamDecoder {
    frames: FrameCollector<{ MAX_FRAME_LEN - 1 }>,
    stats: DecoderStats,
}

impl Default for StreamDecoder {
    fn default() -> Self {
        StreamDecoder::new()
    }
}

impl StreamDecoder {
    /// A decoder waiting for its first frame.
    pub const fn new() -> StreamDecoder {
        StreamDecoder {
            frames: FrameCollector::new(),
            stats: DecoderStats {
                frames_ok: 0,
                overlong: 0,
                bad_cobs: 0,
                too_short: 0,
                bad_crc: 0,
                bad_version: 0,
                bad_body: 0,
            },
        }
    }

    /// Counts so far.
    pub fn stats(&self) -> &DecoderStats {
        &self.stats
    }

    /// Whether bytes of an unfinished frame are waiting for their delimiter (at the end of
    /// a recording: a frame cut short).
    pub fn has_partial_frame(&self) -> bool {
        self.frames.has_partial()
    }

    /// Feeds one byte: `Some` when it ends a frame (a message, or why the frame was
    /// dropped, already counted), `None` otherwise.
    pub fn push(&mut self, byte: u8) -> Option<Result<Message, FrameError>> {
        let result = match self.frames.push(byte)? {
            Collected::Overlong => Err(FrameError::Overlong),
            Collected::Frame(encoded) => Self::parse(encoded),
        };
        match result {
            Ok(_) => self.stats.frames_ok = self.stats.frames_ok.wrapping_add(1),
            Err(e) => self.stats.count(e),
        }
        Some(result)
    }

    /// Feeds a run of bytes; the iterator yields each frame they end.
    pub fn feed<'d, 'b>(&'d mut self, bytes: &'b [u8]) -> Frames<'d, 'b> {
        Frames {
            decoder: self,
            bytes: bytes.iter(),
        }
    }

    fn parse(encoded: &mut [u8]) -> Result<Message, FrameError> {
        let n = cobs_decode_in_place(encoded).map_err(|_| FrameError::Cobs)?;
        let raw = encoded.get(..n).ok_or(FrameError::Cobs)?;
        if raw.len() < 3 {
            return Err(FrameError::TooShort);
        }
        let (checked, crc) = raw.split_at(raw.len() - 2);
        let sent = u16::from_le_bytes([
            *crc.first().ok_or(FrameError::TooShort)?,
            *crc.get(1).ok_or(FrameError::TooShort)?,
        ]);
        if crc16(checked) != sent {
            return Err(FrameError::Crc);
        }
        let (version, body) = checked.split_first().ok_or(FrameError::TooShort)?;
        if *version != WIRE_VERSION {
            return Err(FrameError::Version);
        }
        match postcard::take_from_bytes::<Message>(body) {
            Ok((message, [])) => Ok(message),
            _ => Err(FrameError::Body),
        }
    }
}

/// The frames a run of bytes ends: see [`StreamDecoder::feed`].
pub struct Frames<'d, 'b> {
    decoder: &'d mut StreamDecoder,
    bytes: core::slice::Iter<'b, u8>,
}

impl Iterator for Frames<'_, '_> {
    type Item = Result<Message, FrameError>;
    fn next(&mut self) -> Option<Self::Item> {
        for &b in self.bytes.by_ref() {
            if let Some(r) = self.decoder.push(b) {
                return Some(r);
            }
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `raw` as it goes on the wire, built by hand: its CRC appended, COBS-stuffed, and
    /// the zero delimiter.
    fn sealed(raw: &[u8]) -> Vec<u8> {
        let mut raw = raw.to_vec();
        let crc = crc16(&raw);
        raw.extend_from_slice(&crc.to_le_bytes());
        let mut stuffed = std::vec![0u8; 32];
        let n = cobs_encode(&raw, &mut stuffed).expect("room");
        stuffed.truncate(n);
        stuffed.push(0);
        stuffed
    }
    use crate::grid::GridGeometry;
    use crate::tagfix::FixRejection;
    use crate::SlamConfig;
    use proptest::prelude::*;
    use std::vec::Vec;

    const FW: FirmwareVersion = FirmwareVersion {
        major: 0,
        minor: 3,
        patch: 1,
    };

    fn hello() -> Message {
        Message::Hello(Hello {
            width: 46,
            height: 46,
            cell_mm: 50,
            origin_x_mm: -150,
            origin_y_mm: -150,
            free_below: 16,
            occupied_above: 16,
            firmware: FW,
        })
    }

    fn tick() -> Message {
        Message::Tick(Tick {
            tick: 137,
            time_ms: 13_600,
            x_um: 812_345,
            y_um: -1_234,
            heading_bits: 0xC000_0001,
            fix: FixOutcome::Rejected(FixRejection::Gate),
            stale: STALE_FLOW | STALE_DEPTH,
            cells_written: 77,
            counters: Counters {
                ticks: 137,
                fixes_taken: 12,
                fixes_rejected_geometry: 1,
                fixes_rejected_gate: 2,
                fixes_rejected_too_old: 3,
                relocalisations: 0,
                beams_mapped: 1000,
                beams_invalid: 96,
                flow_stale: 3,
                gyro_stale: 0,
                depth_stale: 1,
            },
        })
    }

    fn map_rows() -> Message {
        let cells: Vec<i8> = (0..92).map(|i| (i * 3 - 128) as i8).collect();
        Message::MapRows(MapRows {
            first_row: 44,
            first_column: 0,
            cells: CellChunk::from_slice(&cells).unwrap_or_default(),
        })
    }

    fn health() -> Message {
        Message::Health(SensorHealth {
            depth_timeouts: 1,
            depth_bus_errors: 2,
            flow_no_surface: 3,
            flow_outliers: 4,
            flow_bus_errors: 5,
            gyro_bus_errors: 6,
            camera_bad_frames: 7,
            tick_overruns: 8,
            watchdog_feeds: u32::MAX,
            depth_start_failures: 9,
            flow_start_failures: 10,
            gyro_start_failures: 11,
        })
    }

    fn frame(m: &Message) -> Vec<u8> {
        let mut buf = [0u8; MAX_FRAME_LEN];
        let n = encode(m, &mut buf).expect("encodes");
        buf[..n].to_vec()
    }

    fn decode_all(bytes: &[u8]) -> (Vec<Result<Message, FrameError>>, DecoderStats) {
        let mut d = StreamDecoder::new();
        let out = d.feed(bytes).collect();
        (out, *d.stats())
    }

    #[test]
    fn crc_check_value() {
        assert_eq!(crc16(b"123456789"), 0x29B1);
    }

    #[test]
    fn health_frame_fixture() {
        // The layout written out by hand: version, variant 3, twelve varints, CRC, stuffed.
        let h = Message::Health(SensorHealth {
            depth_timeouts: 0,
            depth_bus_errors: 1,
            flow_no_surface: 300,
            gyro_start_failures: 2,
            ..SensorHealth::default()
        });
        let stuffed = sealed(&[0xB3, 3, 0, 1, 0xAC, 0x02, 0, 0, 0, 0, 0, 0, 0, 0, 2]);
        assert_eq!(frame(&h), stuffed);
        // No zero before the delimiter.
        assert!(!stuffed[..stuffed.len() - 1].contains(&0));
        assert_eq!(stuffed[0], 3, "first COBS code: b3 03 then a zero");
    }

    #[test]
    fn round_trip_each_message() {
        for m in [hello(), tick(), map_rows(), health()] {
            let bytes = frame(&m);
            assert_eq!(bytes.last(), Some(&0));
            assert!(bytes.len() <= MAX_FRAME_LEN);
            let (out, stats) = decode_all(&bytes);
            assert_eq!(out, std::vec![Ok(m)]);
            assert_eq!(stats.frames_ok, 1);
            assert_eq!(stats.bad_frames(), 0);
        }
    }

    #[test]
    fn worst_case_messages_fit() {
        let full = CellChunk::from_slice(&[-1i8; MAX_CHUNK_CELLS]).unwrap_or_default();
        let big = Message::MapRows(MapRows {
            first_row: u16::MAX,
            first_column: u16::MAX,
            cells: full,
        });
        let body = postcard::to_slice(&big, &mut [0u8; 512])
            .map(|b| b.len())
            .unwrap_or(0);
        assert_eq!(body, MAX_MESSAGE_LEN);
        let mut worst_tick = tick();
        if let Message::Tick(t) = &mut worst_tick {
            t.tick = u32::MAX;
            t.time_ms = u32::MAX;
            t.x_um = i32::MIN;
            t.y_um = i32::MIN;
            t.heading_bits = u32::MAX;
            t.cells_written = u32::MAX;
            t.fix = FixOutcome::Rejected(FixRejection::TooOld);
            t.counters = Counters {
                ticks: u32::MAX,
                fixes_taken: u32::MAX,
                fixes_rejected_geometry: u32::MAX,
                fixes_rejected_gate: u32::MAX,
                fixes_rejected_too_old: u32::MAX,
                relocalisations: u32::MAX,
                beams_mapped: u32::MAX,
                beams_invalid: u32::MAX,
                flow_stale: u32::MAX,
                gyro_stale: u32::MAX,
                depth_stale: u32::MAX,
            };
        }
        let all_max = SensorHealth {
            depth_timeouts: u32::MAX,
            depth_bus_errors: u32::MAX,
            flow_no_surface: u32::MAX,
            flow_outliers: u32::MAX,
            flow_bus_errors: u32::MAX,
            gyro_bus_errors: u32::MAX,
            camera_bad_frames: u32::MAX,
            tick_overruns: u32::MAX,
            watchdog_feeds: u32::MAX,
            depth_start_failures: u32::MAX,
            flow_start_failures: u32::MAX,
            gyro_start_failures: u32::MAX,
        };
        let mut worst_hello = hello();
        if let Message::Hello(h) = &mut worst_hello {
            h.width = u16::MAX;
            h.height = u16::MAX;
            h.cell_mm = i32::MIN;
            h.origin_x_mm = i32::MIN;
            h.origin_y_mm = i32::MIN;
        }
        for (m, limit) in [
            (big, MAX_FRAME_LEN),
            (worst_tick, 96),
            (Message::Health(all_max), 66),
            (worst_hello, 33),
        ] {
            let bytes = frame(&m);
            assert!(bytes.len() <= limit, "{} > {limit}", bytes.len());
            assert_eq!(decode_all(&bytes).0, std::vec![Ok(m)]);
        }
    }

    #[test]
    fn buffer_too_small_is_an_error() {
        let needed = frame(&map_rows()).len();
        let mut small = [0u8; 40];
        assert_eq!(
            encode(&map_rows(), &mut small),
            Err(EncodeError::BufferTooSmall { needed })
        );
        let mut exact = std::vec![0u8; needed];
        assert_eq!(encode(&map_rows(), &mut exact), Ok(needed));
    }

    #[test]
    fn garbage_between_frames_resynchronises() {
        let mut bytes = std::vec![0x55, 0x13, 0xFF];
        bytes.extend(frame(&hello()));
        bytes.extend([1, 2, 3, 4, 5, 0]);
        bytes.extend(frame(&tick()));
        bytes.extend([0, 0, 0]); // empty frames: ignored
        bytes.extend([0xB3, 0x07, 0]); // stuffing that runs past the end
        bytes.extend(frame(&health()));
        let (out, stats) = decode_all(&bytes);
        let good: Vec<Message> = out.iter().filter_map(|r| r.ok()).collect();
        assert_eq!(good, std::vec![tick(), health()]);
        assert_eq!(stats.frames_ok, 2);
        // The leading garbage swallowed the hello: the frame boundary was lost.
        assert_eq!(stats.bad_frames(), 3, "{stats:?}");
        assert_eq!(
            stats.bad_cobs, 3,
            "each piece of garbage fails its stuffing"
        );
    }

    #[test]
    fn truncated_frame_is_counted_and_the_next_one_decodes() {
        let whole = frame(&tick());
        let mut bytes = whole[..whole.len() / 2].to_vec();
        bytes.push(0);
        bytes.extend(frame(&hello()));
        let (out, stats) = decode_all(&bytes);
        assert_eq!(out.len(), 2);
        assert!(out[0].is_err());
        assert_eq!(out[1], Ok(hello()));
        assert_eq!(stats.bad_frames(), 1);
        // Too short to hold anything.
        let (out, stats) = decode_all(&[0x02, 0xB3, 0]);
        assert_eq!(out, std::vec![Err(FrameError::TooShort)]);
        assert_eq!(stats.too_short, 1);
    }

    #[test]
    fn every_flipped_bit_is_caught() {
        let good = frame(&tick());
        let mut codes = Vec::new();
        let mut at = 0;
        while at < good.len() - 1 {
            codes.push(at);
            at += good[at] as usize;
        }
        for i in 0..good.len() - 1 {
            for bit in 0..8 {
                let mut bad = good.clone();
                bad[i] ^= 1 << bit;
                let (out, stats) = decode_all(&bad);
                assert_eq!(stats.frames_ok, 0, "byte {i} bit {bit}: {out:?}");
                assert!(stats.bad_frames() >= 1);
                if bad[i] != 0 && !codes.contains(&i) {
                    // A data byte changed and the stuffing still adds up: the CRC tells.
                    assert_eq!(stats.bad_crc, 1, "byte {i} bit {bit}: {stats:?}");
                    assert_eq!(stats.bad_frames(), 1);
                }
            }
        }
    }

    #[test]
    fn wrong_version_and_bad_body_are_told_apart() {
        // Layout 1's and layout 2's health frames: older firmwares'.
        for old in [
            std::vec![0xB1, 3, 0, 0, 0, 0, 0, 0, 0, 0, 0],
            std::vec![0xB2, 3, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0],
        ] {
            assert_eq!(
                decode_all(&sealed(&old)).0,
                std::vec![Err(FrameError::Version)]
            );
        }

        for raw in [
            std::vec![0xB3, 9],                                        // no such variant
            std::vec![0xB3, 3, 0, 0, 0, 0, 0, 0, 0, 0, 0],             // health cut short
            std::vec![0xB3, 3, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 7], // a byte left over
            std::vec![0xB3, 2, 0, 0, 0x81, 0x01],                      // 129 cells announced
        ] {
            assert_eq!(
                decode_all(&sealed(&raw)).0,
                std::vec![Err(FrameError::Body)]
            );
        }
    }

    #[test]
    fn overlong_frame_is_dropped_and_the_next_decodes() {
        let mut bytes = std::vec![0x42; MAX_FRAME_LEN * 3];
        bytes.push(0);
        bytes.extend(frame(&health()));
        let (out, stats) = decode_all(&bytes);
        assert_eq!(out, std::vec![Err(FrameError::Overlong), Ok(health())]);
        assert_eq!(stats.overlong, 1);
        // Exactly the longest legal frame still fits.
        let longest = CellChunk::from_slice(&[5i8; MAX_CHUNK_CELLS]).unwrap_or_default();
        let m = Message::MapRows(MapRows {
            first_row: u16::MAX,
            first_column: u16::MAX,
            cells: longest,
        });
        let bytes = frame(&m);
        assert_eq!(bytes.len(), MAX_FRAME_LEN);
        assert_eq!(decode_all(&bytes).0, std::vec![Ok(m)]);
    }

    #[test]
    fn cobs_handles_long_runs_and_zeros() {
        for raw in [
            std::vec![0u8; 5],
            std::vec![7u8; 254],
            std::vec![7u8; 253],
            std::vec![7u8; 255],
            (0..=255u8).cycle().take(600).collect::<Vec<u8>>(),
        ] {
            let mut enc = std::vec![0u8; cobs_len(&raw)];
            let n = cobs_encode(&raw, &mut enc).expect("room");
            assert_eq!(n, enc.len());
            assert!(!enc.contains(&0));
            let m = cobs_decode_in_place(&mut enc).expect("decodes");
            assert_eq!(&enc[..m], &raw[..]);
        }
    }

    #[test]
    fn cells_keep_their_belief() {
        let scale = CellScale::new(&Evidence::SEED);
        assert_eq!((scale.free_below, scale.occupied_above), (16, 16));
        let e = Evidence::SEED;
        for l in -e.clamp..=e.clamp {
            let belief = if l < -e.free_below {
                Occupancy::Free
            } else if l > e.occupied_above {
                Occupancy::Occupied
            } else {
                Occupancy::Unknown
            };
            let q = scale.encode(l, belief);
            assert_eq!(scale.belief(q), belief, "log odds {l}");
            assert!((q as i16 - (l >> 4).clamp(-128, 127)).abs() <= 1, "{l}");
        }
        // Thresholds past the byte's reach still leave room for both beliefs.
        let odd = Evidence {
            free_below: 7000,
            occupied_above: 5,
            ..Evidence::SEED
        };
        let s = CellScale::new(&odd);
        assert_eq!(
            s.belief(s.encode(i16::MIN, Occupancy::Free)),
            Occupancy::Free
        );
        assert_eq!(
            s.belief(s.encode(6, Occupancy::Occupied)),
            Occupancy::Occupied
        );
        assert_eq!(
            s.belief(s.encode(4, Occupancy::Unknown)),
            Occupancy::Unknown
        );
    }

    fn seed_map() -> GridMap<46, 46> {
        let mut map = GridMap::new(SlamConfig::seed_mat().geometry, Evidence::SEED);
        for i in 0..46 {
            map.add(i, i, 300);
            map.add(45 - i, i, -300);
            map.add(i, 0, 2000);
        }
        map
    }

    #[test]
    fn a_sweep_covers_the_map_in_whole_rows() {
        let map = seed_map();
        let mut s = Streamer::new(Schedule::DEFAULT, FW);
        let mut rebuilt = [[0i8; 46]; 46];
        let scale = CellScale::new(map.evidence());
        for i in 0..23 {
            let rows = s.next_map_rows(&map).expect("a chunk");
            assert_eq!((rows.first_row, rows.first_column), (2 * i, 0));
            assert_eq!(rows.cells.len(), 92);
            for (k, &c) in rows.cells.as_slice().iter().enumerate() {
                rebuilt[rows.first_row as usize + k / 46][k % 46] = c;
            }
        }
        assert_eq!(s.next_map_rows(&map).map(|r| r.first_row), Some(0));
        for (r, row) in rebuilt.iter().enumerate() {
            for (c, &q) in row.iter().enumerate() {
                assert_eq!(scale.belief(q), map.occupancy(c as i32, r as i32));
            }
        }
    }

    #[test]
    fn wide_grids_go_in_row_pieces() {
        let geometry = GridGeometry {
            cell_mm: 50,
            origin_x_mm: 0,
            origin_y_mm: 0,
        };
        let map: GridMap<206, 3> = GridMap::new(geometry, Evidence::SEED);
        let mut s = Streamer::new(Schedule::DEFAULT, FW);
        let mut seen = Vec::new();
        s.send_whole_map(&map, |m| {
            if let Message::MapRows(r) = m {
                seen.push((r.first_row, r.first_column, r.cells.len()));
            }
        });
        assert_eq!(
            seen,
            std::vec![
                (0, 0, 128),
                (0, 128, 78),
                (1, 0, 128),
                (1, 128, 78),
                (2, 0, 128),
                (2, 128, 78)
            ]
        );
        // Every frame of a sweep fits the longest frame.
        s.send_whole_map(&map, |m| assert!(frame(m).len() <= MAX_FRAME_LEN));
    }

    #[test]
    fn the_schedule() {
        let map = seed_map();
        let mut s = Streamer::new(Schedule::DEFAULT, FW);
        let report = StepReport {
            pose: Pose::from_mm_mdeg(1, 2, 3),
            fix: FixOutcome::Taken,
            stale: Staleness::default(),
            cells_written: 3,
            counters: Counters::default(),
        };
        let mut kinds = Vec::new();
        for t in 0..51u32 {
            s.tick(t * 100, &report, &map, &SensorHealth::default(), |m| {
                kinds.push((t, core::mem::discriminant(m)))
            });
        }
        let count = |m: &Message| {
            kinds
                .iter()
                .filter(|(_, d)| *d == core::mem::discriminant(m))
                .count()
        };
        assert_eq!(count(&hello()), 2); // ticks 0 and 50
        assert_eq!(count(&tick()), 51);
        assert_eq!(count(&map_rows()), 51);
        assert_eq!(count(&health()), 6); // ticks 0, 10, ..., 50
        assert_eq!(kinds[0].1, core::mem::discriminant(&hello()));
    }

    #[test]
    fn tick_carries_the_report() {
        let report = StepReport {
            pose: Pose {
                x_um: -5,
                y_um: 7,
                heading: Angle::from_bits(0x8000_0000),
            },
            fix: FixOutcome::Rejected(FixRejection::Geometry),
            stale: Staleness {
                flow: true,
                gyro: false,
                depth: true,
            },
            cells_written: 9,
            counters: Counters {
                ticks: 4,
                ..Counters::default()
            },
        };
        let t = Tick::new(300, &report);
        assert_eq!(t.pose(), report.pose);
        assert_eq!(t.staleness(), report.stale);
        assert_eq!(t.tick, 4);
        let (out, _) = decode_all(&frame(&Message::Tick(t)));
        assert_eq!(out, std::vec![Ok(Message::Tick(t))]);
    }

    proptest! {
        #[test]
        fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..2000)) {
            let mut d = StreamDecoder::new();
            let results: Vec<_> = d.feed(&bytes).collect();
            let stats = *d.stats();
            prop_assert_eq!(results.len() as u32, stats.frames_ok + stats.bad_frames());
        }

        #[test]
        fn arbitrary_ticks_round_trip(
            v in proptest::array::uniform17(any::<u32>()),
            fix in 0u8..5,
            stale in any::<u8>(),
            noise in proptest::collection::vec(any::<u8>(), 0..300),
        ) {
            let t = Tick {
                tick: v[0], time_ms: v[1], x_um: v[2] as i32, y_um: v[3] as i32,
                heading_bits: v[4],
                fix: match fix {
                    0 => FixOutcome::NotAttempted,
                    1 => FixOutcome::Taken,
                    2 => FixOutcome::Rejected(FixRejection::Geometry),
                    3 => FixOutcome::Rejected(FixRejection::Gate),
                    _ => FixOutcome::Rejected(FixRejection::TooOld),
                },
                stale,
                cells_written: v[5],
                counters: Counters {
                    ticks: v[6], fixes_taken: v[7], fixes_rejected_geometry: v[8],
                    fixes_rejected_gate: v[9], fixes_rejected_too_old: v[16], relocalisations: v[10], beams_mapped: v[11],
                    beams_invalid: v[12], flow_stale: v[13], gyro_stale: v[14], depth_stale: v[15],
                },
            };
            // Noise, a delimiter, then the frame: the frame always comes through.
            let mut bytes = noise;
            bytes.push(0);
            bytes.extend(frame(&Message::Tick(t)));
            let (out, _) = decode_all(&bytes);
            prop_assert_eq!(out.last().copied(), Some(Ok(Message::Tick(t))));
        }
    }
}
