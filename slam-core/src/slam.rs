//! The SLAM loop: one pure `step` per tick, called alike by the firmware and the simulator.

use core::mem::MaybeUninit;
use core::ptr::addr_of_mut;

use crate::angle::Angle;
use crate::camera_check::{CameraCheck, Picture};
use crate::estimator::{
    Estimate, Estimator, EstimatorConfig, MapUncertainty, MatchCounters, MatchNoise, TagCounters,
    TagRefusal, TagShare,
};
use crate::frame::{DepthScan, FlowDelta, GyroRate, SensorFrame, TagDetection, BEAMS};
use crate::grid::{BeamWriter, Evidence, GridGeometry, GridMap};
use crate::history::{PoseHistory, HISTORY_LEN};
use crate::matcher::{Match, Matcher, MatcherConfig};
#[cfg(feature = "matching")]
use crate::matcher::{MatchRefusal, Sweep, SWEEP_TICKS};
use crate::odometry::{self, OdometryConfig};
use crate::plausible::{DepthReading, Judged, Known, Plausibility, PlausibleConfig, Trust};
use crate::pose::{mul_q16, Pose, RigidMotion};
use crate::tag_range::Witness;
#[cfg(feature = "tag-range")]
use crate::tag_range::{self, ZoneColumns};
use crate::tagfix::{self, CameraConfig, FixConfig, FixOutcome, FixRejection, KnownTag, TagMap};
#[cfg(feature = "matching")]
use crate::wall_rate::WallRate;
#[cfg(feature = "matching")]
use crate::{
    wall_rate::{fit_wall, WallFit},
    wall_turn::{self, WallTurn},
};

#[cfg(feature = "matching")]
pub mod first_turn;

/// The depth sensor's fan and the mapper's range limit.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DepthConfig {
    /// Direction of each beam relative to the nose, left to right.
    pub beam_angles: [Angle; BEAMS],
    /// Ranges at or beyond this, in millimetres, mark no hit (the seed's 170 cm).
    pub max_range_mm: u16,
}

impl DepthConfig {
    /// Eight beams at the centres of eight equal zones across a 45 degree fan, 170 cm limit.
    pub const SEED: DepthConfig = DepthConfig {
        beam_angles: fan(45_000),
        max_range_mm: 1700,
    };
}

/// Beam centres of `BEAMS` equal zones across a fan `width_mdeg` wide, centred on the nose.
pub const fn fan(width_mdeg: i64) -> [Angle; BEAMS] {
    let mut out = [Angle::ZERO; BEAMS];
    let mut i = 0;
    while i < BEAMS {
        // Centre of zone i: -w/2 + w * (2i + 1) / (2 * BEAMS).
        let mdeg = -width_mdeg / 2 + width_mdeg * (2 * i as i64 + 1) / (2 * BEAMS as i64);
        out[i] = Angle::from_millidegrees(mdeg);
        i += 1;
    }
    out
}

/// Everything the core needs to know about the robot and its world, fixed at start.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SlamConfig {
    /// Where the grid lies and how big its cells are.
    pub geometry: GridGeometry,
    /// Evidence per beam.
    pub evidence: Evidence,
    /// The depth fan.
    pub depth: DepthConfig,
    /// Odometry calibration.
    pub odometry: OdometryConfig,
    /// Camera intrinsics for tag bearings.
    pub camera: CameraConfig,
    /// Tags whose places are known.
    pub tags: TagMap,
    /// How the pose is corrected beyond odometry.
    pub localiser: Localiser,
    /// When a two-tag fix is believed ([`Localiser::TwoTagFix`]).
    pub fix: FixConfig,
    /// The filter's noise model and gate ([`Localiser::Filter`]).
    pub estimator: EstimatorConfig,
    /// Scan-to-map matching as a filter update ([`Localiser::Filter`] only); `None`: off.
    pub matching: Option<MatchingConfig>,
    /// What the inputs are held to before the pose and the map believe them; `None`:
    /// every reading is believed (for tests of the odometry and the filter alone).
    pub plausible: Option<PlausibleConfig>,
}

/// The matcher and what the filter adds to its matches' spread.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MatchingConfig {
    /// The search.
    pub matcher: MatcherConfig,
    /// The filter's view of a match.
    pub noise: MatchNoise,
}

impl MatchingConfig {
    /// The seed's matcher and noise.
    pub const SEED: MatchingConfig = MatchingConfig {
        matcher: MatcherConfig::SEED,
        noise: MatchNoise::SEED,
    };
}

/// What corrects the pose that odometry predicts.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Localiser {
    /// Nothing: dead reckoning.
    DeadReckoning,
    /// The seed's fix: the pose is replaced by the one two known tags in one picture give.
    TwoTagFix,
    /// The filter: every tag sighting updates the pose in proportion to its certainty.
    Filter,
}

/// A configuration the core refuses.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ConfigError {
    /// Cells must be at least 1 mm.
    CellSize,
    /// Evidence must have `hit > 0 > miss`, positive thresholds below a positive clamp.
    Evidence,
    /// The camera's focal length must be positive.
    FocalLength,
    /// The depth sensor's range limit must be longer than a cell.
    MaxRange,
    /// Matching needs the filter, a window the matcher can search, and the core built
    /// with its `matching` feature.
    Matching,
}

impl SlamConfig {
    /// The robot's own sensors and tuning on a world's grid, with the tags whose places
    /// it knows: the two-tag fix as localiser, no matching. The world's numbers (grid,
    /// tags, start, route) are not the core's: the `world` crate reads them from a
    /// scenario file and overrides the sensors' calibration from it too.
    pub const fn on_grid(geometry: GridGeometry, tags: TagMap) -> SlamConfig {
        SlamConfig {
            geometry,
            evidence: Evidence::SEED,
            depth: DepthConfig::SEED,
            odometry: OdometryConfig::NOMINAL,
            camera: CameraConfig::SEED,
            tags,
            localiser: Localiser::TwoTagFix,
            fix: FixConfig::SEED,
            estimator: EstimatorConfig::SEED,
            matching: None,
            plausible: Some(PlausibleConfig::SEED),
        }
    }

    /// Checks the numbers the core divides by or relies on.
    pub fn validate(&self) -> Result<(), ConfigError> {
        if self.geometry.cell_mm < 1 {
            return Err(ConfigError::CellSize);
        }
        let e = &self.evidence;
        if !(e.hit > 0 && e.miss < 0 && e.free_below > 0 && e.occupied_above > 0 && e.clamp > 0) {
            return Err(ConfigError::Evidence);
        }
        if e.free_below >= e.clamp || e.occupied_above >= e.clamp {
            return Err(ConfigError::Evidence);
        }
        if self.camera.focal_centipx <= 0 {
            return Err(ConfigError::FocalLength);
        }
        if (self.depth.max_range_mm as i32) <= self.geometry.cell_mm {
            return Err(ConfigError::MaxRange);
        }
        if let Some(m) = &self.matching {
            if self.localiser != Localiser::Filter || !cfg!(feature = "matching") {
                return Err(ConfigError::Matching);
            }
            Matcher::new(m.matcher, self.geometry.cell_mm).map_err(|_| ConfigError::Matching)?;
        }
        Ok(())
    }
}

/// Running totals since start: what the robot reports and the tests check.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Counters {
    /// Steps run.
    pub ticks: u32,
    /// Tag fixes taken.
    pub fixes_taken: u32,
    /// Fixes thrown away because the tags' geometry did not add up.
    pub fixes_rejected_geometry: u32,
    /// Fixes thrown away because they disagreed with the prediction.
    pub fixes_rejected_gate: u32,
    /// Pictures with two known tags not used because they were older than the pose
    /// history reaches.
    pub fixes_rejected_too_old: u32,
    /// Fixes taken against the gate after too many rejections in a row, or (the filter)
    /// times the heading or the position was forgotten for them
    /// ([`crate::Estimator::forget_heading`], [`crate::Estimator::forget_position`]).
    pub relocalisations: u32,
    /// Pictures refused whole for repeating the last one bit for bit
    /// ([`crate::camera_check`]).
    pub pictures_repeated: u32,
    /// Pictures the gate refused whose refusals began with a leap: they do not count
    /// towards forgetting the heading ([`crate::camera_check`]).
    pub pictures_leapt: u32,
    /// Pictures refused whole for repeating one from a few ticks before, or refused
    /// picture after picture and fitting a moment a few ticks older: the camera had
    /// fallen behind, and the pictures after them are taken as that much older
    /// ([`crate::camera_check`]).
    pub pictures_late: u32,
    /// Beams written into the map.
    pub beams_mapped: u32,
    /// Beams with no valid return, skipped.
    pub beams_invalid: u32,
    /// Ticks without a flow reading (position not advanced).
    pub flow_stale: u32,
    /// Ticks without a gyro reading (heading not advanced).
    pub gyro_stale: u32,
    /// Ticks without a depth scan (nothing mapped).
    pub depth_stale: u32,
    /// Ticks the gyro was doubted ([`crate::plausible`]).
    pub gyro_doubted: u32,
    /// Ticks the flow was doubted.
    pub flow_doubted: u32,
    /// Ticks the depth sensor was doubted.
    pub depth_doubted: u32,
    /// Scans not mapped because the pose or the scan could not be vouched for.
    pub scans_withheld: u32,
}

/// Which inputs a tick lacked.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Staleness {
    /// No flow this tick.
    pub flow: bool,
    /// No gyro this tick.
    pub gyro: bool,
    /// No depth scan this tick.
    pub depth: bool,
}

/// What one step did.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct StepReport {
    /// The pose the scan was mapped at: the best estimate after this tick.
    pub pose: Pose,
    /// Whether a tag fix was taken, rejected or not tried.
    pub fix: FixOutcome,
    /// Inputs missing this tick.
    pub stale: Staleness,
    /// Inputs doubted after this tick, and why: the motion that needs one holds.
    pub trust: Trust,
    /// Grid cells written this tick.
    pub cells_written: u32,
    /// Totals since start.
    pub counters: Counters,
    /// The filter's belief after this tick ([`Localiser::Filter`] only).
    pub estimate: Option<Estimate>,
}

impl StepReport {
    /// The report of a step.
    ///
    /// Out of line and not generic: the step is generic over the grid's size, so the
    /// firmware builds it for size, where the 60-byte copy of the counters is a byte-wise
    /// library `memcpy`; built here, for speed, it is a few word loads and stores.
    #[inline(never)]
    fn of(
        pose: &Pose,
        fix: FixOutcome,
        stale: Staleness,
        trust: Trust,
        cells_written: u32,
        counters: &Counters,
        filter: Option<&Estimator>,
    ) -> StepReport {
        StepReport {
            pose: *pose,
            fix,
            stale,
            trust,
            cells_written,
            counters: *counters,
            estimate: filter.map(Estimator::estimate),
        }
    }
}

/// The SLAM state: a pose, a map and the rules to update them.
#[derive(Clone, Debug)]
pub struct Slam<const W: usize, const H: usize> {
    config: SlamConfig,
    pose: Pose,
    /// The poses of the last few ticks, this one's included, to place old pictures.
    history: PoseHistory,
    map: GridMap<W, H>,
    counters: Counters,
    gate_rejections_in_a_row: u8,
    /// The pose when the gate began to refuse every sighting, picture after picture.
    refusals_from: Pose,
    /// Whether a tag the filter's gate refused since it last took one was refused at a
    /// range its listed place does not have.
    refused_off_range: bool,
    /// Pictures in a row whose every sighting the gate refused, two or more of them,
    /// since one was refused off in range, with the depth sensor not seeing the tags
    /// elsewhere ([`Slam::position_refused`]).
    off_range_in_a_row: u8,
    /// The camera held to itself: pictures given again, sightings that leap.
    camera: CameraCheck,
    estimator: Estimator,
    /// The scans of the last second, not yet in the map ([`SlamConfig::matching`]).
    #[cfg(feature = "matching")]
    sweep: Sweep<SWEEP_TICKS>,
    #[cfg(feature = "matching")]
    matcher: Matcher,
    /// Whether the step leaves the match to [`Slam::search_match`].
    #[cfg(feature = "matching")]
    defer_matching: bool,
    /// Whether the last step's sweep is still to be matched.
    #[cfg(feature = "matching")]
    match_due: bool,
    /// The match searched and not yet applied.
    #[cfg(feature = "matching")]
    matched: Option<Result<Match, MatchRefusal>>,
    match_counters: MatchCounters,
    last_match: Option<Match>,
    /// How far the map may be off, for the matches against it.
    map_uncertainty: MapUncertainty,
    /// The inputs' checks and trust.
    plausibility: Plausibility,
    /// The depth zones as the camera's columns, to hold ranges to tags' distances.
    #[cfg(feature = "tag-range")]
    zones: ZoneColumns,
}

/// Builds only while [`Slam::new_in`] writes every field: a field added to the core stops
/// the build here until it is written there too.
#[allow(dead_code)]
fn written_by_new_in<const W: usize, const H: usize>(s: Slam<W, H>) {
    let Slam {
        config: _,
        pose: _,
        history: _,
        map: _,
        counters: _,
        gate_rejections_in_a_row: _,
        refusals_from: _,
        refused_off_range: _,
        off_range_in_a_row: _,
        camera: _,
        estimator: _,
        #[cfg(feature = "matching")]
            sweep: _,
        #[cfg(feature = "matching")]
            matcher: _,
        #[cfg(feature = "matching")]
            defer_matching: _,
        #[cfg(feature = "matching")]
            match_due: _,
        #[cfg(feature = "matching")]
            matched: _,
        match_counters: _,
        last_match: _,
        map_uncertainty: _,
        plausibility: _,
        #[cfg(feature = "tag-range")]
            zones: _,
    } = s;
}

impl<const W: usize, const H: usize> Slam<W, H> {
    /// A robot at `start` with an empty map.
    pub fn new(config: SlamConfig, start: Pose) -> Result<Self, ConfigError> {
        let mut slot = MaybeUninit::uninit();
        Self::new_in(&mut slot, config, start)?;
        // SAFETY: `new_in` wrote every field (it returned `Ok`).
        #[allow(unsafe_code)]
        Ok(unsafe { slot.assume_init() })
    }

    /// [`Slam::new`] built in `slot`, field by field, the map and the matcher in place: a
    /// robot whose stack is smaller than its core (a 10 m room's) builds it where it lives.
    #[allow(unsafe_code)]
    pub fn new_in(
        slot: &mut MaybeUninit<Self>,
        config: SlamConfig,
        start: Pose,
    ) -> Result<&mut Self, ConfigError> {
        config.validate()?;
        let s = slot.as_mut_ptr();
        // SAFETY: every field of `*s` is written once, through raw pointers into `slot`
        // (no reference to the unwritten whole is made); the check before this impl names
        // them. The map and the matcher write their own fields; `MaybeUninit<T>` has
        // `T`'s layout. A refused configuration leaves `slot` unwritten as far as its
        // caller knows (nothing in it needs dropping).
        unsafe {
            #[cfg(feature = "matching")]
            Matcher::new_in(
                &mut *addr_of_mut!((*s).matcher).cast::<MaybeUninit<Matcher>>(),
                config.matching.map_or(MatcherConfig::SEED, |m| m.matcher),
                config.geometry.cell_mm,
            )
            .map_err(|_| ConfigError::Matching)?;
            GridMap::new_in(
                &mut *addr_of_mut!((*s).map).cast::<MaybeUninit<GridMap<W, H>>>(),
                config.geometry,
                config.evidence,
            );
            addr_of_mut!((*s).config).write(config);
            addr_of_mut!((*s).pose).write(start);
            addr_of_mut!((*s).history).write(PoseHistory::new(start));
            addr_of_mut!((*s).counters).write(Counters::default());
            addr_of_mut!((*s).gate_rejections_in_a_row).write(0);
            addr_of_mut!((*s).refusals_from).write(start);
            addr_of_mut!((*s).refused_off_range).write(false);
            addr_of_mut!((*s).off_range_in_a_row).write(0);
            addr_of_mut!((*s).camera).write(CameraCheck::new(&config.fix.leap));
            addr_of_mut!((*s).estimator).write(Estimator::new(config.estimator));
            #[cfg(feature = "matching")]
            {
                addr_of_mut!((*s).sweep).write(Sweep::new());
                addr_of_mut!((*s).defer_matching).write(false);
                addr_of_mut!((*s).match_due).write(false);
                addr_of_mut!((*s).matched).write(None);
            }
            addr_of_mut!((*s).match_counters).write(MatchCounters::default());
            addr_of_mut!((*s).last_match).write(None);
            addr_of_mut!((*s).map_uncertainty).write(MapUncertainty::default());
            addr_of_mut!((*s).plausibility).write(Plausibility::default());
            #[cfg(feature = "tag-range")]
            addr_of_mut!((*s).zones).write(ZoneColumns::new(&config.depth, &config.camera));
            Ok(slot.assume_init_mut())
        }
    }

    /// Starts over in place (no large move on a small stack): empty map, pose `start`.
    pub fn reset(&mut self, start: Pose) {
        self.pose = start;
        self.history = PoseHistory::new(start);
        self.map.clear();
        self.counters = Counters::default();
        self.gate_rejections_in_a_row = 0;
        self.refused_off_range = false;
        self.off_range_in_a_row = 0;
        self.camera = CameraCheck::new(&self.config.fix.leap);
        self.estimator = Estimator::new(self.config.estimator);
        #[cfg(feature = "matching")]
        self.sweep.clear();
        self.match_counters = MatchCounters::default();
        self.last_match = None;
        self.map_uncertainty = MapUncertainty::default();
        self.plausibility = Plausibility::default();
    }

    /// Matches used and refused, by cause ([`SlamConfig::matching`]).
    pub fn match_counters(&self) -> &MatchCounters {
        &self.match_counters
    }

    /// The newest match the matcher made, whether the filter took it or not.
    pub fn last_match(&self) -> Option<&Match> {
        self.last_match.as_ref()
    }

    /// The current pose estimate.
    pub fn pose(&self) -> &Pose {
        &self.pose
    }

    /// The map so far.
    pub fn map(&self) -> &GridMap<W, H> {
        &self.map
    }

    /// Maps only the first `columns` x `rows` cells ([`GridMap::limit_to`]): for a core
    /// built with a larger grid than the world's, to map as the robot built for that world
    /// does.
    pub fn limit_map(&mut self, columns: usize, rows: usize) {
        self.map.limit_to(columns, rows);
    }

    /// Whether a tag's distance agreed with the last step's scan: the depth sensor's
    /// ranges are right.
    pub fn depth_vouched(&self) -> bool {
        self.plausibility.depth_vouched()
    }

    /// Whether the depth task is to forget what its frames' steps summed to
    /// ([`crate::depth_step::DepthSteps::forget_steps`]): a tag vouched for the ranges
    /// ([`Slam::depth_vouched`]), or the last step doubted the gyro, by whose turn the
    /// depth task holds each frame to the one before.
    pub fn depth_steps_void(&self) -> bool {
        self.plausibility.depth_vouched() || self.plausibility.trust().gyro.is_some()
    }

    /// Totals since start.
    pub fn counters(&self) -> &Counters {
        &self.counters
    }

    /// The filter's belief: the pose's covariance and the learned calibration
    /// ([`Localiser::Filter`] only).
    pub fn estimate(&self) -> Option<Estimate> {
        self.filter().map(Estimator::estimate)
    }

    /// The filter, when it is the localiser.
    fn filter(&self) -> Option<&Estimator> {
        (self.config.localiser == Localiser::Filter).then_some(&self.estimator)
    }

    /// Tag sightings the filter used and refused, by cause.
    pub fn tag_counters(&self) -> TagCounters {
        *self.estimator.counters()
    }

    /// The filter itself, for tests and for reading its whole covariance.
    pub fn estimator(&self) -> &Estimator {
        &self.estimator
    }

    /// The configuration in use.
    pub fn config(&self) -> &SlamConfig {
        &self.config
    }

    /// One tick: predict the pose from odometry, correct it from known tags, map the scan
    /// at the corrected pose.
    ///
    /// The tag fix comes before mapping (as in the seed) so the scan is mapped at the
    /// corrected pose. A picture `frame.tags_age_us` old gives the pose of that moment: it
    /// is gated against the pose believed then (from the last ticks' poses) and carried
    /// to now by the motion believed since. At age 0 that is the fix itself, bit for bit.
    pub fn step(&mut self, frame: &SensorFrame) -> StepReport {
        // A match left in progress is finished before anything moves.
        #[cfg(feature = "matching")]
        if self.match_pending() {
            self.complete_match();
        }
        self.counters.ticks = self.counters.ticks.wrapping_add(1);
        let mut stale = Staleness {
            flow: frame.flow.is_none(),
            gyro: frame.gyro.is_none(),
            depth: frame.depth.is_none(),
        };
        self.counters.flow_stale += stale.flow as u32;
        self.counters.gyro_stale += stale.gyro as u32;
        self.counters.depth_stale += stale.depth as u32;

        // What the picture's tags say of the depth scan, where the checks ask.
        let mut witness = Witness::Silent;
        let mut judged = match &self.config.plausible {
            Some(limits) => {
                let depth = frame.depth.as_ref().map(|scan| {
                    witness = self.tags_on_depth(frame, limits);
                    DepthReading {
                        scan,
                        steps: frame.depth_doubt,
                        tags: witness,
                    }
                });
                self.plausibility
                    .judge(frame.gyro, frame.flow, depth, frame.commanded, limits)
            }
            None => Judged::believing(frame.gyro, frame.flow),
        };
        let trust = judged.trust;
        // A tick whose motion is a guess: a reading past a command just changed stands in
        // that command's motion; what corrects the pose next mends the guess, not the poses
        // of the scans the sweep holds.
        if judged.guessed() {
            self.plausibility.stand_in_past(&mut judged);
            #[cfg(feature = "matching")]
            self.sweep.anchor();
        }
        if let Some(limits) = &self.config.plausible {
            self.plausibility
                .settle_flow(frame.flow, &mut judged, limits);
        }
        self.counters.gyro_doubted += trust.gyro.is_some() as u32;
        self.counters.flow_doubted += trust.flow.is_some() as u32;
        self.counters.depth_doubted += trust.depth.is_some() as u32;

        let fix = match frame.external_pose {
            Some(p) => {
                self.pose = p;
                self.history.push(p, frame.dt_us);
                FixOutcome::NotAttempted
            }
            None if self.config.localiser == Localiser::Filter => {
                self.predict_filtered(frame.dt_us, judged.flow, judged.gyro);
                self.filter_tags(frame, witness)
            }
            None => {
                let motion = odometry::motion(
                    judged.flow.reading(),
                    judged.gyro.reading(),
                    frame.dt_us,
                    &self.config.odometry,
                );
                self.pose = odometry::apply(&self.pose, &motion);
                self.history.push(self.pose, frame.dt_us);
                self.correct(frame)
            }
        };

        // A scan goes in only at a pose the core can vouch for (its odometry trusted, or
        // a pose from outside) and only if the scan itself is believed.
        let vouched = trust.depth.is_none()
            && (frame.external_pose.is_some() || (trust.pose() && !judged.unfollowed.any()));
        // The scan goes in at the pose of its own moment (after any fix has moved the
        // remembered poses); one older than the history reaches is as good as none.
        // The history is consulted only when there is a scan to place.
        let scan = frame
            .depth
            .as_ref()
            .filter(|_| {
                vouched || {
                    self.counters.scans_withheld += 1;
                    false
                }
            })
            .map(|scan| (scan, self.history.at(frame.depth_age_us)));
        let cells_written = match scan {
            #[cfg(feature = "matching")]
            Some((scan, Some(then))) if self.config.matching.is_some() => {
                if !self.estimator.heading_matchable() {
                    self.withhold_leaving();
                }
                self.sweep_scan(scan, &then)
            }
            // Without matching nothing ties the map to itself: the filter must also be
            // sure of the pose to within about a cell.
            Some((_, Some(_)))
                if self.config.localiser == Localiser::Filter
                    && !self.estimator.sure_enough_to_map() =>
            {
                self.counters.scans_withheld += 1;
                0
            }
            Some((scan, Some(then))) => self.map_scan(scan, &then),
            Some((_, None)) => {
                stale.depth = true;
                self.counters.depth_stale += 1;
                self.expire_sweep()
            }
            None => self.expire_sweep(),
        };
        StepReport::of(
            &self.pose,
            fix,
            stale,
            trust,
            cells_written,
            &self.counters,
            self.filter(),
        )
    }

    /// What the picture's tags say of the depth scan ([`crate::tag_range`]): nothing from a
    /// discredited camera ([`Slam::camera_discredited`]); silent in a core built without
    /// the `tag-range` feature.
    #[cfg(feature = "tag-range")]
    fn tags_on_depth(&self, frame: &SensorFrame, limits: &PlausibleConfig) -> Witness {
        if self.camera_discredited() {
            return Witness::Discredited;
        }
        tag_range::witness(&self.zones, frame, &limits.tag_range)
    }

    #[cfg(not(feature = "tag-range"))]
    fn tags_on_depth(&self, _: &SensorFrame, _: &PlausibleConfig) -> Witness {
        Witness::Silent
    }

    /// Dead reckoning with the learned calibration, and the covariance carried along.
    fn predict_filtered(&mut self, dt_us: u32, flow: Known<FlowDelta>, gyro: Known<GyroRate>) {
        let odometry = self.estimator.odometry(&self.config.odometry);
        let rate = gyro.reading().map(|g| self.estimator.correct_gyro(g));
        let motion = odometry::motion(flow.reading(), rate, dt_us, &odometry);
        let before = self.pose;
        self.pose = odometry::apply(&before, &motion);
        self.history.push(self.pose, dt_us);
        // A tick without a reading integrated its guess (none: no turn); the truth lies
        // within what the commands allow. A tick read or held still needs no bound.
        let guess_bound = if gyro.is_known() {
            None
        } else {
            self.plausibility
                .recent_commands()
                .turn_guess_bound_mdps(rate.map_or(0, |r| r.rate_mdps))
        };
        self.estimator.predict(
            &before,
            &self.pose,
            &motion,
            dt_us,
            flow.kind(),
            gyro.kind(),
            guess_bound,
        );
    }

    /// Every tag in the picture, one update each at the picture's moment, each from the
    /// pose the updates before it left there; the taken corrections then carry the
    /// remembered poses and the pose now once, as a fix does (one motion from the
    /// picture's pose before the first to after the last: the same as carrying each in
    /// turn, but for rounding, for half the work with two tags in view).
    fn filter_tags(&mut self, frame: &SensorFrame, witness: Witness) -> FixOutcome {
        let mut outcome = FixOutcome::NotAttempted;
        self.camera
            .tick(self.plausibility.recent_commands(), frame.dt_us);
        // Sightings the gate refused.
        let mut refused = 0u8;
        match self.camera.judge(&frame.tags, self.counters.ticks) {
            Picture::New => {}
            Picture::Repeated => {
                self.counters.pictures_repeated += 1;
                self.estimator.settle();
                return outcome;
            }
            Picture::Late { ticks } => {
                // A robot standing still sees the same picture now and then; its lag
                // would say nothing, and taken for a camera's it would misplace the
                // pictures once the robot moves.
                let then = self.history.at(ticks.saturating_mul(frame.dt_us));
                if !then.is_some_and(|then| moved(&then, &self.pose)) {
                    self.camera.caught_up();
                }
                self.counters.pictures_late += 1;
                self.estimator.settle();
                return outcome;
            }
        }
        // A camera fallen behind gives pictures older than they say.
        let age = match self.camera.lag_ticks() {
            None => frame.tags_age_us,
            Some(lag) => frame
                .tags_age_us
                .saturating_add(lag.saturating_mul(frame.dt_us)),
        };
        // Whether every sighting the gate refused leapt ([`CameraCheck::leaps`]), and
        // whether one crept ([`CameraCheck::creeps`]).
        let mut leapt = true;
        let mut crept = false;
        // The picture's pose before the first taken update and after the latest.
        let mut carried: Option<(Pose, Pose)> = None;
        // Where the map is matched, the picture's sightings together move the position at
        // most a tag's step, each its share: a jump there writes the map across it and
        // sets the matches against the tags, while a filter without matching is best
        // brought back from the dark at once.
        let share = self
            .limits_tag_steps()
            .then(|| TagShare::of(frame.tags.len()));
        self.estimator.doubt_camera(self.camera_discredited());
        for detection in frame.tags.iter() {
            let mut then = match carried {
                Some((_, corrected)) => Some(corrected),
                None => self.history.at(age),
            };
            let tag = self.config.tags.get(detection.id);
            let mut sighted =
                self.estimator
                    .sight(detection, tag, &self.config.camera, then, share);
            if age != frame.tags_age_us && carried.is_none() && sighted == Err(TagRefusal::Gate) {
                let tag = tag.copied();
                match self.sight_at_own_moment(detection, tag, frame.tags_age_us, share) {
                    Some(own) => (then, sighted) = own,
                    None => self.camera.fits_no_moment(),
                }
            }
            match sighted {
                Ok(corrected) => {
                    if let Some(then) = then {
                        let first = carried.map_or(then, |(first, _)| first);
                        carried = Some((first, corrected));
                    }
                    outcome = FixOutcome::Taken;
                }
                Err(TagRefusal::Gate) => {
                    self.refused_off_range |= !self.estimator.refused_at_its_range();
                    refused = refused.saturating_add(1);
                    let by = self.estimator.refused_by();
                    leapt &= self.camera.leaps(by, self.counters.ticks);
                    crept |= self.camera.creeps(detection.id, by);
                    if outcome != FixOutcome::Taken {
                        outcome = FixOutcome::Rejected(FixRejection::Gate);
                    }
                }
                Err(TagRefusal::TooOld) if outcome == FixOutcome::NotAttempted => {
                    outcome = FixOutcome::Rejected(FixRejection::TooOld);
                }
                Err(_) => {}
            }
        }
        if let Some((first, last)) = carried {
            let motion = RigidMotion::carrying(&first, &last);
            self.carry_past(&motion);
            self.estimator.settle_updated();
        } else {
            self.estimator.settle();
        }
        // A filter sure of its pose whose every sighting the gate refuses, picture after
        // picture, each at the range its tag should have (a tag moved from its place
        // shows in its range), is sure of a heading that is not the robot's: it forgets
        // the heading, as the fix relocalises; unless the refusals began with a leap
        // ([`crate::camera_check`]) or a camera behind explains them. Refused off in
        // range by two tags the depth sensor does not contradict, it forgets the position.
        match outcome {
            FixOutcome::Taken => {
                self.counters.fixes_taken += 1;
                self.camera.taken(self.counters.ticks);
                self.gate_rejections_in_a_row = 0;
                self.refused_off_range = false;
                self.off_range_in_a_row = 0;
            }
            FixOutcome::Rejected(FixRejection::Gate) => {
                self.counters.fixes_rejected_gate += 1;
                if self.camera.refused(leapt, crept) {
                    if self.gate_rejections_in_a_row == 0 {
                        self.refusals_from = self.pose;
                    }
                    self.gate_rejections_in_a_row = self.gate_rejections_in_a_row.saturating_add(1);
                } else {
                    self.counters.pictures_leapt += 1;
                }
                let limit = self.config.fix.relocalise_after;
                let together = (refused >= 2 && self.refused_off_range).then_some(witness);
                if self.position_refused(together) {
                    // Forgotten: the heading is not also.
                } else if limit != 0
                    && self.gate_rejections_in_a_row > limit
                    && !self.refused_off_range
                {
                    if let Some(lag) = self.lag_that_explains(frame) {
                        self.camera.behind(lag);
                        self.counters.pictures_late += 1;
                        self.gate_rejections_in_a_row = 0;
                    } else if self.estimator.forget_heading(self.driven_since_refusals()) {
                        self.relocalised();
                    }
                }
            }
            FixOutcome::Rejected(FixRejection::TooOld) => self.counters.fixes_rejected_too_old += 1,
            _ => {}
        }
        outcome
    }

    /// How far the pose moved since the gate began to refuse every sighting, x and y,
    /// micrometres.
    fn driven_since_refusals(&self) -> (i64, i64) {
        let (from, now) = (&self.refusals_from, &self.pose);
        (
            i64::from(now.x_um) - i64::from(from.x_um),
            i64::from(now.y_um) - i64::from(from.y_um),
        )
    }

    /// A picture whose every sighting the gate refused: `together` with what the depth
    /// sensor said of the tags if two or more were refused, and a refusal since the last
    /// sighting taken was off in range (as the refusals go on the filter grows less sure
    /// of its position, and the same offset soon fits the range alone). A filter sure of
    /// its position that such pictures refuse, picture after picture, is sure of a
    /// position that is not the robot's (the flow lost a few ticks of a drive), where a
    /// tag moved from its place is refused alone while the others are taken, and a camera
    /// lying in range disagrees with the depth sensor where its fan holds the tags: after
    /// `relocalise_after` such pictures in a row it forgets the position, whatever the
    /// leap check says of the run. Returns whether it forgot.
    #[cold]
    #[inline(never)]
    fn position_refused(&mut self, together: Option<Witness>) -> bool {
        self.off_range_in_a_row = match together {
            Some(Witness::Agrees | Witness::Silent) => self.off_range_in_a_row.saturating_add(1),
            Some(Witness::Disagrees | Witness::Discredited) | None => 0,
        };
        let limit = self.config.fix.relocalise_after;
        let forgot =
            limit != 0 && self.off_range_in_a_row > limit && self.estimator.forget_position();
        if forgot {
            self.relocalised();
        }
        forgot
    }

    /// The filter forgot its heading or its position: counted, and every run of refused
    /// pictures that could lead there starts again.
    fn relocalised(&mut self) {
        self.counters.relocalisations += 1;
        self.gate_rejections_in_a_row = 0;
        self.off_range_in_a_row = 0;
        self.camera.relocalised();
    }

    /// Whether the camera has lost its word: the filter refuses its pictures and blames it
    /// ([`CameraCheck::blamed`]) where the map is matched, which holds the pose without
    /// it. Its tags then neither doubt the depth sensor ([`Witness::Discredited`]) nor
    /// pass the usual gate ([`Estimator::doubt_camera`]). Without matching the tags are
    /// all the pose has besides dead reckoning, and a scan the camera disagrees with may
    /// be drawn at a pose the camera was right to refuse: the depth sensor stays doubted,
    /// and the gate as it is (refusing the camera only leaves the heading to drift).
    #[inline(always)]
    fn camera_discredited(&self) -> bool {
        self.limits_tag_steps() && self.camera.blamed()
    }

    /// Whether a picture's tags may move the position at most
    /// [`crate::estimator::TAG_STEP_UM`]: where the map is matched.
    #[inline(always)]
    fn limits_tag_steps(&self) -> bool {
        #[cfg(feature = "matching")]
        return self.config.matching.is_some();
        #[cfg(not(feature = "matching"))]
        return false;
    }

    /// How many ticks behind the camera must be for every sighting of `frame`, refused
    /// picture after picture, to pass the gate at once, if a lag up to the pose
    /// history's reach does: a camera that fell behind while no tag was in view (so no
    /// picture repeated to say so) shows a turning robot its tags where they were a few
    /// ticks before, and forgetting the heading would take the lag for the heading's
    /// error. Of the lags that pass, the one whose sightings move the pose least (a
    /// filter unsure of its heading may pass a lag a tick short of the camera's, and
    /// taking the pictures at it turns the heading a tick's turn off). Tried on a copy of
    /// the filter: nothing changes. Out of line and cold: it runs only where the heading
    /// would otherwise be forgotten.
    #[cold]
    #[inline(never)]
    fn lag_that_explains(&self, frame: &SensorFrame) -> Option<u32> {
        if self.camera.lag_ticks().is_some() || frame.tags.is_empty() {
            return None;
        }
        // Every sighting taken at the lag, and how far they moved the pose together.
        let taken_at = |lag: u32| {
            let age = frame
                .tags_age_us
                .saturating_add(lag.saturating_mul(frame.dt_us));
            let mut trial = self.estimator.clone();
            let mut then = self.history.at(age);
            let mut size = 0u64;
            for detection in frame.tags.iter() {
                let tag = self.config.tags.get(detection.id);
                let before = then?;
                let sighted = trial.sight(detection, tag, &self.config.camera, then, None);
                trial.settle();
                let after = sighted.ok()?;
                size = size.saturating_add(correction_size(&before, &after));
                then = Some(after);
            }
            Some((size, lag))
        };
        (1..HISTORY_LEN as u32 - 1)
            .filter_map(taken_at)
            .min()
            .map(|(_, lag)| lag)
    }

    /// A sighting refused at the moment a camera behind would have taken it, tried at
    /// the moment its picture gives, `age_us` ago: taken there, the camera has caught up.
    /// Returns the moment's pose and the outcome if it was taken. Out of line and cold,
    /// so that the step's own sighting keeps its code.
    #[cold]
    #[inline(never)]
    fn sight_at_own_moment(
        &mut self,
        detection: &TagDetection,
        tag: Option<KnownTag>,
        age_us: u32,
        share: Option<&TagShare>,
    ) -> Option<(Option<Pose>, Result<Pose, TagRefusal>)> {
        let own = self.history.at(age_us);
        let retried =
            self.estimator
                .sight(detection, tag.as_ref(), &self.config.camera, own, share);
        retried.is_ok().then(|| {
            self.camera.caught_up();
            (own, retried)
        })
    }

    #[cfg(feature = "matching")]
    /// With matching on: the scan joins the sweep, the scan leaving the sweep goes into
    /// the map (so the map never holds a beam the sweep matches against it), and the
    /// sweep is matched, now or, deferred, by [`Slam::search_match`] and
    /// [`Slam::finish_match`]. Returns the cells written.
    fn sweep_scan(&mut self, scan: &DepthScan, then: &Pose) -> u32 {
        let written = sweep_in(
            &mut self.sweep,
            &mut self.map.beams(),
            &self.config,
            &mut self.counters,
            (scan, then),
        );
        if written.is_some() {
            self.map_uncertainty.wrote(&self.estimator);
        }
        if self.config.matching.is_some() {
            self.match_due = true;
            if !self.defer_matching {
                self.complete_match();
            }
        }
        written.unwrap_or(0)
    }

    /// With the heading too unsure for the matches to find it
    /// ([`Estimator::heading_matchable`]): the scan the sweep lets go next is not mapped,
    /// but the sweep is still matched, so that a match can bring the heading back.
    #[cfg(feature = "matching")]
    #[cold]
    #[inline(never)]
    fn withhold_leaving(&mut self) {
        if self.sweep.forget_leaving() {
            self.counters.scans_withheld += 1;
        }
    }

    /// On a tick that brings the sweep no scan, writes into the map the scans that have
    /// been in it for [`SWEEP_TICKS`] ticks, as a scan coming in would have pushed them
    /// out ([`Sweep::expired`]), or lets them go unmapped while the heading is too unsure
    /// to match ([`Estimator::heading_matchable`]); returns the cells written. Without
    /// matching, nothing.
    #[cold]
    #[inline(never)]
    fn expire_sweep(&mut self) -> u32 {
        #[cfg(feature = "matching")]
        if self.config.matching.is_some() {
            let mut written = 0;
            let mapped = self.estimator.heading_matchable();
            while let Some(old) = self.sweep.expired(self.counters.ticks, SWEEP_TICKS as u32) {
                if !mapped {
                    self.counters.scans_withheld += 1;
                    continue;
                }
                written += self.map_scan(&old.scan, &old.pose);
                self.map_uncertainty.wrote(&self.estimator);
            }
            return written;
        }
        0
    }

    /// Leaves each step's match to the caller ([`Slam::search_match`], then
    /// [`Slam::finish_match`]), so that it can yield to other work between pieces; the
    /// result is the same, bit for bit, as a step that matches itself.
    #[cfg(feature = "matching")]
    pub fn defer_matching(&mut self, defer: bool) {
        self.defer_matching = defer;
    }

    /// Does up to `pieces` more pieces of the match the last step started: its start,
    /// each piece of its search ([`Matcher::search`]), then the surface's moments. `true`
    /// when nothing is left but to apply it ([`Slam::finish_match`]).
    #[cfg(feature = "matching")]
    pub fn search_match(&mut self, pieces: usize) -> bool {
        for _ in 0..pieces {
            if core::mem::take(&mut self.match_due) {
                self.start_match();
                continue;
            }
            if self.matched.is_some() || !self.matcher.in_progress() {
                return true;
            }
            if self.matcher.searched() {
                self.matched = Some(self.matcher.finish());
                continue;
            }
            let view = self.map.view();
            if let Err(why) = self.matcher.search(&view, 1) {
                self.estimator.settle();
                self.match_counters.count(Err(why));
                return true;
            }
        }
        !self.match_due && (self.matched.is_some() || !self.matcher.in_progress())
    }

    /// Finishes the match the last step started, if any (searching what is left), and
    /// returns `report` with the pose and the filter's belief after it. Applies the
    /// corrections the step left recorded to the remembered poses; a caller that defers
    /// matching calls it after every step.
    #[cfg(feature = "matching")]
    pub fn finish_match(&mut self, report: StepReport) -> StepReport {
        let pending = self.match_pending();
        if pending {
            self.complete_match();
        }
        // Here, off the step, rather than by the next correction in it.
        self.history.settle();
        self.sweep.settle();
        if !pending {
            return report;
        }
        self.with_belief(report)
    }

    /// `report` with the pose and the filter's belief now. Out of line: one read-out of
    /// the belief off the step for every caller, and the step's own left as it is.
    #[cfg(feature = "matching")]
    #[inline(never)]
    fn with_belief(&self, report: StepReport) -> StepReport {
        StepReport {
            pose: self.pose,
            estimate: self.filter().map(Estimator::estimate),
            ..report
        }
    }

    /// The walls ahead measure the flow sensor's scale ([`crate::wall_rate`]) and hold the
    /// gyro's turn to their own ([`crate::wall_turn`]) from the tick `step` took `frame`
    /// in, with the drive under way in `walls` and the wall held in `turn` (the caller's,
    /// as the frame is: kept out of the core's own state, whose layout the step's worst
    /// case feels); returns `report` (the step's, or what [`Slam::finish_match`] returned
    /// from it) with the pose, the filter's belief and the trust after it. Called after
    /// every step (after [`Slam::finish_match`] by a caller that defers matching): off
    /// the step, and out of line, so that the caller's loop (the firmware's task, the
    /// step inlined in it) keeps its code.
    #[cfg(feature = "matching")]
    #[inline(never)]
    pub fn measure_walls(
        &mut self,
        walls: &mut WallRate,
        turn: &mut WallTurn,
        frame: &SensorFrame,
        report: StepReport,
    ) -> StepReport {
        // The frame's wall, fitted at most once for both.
        let fitted = core::cell::OnceCell::new();
        let angles = self.config.depth.beam_angles;
        let wall =
            || *fitted.get_or_init(|| frame.depth.as_ref().and_then(|s| fit_wall(s, &angles)));
        let turned = self.wall_turn_tick(turn, frame, report.trust, &wall);
        if !self.wall_tick(walls, frame, report.trust, &wall) && !turned {
            return report;
        }
        StepReport {
            trust: self.plausibility.trust(),
            ..self.with_belief(report)
        }
    }

    /// The gyro's turn over this tick, whose inputs `step` trusted as `trust`, held to the
    /// walls' ([`crate::wall_turn`]): checked when no turn was commanded of late and the
    /// gyro and the depth sensor are trusted. A gyro the walls part from is doubted, and
    /// the heading turned back by as much as it turned past them, the filter's heading
    /// taken as set from outside ([`Estimator::heading_set_by_walls`]); while the robot
    /// is then held, the wall's tilt averaged turns it back again, more exactly
    /// ([`Estimator::heading_pinned_by_walls`]). Only with the filter. Returns whether
    /// the heading was turned.
    #[cfg(feature = "matching")]
    #[inline(never)]
    fn wall_turn_tick(
        &mut self,
        turn: &mut WallTurn,
        frame: &SensorFrame,
        trust: Trust,
        wall: &impl Fn() -> Option<WallFit>,
    ) -> bool {
        if self.config.localiser != Localiser::Filter {
            return false;
        }
        if turn.holding() {
            let wall = if trust.depth.is_none() { wall() } else { None };
            let doubted = trust.gyro == Some(crate::Doubt::UnseenTurn);
            if let Some(further) = turn.held(wall, doubted) {
                self.turn_back(further);
                self.estimator.heading_pinned_by_walls();
                return true;
            }
            if turn.holding() {
                return false;
            }
        }
        let checked = trust.gyro.is_none()
            && trust.depth.is_none()
            && self.plausibility.turning_of_late() == Some(false);
        let gyro = frame.gyro.filter(|_| checked).map(|g| {
            let g = self.estimator.correct_gyro(g);
            wall_turn::gyro_turn_ndeg(g.rate_mdps, frame.dt_us)
        });
        let wall = if gyro.is_some() { wall() } else { None };
        let Some(excess) = turn.observe(wall, gyro) else {
            return false;
        };
        self.plausibility.doubt_gyro(crate::Doubt::UnseenTurn);
        self.turn_back(excess);
        self.estimator.heading_set_by_walls();
        true
    }

    /// Turns the heading, and the past with it, back anticlockwise by `turn`: the gyro's
    /// turn past the walls. The caller tells the filter how sure of the heading to be.
    #[cfg(feature = "matching")]
    fn turn_back(&mut self, turn: Angle) {
        let then = self.pose;
        let corrected = Pose {
            heading: then.heading - turn,
            ..then
        };
        self.carry_past(&RigidMotion::carrying(&then, &corrected));
    }

    /// The drive at a wall takes this tick, whose inputs `step` trusted as `trust`: a
    /// tick that drove straight on a trusted gyro and flow, with a trusted scan of a wall
    /// ahead, adds to it; any other ends it, and a drive long enough is a measurement of
    /// the flow sensor's scale for the filter, which moves the pose at most a match's
    /// step. Only with matching on. Returns whether the filter took a measurement.
    #[cfg(feature = "matching")]
    #[inline(never)]
    fn wall_tick(
        &mut self,
        walls: &mut WallRate,
        frame: &SensorFrame,
        trust: Trust,
        wall: &impl Fn() -> Option<WallFit>,
    ) -> bool {
        if self.config.matching.is_none() || self.config.localiser != Localiser::Filter {
            return false;
        }
        let Some(measured) = walls.observe(
            frame,
            self.config.odometry.flow_um_per_count_q16,
            wall,
            &trust,
        ) else {
            return false;
        };
        let then = self.pose;
        let counters = &mut walls.counters;
        let Some(outcome) = self.estimator.apply_flow_scale(&then, &measured) else {
            counters.known += 1;
            return false;
        };
        match outcome {
            Ok(corrected) => {
                counters.taken += 1;
                self.carry_past(&RigidMotion::carrying(&then, &corrected));
            }
            Err(_) => counters.refused += 1,
        }
        self.estimator.settle();
        outcome.is_ok()
    }

    /// Whether a match is due, in progress or found and not yet applied.
    #[cfg(feature = "matching")]
    #[inline]
    fn match_pending(&self) -> bool {
        self.match_due || self.matcher.in_progress() || self.matched.is_some()
    }

    #[cfg(feature = "matching")]
    /// Starts matching the sweep; a sweep refused at once is counted.
    fn start_match(&mut self) {
        self.sweep.settle();
        if let Err(why) = self
            .matcher
            .start(&self.sweep, &self.config.depth.beam_angles)
        {
            self.estimator.settle();
            self.match_counters.count(Err(why));
        }
    }

    #[cfg(feature = "matching")]
    /// Searches what is left of the match in progress, if any, and applies it through the
    /// pose history.
    fn complete_match(&mut self) {
        if !self.search_match(usize::MAX) {
            return;
        }
        let (Some(matching), Some(matched)) = (self.config.matching, self.matched.take()) else {
            return;
        };
        let outcome = matched.and_then(|m| {
            self.last_match = Some(m);
            let corrected =
                self.estimator
                    .apply_match(&m, &matching.noise, &self.map_uncertainty)?;
            Ok(RigidMotion::carrying(&m.prediction, &corrected))
        });
        if let Ok(motion) = &outcome {
            self.carry_past(motion);
        }
        self.estimator.settle();
        self.match_counters.count(outcome.map(|_| ()));
    }

    /// Moves the pose now and every remembered one by a correction. The remembered poses
    /// take it when they are read; the rest of them at once, unless the caller settles
    /// them off the step ([`Slam::defer_matching`], then [`Slam::finish_match`]).
    fn carry_past(&mut self, motion: &RigidMotion) {
        #[cfg(feature = "matching")]
        {
            self.pose = carry_sweep_and_history(
                &mut self.sweep,
                &mut self.history,
                motion,
                self.defer_matching,
            );
        }
        #[cfg(not(feature = "matching"))]
        {
            self.history.carry(motion);
            self.pose = self.history.newest();
        }
    }

    fn correct(&mut self, frame: &SensorFrame) -> FixOutcome {
        if self.config.localiser != Localiser::TwoTagFix {
            return FixOutcome::NotAttempted;
        }
        let Some((a, b)) = tagfix::best_pair(frame.tags.as_slice(), &self.config.tags) else {
            return FixOutcome::NotAttempted;
        };
        // Where the robot was believed to be when the picture was taken.
        let Some(then) = self.history.at(frame.tags_age_us) else {
            self.counters.fixes_rejected_too_old += 1;
            return FixOutcome::Rejected(FixRejection::TooOld);
        };
        let fix = match tagfix::two_tag_pose(a, b, &self.config.camera, &self.config.fix) {
            Ok(fix) => fix,
            Err(reason) => {
                self.counters.fixes_rejected_geometry += 1;
                return FixOutcome::Rejected(reason);
            }
        };
        if !tagfix::within_gate(&fix, &then, &self.config.fix) {
            self.gate_rejections_in_a_row = self.gate_rejections_in_a_row.saturating_add(1);
            let limit = self.config.fix.relocalise_after;
            if limit == 0 || self.gate_rejections_in_a_row <= limit {
                self.counters.fixes_rejected_gate += 1;
                return FixOutcome::Rejected(FixRejection::Gate);
            }
            self.counters.relocalisations += 1;
        }
        self.gate_rejections_in_a_row = 0;
        // The pose then becomes the fix; now and every remembered pose move with it.
        let correction = RigidMotion::carrying(&then, &fix);
        self.carry_past(&correction);
        self.counters.fixes_taken += 1;
        FixOutcome::Taken
    }

    fn map_scan(&mut self, scan: &DepthScan, pose: &Pose) -> u32 {
        map_scan(
            &mut self.map.beams(),
            &self.config,
            &mut self.counters,
            scan,
            pose,
        )
    }
}

/// [`Slam::carry_past`] with matching: the sweep, then the history (recorded if `later`);
/// returns the pose now. Not generic over the grid's size, so that it is built in this
/// crate at its optimisation level (the caller's crate may build for size, where the
/// recorded motion's copy is a call).
#[cfg(feature = "matching")]
fn carry_sweep_and_history(
    sweep: &mut Sweep<SWEEP_TICKS>,
    history: &mut PoseHistory,
    motion: &RigidMotion,
    later: bool,
) -> Pose {
    sweep.carry(motion);
    if later {
        history.carry_later(motion);
    } else {
        history.carry(motion);
    }
    history.newest()
}

/// Puts this tick's scan, taken at `then`, into the sweep; the scan it pushes out goes
/// into the grid, at its pose carried by any recorded correction. Returns the cells that
/// one wrote, `None` if none left. The leaving scan is written where it lies in the
/// ring, before its slot is taken: moved out by value it would be copied byte by byte.
/// Not generic over the grid's size (as [`carry_sweep_and_history`]).
#[cfg(feature = "matching")]
#[inline(never)]
fn sweep_in(
    sweep: &mut Sweep<SWEEP_TICKS>,
    map: &mut BeamWriter<'_>,
    config: &SlamConfig,
    counters: &mut Counters,
    (scan, then): (&DepthScan, &Pose),
) -> Option<u32> {
    let written = sweep
        .leaving()
        .map(|(left, pose)| map_scan(map, config, counters, left, &pose));
    sweep.push_in_place(counters.ticks, then, scan);
    written
}

/// Writes `scan`, taken at `pose`, into the grid; returns the cells written.
///
/// Not generic over the grid's size (the beams go through a [`BeamWriter`]): built in this
/// crate, whatever grid the caller sizes. With matching it is inlined into [`sweep_in`],
/// which the step calls out of line (measured the faster of the ways tried: the README's
/// emulator section).
#[cfg_attr(feature = "matching", inline(always))]
fn map_scan(
    map: &mut BeamWriter<'_>,
    config: &SlamConfig,
    counters: &mut Counters,
    scan: &DepthScan,
    pose: &Pose,
) -> u32 {
    let origin = (pose.x_mm(), pose.y_mm());
    let start = map.beam_origin(origin);
    let max = config.depth.max_range_mm as i32;
    let cell = config.geometry.cell_mm;
    let mut written = 0;
    for (range, angle) in scan.ranges_mm.iter().zip(config.depth.beam_angles.iter()) {
        let Some(range) = *range else {
            counters.beams_invalid += 1;
            continue;
        };
        let range = range as i32;
        let dir = pose.heading + *angle;
        let (s, c) = (dir.sin(), dir.cos());
        // `mul_q16`; a range under 2^15 mm times a sine (at most 2^16) fits 32 bits,
        // one M0+ multiply.
        let along = |r: i32, f: i32| {
            if r < 1 << 15 {
                (r * f + (1 << 15)) >> 16
            } else {
                mul_q16(i64::from(r), f) as i32
            }
        };
        let point = |r: i32| (along(r, s), along(r, c));
        // Free up to a cell short of where the beam stopped (or of the range limit).
        let free = point((range.min(max) - cell).max(0));
        let hit = range < max;
        written += map.insert_ray(&start, free, point(range.min(max)), hit);
        counters.beams_mapped += 1;
    }
    written
}

/// Whether the robot moved between `a` and `b` by more than a camera's noise shows: 5 mm
/// or half a degree.
fn moved(a: &Pose, b: &Pose) -> bool {
    const MM: i64 = 5;
    const HALF_DEGREE_BITS: i64 = (1i64 << 32) / 720;
    let far = |p: i32, q: i32| (i64::from(p) - i64::from(q)).abs() > MM * 1000;
    far(a.x_um, b.x_um)
        || far(a.y_um, b.y_um)
        || i64::from((a.heading - b.heading).signed_bits()).abs() > HALF_DEGREE_BITS
}

/// How far a correction moved the pose from `a` to `b`, in micrometres: the position's
/// move plus the heading's turn as the sideways move it makes of a tag a metre away (a
/// milliradian a millimetre), the camera's reach over which a heading error and a
/// position error show alike.
fn correction_size(a: &Pose, b: &Pose) -> u64 {
    const BITS_PER_MRAD: u64 = (1u64 << 32) / 6_283;
    let dx = (i64::from(a.x_um) - i64::from(b.x_um)).unsigned_abs();
    let dy = (i64::from(a.y_um) - i64::from(b.y_um)).unsigned_abs();
    let turned = u64::from((a.heading - b.heading).signed_bits().unsigned_abs());
    dx + dy + turned * 1_000 / BITS_PER_MRAD
}
