//! The SLAM loop: one pure `step` per tick, called alike by the firmware and the simulator.
//!
//! - `config`: what a [`Slam`] is built with, and why a configuration is refused;
//! - `report`: what a step reports, and the running totals;
//! - `tags`: the camera's tags, each an update of the filter, and the seed's two-tag fix;
//! - `mapping`: the depth scans into the map, through the sweep when matching;
//! - `matching`: the sweep's match against the map, searched in pieces and applied;
//! - `walls`: the walls ahead after the step, for the flow's scale and the gyro's turn;
//! - [`first_turn`]: the first turn on the spot, drawn again once it closes.

use core::mem::MaybeUninit;
use core::ptr::addr_of_mut;

use crate::camera_check::CameraCheck;
use crate::estimator::{Estimate, Estimator, MapUncertainty, MatchCounters, TagCounters};
use crate::frame::{FlowDelta, GyroRate, SensorFrame};
use crate::grid::GridMap;
use crate::history::PoseHistory;
use crate::matcher::Match;
#[cfg(feature = "matching")]
use crate::matcher::{MatchRefusal, Matcher, MatcherConfig, Sweep, SWEEP_TICKS};
use crate::odometry;
use crate::plausible::{DepthReading, Judged, Known, Plausibility};
use crate::pose::{Pose, RigidMotion};
use crate::tag_range::Witness;
#[cfg(feature = "tag-range")]
use crate::tag_range::ZoneColumns;
use crate::tagfix::FixOutcome;

#[cfg(feature = "matching")]
pub mod first_turn;

mod config;
mod mapping;
#[cfg(feature = "matching")]
mod matching;
mod report;
mod tags;
#[cfg(feature = "matching")]
mod walls;

pub use config::{fan, ConfigError, DepthConfig, Localiser, MatchingConfig, SlamConfig};
pub use report::{Counters, Staleness, StepReport};

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
