//! The sending side: which messages go out on each tick, and framing one into bytes.

use super::{
    Boot, CellChunk, CellScale, FilterState, FirmwareVersion, Hello, Inputs, MapRows, Message,
    SensorHealth, Tick, MAX_CHUNK_CELLS, MAX_MESSAGE_LEN, MAX_RAW_LEN, WIRE_VERSION,
};
use crate::framing::{cobs_encode, cobs_len, crc16};
use slam_core::{GridMap, Localiser, SensorFrame, StepReport, TagCounters};

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
    /// Whether each tick's [`Inputs`] (the frame the core stepped on) go out before its
    /// `Tick`, so that the run can be replayed on a host.
    pub inputs: bool,
}

impl Schedule {
    /// At 10 Hz: a `Hello` every 5 s, a `Health` every second, one chunk a tick, and
    /// each tick's inputs.
    pub const DEFAULT: Schedule = Schedule {
        hello_every_ticks: 50,
        health_every_ticks: 10,
        map_chunks_per_tick: 1,
        inputs: true,
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
    localiser: Localiser,
    matching: bool,
    boot: Boot,
    ticks_sent: u32,
    next_column: u16,
    next_row: u16,
}

impl Streamer {
    /// A stream starting with a `Hello` and the map's first row, from a robot whose pose
    /// `localiser` corrects.
    pub const fn new(
        schedule: Schedule,
        firmware: FirmwareVersion,
        localiser: Localiser,
    ) -> Streamer {
        Streamer {
            schedule,
            firmware,
            localiser,
            matching: false,
            boot: Boot {
                cause: super::ResetCause::PowerOn,
                resumed: false,
                resumes: 0,
            },
            ticks_sent: 0,
            next_column: 0,
            next_row: 0,
        }
    }

    /// The same stream from a robot whose filter also matches its scans against the map.
    pub const fn with_matching(mut self, matching: bool) -> Streamer {
        self.matching = matching;
        self
    }

    /// The same stream from a run that started as `boot` says (a fresh start after
    /// power-on unless told): every `Hello` carries it.
    pub const fn with_boot(mut self, boot: Boot) -> Streamer {
        self.boot = boot;
        self
    }

    /// Hands `send` this tick's messages, in order: a `Hello` when due, the [`Inputs`]
    /// (`frame`, what `step` was given) when the schedule sends them, the `Tick`, the
    /// [`FilterState`] when the report has an estimate (with `tags`, the core's
    /// `tag_counters()`), the map chunks, and `health` when due. `time_ms` is the tick's
    /// time since start, the moment its pose is of.
    #[allow(clippy::too_many_arguments)]
    pub fn tick<const W: usize, const H: usize>(
        &mut self,
        time_ms: u32,
        frame: &SensorFrame,
        report: &StepReport,
        tags: TagCounters,
        map: &GridMap<W, H>,
        health: &SensorHealth,
        mut send: impl FnMut(&Message),
    ) {
        let n = self.ticks_sent;
        self.ticks_sent = n.wrapping_add(1);
        let due = |every: u32| n.checked_rem(every) == Some(0);
        if n == 0 || due(self.schedule.hello_every_ticks) {
            send(&Message::Hello(Hello::new(
                map,
                self.firmware,
                self.localiser,
                self.matching,
                self.boot,
            )));
        }
        if self.schedule.inputs {
            send(&Message::Inputs(Inputs {
                tick: report.counters.ticks,
                time_ms,
                frame: frame.clone(),
            }));
        }
        send(&Message::Tick(Tick::new(time_ms, report)));
        if let Some(state) = FilterState::new(report, tags) {
            send(&Message::Filter(state));
        }
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
    /// ([`MAX_FRAME_LEN`](super::MAX_FRAME_LEN) always does).
    BufferTooSmall {
        /// The frame's length, delimiter included.
        needed: usize,
    },
    /// postcard refused the message (cannot happen for messages built by this module).
    Body,
}

/// Frames `message` into `out` and returns the frame's length, delimiter included.
///
/// Needs at most [`MAX_FRAME_LEN`](super::MAX_FRAME_LEN) bytes of `out`; on
/// [`EncodeError`] `out` may hold part of a frame and must not be sent.
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
