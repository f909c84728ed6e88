//! A recorded run stepped again: the `Inputs` of a telemetry stream through `Slam::step`.
//!
//! With the robot's own settings (the localiser its `Hello` names, the configuration of the
//! scenario it was built for) the core must do on the host exactly what it did on the
//! robot: every replayed `Tick` (pose, fix, stale inputs, cells written, counters) and
//! `Filter` (covariance, calibration, tag counters) equals the one the robot sent for the
//! same tick, and every map chunk it sent equals the replayed map at that tick. The first
//! difference is reported by tick and field. With other settings ([`replay`]'s `pose`) the
//! same inputs show what those settings would have done.
//!
//! The replayed run is written as a telemetry stream by the simulator's own sink
//! ([`TelemetryWriter`]), so `view`'s decoding, figures and pictures apply to it unchanged.
//!
//! A stream that lies is stepped as far as it makes sense and never panics: an input frame
//! whose tick is not after the last one stepped is skipped and counted (the replay stays
//! whole); one after a gap is stepped, and the missing ticks are counted and named as the
//! first difference, since the core's state no longer follows the robot's.

use crate::robot::TruePose;
use crate::run::{slam_config, to_core_pose, PoseMode, GRID_SIDES};
use crate::scenario::Scenario;
use crate::telemetry::TelemetryWriter;
use serde::Serialize;
use slam_core::slam::first_turn::FirstTurn;
use slam_core::wall_rate::WallRate;
use slam_core::wall_turn::WallTurn;
use slam_core::{GridMap, Slam};
use std::fmt;
use wire::telemetry::{
    CellScale, FilterState, Hello, Inputs, MapRows, Message, StreamDecoder, Tick,
};

/// Why a stream cannot be replayed.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ReplayError {
    /// The stream carries no `Inputs`: it was recorded without them.
    NoInputs {
        /// Good frames it did carry.
        frames_ok: u32,
    },
    /// No `Hello` came before the first `Inputs`, so the grid is unknown.
    NoHello,
    /// The `Hello`'s grid is not one the core is built with here, or not the scenario's.
    Grid(String),
    /// `--pose truth`: a replay has no truth to give the core.
    Truth,
    /// The core refused the scenario's configuration.
    Config(String),
}

impl fmt::Display for ReplayError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ReplayError::NoInputs { frames_ok } => write!(
                f,
                "the stream holds no input frames ({frames_ok} good frames of other kinds), so there is nothing to replay: record one with the firmware's `record-inputs` feature (on by default: `cargo xtask firmware`) or with `host-sim run SCENARIO --telemetry FILE`"
            ),
            ReplayError::NoHello => write!(
                f,
                "no Hello before the first input frame: the grid is unknown"
            ),
            ReplayError::Grid(why) => write!(f, "{why}"),
            ReplayError::Truth => write!(
                f,
                "--pose truth cannot be replayed: a recording has no truth to hand the core (use dead-reckoning, tags or slam)"
            ),
            ReplayError::Config(why) => write!(f, "the core refused the configuration: {why}"),
        }
    }
}

impl std::error::Error for ReplayError {}

/// The first place where the replay and the robot part.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct Difference {
    /// The tick (the robot's number).
    pub tick: u32,
    /// What differs: a field of `Tick` or `Filter`, a map cell, or a missing input.
    pub field: String,
    /// The robot's value, as text.
    pub robot: String,
    /// The replay's value, as text.
    pub replay: String,
}

impl fmt::Display for Difference {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "tick {}: {} (robot {}, replay {})",
            self.tick, self.field, self.robot, self.replay
        )
    }
}

/// The replay against the robot's own messages, when it ran with the robot's settings.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize)]
pub struct BitForBit {
    /// `Tick`s compared field by field.
    pub ticks: u32,
    /// `Filter`s compared field by field.
    pub filters: u32,
    /// Map chunks compared cell by cell.
    pub map_chunks: u32,
    /// The first difference; `None` when everything compared was equal.
    pub first_difference: Option<Difference>,
}

impl BitForBit {
    /// Whether everything compared was equal (a converted log with no `Tick` in it has
    /// nothing to compare, and is not a difference).
    pub fn identical(&self) -> bool {
        self.first_difference.is_none()
    }

    fn differ(
        &mut self,
        tick: u32,
        field: &str,
        robot: impl fmt::Display,
        replay: impl fmt::Display,
    ) {
        if self.first_difference.is_none() {
            self.first_difference = Some(Difference {
                tick,
                field: field.to_string(),
                robot: robot.to_string(),
                replay: replay.to_string(),
            });
        }
    }
}

/// What a replay did.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ReplaySummary {
    /// The localiser the replay flew, as `--pose` names it.
    pub pose: String,
    /// Whether that is the robot's own (its `Hello`'s): then [`ReplaySummary::bit_for_bit`]
    /// is filled in.
    pub robot_settings: bool,
    /// Input frames stepped.
    pub steps: u32,
    /// Input frames skipped because their tick was not after the last one stepped.
    pub skipped_out_of_order: u32,
    /// Ticks with no input frame between two that came (frames lost or cut out).
    pub missing_inputs: u32,
    /// Frames the decoder dropped (damaged, wrong layout).
    pub bad_frames: u32,
    /// The comparison with the robot's messages; `None` with other settings.
    pub bit_for_bit: Option<BitForBit>,
}

impl fmt::Display for ReplaySummary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "replay: {} input frames stepped with --pose {} ({})",
            self.steps,
            self.pose,
            if self.robot_settings {
                "the robot's own"
            } else {
                "not the robot's"
            }
        )?;
        if self.skipped_out_of_order + self.missing_inputs + self.bad_frames > 0 {
            write!(
                f,
                "; skipped {} out of order, {} ticks' inputs missing, {} bad frames",
                self.skipped_out_of_order, self.missing_inputs, self.bad_frames
            )?;
        }
        if let Some(b) = &self.bit_for_bit {
            write!(
                f,
                "\nbit for bit: {} ticks, {} filter states, {} map chunks compared: ",
                b.ticks, b.filters, b.map_chunks
            )?;
            match &b.first_difference {
                None if b.ticks > 0 => write!(f, "all equal")?,
                None => write!(f, "nothing to compare")?,
                Some(d) => write!(f, "first difference at {d}")?,
            }
        }
        Ok(())
    }
}

/// A replay's outcome: what happened, and the replayed run as a telemetry stream.
pub struct Replay {
    /// What happened.
    pub summary: ReplaySummary,
    /// The replayed run, framed as the robot frames its own (decode it as `view` does).
    pub stream: Vec<u8>,
}

/// Replays the `Inputs` in `bytes` with the configuration of `scenario` (the world the
/// robot was built for) and the localiser `pose` names, or the stream's own when `None`.
pub fn replay(
    scenario: &Scenario,
    bytes: &[u8],
    pose: Option<PoseMode>,
) -> Result<Replay, ReplayError> {
    let mut decoder = StreamDecoder::new();
    let messages: Vec<Message> = decoder.feed(bytes).flatten().collect();
    let stats = *decoder.stats();
    let Some(first_input) = messages
        .iter()
        .position(|m| matches!(m, Message::Inputs(_)))
    else {
        return Err(ReplayError::NoInputs {
            frames_ok: stats.frames_ok,
        });
    };
    let hello = messages
        .iter()
        .take(first_input)
        .rev()
        .find_map(|m| match m {
            Message::Hello(h) => Some(*h),
            _ => None,
        })
        .ok_or(ReplayError::NoHello)?;
    let own = PoseMode::of_hello(&hello);
    let mode = match pose {
        Some(PoseMode::Truth) => return Err(ReplayError::Truth),
        Some(mode) => mode,
        None => own,
    };
    let side = check_grid(scenario, &hello)?;
    let run = Run {
        scenario,
        messages: &messages,
        mode,
        robot_settings: mode == own,
        robot_width: usize::from(hello.width),
        robot_height: usize::from(hello.height),
        bad_frames: stats.bad_frames.total(),
    };
    if side == GRID_SIDES[0] {
        run.sized::<{ GRID_SIDES[0] }, { GRID_SIDES[0] }>()
    } else {
        run.sized::<{ GRID_SIDES[1] }, { GRID_SIDES[1] }>()
    }
}

/// The `Hello`'s grid must fit a built-in square and be the scenario's geometry; the
/// side of the smallest square that holds it. The robot's grid is its world's size
/// (`world::robot::grid_size`), which need not be square: the replay maps into the
/// built-in square from the same origin, limited to the robot's cells.
fn check_grid(scenario: &Scenario, h: &Hello) -> Result<usize, ReplayError> {
    let (w, hh) = (usize::from(h.width), usize::from(h.height));
    let Some(side) = GRID_SIDES
        .into_iter()
        .find(|&s| w >= 1 && hh >= 1 && w <= s && hh <= s)
    else {
        return Err(ReplayError::Grid(format!(
            "the stream's grid is {} x {}; the core is built here with {}",
            h.width,
            h.height,
            GRID_SIDES.map(|s| format!("{s} x {s}")).join(" or ")
        )));
    };
    let g = &scenario.grid;
    if (h.cell_mm, h.origin_x_mm, h.origin_y_mm) != (g.cell_mm, g.origin_x_mm, g.origin_y_mm) {
        return Err(ReplayError::Grid(format!(
            "the stream's grid ({} mm cells from ({}, {}) mm) is not the scenario's ({} mm cells from ({}, {}) mm): pass the scenario the robot was built for with --scenario",
            h.cell_mm, h.origin_x_mm, h.origin_y_mm, g.cell_mm, g.origin_x_mm, g.origin_y_mm
        )));
    }
    Ok(side)
}

/// One replay's fixed inputs.
struct Run<'a> {
    scenario: &'a Scenario,
    messages: &'a [Message],
    mode: PoseMode,
    robot_settings: bool,
    /// Columns of the robot's grid, which its map chunks run along, and its rows: the
    /// replay maps only those cells, as the robot does.
    robot_width: usize,
    robot_height: usize,
    bad_frames: u32,
}

impl Run<'_> {
    fn sized<const W: usize, const H: usize>(&self) -> Result<Replay, ReplayError> {
        let mut config = slam_config(self.scenario);
        self.mode.configure(&mut config);
        let s = &self.scenario.start;
        let start = to_core_pose(&TruePose {
            x_mm: s.x_mm,
            y_mm: s.y_mm,
            heading_deg: s.heading_deg,
        });
        let mut slam: Box<Slam<W, H>> =
            Box::new(Slam::new(config, start).map_err(|e| ReplayError::Config(format!("{e:?}")))?);
        slam.limit_map(self.robot_width, self.robot_height);
        let mut writer = TelemetryWriter::new(self.mode);
        let mut check = self.robot_settings.then(BitForBit::default);
        let mut summary = ReplaySummary {
            pose: self.mode.name().to_string(),
            robot_settings: self.robot_settings,
            steps: 0,
            skipped_out_of_order: 0,
            missing_inputs: 0,
            bad_frames: self.bad_frames,
            bit_for_bit: None,
        };
        // The robot's number of the last tick stepped, and what the replay made of it.
        let mut last: Option<(u32, Tick, Option<FilterState>)> = None;
        // The drive at a wall under way and the wall the gyro is held to, as the robot
        // keeps them beside its core.
        let mut walls = WallRate::default();
        let mut turn = WallTurn::default();
        // The run's first turn on the spot, kept until it closes, unless the recording
        // starts after the run's first tick (a robot resumed after a reset).
        let mut first_turn: Option<Box<FirstTurn>> = None;
        // The robot's number of the last `Tick` it sent: map chunks after it belong to it.
        let mut robot_tick: Option<u32> = None;
        for message in self.messages {
            match message {
                Message::Inputs(i) => {
                    let expected = last.as_ref().map_or(1, |(t, ..)| t.wrapping_add(1));
                    if last.as_ref().is_some_and(|(t, ..)| i.tick <= *t) {
                        summary.skipped_out_of_order += 1;
                        continue;
                    }
                    if i.tick != expected {
                        let missing = i.tick.saturating_sub(expected);
                        summary.missing_inputs = summary.missing_inputs.saturating_add(missing);
                        if let Some(c) = check.as_mut() {
                            c.differ(
                                expected,
                                "inputs",
                                "not in the stream",
                                format!("{missing} ticks' inputs missing"),
                            );
                        }
                    }
                    let first = first_turn.get_or_insert_with(|| {
                        let mut first = Box::new(FirstTurn::new());
                        if i.tick != 1 {
                            first.resume();
                        }
                        first
                    });
                    last =
                        Some(self.step(&mut slam, (&mut walls, &mut turn, first), &mut writer, i));
                    summary.steps += 1;
                }
                Message::Tick(t) => {
                    robot_tick = Some(t.tick);
                    if let Some(c) = check.as_mut() {
                        match &last {
                            Some((n, replayed, _)) if *n == t.tick => {
                                c.ticks += 1;
                                compare_tick(c, t, replayed);
                            }
                            _ => c.differ(
                                t.tick,
                                "inputs",
                                "a Tick without its inputs",
                                "not stepped",
                            ),
                        }
                    }
                }
                Message::Filter(f) => {
                    if let (Some(c), Some((n, _, replayed))) = (check.as_mut(), &last) {
                        if *n == f.tick {
                            c.filters += 1;
                            match replayed {
                                Some(r) => compare_filter(c, f, r),
                                None => c.differ(f.tick, "Filter", "sent", "no estimate"),
                            }
                        }
                    }
                }
                Message::MapRows(r) => {
                    let stepped = last.as_ref().map(|(n, ..)| *n);
                    if let Some(c) = check.as_mut() {
                        if stepped.is_some() && stepped == robot_tick {
                            c.map_chunks += 1;
                            compare_chunk(c, stepped.unwrap_or(0), r, slam.map(), self.robot_width);
                        }
                    }
                }
                Message::Hello(_) | Message::Health(_) => {}
            }
        }
        writer.finish(slam.map());
        summary.bit_for_bit = check;
        Ok(Replay {
            summary,
            stream: writer.bytes().to_vec(),
        })
    }

    /// Steps one input frame and writes its telemetry; returns the robot's tick number
    /// with the replayed `Tick` and `Filter`.
    fn step<const W: usize, const H: usize>(
        &self,
        slam: &mut Slam<W, H>,
        (walls, turn, first_turn): (&mut WallRate, &mut WallTurn, &mut FirstTurn),
        writer: &mut TelemetryWriter,
        i: &Inputs,
    ) -> (u32, Tick, Option<FilterState>) {
        let report = slam.step(&i.frame);
        let report = slam.measure_walls(walls, turn, &i.frame, report);
        let report = slam.close_first_turn(first_turn, &i.frame, report);
        writer.tick(
            i.time_ms,
            &i.frame,
            &report,
            slam.tag_counters(),
            slam.map(),
        );
        (
            i.tick,
            Tick::new(i.time_ms, &report),
            FilterState::new(&report, slam.tag_counters()),
        )
    }
}

/// Every field of the robot's `Tick` but its time against the replay's.
fn compare_tick(c: &mut BitForBit, robot: &Tick, replay: &Tick) {
    let (a, b) = (&robot.counters, &replay.counters);
    let fields: [(&str, i64, i64); 19] = [
        ("x_um", robot.x_um.into(), replay.x_um.into()),
        ("y_um", robot.y_um.into(), replay.y_um.into()),
        (
            "heading_bits",
            robot.heading_bits.into(),
            replay.heading_bits.into(),
        ),
        ("stale", robot.stale.into(), replay.stale.into()),
        (
            "cells_written",
            robot.cells_written.into(),
            replay.cells_written.into(),
        ),
        ("counters.ticks", a.ticks.into(), b.ticks.into()),
        (
            "counters.fixes_taken",
            a.fixes_taken.into(),
            b.fixes_taken.into(),
        ),
        (
            "counters.fixes_rejected_geometry",
            a.fixes_rejected_geometry.into(),
            b.fixes_rejected_geometry.into(),
        ),
        (
            "counters.fixes_rejected_gate",
            a.fixes_rejected_gate.into(),
            b.fixes_rejected_gate.into(),
        ),
        (
            "counters.fixes_rejected_too_old",
            a.fixes_rejected_too_old.into(),
            b.fixes_rejected_too_old.into(),
        ),
        (
            "counters.relocalisations",
            a.relocalisations.into(),
            b.relocalisations.into(),
        ),
        (
            "counters.pictures_repeated",
            a.pictures_repeated.into(),
            b.pictures_repeated.into(),
        ),
        (
            "counters.pictures_leapt",
            a.pictures_leapt.into(),
            b.pictures_leapt.into(),
        ),
        (
            "counters.pictures_late",
            a.pictures_late.into(),
            b.pictures_late.into(),
        ),
        (
            "counters.beams_mapped",
            a.beams_mapped.into(),
            b.beams_mapped.into(),
        ),
        (
            "counters.beams_invalid",
            a.beams_invalid.into(),
            b.beams_invalid.into(),
        ),
        (
            "counters.flow_stale",
            a.flow_stale.into(),
            b.flow_stale.into(),
        ),
        (
            "counters.gyro_stale",
            a.gyro_stale.into(),
            b.gyro_stale.into(),
        ),
        (
            "counters.depth_stale",
            a.depth_stale.into(),
            b.depth_stale.into(),
        ),
    ];
    if robot.fix != replay.fix {
        c.differ(
            robot.tick,
            "fix",
            format!("{:?}", robot.fix),
            format!("{:?}", replay.fix),
        );
    }
    for (name, x, y) in fields {
        if x != y {
            c.differ(robot.tick, name, x, y);
        }
    }
}

/// Every field of the robot's `Filter` against the replay's.
fn compare_filter(c: &mut BitForBit, robot: &FilterState, replay: &FilterState) {
    let (p, q) = (&robot.covariance, &replay.covariance);
    let (k, l) = (&robot.calibration, &replay.calibration);
    let (s, t) = (&robot.tags, &replay.tags);
    let fields: [(&str, i64, i64); 15] = [
        ("covariance.xx", p.xx, q.xx),
        ("covariance.xy", p.xy, q.xy),
        ("covariance.yy", p.yy, q.yy),
        ("covariance.xh", p.xh, q.xh),
        ("covariance.yh", p.yh, q.yh),
        ("covariance.hh", p.hh, q.hh),
        (
            "calibration.gyro_scale_ppm",
            k.gyro_scale_ppm.into(),
            l.gyro_scale_ppm.into(),
        ),
        (
            "calibration.gyro_bias_mdps",
            k.gyro_bias_mdps.into(),
            l.gyro_bias_mdps.into(),
        ),
        (
            "calibration.flow_scale_ppm",
            k.flow_scale_ppm.into(),
            l.flow_scale_ppm.into(),
        ),
        ("tags.used", s.used.into(), t.used.into()),
        ("tags.unknown_id", s.unknown_id.into(), t.unknown_id.into()),
        ("tags.behind", s.behind.into(), t.behind.into()),
        ("tags.too_far", s.too_far.into(), t.too_far.into()),
        ("tags.too_old", s.too_old.into(), t.too_old.into()),
        ("tags.gate", s.gate.into(), t.gate.into()),
    ];
    for (name, x, y) in fields {
        if x != y {
            c.differ(robot.tick, &format!("Filter {name}"), x, y);
        }
    }
}

/// The robot's chunk against the replayed map's cells at the same tick, encoded as the
/// robot encodes them. The chunk runs along the robot's rows, `width` cells long, which
/// the replay's grid holds from the same origin.
fn compare_chunk<const W: usize, const H: usize>(
    c: &mut BitForBit,
    tick: u32,
    chunk: &MapRows,
    map: &GridMap<W, H>,
    width: usize,
) {
    let scale = CellScale::new(map.evidence());
    let rows = map.rows();
    let width = width.max(1);
    let start = usize::from(chunk.first_row) * width + usize::from(chunk.first_column);
    for (k, &sent) in chunk.cells.iter().enumerate() {
        let i = start + k;
        let (column, row) = (i % width, i / width);
        let mine = rows
            .get(row)
            .and_then(|r| r.get(column))
            .map(|&l| scale.encode(l, map.occupancy(column as i32, row as i32)));
        if mine != Some(sent) {
            let replay = mine.map_or("off the grid".to_string(), |m| m.to_string());
            c.differ(
                tick,
                &format!("map cell (column {column}, row {row})"),
                sent,
                replay,
            );
            return;
        }
    }
}
