//! One run of a scenario: the robot drives its route and the core maps, tick by tick.

use crate::consistency::{estimator_figures, EstimatorFigures};
use crate::fault::{Fault, Injector};
use crate::floor::floor_mask;
use crate::match_truth::{MatchTruth, MatchTruthFigures};
use crate::matching::MatchingFigures;
use crate::record::{
    Belief, CellBelief, MapSnapshot, RunRecord, TickRecord, TrueCalibration, WorldOutline,
};
use crate::robot::{Command, Robot, TruePose};
use crate::route::Route;
use crate::scenario::Scenario;
use crate::score::{map_counts, out_of_place_mask, pose_errors, real_mask, MapCounts, PoseErrors};
use crate::telemetry::TelemetryWriter;
use serde::Serialize;
use slam_core::depth_step::{DepthSteps, ZoneTurn};
use slam_core::slam::first_turn::{FirstTurn, GiveUp, Outcome};
use slam_core::{
    Angle, Decision, DriveCommand, FixOutcome, GridMap, GuardConfig, Localiser, MatchingConfig,
    Occupancy, PlausibleConfig, Pose, SensorFrame, Slam, SlamConfig, TagMap,
};
use std::fmt;
use std::str::FromStr;
use wire::telemetry::Hello;

/// The SLAM tick, seconds.
pub const TICK_S: f64 = 0.1;
/// The flow quality below which the firmware drops a reading.
pub const MIN_FLOW_QUALITY: u8 = 30;
/// The longest run, seconds: a route planned longer is refused before it starts
/// ([`RunError::RouteTooLong`]), and one that runs past it anyway is cut there and says
/// so ([`Figures::route_cut_at_s`]).
pub const MAX_RUN_S: f64 = 3600.0;

/// The grid sizes the core is built with here, smallest first (columns = rows).
pub const GRID_SIDES: [usize; 2] = [46, 206];

/// Which pose the mapper uses: the only thing that differs between the seed's demos.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PoseMode {
    /// The simulator's truth, as a lab's overhead camera would give it.
    Truth,
    /// Odometry alone.
    DeadReckoning,
    /// Odometry corrected by two-tag fixes.
    Tags,
    /// The filter on odometry and every tag sighting, no matching: what the firmware
    /// flies, so what its streams replay with and the emulator is compared against.
    Filter,
    /// The filter with scan-to-map matching and no tags: odometry and the map alone.
    Match,
    /// The filter on odometry, every tag sighting and scan-to-map matching together.
    Slam,
}

impl PoseMode {
    /// Every mode, in the order `--help` lists them.
    pub const ALL: [PoseMode; 6] = [
        PoseMode::Truth,
        PoseMode::DeadReckoning,
        PoseMode::Tags,
        PoseMode::Filter,
        PoseMode::Match,
        PoseMode::Slam,
    ];

    /// The name used on the command line and in records.
    pub fn name(self) -> &'static str {
        match self {
            PoseMode::Truth => "truth",
            PoseMode::DeadReckoning => "dead-reckoning",
            PoseMode::Tags => "tags",
            PoseMode::Filter => "filter",
            PoseMode::Match => "match",
            PoseMode::Slam => "slam",
        }
    }

    /// What corrects the core's pose in this mode (truth replaces it from outside).
    pub fn localiser(self) -> Localiser {
        match self {
            PoseMode::Truth | PoseMode::DeadReckoning => Localiser::DeadReckoning,
            PoseMode::Tags => Localiser::TwoTagFix,
            PoseMode::Filter | PoseMode::Match | PoseMode::Slam => Localiser::Filter,
        }
    }

    /// Whether the filter matches scans against the map in this mode.
    pub fn matches(self) -> bool {
        matches!(self, PoseMode::Match | PoseMode::Slam)
    }

    /// The mode a stream's `Hello` names by its localiser and whether it matches: the
    /// filter with matching is `slam` (a robot keeps the world's tags).
    pub fn of_hello(hello: &Hello) -> PoseMode {
        match (hello.localiser, hello.matching) {
            (Localiser::DeadReckoning, _) => PoseMode::DeadReckoning,
            (Localiser::TwoTagFix, _) => PoseMode::Tags,
            (Localiser::Filter, false) => PoseMode::Filter,
            (Localiser::Filter, true) => PoseMode::Slam,
        }
    }

    /// Sets `config` (a scenario's, from [`slam_config`]) up for this mode: its
    /// localiser, matching for `match` and `slam`, and no tags for `match`.
    pub fn configure(self, config: &mut SlamConfig) {
        config.localiser = self.localiser();
        config.matching = self.matches().then_some(MatchingConfig::SEED);
        if self == PoseMode::Match {
            config.tags = TagMap::default();
        }
    }
}

impl FromStr for PoseMode {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        PoseMode::ALL
            .into_iter()
            .find(|m| m.name() == s)
            .ok_or_else(|| {
                format!(
                    "unknown pose mode `{s}`: expected truth, dead-reckoning, tags, filter, match or slam"
                )
            })
    }
}

/// What the core is told about how old the camera's pictures are.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum TagAge {
    /// Their true age (the scenario's `sensors.camera.latency_ms`), as the firmware
    /// measures it: the core places each fix at the moment of the picture.
    #[default]
    Reported,
    /// Always 0, whatever the latency: the core takes each fix as the pose at the tick,
    /// as it did before frames carried an age. For measuring what the compensation buys.
    Hidden,
}

/// Whether the core is told what the motors were driven with.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Commands {
    /// Every tick, as the firmware tells it: the gyro is checked against it.
    #[default]
    Reported,
    /// Never, as before frames carried it: for measuring what the check buys.
    Hidden,
}

/// Whether the route consults the guard ([`slam_core::guard`]) before each tick's drive.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Guarding {
    /// Every tick, as the firmware does: a drive the guard stops is skipped.
    #[default]
    On,
    /// Never: the route drives blind (into walls, where the robot stops at contact). For
    /// showing that a scenario's route does meet walls.
    Off,
}

/// Added to the guard's reach for the depth sensor's range noise, millimetres: the
/// firmware's, 5 sigma of the shipped scenarios' 5 mm noise.
pub const GUARD_MARGIN_MM: u16 = GuardConfig::SEED.margin_mm;

/// The figures the seed quotes, and a few more.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Figures {
    /// Ticks run.
    pub ticks: usize,
    /// Simulated seconds.
    pub duration_s: f64,
    /// Share of the world's floor (see [`crate::floor`]) the map has an opinion about,
    /// percent.
    pub known_pct: f64,
    /// Share of the whole grid the map has an opinion about, percent: the seed page's
    /// "known %", which counts the margin round the mat too.
    pub known_grid_pct: f64,
    /// Cells believed free.
    pub free: u32,
    /// Cells believed occupied.
    pub occupied: u32,
    /// Occupied cells on no real wall or tag.
    pub out_of_place: u32,
    /// Tag fixes taken.
    pub fixes: u32,
    /// Tag fixes rejected (geometry, gate, or a picture too old to place).
    pub fixes_rejected: u32,
    /// Time of the first fix, seconds; `None` if there was none.
    pub first_fix_s: Option<f64>,
    /// The pose's errors against the truth, scored as `host-sim view` scores a
    /// robot's run (flattened: each under its own name).
    #[serde(flatten)]
    pub errors: PoseErrors,
    /// Times the robot's body ran into a wall or a box and stopped there, one per contact
    /// (however many ticks it pushed on).
    pub collisions: u32,
    /// Drives the guard stopped before an obstacle (each skipped its route step).
    pub guard_stops: u32,
    /// Ticks the guard held the route because an input its motion needs was doubted
    /// ([`slam_core::plausible`]); absent when none.
    #[serde(skip_serializing_if = "is_zero")]
    pub held_ticks: u32,
    /// When the run reached [`MAX_RUN_S`] before its route ended, the time it was cut
    /// at, seconds; absent (not even `null`) when the route ran to its end.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub route_cut_at_s: Option<f64>,
    /// The filter's bounds against the truth, its calibration and its tags; absent (not
    /// even `null`) when the run has no filter (every mode but `slam`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub estimator: Option<EstimatorFigures>,
    /// What came of the run's first turn on the spot ([`Slam::close_first_turn`]);
    /// absent when the core does not match (every mode but `slam`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub first_turn: Option<FirstTurnFigures>,
    /// Scan matches used and refused by cause, and the drives at a wall that measured the
    /// flow's scale; absent when the core does not match (every mode but `match` and
    /// `slam`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub matching: Option<MatchingFigures>,
    /// The matches against the truth ([`crate::match_truth`]); absent when the core does
    /// not match.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub match_truth: Option<MatchTruthFigures>,
}

/// What came of the run's first turn on the spot: closed (the map drawn again at the
/// closure's headings), closed but known (the filter already surer of the heading: nothing
/// changed), refused by the closure, given up before it, or still kept when the route
/// ended without a drive.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FirstTurnFigures {
    /// `closed`, `known`, `refused`, `given up` or `kept`.
    pub outcome: &'static str,
    /// Why it was refused or given up; absent when closed or kept.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub why: Option<String>,
    /// The closure's excess, degrees: how far the gyro's integral ran past the true turn;
    /// absent unless closed or known.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub excess_deg: Option<f64>,
    /// The excess's standard deviation, degrees.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sd_deg: Option<f64>,
}

impl FirstTurnFigures {
    /// The figures of `turn` at the run's end; `None` when the core does not match.
    fn of(turn: &FirstTurn) -> Option<FirstTurnFigures> {
        let figures = |outcome, why: Option<String>| FirstTurnFigures {
            outcome,
            why,
            excess_deg: None,
            sd_deg: None,
        };
        Some(match turn.outcome() {
            None => figures("kept", None),
            Some(o @ (Outcome::Closed(c) | Outcome::Known(c))) => FirstTurnFigures {
                excess_deg: Some(f64::from(c.excess_mdeg) / 1000.0),
                sd_deg: Some(f64::from(c.sd_mdeg) / 1000.0),
                ..figures(
                    match o {
                        Outcome::Closed(_) => "closed",
                        _ => "known",
                    },
                    None,
                )
            },
            Some(Outcome::Refused(why)) => figures("refused", Some(format!("{why:?}"))),
            Some(Outcome::GivenUp(GiveUp::NotMatching)) => return None,
            Some(Outcome::GivenUp(why)) => figures("given up", Some(format!("{why:?}"))),
        })
    }
}

/// Why a run could not start.
#[derive(Debug, PartialEq)]
pub enum RunError {
    /// The scenario's world does not fit any grid size the core is built with.
    GridTooLarge {
        /// Cells needed across, from the grid's origin.
        columns: i64,
        /// Cells needed up, from the grid's origin.
        rows: i64,
        /// The field of the point furthest out, e.g. `world.walls[1][1]`.
        furthest: String,
    },
    /// The route would run longer than [`MAX_RUN_S`].
    RouteTooLong {
        /// How long the route takes by its own numbers, seconds.
        planned_s: f64,
    },
    /// The core refused the configuration.
    Config(slam_core::ConfigError),
}

impl fmt::Display for RunError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RunError::GridTooLarge {
                columns,
                rows,
                furthest,
            } => {
                let largest = GRID_SIDES[GRID_SIDES.len() - 1];
                write!(
                    f,
                    "the world needs a {columns} x {rows} grid from grid.origin_x_mm, \
                     grid.origin_y_mm (reaching {furthest}); the largest built in is \
                     {largest} x {largest}: raise grid.cell_mm or shrink the world"
                )
            }
            RunError::RouteTooLong { planned_s } => write!(
                f,
                "scenario field `route`: takes about {planned_s:.1} s, longer than a run may \
                 last ({MAX_RUN_S} s)"
            ),
            RunError::Config(e) => {
                let field = match e {
                    slam_core::ConfigError::CellSize => " (grid.cell_mm)",
                    slam_core::ConfigError::FocalLength => " (sensors.camera.focal_px)",
                    slam_core::ConfigError::MaxRange => " (grid.max_range_mm)",
                    slam_core::ConfigError::Evidence => "",
                    slam_core::ConfigError::Matching => " (grid.cell_mm: the matcher's window)",
                };
                write!(f, "the core refused the configuration: {e:?}{field}")
            }
        }
    }
}

impl std::error::Error for RunError {}

/// The core's configuration for a scenario: what the robot's firmware is built with (the
/// `world` crate's, shared with the firmware's build).
pub use ::world::robot::slam_config;

/// The guard's configuration for a scenario: its body and depth fan, a scan at most a
/// tick old acted on for one tick, and [`GUARD_MARGIN_MM`].
pub fn guard_config(s: &Scenario) -> GuardConfig {
    let tick_us = (TICK_S * 1e6).round() as u32;
    GuardConfig {
        radius_mm: s.robot.radius_mm.ceil().clamp(0.0, f64::from(u16::MAX)) as u16,
        margin_mm: GUARD_MARGIN_MM,
        latency_us: tick_us,
        tick_us,
        beam_angles: slam_core::slam::fan((s.sensors.tof.fov_deg * 1000.0).round() as i64),
    }
}

/// A route's command in the guard's integer units.
fn drive_command(c: &Command) -> DriveCommand {
    DriveCommand {
        speed_mm_s: c.speed_mm_s.round() as i32,
        turn_mdps: (c.turn_dps * 1000.0).round() as i32,
    }
}

/// A true pose in the core's integer units.
pub fn to_core_pose(t: &TruePose) -> Pose {
    ::world::robot::core_pose(t.x_mm, t.y_mm, t.heading_deg)
}

/// What a run produced.
pub struct RunOutput {
    /// Per-tick rows, the final map and the world.
    pub record: RunRecord,
    /// The summary figures.
    pub figures: Figures,
    /// Every frame handed to `step`, in order: replayed by the benchmark.
    pub frames: Vec<SensorFrame>,
}

/// Runs a scenario to the end of its route. The scenario is taken as checked (as
/// [`Scenario::load`] and [`Scenario::parse`] give it); the grid and the route's length
/// are checked here, before the first tick.
pub fn run(scenario: &Scenario, mode: PoseMode, seed: u64) -> Result<RunOutput, RunError> {
    run_with_telemetry(scenario, mode, seed, None)
}

/// [`run`], also writing the telemetry stream the robot would send into `telemetry`.
pub fn run_with_telemetry(
    scenario: &Scenario,
    mode: PoseMode,
    seed: u64,
    telemetry: Option<&mut TelemetryWriter>,
) -> Result<RunOutput, RunError> {
    let options = RunOptions {
        telemetry,
        ..RunOptions::default()
    };
    run_with(scenario, mode, seed, options)
}

/// [`run`], telling the core the pictures' age as `tag_age` says.
pub fn run_with_tag_age(
    scenario: &Scenario,
    mode: PoseMode,
    seed: u64,
    tag_age: TagAge,
) -> Result<RunOutput, RunError> {
    let options = RunOptions {
        tag_age,
        ..RunOptions::default()
    };
    run_with(scenario, mode, seed, options)
}

/// What a run may add to its scenario.
#[derive(Default)]
pub struct RunOptions<'a> {
    /// How the core is told the pictures' age.
    pub tag_age: TagAge,
    /// Whether the route consults the guard.
    pub guarding: Guarding,
    /// Where to write the telemetry stream the robot would send.
    pub telemetry: Option<&'a mut TelemetryWriter>,
    /// Sensor faults to inject into what the core reads.
    pub faults: &'a [Fault],
    /// Whether the core is told the motors' commands.
    pub commands: Commands,
}

/// [`run`] with `options`.
pub fn run_with(
    scenario: &Scenario,
    mode: PoseMode,
    seed: u64,
    options: RunOptions<'_>,
) -> Result<RunOutput, RunError> {
    run_sized_to_fit(scenario, mode, seed, options)
}

/// Runs on the smallest built-in grid that holds the scenario's world.
fn run_sized_to_fit(
    scenario: &Scenario,
    mode: PoseMode,
    seed: u64,
    options: RunOptions<'_>,
) -> Result<RunOutput, RunError> {
    let planned_s = crate::route::planned_ticks(&scenario.route, TICK_S) as f64 * TICK_S;
    if planned_s > MAX_RUN_S {
        return Err(RunError::RouteTooLong { planned_s });
    }
    let cell = scenario.grid.cell_mm.max(1) as f64;
    // The grid must reach a cell past the furthest wall, tag or start (validation put
    // them all on the grid's side of its origin).
    let cells_to = |v: f64, origin: i32| ((v - f64::from(origin)) / cell).ceil() as i64 + 1;
    let (mut columns, mut rows, mut furthest) = (1, 1, String::new());
    for (field, p) in scenario.placed_points() {
        let (c, r) = (
            cells_to(p.x, scenario.grid.origin_x_mm),
            cells_to(p.y, scenario.grid.origin_y_mm),
        );
        if c.max(r) > columns.max(rows) {
            furthest = field;
        }
        (columns, rows) = (columns.max(c), rows.max(r));
    }
    let fits = |side: usize| columns <= side as i64 && rows <= side as i64;
    if fits(GRID_SIDES[0]) {
        run_sized::<{ GRID_SIDES[0] }, { GRID_SIDES[0] }>(scenario, mode, seed, options)
    } else if fits(GRID_SIDES[1]) {
        run_sized::<{ GRID_SIDES[1] }, { GRID_SIDES[1] }>(scenario, mode, seed, options)
    } else {
        Err(RunError::GridTooLarge {
            columns,
            rows,
            furthest,
        })
    }
}

/// The depth frames held to each other where they arrive ([`slam_core::depth_step`]), as
/// the firmware's depth task holds them: each tick's scan, at its own moment, against the
/// gyro's integral of the frames' rates.
struct DepthFrames {
    steps: DepthSteps,
    fan: ZoneTurn,
    limits: Option<PlausibleConfig>,
    clock_us: u32,
    /// The gyro's integral, millidegrees times 10^6 (rate in mdps times microseconds).
    yaw: i64,
}

impl DepthFrames {
    fn new(config: &SlamConfig) -> DepthFrames {
        DepthFrames {
            steps: DepthSteps::default(),
            fan: ZoneTurn::new(&config.depth.beam_angles),
            limits: config.plausible,
            clock_us: 0,
            yaw: 0,
        }
    }

    /// Sets `frame`'s depth doubt; a core without plausibility checks gets none.
    fn judge(&mut self, frame: &mut SensorFrame) {
        self.clock_us = self.clock_us.wrapping_add(frame.dt_us);
        let rate = frame.gyro.map_or(0, |g| g.rate_mdps);
        self.yaw = self
            .yaw
            .saturating_add(i64::from(rate) * i64::from(frame.dt_us));
        let (Some(limits), Some(scan)) = (&self.limits, &frame.depth) else {
            return;
        };
        let moment = self.clock_us.wrapping_sub(frame.depth_age_us);
        // The integral at the frame's own moment, the tick's rate taken back over its age.
        let yaw = self
            .yaw
            .saturating_sub(i64::from(rate) * i64::from(frame.depth_age_us));
        let heading = Angle::from_millidegrees(yaw / 1_000_000);
        frame.depth_doubt = self
            .steps
            .judge(scan, moment, heading, &self.fan, limits)
            .err();
    }

    fn forget_steps(&mut self) {
        self.steps.forget_steps();
    }
}

fn run_sized<const W: usize, const H: usize>(
    scenario: &Scenario,
    mode: PoseMode,
    seed: u64,
    options: RunOptions<'_>,
) -> Result<RunOutput, RunError> {
    let RunOptions {
        tag_age,
        guarding,
        mut telemetry,
        faults,
        commands,
    } = options;
    let mut injector = Injector::new(faults, seed);
    let guard = guard_config(scenario);
    let mut guard_stops = 0;
    let mut held_ticks = 0;
    let mut config = slam_config(scenario);
    mode.configure(&mut config);
    let mut robot = Robot::new(scenario, seed);
    let start = to_core_pose(&robot.truth());
    let mut slam: Box<Slam<W, H>> = Box::new(Slam::new(config, start).map_err(RunError::Config)?);
    // The robot's grid is the world's own size: map only that much of the built-in square.
    let (columns, rows) = world::robot::grid_size(scenario);
    slam.limit_map(columns, rows);
    let real = real_mask(robot.world(), &config.geometry, W, H);
    let floor = floor_mask(robot.world(), &config.geometry, W, H);
    let floor_cells = FloorCells::new(&floor, W);

    let mut route = Route::new(&scenario.route);
    route.start(robot.truth());
    let mut ticks = Vec::new();
    let mut frames = Vec::new();
    let mut out_of_place_pct = 0.0;
    let mut first_fix: Option<usize> = None;
    let mut route_cut_at_s = None;
    let dt_us = (TICK_S * 1e6) as u32;
    let tags_age_us = match tag_age {
        TagAge::Reported => u32::try_from(robot.camera_latency_us()).unwrap_or(u32::MAX),
        TagAge::Hidden => 0,
    };
    // What the motors were driven with since the last frame: before the first, nothing.
    let mut driven = Command::default();
    // The depth frames held to each other where they arrive, as the firmware's depth task
    // does, over the gyro's own integral.
    let mut depth_steps = DepthFrames::new(&config);
    // The drive at a wall under way and the wall the gyro is held to
    // ([`Slam::measure_walls`]).
    let mut walls = slam_core::wall_rate::WallRate::default();
    let mut turn = slam_core::wall_turn::WallTurn::default();
    // The first turn on the spot, kept until it closes ([`Slam::close_first_turn`]).
    let mut first_turn = Box::new(FirstTurn::new());
    // Each tick's truth by the core's tick count, for the matches placed at their ticks.
    let mut truths: Vec<(u32, TruePose)> = Vec::new();
    let mut match_truth = MatchTruth::default();
    while let Some(command) = route.command() {
        if robot.time_s() > MAX_RUN_S {
            route_cut_at_s = Some(robot.time_s());
            break;
        }
        let truth = robot.truth();
        let (flow, gyro) = robot.take_odometry(MIN_FLOW_QUALITY);
        let (scan, depth_age_us) = robot.read_depth_frame();
        let mut frame = SensorFrame {
            // The first frame is the run's start: no time has passed since a frame before
            // it, and the gyro has not yet read (the firmware's first frame comes a tick
            // after its tasks start, with a reading).
            dt_us: if ticks.is_empty() { 0 } else { dt_us },
            flow,
            gyro,
            // The sensor's newest frame, ranged on its own clock.
            depth: Some(scan),
            depth_age_us,
            depth_doubt: None,
            tags: robot.read_tags(),
            tags_age_us,
            external_pose: (mode == PoseMode::Truth).then(|| to_core_pose(&truth)),
            commanded: (commands == Commands::Reported).then(|| drive_command(&driven)),
        };
        injector.apply(robot.time_s(), &mut frame);
        depth_steps.judge(&mut frame);
        let report = slam.step(&frame);
        let report = slam.measure_walls(&mut walls, &mut turn, &frame, report);
        let report = slam.close_first_turn(&mut first_turn, &frame, report);
        truths.push((report.counters.ticks, truth));
        if let Some(m) = slam.last_match() {
            // The newest tick with its count: the match is this tick's or a recent one's.
            if let Some((_, t)) = truths.iter().rev().find(|&&(tick, _)| tick == m.tick) {
                match_truth.add(m, t);
            }
        }
        if slam.depth_steps_void() {
            depth_steps.forget_steps();
        }
        // The guard reads what the mapper believes, never the truth.
        let mut command = command;
        if guarding == Guarding::On {
            let decision = slam_core::decide(
                &guard,
                &report.pose,
                slam.map(),
                frame.sight(),
                &report.trust,
                drive_command(&command),
            );
            match decision {
                Decision::Go => {}
                Decision::Stop(_) => {
                    guard_stops += 1;
                    route.skip();
                    command = Command::default();
                }
                Decision::Hold(_) => {
                    held_ticks += 1;
                    route.hold();
                    command = Command::default();
                }
            }
        }
        if let Some(t) = telemetry.as_mut() {
            let time_ms = (ticks.len() as f64 * TICK_S * 1000.0).round() as u32;
            t.tick(time_ms, &frame, &report, slam.tag_counters(), slam.map());
        }
        frames.push(frame);
        let fix_taken = report.fix == FixOutcome::Taken;
        if fix_taken && first_fix.is_none() {
            first_fix = Some(ticks.len());
        }
        let est = report.pose;
        if ticks.len().is_multiple_of(10) {
            out_of_place_pct = count_map(slam.map(), &real).out_of_place_pct();
        }
        let mut tick = TickRecord::estimated(
            ticks.len() as f64 * TICK_S,
            (est.x_um as f64 / 1000.0, est.y_um as f64 / 1000.0),
            est.heading.to_microdegrees() as f64 / 1e6,
            floor_cells.known_pct(slam.map()),
            fix_taken,
        );
        tick.set_truth((truth.x_mm, truth.y_mm), truth.heading_deg);
        tick.belief = report
            .estimate
            .map(|e| Belief::new(&e, slam.tag_counters()));
        tick.true_gyro_bias_mdps =
            (scenario.sensors.gyro.bias_dps + robot.gyro_bias_walk_dps()) * 1000.0;
        tick.out_of_place_pct = out_of_place_pct;
        ticks.push(tick);
        robot.advance(TICK_S, command);
        driven = command;
        route.after_tick(robot.truth(), TICK_S);
    }

    if let Some(t) = telemetry {
        t.finish(slam.map());
    }
    let final_counts = map_counts(beliefs(slam.map()), &real, &floor);
    if let Some(last) = ticks.last_mut() {
        last.out_of_place_pct = final_counts.out_of_place_pct();
    }
    let counters = slam.counters();
    let errors = pose_errors(&ticks);
    let true_calibration = TrueCalibration::of(scenario);
    let figures = Figures {
        ticks: ticks.len(),
        duration_s: ticks.len() as f64 * TICK_S,
        known_pct: final_counts.known_pct(),
        known_grid_pct: final_counts.known_grid_pct(),
        free: final_counts.free,
        occupied: final_counts.occupied,
        out_of_place: final_counts.out_of_place,
        fixes: counters.fixes_taken,
        fixes_rejected: counters.fixes_rejected_gate
            + counters.fixes_rejected_geometry
            + counters.fixes_rejected_too_old,
        first_fix_s: first_fix.map(|i| i as f64 * TICK_S),
        errors,
        collisions: robot.collisions(),
        guard_stops,
        held_ticks,
        route_cut_at_s,
        estimator: estimator_figures(&ticks, Some(true_calibration)),
        first_turn: FirstTurnFigures::of(&first_turn),
        matching: mode
            .matches()
            .then(|| MatchingFigures::of(slam.match_counters(), &walls.counters)),
        match_truth: mode.matches().then(|| match_truth.figures()),
    };
    let record = RunRecord {
        scenario: scenario.name.clone(),
        pose_mode: mode.name().to_string(),
        true_calibration: Some(true_calibration),
        ticks,
        map: snapshot(slam.map(), &real),
        world: WorldOutline::of(robot.world()),
    };
    Ok(RunOutput {
        record,
        figures,
        frames,
    })
}

fn is_zero(n: &u32) -> bool {
    *n == 0
}

/// The beliefs of `map`, row-major from the lowest row.
fn beliefs<const W: usize, const H: usize>(
    map: &GridMap<W, H>,
) -> impl Iterator<Item = CellBelief> + '_ {
    (0..W * H).map(|i| map.occupancy((i % W) as i32, (i / W) as i32).into())
}

fn count_map<const W: usize, const H: usize>(map: &GridMap<W, H>, real: &[bool]) -> MapCounts {
    map_counts(beliefs(map), real, &[])
}

/// The floor's cells, for a known share every tick at the cost of the floor alone.
enum FloorCells {
    /// The whole grid: the map's own counts give it.
    Grid,
    /// Column and row of each floor cell.
    Cells(Vec<(i32, i32)>),
}

impl FloorCells {
    fn new(floor: &[bool], width: usize) -> FloorCells {
        if floor.iter().all(|&f| f) {
            return FloorCells::Grid;
        }
        let at = |i: usize| ((i % width) as i32, (i / width) as i32);
        FloorCells::Cells((0..floor.len()).filter(|&i| floor[i]).map(at).collect())
    }

    /// Share of the floor `map` holds a firm belief about, percent.
    fn known_pct<const W: usize, const H: usize>(&self, map: &GridMap<W, H>) -> f64 {
        match self {
            FloorCells::Grid => {
                let counts = map.counts();
                100.0 * (counts.free + counts.occupied) as f64 / (W * H) as f64
            }
            FloorCells::Cells(cells) => {
                let known = cells
                    .iter()
                    .filter(|&&(c, r)| map.occupancy(c, r) != Occupancy::Unknown)
                    .count();
                100.0 * known as f64 / cells.len().max(1) as f64
            }
        }
    }
}

fn snapshot<const W: usize, const H: usize>(map: &GridMap<W, H>, real: &[bool]) -> MapSnapshot {
    let g = map.geometry();
    let cells: Vec<CellBelief> = beliefs(map).collect();
    MapSnapshot {
        width: W,
        height: H,
        cell_mm: g.cell_mm as f64,
        origin_x_mm: g.origin_x_mm as f64,
        origin_y_mm: g.origin_y_mm as f64,
        out_of_place: out_of_place_mask(&cells, real),
        cells,
    }
}
