//! The camera's tags in the step: each sighting an update of the filter at the picture's
//! own moment, the depth scan held to their distances, and the seed's two-tag fix.

use super::{Localiser, Slam};

use crate::camera_check::Picture;
use crate::estimator::{TagRefusal, TagShare};
use crate::frame::{SensorFrame, TagDetection};
use crate::history::HISTORY_LEN;
use crate::plausible::PlausibleConfig;
use crate::pose::{Pose, RigidMotion};
#[cfg(feature = "tag-range")]
use crate::tag_range;
use crate::tag_range::Witness;
use crate::tagfix::{self, FixOutcome, FixRejection, KnownTag};

impl<const W: usize, const H: usize> Slam<W, H> {
    /// What the picture's tags say of the depth scan ([`crate::tag_range`]): nothing from a
    /// discredited camera ([`Slam::camera_discredited`]); silent in a core built without
    /// the `tag-range` feature.
    #[cfg(feature = "tag-range")]
    pub(super) fn tags_on_depth(&self, frame: &SensorFrame, limits: &PlausibleConfig) -> Witness {
        if self.camera_discredited() {
            return Witness::Discredited;
        }
        tag_range::witness(&self.zones, frame, &limits.tag_range)
    }

    #[cfg(not(feature = "tag-range"))]
    pub(super) fn tags_on_depth(&self, _: &SensorFrame, _: &PlausibleConfig) -> Witness {
        Witness::Silent
    }

    /// Every tag in the picture, one update each at the picture's moment, each from the
    /// pose the updates before it left there; the taken corrections then carry the
    /// remembered poses and the pose now once, as a fix does (one motion from the
    /// picture's pose before the first to after the last: the same as carrying each in
    /// turn, but for rounding, for half the work with two tags in view).
    pub(super) fn filter_tags(&mut self, frame: &SensorFrame, witness: Witness) -> FixOutcome {
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
    ///
    /// [`CameraCheck::blamed`]: crate::camera_check::CameraCheck::blamed
    /// [`Estimator::doubt_camera`]: crate::estimator::Estimator::doubt_camera
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

    pub(super) fn correct(&mut self, frame: &SensorFrame) -> FixOutcome {
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
