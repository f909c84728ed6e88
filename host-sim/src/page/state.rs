//! What the live page shows, kept up to date message by message: the latest map, the
//! two paths, the world's tags and walls, and the figures. Fixed in size whatever the
//! run's length (the map is the latest one, the paths are [`DecimatedPath`]s), and
//! turned into the JSON the page polls by [`PageState::to_json`].

use super::layout::MapLayout;
use super::path::{DecimatedPath, PathPoint};
use crate::record::{Belief, PointMm, WorldOutline};
use crate::telemetry::{localiser_name, MAX_GRID_SIDE};
use crate::truth::TruthSample;
use serde::Serialize;
use slam_core::Occupancy;
use wire::telemetry::{FilterState, Hello, MapRows, Message, SensorHealth, Tick};

/// The character the page gets for a cell of each belief, row-major from the lowest
/// row: one byte a cell, the smallest that JSON carries as it is.
const UNKNOWN_CELL: char = '0';
const FREE_CELL: char = '1';
const OCCUPIED_CELL: char = '2';

/// A truth sample this close to a tick's time, milliseconds, is that tick's truth (a
/// tick is 100 ms).
const TRUTH_MATCH_MS: f64 = 50.0;

/// Everything the page draws, as the messages left it.
#[derive(Clone, Debug, Default)]
pub struct PageState {
    /// Bumped on every change, so the page can tell a new state from the last.
    version: u64,
    hello: Option<Hello>,
    /// The latest cell bytes, `width * height`, row-major from the lowest row.
    cells: Vec<i8>,
    estimate: DecimatedPath,
    truth: DecimatedPath,
    last_tick: Option<Tick>,
    last_truth: Option<TruthSample>,
    health: Option<SensorHealth>,
    filter: Option<FilterState>,
    world: WorldOutline,
    messages: u64,
    hellos_refused: u32,
    map_rows_refused: u32,
    restarts: u32,
}

impl PageState {
    /// Nothing received yet.
    pub fn new() -> PageState {
        PageState::default()
    }

    /// Takes one decoded message.
    pub fn push(&mut self, message: &Message) {
        self.version += 1;
        self.messages += 1;
        match message {
            Message::Hello(h) => self.take_hello(h),
            Message::Tick(t) => self.take_tick(t),
            Message::MapRows(r) => self.take_map_rows(r),
            Message::Health(h) => self.health = Some(*h),
            Message::Filter(f) => self.filter = Some(*f),
            // The raw inputs change nothing the page draws.
            Message::Inputs(_) => {}
        }
    }

    /// Takes a true pose (in a simulation): the true path grows by it.
    pub fn truth(&mut self, sample: &TruthSample) {
        self.version += 1;
        self.truth.push(PathPoint {
            x_mm: sample.x_mm,
            y_mm: sample.y_mm,
        });
        if sample.t_s.is_finite() && sample.x_mm.is_finite() && sample.y_mm.is_finite() {
            self.last_truth = Some(*sample);
        }
    }

    /// The walls and tags to draw under the paths.
    pub fn world(&mut self, outline: &WorldOutline) {
        self.version += 1;
        self.world = outline.clone();
    }

    fn take_hello(&mut self, h: &Hello) {
        let fits = (1..=MAX_GRID_SIDE).contains(&h.width)
            && (1..=MAX_GRID_SIDE).contains(&h.height)
            && h.cell_mm > 0;
        if !fits {
            // A corrupted or hostile Hello: keep the grid there is.
            self.hellos_refused += 1;
            return;
        }
        let same_grid = self.hello.is_some_and(|old| {
            (old.width, old.height) == (h.width, h.height)
                && (old.cell_mm, old.origin_x_mm, old.origin_y_mm)
                    == (h.cell_mm, h.origin_x_mm, h.origin_y_mm)
        });
        if !same_grid {
            self.cells = vec![0; usize::from(h.width) * usize::from(h.height)];
        }
        self.hello = Some(*h);
    }

    fn take_tick(&mut self, t: &Tick) {
        if self.last_tick.is_some_and(|last| t.tick <= last.tick) {
            self.restarts += 1;
        }
        self.estimate.push(PathPoint {
            x_mm: f64::from(t.x_um) / 1000.0,
            y_mm: f64::from(t.y_um) / 1000.0,
        });
        self.last_tick = Some(*t);
    }

    fn take_map_rows(&mut self, r: &MapRows) {
        let Some(h) = self.hello else {
            self.map_rows_refused += 1;
            return;
        };
        match r.slot_in(&mut self.cells, usize::from(h.width)) {
            Some(slot) => slot.copy_from_slice(r.cells.as_slice()),
            _ => self.map_rows_refused += 1,
        }
    }

    /// The state as the page reads it from `GET /state.json`.
    pub fn to_json(&self) -> String {
        // Serializing plain structs of numbers and strings cannot fail; should it ever,
        // the page shows that the state could not be read and asks again.
        serde_json::to_string(&self.snapshot()).unwrap_or_else(|_| "{}".to_string())
    }

    fn snapshot(&self) -> Snapshot<'_> {
        let scale = self.hello.map(|h| h.scale());
        let mut map = String::with_capacity(self.cells.len());
        let (mut free, mut occupied) = (0usize, 0usize);
        if let Some(scale) = scale {
            for &c in &self.cells {
                map.push(match scale.belief(c) {
                    Occupancy::Unknown => UNKNOWN_CELL,
                    Occupancy::Free => {
                        free += 1;
                        FREE_CELL
                    }
                    Occupancy::Occupied => {
                        occupied += 1;
                        OCCUPIED_CELL
                    }
                });
            }
        }
        let known_pct = (!self.cells.is_empty())
            .then(|| 100.0 * (free + occupied) as f64 / self.cells.len() as f64);
        let pose = self.last_tick.map(|t| {
            let p = t.pose();
            PoseFigures {
                x_mm: f64::from(p.x_um) / 1000.0,
                y_mm: f64::from(p.y_um) / 1000.0,
                heading_deg: f64::from(p.heading.to_microdegrees()) / 1e6,
            }
        });
        let true_pose = self.last_truth.map(|s| PoseFigures {
            x_mm: s.x_mm,
            y_mm: s.y_mm,
            heading_deg: s.heading_deg,
        });
        // The error, when the latest truth belongs to the latest tick.
        let error_cm = match (self.last_tick, self.last_truth, pose) {
            (Some(t), Some(s), Some(p))
                if (s.t_s * 1000.0 - f64::from(t.time_ms)).abs() <= TRUTH_MATCH_MS =>
            {
                Some((p.x_mm - s.x_mm).hypot(p.y_mm - s.y_mm) / 10.0)
            }
            _ => None,
        };
        let figures = Figures {
            tick: self.last_tick.map(|t| t.tick),
            time_s: self.last_tick.map(|t| f64::from(t.time_ms) / 1000.0),
            fixes_taken: self.last_tick.map_or(0, |t| t.counters.fixes_taken),
            fixes_rejected: self.last_tick.map_or(0, |t| {
                let c = &t.counters;
                c.fixes_rejected_geometry
                    .saturating_add(c.fixes_rejected_gate)
                    .saturating_add(c.fixes_rejected_too_old)
            }),
            stale: Stale {
                flow: self.last_tick.map_or(0, |t| t.counters.flow_stale),
                gyro: self.last_tick.map_or(0, |t| t.counters.gyro_stale),
                depth: self.last_tick.map_or(0, |t| t.counters.depth_stale),
                now: self.last_tick.map_or(0, |t| t.stale),
            },
            beams_mapped: self.last_tick.map_or(0, |t| t.counters.beams_mapped),
            known_pct,
            free,
            occupied,
            error_cm,
            firmware: self.hello.map(|h| {
                let v = h.firmware;
                format!("{}.{}.{}", v.major, v.minor, v.patch)
            }),
            localiser: self.hello.map(|h| localiser_name(&h)),
            health: self.health,
            filter: self.filter.map(|f| {
                let belief = Belief::new(&f.estimate(), f.tags);
                FilterFigures {
                    bound_3sigma_cm: belief.bound_3sigma_cm(),
                    bound_3sigma_heading_deg: belief.bound_3sigma_heading_deg(),
                    belief,
                }
            }),
            link: Link {
                messages: self.messages,
                hellos_refused: self.hellos_refused,
                map_rows_refused: self.map_rows_refused,
                restarts: self.restarts,
            },
        };
        Snapshot {
            version: self.version,
            layout: self.hello.map(|h| MapLayout::for_grid(h.width, h.height)),
            grid: self.hello.map(|h| GridFigures {
                width: h.width,
                height: h.height,
                cell_mm: h.cell_mm,
                origin_x_mm: h.origin_x_mm,
                origin_y_mm: h.origin_y_mm,
            }),
            map,
            estimate: self.estimate.points(),
            truth: self.truth.points(),
            pose,
            true_pose,
            walls: &self.world.walls,
            tags: self
                .world
                .tags
                .iter()
                .map(|&(id, (x_mm, y_mm))| TagMark { id, x_mm, y_mm })
                .collect(),
            figures,
        }
    }
}

/// `GET /state.json`.
#[derive(Serialize)]
struct Snapshot<'a> {
    version: u64,
    /// Where to draw the map; `null` before a `Hello`.
    layout: Option<MapLayout>,
    grid: Option<GridFigures>,
    /// One character a cell, row-major from the lowest row: `0` unknown, `1` free,
    /// `2` occupied, classified by the `Hello`'s thresholds as the PNG map's cells are.
    map: String,
    estimate: Vec<PathPoint>,
    truth: Vec<PathPoint>,
    pose: Option<PoseFigures>,
    true_pose: Option<PoseFigures>,
    walls: &'a [(PointMm, PointMm)],
    tags: Vec<TagMark>,
    figures: Figures,
}

#[derive(Serialize)]
struct GridFigures {
    width: u16,
    height: u16,
    cell_mm: i32,
    origin_x_mm: i32,
    origin_y_mm: i32,
}

#[derive(Clone, Copy, Serialize)]
struct PoseFigures {
    x_mm: f64,
    y_mm: f64,
    /// Clockwise from +y.
    heading_deg: f64,
}

#[derive(Serialize)]
struct TagMark {
    id: u16,
    x_mm: f64,
    y_mm: f64,
}

#[derive(Serialize)]
struct Figures {
    tick: Option<u32>,
    time_s: Option<f64>,
    fixes_taken: u32,
    fixes_rejected: u32,
    stale: Stale,
    beams_mapped: u32,
    known_pct: Option<f64>,
    free: usize,
    occupied: usize,
    /// Distance from the estimate to the truth, when the truth is known.
    error_cm: Option<f64>,
    firmware: Option<String>,
    localiser: Option<&'static str>,
    health: Option<SensorHealth>,
    filter: Option<FilterFigures>,
    link: Link,
}

/// Ticks that missed each input since start, and the latest tick's stale bits.
#[derive(Serialize)]
struct Stale {
    flow: u32,
    gyro: u32,
    depth: u32,
    now: u8,
}

#[derive(Serialize)]
struct FilterFigures {
    bound_3sigma_cm: f64,
    bound_3sigma_heading_deg: f64,
    belief: Belief,
}

/// What came over the link, and what of it was refused.
#[derive(Serialize)]
struct Link {
    messages: u64,
    hellos_refused: u32,
    map_rows_refused: u32,
    restarts: u32,
}
