//! The telemetry messages: what each carries, in the order postcard lays it out.

use super::core_layout::{
    CalibrationDef, CountersDef, FixOutcomeDef, LocaliserDef, PoseCovarianceDef, SensorFrameDef,
    TagCountersDef,
};
use super::{CellScale, SensorHealth, MAX_CHUNK_CELLS};
use serde::{Deserialize, Serialize};
use slam_core::{
    Angle, Calibration, Counters, Estimate, FixOutcome, GridMap, Localiser, Pose, PoseCovariance,
    SensorFrame, Staleness, StepReport, TagCounters, Trust,
};

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

/// What reset the robot's chip before this run of the firmware.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ResetCause {
    /// Power-on or brown-out: RAM held nothing (variant 0).
    #[default]
    PowerOn,
    /// The watchdog timed out: a loop stopped feeding it (variant 1).
    Watchdog,
    /// Anything else: the RUN pin, a debugger, a deliberate reboot (variant 2).
    Other,
}

/// How this run of the firmware started: why the chip reset, and whether the map, the
/// pose and the route were taken up from RAM the reset left alone.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Boot {
    /// What reset the chip.
    #[serde(rename = "reset")]
    pub cause: ResetCause,
    /// Whether the state from before the reset was resumed (else the robot started fresh
    /// at the world's start with an empty map).
    pub resumed: bool,
    /// Resets resumed from since the robot last started fresh.
    pub resumes: u16,
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
    /// What corrects its pose beyond odometry: with [`Localiser::Filter`] each `Tick`
    /// is followed by a [`FilterState`].
    #[serde(with = "LocaliserDef")]
    pub localiser: Localiser,
    /// Whether the filter also matches the depth scans against the map (`host-sim run
    /// --pose slam`), or takes tags alone (`--pose filter`).
    pub matching: bool,
    /// How this run started: the robot says in every `Hello` that it restarted, and why.
    pub boot: Boot,
}

impl Hello {
    /// The `Hello` describing `map`, corrected by `localiser` (with scan matching if
    /// `matching`), from a run that started as `boot` says. Dimensions past `u16::MAX` saturate (no such grid fits in an RP2040's
    /// 264 KB anyway).
    pub fn new<const W: usize, const H: usize>(
        map: &GridMap<W, H>,
        firmware: FirmwareVersion,
        localiser: Localiser,
        matching: bool,
        boot: Boot,
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
            localiser,
            matching,
            boot,
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
    /// Time of the tick since the run started, milliseconds (wraps after 49 days): the
    /// moment the pose is of (on the robot its odometry's, its newest gyro sample's). A
    /// reset the robot resumed from carries it on.
    pub time_ms: u32,
    /// Pose x, micrometres.
    pub x_um: i32,
    /// Pose y, micrometres.
    pub y_um: i32,
    /// Heading as a binary angle: 2^32 per turn, clockwise from +y.
    pub heading_bits: u32,
    /// Whether a tag fix was taken, rejected or not tried.
    #[serde(with = "FixOutcomeDef")]
    pub fix: FixOutcome,
    /// Inputs missing this tick: bit 0 flow, bit 1 gyro, bit 2 depth ([`Tick::staleness`]).
    pub stale: u8,
    /// Grid cells written this tick.
    pub cells_written: u32,
    /// Inputs doubted after this tick, and why: [`Trust::packed`] ([`Tick::trust`]).
    pub doubts: u16,
    /// The core's totals since start.
    #[serde(with = "CountersDef")]
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
            doubts: report.trust.packed(),
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

    /// The inputs the core doubted after this tick, and why.
    pub fn trust(&self) -> Trust {
        Trust::unpacked(self.doubts)
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

/// The filter's belief after a tick, sent right after that tick's [`Tick`]: how sure it
/// is of the pose, the sensors' errors it has learned, and what it made of the tags.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FilterState {
    /// The tick this belongs to (the `Tick`'s `tick`).
    pub tick: u32,
    /// The pose's covariance, in the core's units (see [`PoseCovariance`]).
    #[serde(with = "PoseCovarianceDef")]
    pub covariance: PoseCovariance,
    /// The learned calibration.
    #[serde(with = "CalibrationDef")]
    pub calibration: Calibration,
    /// Tag sightings used and refused since start, by cause.
    #[serde(with = "TagCountersDef")]
    pub tags: TagCounters,
}

impl FilterState {
    /// The state for a step's report and the core's tag counters; `None` when the step
    /// has no estimate (the robot does not fly the filter).
    pub fn new(report: &StepReport, tags: TagCounters) -> Option<FilterState> {
        report.estimate.map(|e| FilterState {
            tick: report.counters.ticks,
            covariance: e.covariance,
            calibration: e.calibration,
            tags,
        })
    }

    /// The core's estimate this carries.
    pub fn estimate(&self) -> Estimate {
        Estimate {
            covariance: self.covariance,
            calibration: self.calibration,
        }
    }
}

/// The raw inputs of one tick: the [`SensorFrame`] the core stepped on, sent just before
/// that tick's [`Tick`], so that a host can run the same steps again (`host-sim replay`).
#[derive(Clone, PartialEq, Eq, Debug, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Inputs {
    /// The tick this frame was stepped on (the following `Tick`'s `tick`).
    pub tick: u32,
    /// Time of the tick since start, milliseconds (the following `Tick`'s `time_ms`).
    pub time_ms: u32,
    /// Every input of the step, in the core's units.
    #[serde(with = "SensorFrameDef")]
    pub frame: SensorFrame,
}

/// A run of map cells, in cell units; see [the telemetry module](super) for the scale.
#[derive(Clone, PartialEq, Eq, Debug, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MapRows {
    /// Row of the first cell (0 is the lowest y).
    pub first_row: u16,
    /// Column of the first cell; the run carries on at column 0 of the next row.
    pub first_column: u16,
    /// The cells, row-major.
    pub cells: CellChunk,
}

impl MapRows {
    /// The cells this chunk covers in a row-major grid `width` cells wide, held in
    /// `grid`; `None` when its first column is off the grid or the chunk runs past the
    /// grid's end (a receiver drops such a chunk rather than guess).
    pub fn slot_in<'a>(&self, grid: &'a mut [i8], width: usize) -> Option<&'a mut [i8]> {
        if usize::from(self.first_column) >= width {
            return None;
        }
        let start = usize::from(self.first_row)
            .checked_mul(width)?
            .checked_add(usize::from(self.first_column))?;
        let end = start.checked_add(self.cells.len())?;
        grid.get_mut(start..end)
    }
}

/// Up to [`MAX_CHUNK_CELLS`] cells, in cell units: postcard lays it out as a varint count
/// and one `i8` each, and refuses a count past the capacity.
pub type CellChunk = heapless::Vec<i8, MAX_CHUNK_CELLS, u8>;

/// Everything the robot sends.
#[derive(Clone, PartialEq, Eq, Debug, Serialize, Deserialize)]
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
    /// The filter's belief (variant 4).
    Filter(FilterState),
    /// One tick's raw inputs (variant 5), when the schedule sends them.
    Inputs(Inputs),
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rows(first_row: u16, first_column: u16, n: usize) -> MapRows {
        let mut cells = CellChunk::new();
        for i in 0..n {
            let _ = cells.push(i as i8);
        }
        MapRows {
            first_row,
            first_column,
            cells,
        }
    }

    #[test]
    fn a_chunk_lands_where_its_row_and_column_say_or_nowhere() {
        let mut grid = [0i8; 12];
        // Row 1, column 2 of a 4-wide grid is cell 6; three cells run on into row 2.
        let slot = rows(1, 2, 3).slot_in(&mut grid, 4).map(|s| s.len());
        assert_eq!(slot, Some(3));
        if let Some(slot) = rows(1, 2, 3).slot_in(&mut grid, 4) {
            slot.copy_from_slice(&[7, 8, 9]);
        }
        assert_eq!(grid, [0, 0, 0, 0, 0, 0, 7, 8, 9, 0, 0, 0]);
        // A first column off the grid, or a run past its end, lands nowhere.
        assert!(rows(0, 4, 1).slot_in(&mut grid, 4).is_none());
        assert!(rows(2, 2, 3).slot_in(&mut grid, 4).is_none());
        assert!(rows(u16::MAX, 0, 1).slot_in(&mut grid, 4).is_none());
        // The last cell exactly.
        assert!(rows(2, 3, 1).slot_in(&mut grid, 4).is_some());
    }
}
