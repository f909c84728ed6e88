//! The camera held to itself: a picture given again, and sightings that leap.
//!
//! The filter's gate refuses a sighting far from its prediction, and a filter whose every
//! sighting is refused for a few pictures in a row forgets its heading
//! ([`crate::Estimator::forget_heading`]): its own drift is then the likelier cause. A
//! camera that starts lying (a tag put at the wrong column, pictures that come late) is
//! refused by the same gate, and forgetting the heading would hand the pose to the lie.
//! What tells the two apart is how the refusals begin. An estimate that drifts off makes
//! its sightings creep past the gate, a little further each picture; a camera that starts
//! lying moves them at once, further than the odometry can have drifted since the last
//! sighting taken. A run of refusals that begins with such a leap never counts towards
//! forgetting the heading; it ends when a sighting is taken again.
//!
//! A picture whose sightings repeat the last picture's bit for bit says nothing new (a
//! camera stuck on one frame, or one picture handed over twice): it is refused whole,
//! before the filter sees it, so no sighting is counted twice. One that repeats a picture
//! from a few ticks before, with others between, says the camera has fallen behind: it
//! is refused too, and the pictures after it are taken as that many ticks older than they
//! say ([`CameraCheck::lag_ticks`]), until a sighting the gate refuses at that moment is
//! taken at the moment the picture gave (the camera has caught up). A camera that fell
//! behind while no tag was in view repeats no picture: the core guesses its lag when a
//! run of refused pictures would have it forget the heading and the pictures fit a moment
//! a few ticks older instead ([`CameraCheck::behind`]), and drops the guess when a
//! sighting fits neither moment ([`CameraCheck::fits_no_moment`]).

use crate::commanded::{RecentCommands, COMMAND_FRAMES};
use crate::estimator::units;
use crate::frame::TagDetections;

/// How far the first refused sighting after one taken may be from its prediction and
/// still be the estimate's drift rather than the camera's leap.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LeapLimit {
    /// The bearing innovation (given the range) allowed at once, millidegrees.
    pub bearing_mdeg: u32,
    /// And more for each tick since the last sighting taken.
    pub bearing_mdeg_per_tick: u32,
    /// The range innovation allowed at once, millimetres.
    pub range_mm: u32,
    /// And more for each tick since the last sighting taken.
    pub range_mm_per_tick: u32,
    /// How far a tag's bearing innovation may move from the first refused sighting of it
    /// in a run of refusals and still be the estimate's drift, millidegrees.
    pub creep_mdeg: u32,
    /// And more for each tick since that sighting.
    pub creep_mdeg_per_tick: u32,
}

impl LeapLimit {
    /// 3 degrees covers a sighting just past the gate of a filter unsure of its heading
    /// by most of a degree; 5 degrees a second is more than any gyro the core still
    /// trusts can drift (its reading is held to the motors' command within 2 degrees a
    /// second in a turn), and more than the 3 degrees a second of the bias jump that
    /// forgetting the heading recovers from when the command is not known. The range:
    /// 20 mm covers its noise at the camera's reach, and 20 mm a second is a quarter of
    /// the drive's speed, far beyond the flow's scale error. Within a run, a heading
    /// gone off holds a tag's innovation still but for the drift since (3.5 degrees a
    /// second covers the 3 of the bias jump) and the camera's noise (a tenth of a degree;
    /// 1.5 degrees covers a wider-angled camera's pixel).
    pub const SEED: LeapLimit = LeapLimit {
        bearing_mdeg: 3_000,
        bearing_mdeg_per_tick: 500,
        range_mm: 20,
        range_mm_per_tick: 2,
        creep_mdeg: 1_500,
        creep_mdeg_per_tick: 350,
    };
}

/// What the core remembers of the camera to hold it to itself.
#[derive(Clone, Copy, Debug)]
pub struct CameraCheck {
    /// The limit in the filter's units: heading units and position units, at once and
    /// per tick.
    bearing: i64,
    bearing_per_tick: i64,
    range: i64,
    range_per_tick: i64,
    creep: i32,
    creep_per_tick: i32,
    /// Fingerprints of the last pictures with sightings in them (0: none yet), and the
    /// tick of each; the newest at `newest`.
    prints: [u32; REMEMBERED],
    ticks: [u32; REMEMBERED],
    newest: u8,
    /// How many ticks behind the camera has fallen, if it has.
    lag: Option<u32>,
    /// Whether the lag is the filter's guess ([`CameraCheck::behind`]) rather than a
    /// repeated picture's evidence.
    guessed: bool,
    /// The tick the filter last took a sighting on.
    last_taken_tick: u32,
    /// Sightings in a row that fitted neither a guessed lag's moment nor their own
    /// ([`CameraCheck::fits_no_moment`]).
    misses: u8,
    /// The run of refused pictures since the last sighting taken.
    run: Run,
    /// The run's first refused sighting: its tag and bearing innovation.
    first: Option<(u16, i32)>,
    /// How far the estimate's heading may have drifted since that sighting, in heading
    /// units ([`CameraCheck::tick`]).
    drift: i32,
    /// The turn the last change of the commands made, over a tick in heading units
    /// (`i32::MAX` if a command was not known), the change's count
    /// ([`RecentCommands::changes`]) and the ticks since it.
    unsteady: i32,
    seen_changes: u8,
    since_change: u8,
}

/// A turn of `mdps` over `dt_us`, in heading units: mdps x dt / 10^6 in shifts (the M0+
/// divides in software). dt / 1,024 is 2.3 % short of milliseconds, / 1,024 again 2.3 %
/// short of thousandths, and a sixteenth more brings it within 2 %; 32 bits hold a turn
/// of 1,048 deg/s over 4 s, and at most 4.5 million mdeg in heading units.
fn turned_in(mdps: u32, dt_us: u32) -> i32 {
    let ms = (dt_us >> 10).min((1 << 12) - 1);
    let mdeg = (mdps.min(1 << 20) * ms) >> 10;
    let turned = units::heading_from_mdeg(i64::from(mdeg + (mdeg >> 4)));
    turned.min(i64::from(i32::MAX)) as i32
}

/// How many ticks after the commands are steady again a gyro whose readings come late
/// may still read the turn they changed (or not yet read it): as many as a camera
/// behind is found out for (as far back as the pose history reaches).
pub const LATE_GYRO_TICKS: u8 = REMEMBERED as u8;

/// How many sightings in a row must fit neither a guessed lag's moment nor their own
/// before the guess is dropped ([`CameraCheck::fits_no_moment`]).
pub const MISSES_TO_DROP: u8 = 3;

/// How many pictures [`CameraCheck`] remembers: a camera up to three ticks behind is
/// found out, as far back as the pose history can place a picture a tick old
/// ([`crate::history::HISTORY_LEN`]).
const REMEMBERED: usize = crate::history::HISTORY_LEN - 1;

/// What a picture is to the pictures before it.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Picture {
    /// Not seen before.
    New,
    /// The last picture again.
    Repeated,
    /// A picture from `ticks` ticks before, with others since: the camera is behind.
    Late {
        /// How far behind.
        ticks: u32,
    },
}

/// How the pictures refused since the last sighting taken began.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Run {
    /// None refused since.
    None,
    /// The first crept past the gate: the estimate may have drifted.
    Drifted,
    /// The first leapt: the camera's doing.
    Leapt,
}

impl CameraCheck {
    /// A check with nothing seen yet.
    pub fn new(limit: &LeapLimit) -> CameraCheck {
        let position = |mm: u32| i64::from(mm) * units::POSITION_PER_MM;
        let heading = |mdeg: u32| units::heading_from_mdeg(i64::from(mdeg));
        CameraCheck {
            bearing: heading(limit.bearing_mdeg),
            bearing_per_tick: heading(limit.bearing_mdeg_per_tick),
            range: position(limit.range_mm),
            range_per_tick: position(limit.range_mm_per_tick),
            creep: heading(limit.creep_mdeg).clamp(0, i64::from(i32::MAX)) as i32,
            creep_per_tick: heading(limit.creep_mdeg_per_tick).clamp(0, i64::from(i32::MAX)) as i32,
            prints: [0; REMEMBERED],
            ticks: [0; REMEMBERED],
            newest: 0,
            lag: None,
            guessed: false,
            last_taken_tick: 0,
            misses: 0,
            run: Run::None,
            first: None,
            drift: 0,
            unsteady: 0,
            seen_changes: 0,
            since_change: u8::MAX,
        }
    }

    /// A tick went by, `dt_us` long, under the `commands`: in a run of refusals, how far
    /// the heading may have drifted grows by [`LeapLimit::creep_mdeg_per_tick`], and,
    /// while the commands change and for [`LATE_GYRO_TICKS`] after, by the turn they
    /// changed, which a gyro a few ticks late can misread by all of it. With a command
    /// not known nothing bounds it. Off a run, only the commands' changes are followed.
    pub fn tick(&mut self, commands: &RecentCommands, dt_us: u32) {
        if commands.changes() != self.seen_changes {
            self.seen_changes = commands.changes();
            self.since_change = 0;
            self.unsteady = match commands.fastest_turn_mdps() {
                Some(mdps) => turned_in(mdps, dt_us),
                None => i32::MAX,
            };
        } else {
            self.since_change = self.since_change.saturating_add(1);
        }
        if self.first.is_none() {
            return;
        }
        let mut grown = self.creep_per_tick;
        if usize::from(self.since_change) < COMMAND_FRAMES + usize::from(LATE_GYRO_TICKS) {
            grown = grown.saturating_add(self.unsteady);
        }
        if commands.newest().is_none() {
            grown = i32::MAX;
        }
        self.drift = self.drift.saturating_add(grown);
    }

    /// What the picture `tags`, taken in on tick `tick`, is: new, the last one again, or
    /// one from a few ticks before (then the camera's lag is that many ticks). A picture
    /// with no sightings is always new, and is not remembered.
    pub fn judge(&mut self, tags: &TagDetections, tick: u32) -> Picture {
        if tags.is_empty() {
            return Picture::New;
        }
        let print = fingerprint(tags);
        let newest = usize::from(self.newest);
        if self.prints.get(newest) == Some(&print) {
            return Picture::Repeated;
        }
        for (seen, then) in self.prints.iter().zip(self.ticks) {
            if *seen == print {
                let ticks = tick.wrapping_sub(then);
                self.lag = Some(ticks);
                self.guessed = false;
                return Picture::Late { ticks };
            }
        }
        let next = (newest + 1) % REMEMBERED;
        if let (Some(p), Some(t)) = (self.prints.get_mut(next), self.ticks.get_mut(next)) {
            (*p, *t) = (print, tick);
        }
        self.newest = next as u8;
        Picture::New
    }

    /// How many ticks behind the camera has fallen, if it has.
    pub fn lag_ticks(&self) -> Option<u32> {
        self.lag
    }

    /// The camera is `ticks` behind, as the filter found ([`crate::Slam`]'s test of a
    /// run of refused pictures), not as a repeated picture showed.
    pub fn behind(&mut self, ticks: u32) {
        self.lag = Some(ticks);
        self.guessed = true;
        self.misses = 0;
        self.new_run();
    }

    /// A sighting fitted neither the lagged moment nor the picture's own. A guessed lag
    /// that [`MISSES_TO_DROP`] sightings in a row fit neither way was wrong (a heading
    /// gone off in a steady turn looks like a camera behind until the turn ends): it is
    /// dropped, and the refusals count towards forgetting the heading. One such sighting
    /// is not enough: a filter sure of its heading may refuse one only just at the lag
    /// that fits it far better than its own moment. A lag a repeated picture showed
    /// stands.
    pub fn fits_no_moment(&mut self) {
        if !self.guessed {
            return;
        }
        self.misses = self.misses.saturating_add(1);
        if self.misses >= MISSES_TO_DROP {
            self.misses = 0;
            self.lag = None;
            self.guessed = false;
            self.run = Run::Drifted;
            self.first = None;
        }
    }

    /// A sighting refused at the lagged moment was taken at the picture's own: the
    /// camera has caught up.
    pub fn caught_up(&mut self) {
        self.misses = 0;
        self.lag = None;
        self.guessed = false;
    }

    /// The filter took a sighting on tick `tick`: any run of refusals is over.
    pub fn taken(&mut self, tick: u32) {
        self.misses = 0;
        self.last_taken_tick = tick;
        self.new_run();
    }

    /// No refusal since: the next begins a run.
    fn new_run(&mut self) {
        self.run = Run::None;
        self.first = None;
    }

    /// Whether a refused sighting, its bearing and range innovations `refused_by`
    /// ([`crate::Estimator::refused_by`]) on tick `tick`, leapt from the prediction
    /// further than the estimate can have drifted since the last sighting taken.
    pub fn leaps(&self, refused_by: (i32, i32), tick: u32) -> bool {
        // 2^20 ticks (29 hours) are as good as forever; held there, no product passes 2^53.
        let since = i64::from(tick.wrapping_sub(self.last_taken_tick).min(1 << 20));
        let (bearing, range) = refused_by;
        let grown = |at_once: i64, per_tick: i64| at_once.saturating_add(per_tick * since);
        i64::from(bearing).abs() > grown(self.bearing, self.bearing_per_tick)
            || i64::from(range).abs() > grown(self.range, self.range_per_tick)
    }

    /// Whether a sighting of tag `id` the gate refused, its bearing innovation in
    /// `refused_by` ([`crate::Estimator::refused_by`]), moved from the run's first
    /// refused sighting, when that was of the same tag, further than the estimate can
    /// have drifted since ([`CameraCheck::tick`]). A heading gone off holds the innovation
    /// still as the robot turns; a camera putting its tags a few pixels aside does not,
    /// since a column's bearing is not proportional to it (a lie of 40 pixels is 23
    /// degrees at the picture's centre and 8 at its edge). The run's first refused
    /// sighting is remembered here.
    pub fn creeps(&mut self, id: u16, refused_by: (i32, i32)) -> bool {
        let bearing = refused_by.0;
        match self.first {
            None => {
                self.first = Some((id, bearing));
                self.drift = 0;
                false
            }
            Some((first_id, first)) if first_id == id => {
                let moved = bearing.abs_diff(first);
                moved > self.creep.saturating_add(self.drift).unsigned_abs()
            }
            Some(_) => false,
        }
    }

    /// A picture was refused whole by the gate, `leapt` if each of its refused sightings
    /// leapt ([`CameraCheck::leaps`]), `crept` if one crept ([`CameraCheck::creeps`]).
    /// The first such picture after one taken decides the run, unless a later one
    /// creeps: then the run is the camera's. Returns whether the run counts towards
    /// forgetting the heading: it does not if it began with a leap or crept since.
    pub fn refused(&mut self, leapt: bool, crept: bool) -> bool {
        if self.run == Run::None {
            self.run = if leapt { Run::Leapt } else { Run::Drifted };
        }
        if crept {
            self.run = Run::Leapt;
        }
        self.run == Run::Drifted
    }

    /// Whether the run of refused pictures is the camera's: it began with a leap or crept
    /// since ([`CameraCheck::refused`]).
    pub fn blamed(&self) -> bool {
        self.run == Run::Leapt
    }

    /// The filter forgot its heading: the next refusal begins a new run.
    pub fn relocalised(&mut self) {
        self.new_run();
    }
}

/// FNV-1a over each sighting's id, column and distance, never 0: equal pictures print
/// alike, and two different ones alike once in two billion (which costs one picture).
fn fingerprint(tags: &TagDetections) -> u32 {
    let mut h: u32 = 0x811c_9dc5;
    for t in tags.iter() {
        for v in [u32::from(t.id), t.cx_centipx as u32, t.distance_mm] {
            h = (h ^ v).wrapping_mul(0x0100_0193);
        }
    }
    h.max(1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frame::TagDetection;

    fn picture(cx: i32) -> TagDetections {
        let mut tags = TagDetections::new();
        let _ = tags.push(TagDetection {
            id: 11,
            cx_centipx: cx,
            distance_mm: 1_450,
        });
        tags
    }

    #[test]
    fn a_picture_given_again_is_a_repeat_and_a_new_one_is_not() {
        let mut c = CameraCheck::new(&LeapLimit::SEED);
        assert_eq!(c.judge(&picture(16_000), 1), Picture::New);
        assert_eq!(c.judge(&picture(16_000), 2), Picture::Repeated);
        assert_eq!(c.judge(&picture(16_001), 3), Picture::New);
        assert_eq!(c.judge(&TagDetections::new(), 4), Picture::New);
        // An empty picture between two equal ones does not hide the repeat.
        assert_eq!(c.judge(&picture(16_001), 5), Picture::Repeated);
        assert_eq!(c.lag_ticks(), None);
    }

    #[test]
    fn a_picture_from_ticks_before_is_late_by_them_until_the_camera_catches_up() {
        let mut c = CameraCheck::new(&LeapLimit::SEED);
        for tick in 12..16 {
            assert_eq!(c.judge(&picture(tick as i32), tick), Picture::New);
        }
        // The camera falls three ticks behind: tick 13's picture again on tick 16.
        assert_eq!(c.judge(&picture(13), 16), Picture::Late { ticks: 3 });
        assert_eq!(c.lag_ticks(), Some(3));
        assert_eq!(c.judge(&picture(14), 17), Picture::Late { ticks: 3 });
        // A picture not seen before keeps the lag until the camera has caught up.
        assert_eq!(c.judge(&picture(16), 19), Picture::New);
        assert_eq!(c.lag_ticks(), Some(3));
        c.caught_up();
        assert_eq!(c.lag_ticks(), None);
        // Four pictures on, the oldest is forgotten.
        for tick in 20..24 {
            assert_eq!(c.judge(&picture(tick as i32), tick), Picture::New);
        }
        assert_eq!(c.judge(&picture(16), 24), Picture::New);
    }

    #[test]
    fn the_limit_grows_with_the_ticks_since_the_last_sighting_taken() {
        let mut c = CameraCheck::new(&LeapLimit::SEED);
        c.taken(100);
        let deg = |d: i64| units::heading_from_mdeg(d * 1000) as i32;
        // Four degrees off one tick after: more than 3 + 0.5.
        assert!(c.leaps((deg(4), 0), 101));
        assert!(c.leaps((-deg(4), 0), 101));
        // Ten ticks after, 8 degrees are allowed.
        assert!(!c.leaps((deg(4), 0), 110));
        // 30 mm of range one tick after: more than 20 + 2.
        assert!(c.leaps((0, 30 * 16), 101));
        assert!(!c.leaps((0, 30 * 16), 105));
    }

    #[test]
    fn a_guessed_lag_goes_when_no_moment_fits_and_a_seen_one_stays() {
        let mut c = CameraCheck::new(&LeapLimit::SEED);
        assert!(!c.refused(true, false));
        c.behind(3);
        assert_eq!(c.lag_ticks(), Some(3));
        // One sighting that fits neither moment is not enough, nor two with one taken
        // between...
        c.fits_no_moment();
        c.taken(7);
        for _ in 1..MISSES_TO_DROP {
            c.fits_no_moment();
            assert_eq!(c.lag_ticks(), Some(3));
        }
        // ...but as many in a row as it takes are.
        c.fits_no_moment();
        assert_eq!(c.lag_ticks(), None);
        // The refusals now count towards forgetting the heading, though the run leapt.
        assert!(c.refused(true, false));
        // A lag a repeated picture showed is evidence, not a guess.
        for tick in 1..4 {
            assert_eq!(c.judge(&picture(tick as i32), tick), Picture::New);
        }
        assert_eq!(c.judge(&picture(1), 4), Picture::Late { ticks: 3 });
        for _ in 0..MISSES_TO_DROP {
            c.fits_no_moment();
        }
        assert_eq!(c.lag_ticks(), Some(3));
        // Nor does a guess outlive the camera catching up.
        c.behind(2);
        c.caught_up();
        c.behind(1);
        c.judge(&picture(1), 5);
        for _ in 0..MISSES_TO_DROP {
            c.fits_no_moment();
        }
        assert_eq!(c.lag_ticks(), Some(4));
    }

    #[test]
    fn an_innovation_that_creeps_faster_than_drift_is_the_cameras() {
        use crate::frame::DriveCommand;
        let turn = Some(DriveCommand {
            speed_mm_s: 0,
            turn_mdps: 31_500,
        });
        let drive = Some(DriveCommand {
            speed_mm_s: 86,
            turn_mdps: 0,
        });
        let mut c = CameraCheck::new(&LeapLimit::SEED);
        let mut commands = RecentCommands::default();
        let mut ticks = |c: &mut CameraCheck, command: Option<DriveCommand>, n: u32| {
            for _ in 0..n {
                commands.push(command, &crate::commanded::CommandTolerance::SEED);
                c.tick(&commands, 100_000);
            }
        };
        // A steady turn long under way.
        ticks(&mut c, turn, 10);
        c.taken(90);
        let mdeg = |d: i64| units::heading_from_mdeg(d) as i32;
        // The run's first refused sighting of tag 11, 6 degrees off: the drift's.
        assert!(!c.creeps(11, (mdeg(6_000), 0)));
        assert!(c.refused(false, false));
        // A heading gone off, the gyro still lying by 3 degrees a second.
        ticks(&mut c, turn, 1);
        assert!(!c.creeps(11, (mdeg(6_300), 0)));
        ticks(&mut c, turn, 3);
        // Another tag is not held to this tag's first sighting.
        assert!(!c.creeps(12, (mdeg(-2_000), 0)));
        // A lie growing a degree a tick as the tag nears the picture's centre.
        assert!(c.creeps(11, (mdeg(10_300), 0)));
        assert!(!c.refused(false, true));
        // The run stays the camera's until a sighting is taken.
        assert!(!c.refused(false, false));
        c.taken(110);
        assert!(!c.creeps(11, (mdeg(10_300), 0)));
        assert!(c.refused(false, false));
        // As the turn gives way to a drive, a gyro three ticks late misreads it by 3.15
        // degrees a tick: the same creep is then the drift's...
        ticks(&mut c, drive, 4);
        assert!(!c.creeps(11, (mdeg(14_600), 0)));
        // ...but not once the commands have long been steady.
        ticks(&mut c, drive, 10);
        c.taken(125);
        assert!(!c.creeps(11, (mdeg(14_600), 0)));
        ticks(&mut c, drive, 2);
        assert!(c.creeps(11, (mdeg(17_800), 0)));
        // And with the commands not known, nothing is held to the first sighting.
        c.taken(130);
        assert!(!c.creeps(11, (0, 0)));
        ticks(&mut c, None, 1);
        assert!(!c.creeps(11, (mdeg(90_000), 0)));
    }

    #[test]
    fn a_run_that_began_with_a_leap_never_counts_until_a_sighting_is_taken() {
        let mut c = CameraCheck::new(&LeapLimit::SEED);
        assert!(!c.refused(true, false));
        // Later pictures of the run are no further off than the first: still the leap's.
        assert!(!c.refused(false, false));
        c.taken(7);
        assert!(c.refused(false, false));
        assert!(c.refused(true, false));
        c.relocalised();
        assert!(!c.refused(true, false));
    }
}
