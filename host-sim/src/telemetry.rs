//! The host's end of the robot's telemetry stream (`wire::telemetry`).
//!
//! [`TelemetryWriter`] is the simulator's sink: it calls the same [`Streamer`] and
//! [`encode`] the firmware calls, so `host-sim run --telemetry FILE` writes the bytes a
//! robot on the same route would send. [`TelemetryRecorder`] goes the other way: it takes
//! decoded messages from a file or a serial port and builds a [`RunRecord`], so
//! [`crate::picture`] draws a real robot's run as it draws a simulated one.
//!
//! A robot knows nothing of the truth: in a record built from telemetry alone every truth
//! and error field is NaN (the pictures leave NaN out), the world outline is empty and no
//! cell is marked out of place. Given the truth ([`TelemetryRecorder::with_truth`]: the
//! emulator's harness records it) and the world ([`TelemetryRecorder::with_world`]), the
//! recorder fills them in and its [`Summary`] carries `host-sim run`'s figures, worked out
//! by the same code ([`crate::score`]).

use crate::consistency::{estimator_figures, EstimatorFigures};
use crate::floor::floor_mask;
use crate::record::{
    Belief, CellBelief, MapSnapshot, RunRecord, TickRecord, TrueCalibration, WorldOutline,
};
use crate::run::PoseMode;
use crate::score::{map_counts, out_of_place_mask, pose_errors, real_mask, PoseErrors};
use crate::truth::{route_start_s, truth_at, TruthSample};
use crate::world::World;
use serde::Serialize;
use slam_core::{
    Counters, FixOutcome, GridGeometry, GridMap, Occupancy, SensorFrame, StepReport, TagCounters,
};
use std::fmt;
use std::io::{self, Read};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;
use wire::framing::BadFrames;
use wire::telemetry::{
    encode, serialize_counters, Boot, CellScale, DecoderStats, FilterState, FirmwareVersion, Hello,
    MapRows, Message, ResetCause, Schedule, SensorHealth, StreamDecoder, Streamer, Tick,
    MAX_FRAME_LEN,
};

/// The firmware version the simulator claims in its `Hello`: this crate's.
pub fn simulator_firmware() -> FirmwareVersion {
    let part = |s: &str| s.parse().unwrap_or(0);
    FirmwareVersion {
        major: part(env!("CARGO_PKG_VERSION_MAJOR")),
        minor: part(env!("CARGO_PKG_VERSION_MINOR")),
        patch: part(env!("CARGO_PKG_VERSION_PATCH")),
    }
}

/// The simulator's telemetry sink: frames every tick's messages into a byte buffer.
pub struct TelemetryWriter {
    streamer: Streamer,
    bytes: Vec<u8>,
    encode_errors: u32,
}

impl TelemetryWriter {
    /// An empty stream on the firmware's default schedule, from a robot whose pose is
    /// corrected as `mode` says (its `Hello` says so).
    pub fn new(mode: PoseMode) -> TelemetryWriter {
        TelemetryWriter {
            streamer: Streamer::new(Schedule::DEFAULT, simulator_firmware(), mode.localiser())
                .with_matching(mode.matches()),
            bytes: Vec::new(),
            encode_errors: 0,
        }
    }

    /// One tick's messages, after `step` was given `frame` and returned `report` (`tags`:
    /// the core's `tag_counters()`); `time_ms` since the start.
    ///
    /// The simulator has no buses, so its health is what the core saw: a tick without a
    /// depth scan counts as a depth timeout, a tick without flow as flow with no surface,
    /// a tick without gyro as a gyro bus error, and every tick feeds the watchdog.
    pub fn tick<const W: usize, const H: usize>(
        &mut self,
        time_ms: u32,
        frame: &SensorFrame,
        report: &StepReport,
        tags: TagCounters,
        map: &GridMap<W, H>,
    ) {
        let c = &report.counters;
        let health = SensorHealth {
            depth_timeouts: c.depth_stale,
            flow_no_surface: c.flow_stale,
            gyro_bus_errors: c.gyro_stale,
            watchdog_feeds: c.ticks,
            ..SensorHealth::default()
        };
        let (bytes, errors) = (&mut self.bytes, &mut self.encode_errors);
        self.streamer
            .tick(time_ms, frame, report, tags, map, &health, |m| {
                push(bytes, errors, m)
            });
    }

    /// The end of the run: the whole map once more, so the viewer's map is the final one.
    pub fn finish<const W: usize, const H: usize>(&mut self, map: &GridMap<W, H>) {
        let (bytes, errors) = (&mut self.bytes, &mut self.encode_errors);
        self.streamer
            .send_whole_map(map, |m| push(bytes, errors, m));
    }

    /// The stream so far.
    pub fn bytes(&self) -> &[u8] {
        &self.bytes
    }

    /// Messages that could not be framed (always 0: every message fits a frame).
    pub fn encode_errors(&self) -> u32 {
        self.encode_errors
    }
}

fn push(bytes: &mut Vec<u8>, errors: &mut u32, message: &Message) {
    let mut frame = [0u8; MAX_FRAME_LEN];
    match encode(message, &mut frame) {
        Ok(n) => bytes.extend_from_slice(frame.get(..n).unwrap_or(&[])),
        Err(_) => *errors += 1,
    }
}

/// The most columns or rows a stream's `Hello` may declare. The largest grid the core is
/// built with is 206 x 206 (`room-10m`), the firmware's is smaller; the margin leaves room
/// for bigger builds while a 1024 x 1024 map stays a 1 MB buffer. A `Hello` past it (a
/// corrupted or hostile stream: 65535 x 65535 would be 4 GB) is refused and counted.
pub const MAX_GRID_SIDE: u16 = 1024;

/// Where a `Hello`'s grid lies on the world.
fn geometry(h: &Hello) -> GridGeometry {
    GridGeometry {
        cell_mm: h.cell_mm,
        origin_x_mm: h.origin_x_mm,
        origin_y_mm: h.origin_y_mm,
    }
}

/// Builds a run's record from a robot's messages.
#[derive(Clone, Debug, Default)]
pub struct TelemetryRecorder {
    hello: Option<Hello>,
    /// The latest cell bytes, `width * height`, row-major from the lowest row.
    cells: Vec<i8>,
    /// How many of `cells` on the floor the latest `Hello`'s scale calls free or
    /// occupied, kept up to date chunk by chunk so that a tick costs what it changed, not
    /// the whole map.
    known_cells: usize,
    /// Which of `cells` are the world's floor ([`floor_mask`]); empty (every cell) without
    /// a world.
    floor: Vec<bool>,
    /// How many of `cells` are floor.
    floor_cells: usize,
    ticks: Vec<TickRecord>,
    last_tick: Option<Tick>,
    health: Option<SensorHealth>,
    hellos: u32,
    /// `Hello`s refused (see [`MAX_GRID_SIDE`]), and what was wrong with the last.
    refused: Option<RefusedHellos>,
    map_rows: u32,
    map_rows_refused: u32,
    /// `Inputs` messages: each tick's raw inputs, which only `host-sim replay` reads.
    inputs: u32,
    /// `Filter` messages whose tick is not the latest `Tick`'s (its `Tick` was lost).
    filters_unmatched: u32,
    restarts: u32,
    /// The true poses, in time order, when known.
    truth: Option<Vec<TruthSample>>,
    ticks_without_truth: u32,
    /// The world the robot is in, when known.
    world: Option<World>,
    /// The corrections the filter should learn, when the scenario is known.
    true_calibration: Option<TrueCalibration>,
}

impl TelemetryRecorder {
    /// Nothing received yet.
    pub fn new() -> TelemetryRecorder {
        TelemetryRecorder::default()
    }

    /// Scores each tick's pose against `truth` (in time order, as
    /// [`crate::truth::parse_truth`] gives it), paired by [`truth_at`].
    pub fn with_truth(mut self, truth: Vec<TruthSample>) -> TelemetryRecorder {
        self.truth = Some(truth);
        self
    }

    /// Scores the map against `world`: out-of-place cells, and the world under the map.
    pub fn with_world(mut self, world: World) -> TelemetryRecorder {
        self.world = Some(world);
        self
    }

    /// Draws the corrections the robot's filter should learn (the scenario's sensors'
    /// errors) beside the ones it learned.
    pub fn with_true_calibration(mut self, calibration: TrueCalibration) -> TelemetryRecorder {
        self.true_calibration = Some(calibration);
        self
    }

    /// Takes one decoded message.
    pub fn push(&mut self, message: &Message) {
        match message {
            Message::Hello(h) => self.take_hello(h),
            Message::Tick(t) => self.take_tick(t),
            Message::MapRows(r) => self.take_map_rows(r),
            Message::Health(h) => self.health = Some(*h),
            Message::Filter(f) => self.take_filter(f),
            // The raw inputs change nothing the robot reported; `replay` steps them.
            Message::Inputs(_) => self.inputs += 1,
        }
    }

    /// A filter's belief belongs to the `Tick` just before it, with the same tick number.
    fn take_filter(&mut self, f: &FilterState) {
        match (self.last_tick, self.ticks.last_mut()) {
            (Some(t), Some(record)) if t.tick == f.tick => {
                record.belief = Some(Belief::new(&f.estimate(), f.tags));
            }
            _ => self.filters_unmatched += 1,
        }
    }

    fn take_hello(&mut self, h: &Hello) {
        self.hellos += 1;
        if let Some(problem) = grid_problem(h) {
            // Keep the grid there is (if any): its chunks may still come.
            let count = self.refused.as_ref().map_or(0, |r| r.count) + 1;
            self.refused = Some(RefusedHellos {
                count,
                last: problem,
            });
            return;
        }
        let same_grid = self.hello.is_some_and(|old| {
            (
                old.width,
                old.height,
                old.cell_mm,
                old.origin_x_mm,
                old.origin_y_mm,
            ) == (h.width, h.height, h.cell_mm, h.origin_x_mm, h.origin_y_mm)
        });
        if !same_grid {
            // A new grid (or the first): start its map empty.
            self.cells = vec![0; usize::from(h.width) * usize::from(h.height)];
        }
        let same_scale = self.hello.is_some_and(|old| old.scale() == h.scale());
        self.hello = Some(*h);
        if !same_grid {
            self.floor = match &self.world {
                Some(world) => floor_mask(world, &geometry(h), h.width.into(), h.height.into()),
                None => Vec::new(),
            };
            self.floor_cells = (0..self.cells.len()).filter(|&i| self.on_floor(i)).count();
        }
        if !(same_grid && same_scale) {
            // New thresholds classify every cell anew: once per such Hello.
            let scale = h.scale();
            self.known_cells = (0..self.cells.len())
                .filter(|&i| self.on_floor(i) && known(scale, self.cells[i]))
                .count();
        }
    }

    /// Whether cell `i` of the latest grid is floor.
    fn on_floor(&self, i: usize) -> bool {
        self.floor.get(i).copied().unwrap_or(true)
    }

    fn take_tick(&mut self, t: &Tick) {
        if self.last_tick.is_some_and(|last| t.tick <= last.tick) {
            // The robot started over (a reset): its ticks carry on in the same record.
            self.restarts += 1;
        }
        let pose = t.pose();
        let known_pct = match self.hello {
            Some(_) if !self.cells.is_empty() => {
                100.0 * self.known_cells as f64 / self.floor_cells.max(1) as f64
            }
            _ => f64::NAN,
        };
        let mut record = TickRecord::estimated(
            f64::from(t.time_ms) / 1000.0,
            (f64::from(pose.x_um) / 1000.0, f64::from(pose.y_um) / 1000.0),
            f64::from(pose.heading.to_microdegrees()) / 1e6,
            known_pct,
            t.fix == FixOutcome::Taken,
        );
        if let Some(truth) = &self.truth {
            match truth_at(truth, t.time_ms) {
                Some(s) => record.set_truth((s.x_mm, s.y_mm), s.heading_deg),
                None => self.ticks_without_truth += 1,
            }
        }
        self.ticks.push(record);
        self.last_tick = Some(*t);
    }

    fn take_map_rows(&mut self, r: &MapRows) {
        let Some(h) = self.hello else {
            // Joined late: the map waits for the next Hello to say how big it is.
            self.map_rows_refused += 1;
            return;
        };
        let cells = r.cells.as_slice();
        let width = usize::from(h.width);
        // Where the chunk starts, when `slot_in` places it.
        let start = usize::from(r.first_row) * width + usize::from(r.first_column);
        let floor = &self.floor;
        match r.slot_in(&mut self.cells, width) {
            Some(slot) => {
                let scale = h.scale();
                let on_floor = |k: usize| floor.get(start + k).copied().unwrap_or(true);
                let count = |c: &[i8]| {
                    (c.iter().enumerate())
                        .filter(|&(k, &c)| on_floor(k) && known(scale, c))
                        .count()
                };
                self.known_cells = self.known_cells - count(slot) + count(cells);
                slot.copy_from_slice(cells);
                self.map_rows += 1;
            }
            _ => self.map_rows_refused += 1,
        }
    }

    /// The latest `Hello` taken, if one came.
    pub fn hello(&self) -> Option<&Hello> {
        self.hello.as_ref()
    }

    /// `Hello`s refused because their grid is impossible or past [`MAX_GRID_SIDE`].
    pub fn hellos_refused(&self) -> u32 {
        self.refused.as_ref().map_or(0, |r| r.count)
    }

    /// The last `Tick` received.
    pub fn last_tick(&self) -> Option<&Tick> {
        self.last_tick.as_ref()
    }

    /// The latest sensor health received.
    pub fn latest_health(&self) -> Option<&SensorHealth> {
        self.health.as_ref()
    }

    /// Ticks received.
    pub fn tick_count(&self) -> usize {
        self.ticks.len()
    }

    /// The latest map as beliefs, row-major from the lowest row; empty before a `Hello`.
    pub fn beliefs(&self) -> Vec<CellBelief> {
        let Some(h) = self.hello else {
            return Vec::new();
        };
        let scale = h.scale();
        self.cells.iter().map(|&c| scale.belief(c).into()).collect()
    }

    /// For each cell of the latest grid, whether it lies on something real in the world;
    /// empty without a world or a `Hello` (then nothing is out of place).
    fn real_mask(&self) -> Vec<bool> {
        match (&self.world, self.hello) {
            (Some(world), Some(h)) => {
                real_mask(world, &geometry(&h), h.width.into(), h.height.into())
            }
            _ => Vec::new(),
        }
    }

    /// The run as the pictures want it, named `name`.
    pub fn record(&self, name: &str) -> RunRecord {
        let (width, height, cell_mm, ox, oy) = self.hello.map_or((0, 0, 0, 0, 0), |h| {
            (
                usize::from(h.width),
                usize::from(h.height),
                h.cell_mm,
                h.origin_x_mm,
                h.origin_y_mm,
            )
        });
        let cells = self.beliefs();
        let real = self.real_mask();
        let mut ticks = self.ticks.clone();
        // With the world known, the final map's share out of place, as `run` gives its last
        // tick (the viewer scores only the map it ends with, so earlier ticks stay unknown).
        if let (Some(_), Some(last)) = (&self.world, ticks.last_mut()) {
            last.out_of_place_pct =
                map_counts(cells.iter().copied(), &real, &self.floor).out_of_place_pct();
        }
        RunRecord {
            scenario: name.to_string(),
            pose_mode: "robot telemetry".to_string(),
            true_calibration: self.true_calibration,
            ticks,
            map: MapSnapshot {
                width,
                height,
                cell_mm: f64::from(cell_mm),
                origin_x_mm: f64::from(ox),
                origin_y_mm: f64::from(oy),
                out_of_place: out_of_place_mask(&cells, &real),
                cells,
            },
            world: self
                .world
                .as_ref()
                .map_or_else(WorldOutline::default, WorldOutline::of),
        }
    }

    /// What came in, for the summary; `stats` are the decoder's counts.
    pub fn summary(&self, stats: &DecoderStats) -> Summary {
        let map = map_counts(self.beliefs(), &self.real_mask(), &self.floor);
        Summary {
            ticks: self.ticks.len(),
            duration_s: self.ticks.last().map_or(0.0, |t| t.t_s),
            fixes: self.ticks.iter().filter(|t| t.fix_taken).count(),
            first_fix_s: self.ticks.iter().find(|t| t.fix_taken).map(|t| t.t_s),
            final_pose: self.last_tick.map(|t| {
                let p = t.pose();
                FinalPose {
                    x_um: p.x_um,
                    y_um: p.y_um,
                    heading_deg: f64::from(p.heading.to_microdegrees()) / 1e6,
                }
            }),
            counters: self.last_tick.map(|t| t.counters),
            health: self.health,
            firmware: self.hello.map(|h| {
                format!(
                    "{}.{}.{}",
                    h.firmware.major, h.firmware.minor, h.firmware.patch
                )
            }),
            grid: self.hello.map(|h| (h.width, h.height)),
            localiser: self.hello.map(|h| localiser_name(&h).to_string()),
            boot: self.hello.map(|h| h.boot),
            free: map.free as usize,
            occupied: map.occupied as usize,
            known_pct: map.known_pct(),
            out_of_place: self.world.as_ref().map(|_| map.out_of_place),
            truth: self.truth.as_ref().map(|truth| TruthFigures {
                errors: self
                    .ticks
                    .iter()
                    .any(|t| t.error_cm.is_finite())
                    .then(|| pose_errors(&self.ticks)),
                truth_samples: truth.len(),
                ticks_without_truth: self.ticks_without_truth,
                route_start_s: route_start_s(truth),
            }),
            hellos: self.hellos,
            hellos_refused: self.refused.clone(),
            map_rows: self.map_rows,
            map_rows_refused: self.map_rows_refused,
            inputs: self.inputs,
            filters_unmatched: self.filters_unmatched,
            restarts: self.restarts,
            estimator: estimator_figures(&self.ticks, self.true_calibration),
            frames_ok: stats.frames_ok,
            bad_frames: stats.bad_frames,
        }
    }
}

/// The name `--pose` gives the mode a stream's `Hello` names.
pub fn localiser_name(hello: &Hello) -> &'static str {
    crate::run::PoseMode::of_hello(hello).name()
}

/// Whether a cell byte is a firm belief under `scale`.
fn known(scale: CellScale, cell: i8) -> bool {
    scale.belief(cell) != Occupancy::Unknown
}

/// What is wrong with the grid a `Hello` declares, if anything.
fn grid_problem(h: &Hello) -> Option<String> {
    if h.width == 0 || h.height == 0 || h.width > MAX_GRID_SIDE || h.height > MAX_GRID_SIDE {
        Some(format!(
            "a {} x {} grid (at most {MAX_GRID_SIDE} x {MAX_GRID_SIDE} is taken)",
            h.width, h.height
        ))
    } else if h.cell_mm < 1 {
        Some(format!("{} mm cells (at least 1 mm)", h.cell_mm))
    } else {
        None
    }
}

/// `Hello`s the viewer refused.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct RefusedHellos {
    /// How many.
    pub count: u32,
    /// What the last one declared that could not be taken.
    pub last: String,
}

/// The pose in the last tick received.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct FinalPose {
    /// Micrometres.
    pub x_um: i32,
    /// Micrometres.
    pub y_um: i32,
    /// Degrees clockwise from +y, in [-180, 180).
    pub heading_deg: f64,
}

/// What a telemetry stream held: printed by `host-sim view`, as text or JSON.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Summary {
    /// Ticks received.
    pub ticks: usize,
    /// Time of the last tick, seconds.
    pub duration_s: f64,
    /// Ticks with a tag fix taken.
    pub fixes: usize,
    /// Time of the first fix, seconds.
    pub first_fix_s: Option<f64>,
    /// The last tick's pose.
    pub final_pose: Option<FinalPose>,
    /// The last tick's counters.
    #[serde(serialize_with = "serialize_counters")]
    pub counters: Option<Counters>,
    /// The latest sensor health.
    pub health: Option<SensorHealth>,
    /// The firmware's version, from the latest `Hello`.
    pub firmware: Option<String>,
    /// Grid columns and rows.
    pub grid: Option<(u16, u16)>,
    /// What corrects the robot's pose, from the latest `Hello`, as `--pose` names it:
    /// `dead-reckoning`, `tags` or `slam` (the filter).
    pub localiser: Option<String>,
    /// How the robot's run started, from the latest `Hello`: what reset its chip, and
    /// whether it resumed its map, pose and route from before.
    pub boot: Option<Boot>,
    /// Cells believed free in the latest map.
    pub free: usize,
    /// Cells believed occupied in the latest map.
    pub occupied: usize,
    /// Share of the world's floor (the whole grid without a world) with a firm belief in
    /// the latest map, percent.
    pub known_pct: f64,
    /// Occupied cells on no real wall or tag; with the world only.
    pub out_of_place: Option<u32>,
    /// The pose against the truth; with the truth only (its keys sit beside these).
    #[serde(flatten)]
    pub truth: Option<TruthFigures>,
    /// `Hello`s received.
    pub hellos: u32,
    /// `Hello`s refused, with the reason for the last; `None` when all were taken.
    pub hellos_refused: Option<RefusedHellos>,
    /// Map chunks placed.
    pub map_rows: u32,
    /// Map chunks refused: before any `Hello`, or outside the grid.
    pub map_rows_refused: u32,
    /// Ticks' raw inputs received (what `host-sim replay` steps again).
    pub inputs: u32,
    /// `Filter` messages that did not follow their `Tick` (dropped: its `Tick` was lost).
    pub filters_unmatched: u32,
    /// Times the tick number went backwards (the robot reset).
    pub restarts: u32,
    /// The filter's figures, as `host-sim run` gives them (the shares and the median error
    /// need the truth); absent when the robot sent no `Filter`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub estimator: Option<EstimatorFigures>,
    /// Good frames.
    pub frames_ok: u32,
    /// Dropped frames, by kind (serialised with their `total`).
    pub bad_frames: BadFrames,
}

/// A telemetry run's pose against the truth.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct TruthFigures {
    /// The figures `host-sim run` reports, under the same names; `None` (each `null` in
    /// JSON) when no tick had a truth sample near its time, so there was nothing to score.
    #[serde(flatten, serialize_with = "errors_or_nulls")]
    pub errors: Option<PoseErrors>,
    /// Truth samples given.
    pub truth_samples: usize,
    /// Ticks with no truth sample near their time: left out of the errors.
    pub ticks_without_truth: u32,
    /// The last time the robot stood where it started, seconds (see
    /// [`crate::truth::route_start_s`]): subtract it from a time to compare with `run`'s.
    pub route_start_s: Option<f64>,
}

/// The keys of [`PoseErrors`], for [`errors_or_nulls`].
const POSE_ERROR_KEYS: [&str; 8] = [
    "final_error_cm",
    "max_error_after_first_fix_cm",
    "max_error_1s_after_first_fix_cm",
    "final_heading_error_deg",
    "max_heading_error_after_first_fix_deg",
    "max_error_cm",
    "max_heading_error_deg",
    "max_jump_cm",
];

/// The errors' keys with their values, or each with `null`: a reader finds the key
/// either way, and never a 0 that was not measured.
fn errors_or_nulls<S: serde::Serializer>(
    errors: &Option<PoseErrors>,
    s: S,
) -> Result<S::Ok, S::Error> {
    use serde::ser::SerializeMap;
    match errors {
        Some(e) => e.serialize(s),
        None => {
            let mut map = s.serialize_map(Some(POSE_ERROR_KEYS.len()))?;
            for key in POSE_ERROR_KEYS {
                map.serialize_entry(key, &None::<f64>)?;
            }
            map.end()
        }
    }
}

impl fmt::Display for Summary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let fw = self.firmware.as_deref().unwrap_or("?");
        let grid = self
            .grid
            .map_or("no Hello".to_string(), |(w, h)| format!("{w} x {h} grid"));
        let localiser = self.localiser.as_deref().unwrap_or("?");
        writeln!(
            f,
            "telemetry: firmware {fw} ({localiser}), {grid}: {} ticks, {:.1} s",
            self.ticks, self.duration_s
        )?;
        if let Some(b) = self
            .boot
            .filter(|b| b.cause != ResetCause::PowerOn || b.resumed)
        {
            let how = if b.resumed {
                "resumed its map, pose and route"
            } else {
                "started fresh"
            };
            writeln!(
                f,
                "restarted after a {:?} reset: {how} ({} resumes since it last started fresh)",
                b.cause, b.resumes
            )?;
        }
        match self.first_fix_s {
            Some(t) => writeln!(f, "fixes taken {} (first at {t:.1} s)", self.fixes)?,
            None => writeln!(f, "fixes taken 0")?,
        }
        if let Some(p) = self.final_pose {
            writeln!(
                f,
                "final pose ({:.1}, {:.1}) mm, heading {:.1} deg",
                f64::from(p.x_um) / 1000.0,
                f64::from(p.y_um) / 1000.0,
                p.heading_deg
            )?;
        }
        write!(
            f,
            "map: free {}  occupied {}  known {:.1} %",
            self.free, self.occupied, self.known_pct
        )?;
        match self.out_of_place {
            Some(n) => writeln!(f, "  out of place {n}")?,
            None => writeln!(f)?,
        }
        if let Some(t) = self.truth {
            let start = t.route_start_s.map_or("never moved".to_string(), |s| {
                format!("moved after {s:.1} s")
            });
            match t.errors {
                Some(e) => writeln!(
                    f,
                    "against the truth ({} samples, {} ticks without one; {start}): after the first fix error <= {:.1} cm, heading <= {:.1} deg; final error {:.1} cm, heading {:.1} deg; max error {:.1} cm",
                    t.truth_samples, t.ticks_without_truth, e.max_error_after_first_fix_cm,
                    e.max_heading_error_after_first_fix_deg, e.final_error_cm,
                    e.final_heading_error_deg, e.max_error_cm
                )?,
                None => writeln!(
                    f,
                    "against the truth ({} samples, {} ticks without one): no tick has a truth sample near its time, so there is nothing to score against",
                    t.truth_samples, t.ticks_without_truth
                )?,
            }
        }
        if let Some(e) = &self.estimator {
            writeln!(f, "{}", estimator_line(e))?;
        }
        if let Some(c) = self.counters {
            writeln!(
                f,
                "counters: fixes {} taken, {} geometry / {} gate / {} too old rejected, {} relocalisations; pictures {} repeated, {} leapt, {} late; beams {} mapped, {} invalid; stale flow {} gyro {} depth {}",
                c.fixes_taken, c.fixes_rejected_geometry, c.fixes_rejected_gate,
                c.fixes_rejected_too_old, c.relocalisations, c.pictures_repeated, c.pictures_leapt, c.pictures_late,
                c.beams_mapped, c.beams_invalid, c.flow_stale, c.gyro_stale, c.depth_stale
            )?;
        }
        match self.health {
            Some(h) => writeln!(
                f,
                "health: depth {} timeouts {} bus; flow {} no surface {} outliers {} bus; gyro {} bus; camera {} bad frames; {} overruns; {} watchdog feeds",
                h.depth_timeouts, h.depth_bus_errors, h.flow_no_surface, h.flow_outliers,
                h.flow_bus_errors, h.gyro_bus_errors, h.camera_bad_frames, h.tick_overruns,
                h.watchdog_feeds
            )?,
            None => writeln!(f, "health: none received")?,
        }
        if let Some(r) = &self.hellos_refused {
            writeln!(
                f,
                "Hellos refused: {} (the last declared {}); their map is not drawn",
                r.count, r.last
            )?;
        }
        let b = &self.bad_frames;
        write!(
            f,
            "frames: {} good, {} bad ({} overlong, {} COBS, {} short, {} CRC, {} version, {} body); map chunks {} placed, {} refused; {} ticks' inputs; {} restarts",
            self.frames_ok, b.total(), b.overlong, b.bad_cobs, b.too_short, b.bad_crc,
            b.bad_version, b.bad_body, self.map_rows, self.map_rows_refused, self.inputs,
            self.restarts
        )
    }
}

/// The filter's figures in a line or two of text, as `run` and `view` print them.
pub fn estimator_line(e: &EstimatorFigures) -> String {
    let pct = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.1} %"));
    let c = &e.calibration;
    let t = &e.tags;
    let r = &t.refused;
    format!(
        "filter: 3-sigma bound at the end {:.2} cm, {:.2} deg; inside it {} of ticks (heading {}); median bound {:.2} cm, median error {}\n\
         filter: learned gyro scale {:+.0} ppm, gyro bias {:+.1} mdps, flow scale {:+.0} ppm; tags used {}, refused {} unknown / {} behind / {} too far / {} too old / {} gate",
        e.bound_3sigma_cm,
        e.bound_3sigma_heading_deg,
        pct(e.inside_3sigma_pct),
        pct(e.inside_3sigma_heading_pct),
        e.median_bound_cm,
        e.median_error_cm.map_or("-".to_string(), |v| format!("{v:.2} cm")),
        c.gyro_scale_ppm,
        c.gyro_bias_mdps,
        c.flow_scale_ppm,
        t.used,
        r.unknown_id,
        r.behind,
        r.too_far,
        r.too_old,
        r.gate,
    )
}

/// A decoder and a recorder together: bytes in, a record out.
#[derive(Clone, Debug, Default)]
pub struct Recording {
    /// Frame decoding and its counts.
    pub decoder: StreamDecoder,
    /// What the good frames said.
    pub recorder: TelemetryRecorder,
}

impl Recording {
    /// Nothing received yet.
    pub fn new() -> Recording {
        Recording::default()
    }

    /// Feeds received bytes.
    pub fn feed(&mut self, bytes: &[u8]) {
        for message in self.decoder.feed(bytes).flatten() {
            self.recorder.push(&message);
        }
    }

    /// The summary so far.
    pub fn summary(&self) -> Summary {
        self.recorder.summary(self.decoder.stats())
    }

    /// Reads `source` until end of file, `stop` is set, or `deadline` passes.
    ///
    /// Timeouts (a serial port with nothing to say) and interrupted reads are waited out;
    /// any other error ends the reading and is returned after everything before it was
    /// fed.
    pub fn read_from(
        &mut self,
        source: &mut dyn Read,
        stop: &AtomicBool,
        deadline: Option<Instant>,
    ) -> io::Result<()> {
        self.read_each(source, stop, deadline, |_| true)
    }

    /// As [`Recording::read_from`], handing each good message to `each` once recorded;
    /// the reading ends early when `each` returns `false`.
    pub fn read_each(
        &mut self,
        source: &mut dyn Read,
        stop: &AtomicBool,
        deadline: Option<Instant>,
        mut each: impl FnMut(&Message) -> bool,
    ) -> io::Result<()> {
        let mut buf = [0u8; 4096];
        loop {
            if stop.load(Ordering::Relaxed) || deadline.is_some_and(|d| Instant::now() >= d) {
                return Ok(());
            }
            match source.read(&mut buf) {
                Ok(0) => return Ok(()),
                Ok(n) => {
                    for message in self.decoder.feed(buf.get(..n).unwrap_or(&[])).flatten() {
                        self.recorder.push(&message);
                        if !each(&message) {
                            return Ok(());
                        }
                    }
                }
                Err(e)
                    if matches!(
                        e.kind(),
                        io::ErrorKind::TimedOut
                            | io::ErrorKind::Interrupted
                            | io::ErrorKind::WouldBlock
                    ) => {}
                Err(e) => return Err(e),
            }
        }
    }
}

/// Decodes a whole recorded stream.
pub fn decode_bytes(bytes: &[u8]) -> Recording {
    let mut r = Recording::new();
    r.feed(bytes);
    r
}
