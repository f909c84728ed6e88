//! Each depth frame held to the ones before it: every zone's range moving the same way at
//! once, by more than the robot's motion explains, is a step in the sensor, not the world;
//! a frame given again after others is a sensor running late.
//!
//! A depth sensor that starts reading every range 15 cm long (a fogged cover glass, a lost
//! calibration) gives frames as varied and plausible as true ones, and where no tag is in
//! its fan nothing else measures the same lengths ([`crate::tag_range`]). But the change
//! shows in the frame it begins on. Between two scans the robot turns by what the gyro
//! reads and drives a few millimetres, so each zone of the new scan looks where the old
//! scan's zones, turned by that much, looked: its range is predicted by interpolating the
//! two old zones around it. A wall seen at a slant, a corner or a box's edge moves some
//! zones and not others; an offset in the sensor moves all of them, the same way, at once
//! (all but one by the whole offset: the zone at an edge is the worst predicted).
//!
//! The check runs where each frame arrives, before the SLAM tick takes it (the firmware's
//! depth task; host-sim's loop), with the gyro's own integral as the heading, so it sees
//! every frame the sensor gives and costs the tick nothing; its verdict comes to the core
//! with the scan ([`crate::SensorFrame::depth_doubt`]).
//!
//! A frame is held to the one before it, or, where too few zones have returns in both
//! to compare (dropouts), to the one before that: a step that begins just after a frame
//! with lost returns still shows, and is counted once.
//!
//! [`DepthSteps`] sums such steps as the sensor's offset and doubts the depth sensor
//! ([`Doubt::Jump`]) until the offset is back within one step of where it was (the
//! opposite step, when the sensor recovers), a tag vouches for the ranges, or the gyro
//! is found doubted ([`DepthSteps::forget_steps`]): a turn the gyro read late or not at
//! all moves every range of a slanted wall the same way, a step the sensor never made,
//! and no opposite step need come to take it back.
//!
//! A sensor whose frames come late is a step in time. Mid-turn a late frame draws the
//! walls turned by what the robot turned since it was taken, and once late, each frame
//! follows the one before as a fresh one would. But a sensor falling behind hands over
//! again a frame it had already given, which noise makes all but impossible for a fresh
//! one: from that frame the sensor is late by the time since it first came ([`Doubt::Late`]).
//! It is on time again when a frame fits the frame before clearly better as fresh (or as
//! the first fresh one after a late one) than as late, which shows once the turn differs
//! between the two moments by a quarter of a zone or more: as it catches up (it skips the
//! frames it was behind by) or when a turn starts or stops. Driving straight, or facing a
//! plain wall that looks the same turned, it stays late: a late frame is not mapped, and
//! one taken as fresh would be drawn where the robot no longer is.

use crate::angle::Angle;
use crate::frame::{DepthScan, BEAMS};
use crate::plausible::{check_depth, Doubt, PlausibleConfig};

/// What makes a step, and what makes a late sensor on time again.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DepthStepConfig {
    /// Least change from its predicted range that every compared zone but one must show,
    /// the same way, millimetres (that one at least half of it).
    pub min_step_mm: u16,
    /// Fewest zones compared (a return in the new scan and in both old zones around it)
    /// for a step to be called or a frame's fit judged.
    pub min_zones: u8,
    /// Longest time between two scans' moments for one to be held to the other,
    /// microseconds: further apart, the robot may have driven more than a step.
    pub most_apart_us: u32,
    /// Least spread of a late sensor's frame about its predicted ranges, taken as late,
    /// for it to be judged on time again by fitting better as fresh, millimetres (the
    /// spread: the mean distance of the zones' changes from their mean).
    pub min_late_spread_mm: u16,
}

impl DepthStepConfig {
    /// BugBot: 75 mm, half the 150 mm a plausibly wrong sensor is off by and beyond what
    /// noise, slanted walls and edges move all of a scan's zones by together on the
    /// shipped worlds; five of the eight zones; two ticks apart (the robot drives at most
    /// 26 mm in that time at its fastest route speed of 130 mm/s); a late frame is
    /// judged by a spread of 15 mm, beyond the 10 mm noise and slanted walls spread a
    /// fresh frame's changes by on the shipped worlds, and half of that as fresh.
    pub const SEED: DepthStepConfig = DepthStepConfig {
        min_step_mm: 75,
        min_zones: 5,
        most_apart_us: 200_000,
        min_late_spread_mm: 30,
    };
}

/// How far a turn moves the fan, in zones: the zones' spacing.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub struct ZoneTurn {
    /// Millidegrees between neighbouring zones' centres.
    spacing_mdeg: i32,
}

impl ZoneTurn {
    /// One zone in the shift's fixed point.
    pub const SHIFT_ONE: i32 = 1 << 10;

    /// The fan of `beam_angles` (equally spaced).
    pub fn new(beam_angles: &[Angle; BEAMS]) -> ZoneTurn {
        ZoneTurn {
            spacing_mdeg: (beam_angles[1] - beam_angles[0]).to_millidegrees().max(1),
        }
    }

    /// How many zones (in [`ZoneTurn::SHIFT_ONE`]ths) the fan turned from heading
    /// `from` to `to` (positive clockwise, as the gyro reads).
    fn shift(&self, from: Angle, to: Angle) -> i32 {
        // |turn| <= 180,000 mdeg: times 1,024 stays inside 32 bits.
        (to - from).to_millidegrees() * ZoneTurn::SHIFT_ONE / self.spacing_mdeg
    }
}

/// The shift every compared zone of `now` shows from its range predicted from `before`,
/// the fan having turned `shift` zones (in [`ZoneTurn::SHIFT_ONE`]ths, positive
/// clockwise as the gyro reads) between them: the mean change, millimetres, when at least
/// [`DepthStepConfig::min_zones`] zones were compared and all changed the same way by
/// [`DepthStepConfig::min_step_mm`] or more, but one by at least half of it; `None`
/// otherwise.
pub fn step(
    before: &DepthScan,
    now: &DepthScan,
    shift: i32,
    config: &DepthStepConfig,
) -> Option<i32> {
    compare(before, now, shift, config).flatten()
}

/// [`step`], told apart from too few zones compared: `None` when fewer than
/// [`DepthStepConfig::min_zones`] were, else whether they stepped.
fn compare(
    before: &DepthScan,
    now: &DepthScan,
    shift: i32,
    config: &DepthStepConfig,
) -> Option<Option<i32>> {
    let least = i32::from(config.min_step_mm);
    let (mut compared, mut up, mut down, mut sum) = (0u8, 0u8, 0u8, 0i32);
    let (mut up_half, mut down_half) = (0u8, 0u8);
    for i in 0..BEAMS {
        let Some(change) = change(before, now, i, shift) else {
            continue;
        };
        compared += 1;
        up += u8::from(change >= least);
        down += u8::from(change <= -least);
        up_half += u8::from(change >= least / 2);
        down_half += u8::from(change <= -least / 2);
        sum += change;
    }
    // Every zone the same way by half a step, and all but one by a whole step: a zone
    // at a box's edge or a slant is predicted worst, and may show less of it.
    let whole = |n: u8| n >= compared.saturating_sub(1);
    let together = (up_half == compared && whole(up)) || (down_half == compared && whole(down));
    (compared >= config.min_zones).then(|| together.then(|| sum / i32::from(compared)))
}

/// Zone `i`'s range in `now` less the range predicted for it from `before`, the fan
/// having turned `shift` zones between them; `None` where a range is missing.
fn change(before: &DepthScan, now: &DepthScan, i: usize, shift: i32) -> Option<i32> {
    change_within(before, now, i, shift, i32::MAX)
}

/// [`change`], but across an edge (two neighbouring zones whose ranges differ by more
/// than `widest_mm`: a box's side, a corner) the range between them is not their blend:
/// within an eighth of a zone of either, that zone's range is the prediction; further
/// in, `None`.
fn change_within(
    before: &DepthScan,
    now: &DepthScan,
    i: usize,
    shift: i32,
    widest_mm: i32,
) -> Option<i32> {
    // Where zone i looks now, in the old scan's zones.
    let at = (i as i32)
        .checked_mul(ZoneTurn::SHIFT_ONE)?
        .checked_add(shift)?;
    let j = usize::try_from(at >> 10).ok()?;
    let range = now.ranges_mm[i]?;
    let (a, b) = (
        (*before.ranges_mm.get(j)?)?,
        (*before.ranges_mm.get(j + 1)?)?,
    );
    let f = at & (ZoneTurn::SHIFT_ONE - 1);
    let (a, b) = (i32::from(a), i32::from(b));
    let predicted = if (b - a).abs() <= widest_mm {
        a + (((b - a) * f) >> 10)
    } else if f < ZoneTurn::SHIFT_ONE / 8 {
        a
    } else if f > ZoneTurn::SHIFT_ONE * 7 / 8 {
        b
    } else {
        return None;
    };
    Some(i32::from(range) - predicted)
}

/// The widest step between neighbouring zones that [`spread`] blends across,
/// millimetres: a wall's slant between two zones 5.6 degrees apart, not an edge.
const BLENDED_MM: i32 = 250;

/// How far the zones' changes from `before` to `now` (the fan turned `shift` zones)
/// spread about their mean, millimetres: small when `shift` is the turn between the two
/// frames, whatever the offset; `None` with fewer than `min_zones` compared. Zones whose
/// prediction falls across an edge are not compared: blended, an edge makes the true
/// turn fit worse than none.
fn spread(before: &DepthScan, now: &DepthScan, shift: i32, min_zones: u8) -> Option<u32> {
    let mut changes = [0i32; BEAMS];
    let mut n = 0;
    for i in 0..BEAMS {
        if let Some(c) = change_within(before, now, i, shift, BLENDED_MM) {
            changes[n] = c;
            n += 1;
        }
    }
    if n < usize::from(min_zones) {
        return None;
    }
    let changes = &changes[..n];
    let mean = changes.iter().sum::<i32>() / n as i32;
    Some(changes.iter().map(|c| c.abs_diff(mean)).sum::<u32>() / n as u32)
}

/// How many recent frames are kept: to catch one given again, and for the gyro's heading
/// at their moments.
const FRAMES_KEPT: usize = 6;

/// A frame as it came: its moment (microseconds on the caller's clock, wrapping), the
/// gyro's heading then, and the step it was found to make, millimetres (0: none, or not
/// held to a frame before).
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
struct Seen {
    scan: DepthScan,
    moment_us: u32,
    heading: Angle,
    step_mm: i32,
}

/// The frames seen so far, the offset their steps sum to, and how late they come.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default)]
pub struct DepthSteps {
    /// The newest frames that passed the sensor's own checks, newest at `newest`.
    frames: [Option<Seen>; FRAMES_KEPT],
    newest: u8,
    /// What the steps since the sensor was last vouched for sum to, millimetres.
    offset_mm: i32,
    /// How late the sensor's frames come, microseconds; 0: on time.
    late_us: u32,
    /// How many frames running have been the newest again, bit for bit.
    repeats: u8,
}

impl DepthSteps {
    /// The frame `back` places before the newest.
    fn back(&self, back: usize) -> Option<&Seen> {
        let at = (usize::from(self.newest) + FRAMES_KEPT - back % FRAMES_KEPT) % FRAMES_KEPT;
        self.frames[at].as_ref()
    }

    /// The gyro's heading at `moment_us`, between the kept frames' moments around it;
    /// `None` outside them.
    fn heading_at(&self, moment_us: u32, newest: &Seen) -> Option<Angle> {
        let mut later = newest;
        for back in 0..FRAMES_KEPT {
            let Some(earlier) = self.back(back) else {
                break;
            };
            // Ages back from the newest moment, so the clock's wrap does not matter.
            let age = |m: u32| newest.moment_us.wrapping_sub(m) as i32;
            let (want, from, to) = (age(moment_us), age(later.moment_us), age(earlier.moment_us));
            if (from..=to).contains(&want) {
                let span = (to - from).max(1);
                let turn = (later.heading - earlier.heading).to_millidegrees();
                // Back from `later` by the share of the turn the time back is.
                let back_mdeg = i64::from(turn) * i64::from(want - from) / i64::from(span);
                return Some(later.heading - Angle::from_millidegrees(back_mdeg));
            }
            later = earlier;
        }
        None
    }

    /// When `scan` first came, if it came before (not as the newest frame: a frame
    /// repeated at once is a stuck sensor's), and has returns in half its zones (a
    /// sparse frame may repeat by chance).
    fn came_before(&self, scan: &DepthScan) -> Option<u32> {
        if scan.ranges_mm.iter().flatten().count() < BEAMS / 2 {
            return None;
        }
        (1..FRAMES_KEPT).find_map(|back| {
            let seen = self.back(back)?;
            (seen.scan == *scan).then_some(seen.moment_us)
        })
    }

    /// Whether `now`, following `before`, fits as fresh (or as the first fresh frame
    /// after a late one) clearly better than as late by `late_us`.
    fn caught_up(
        &self,
        before: &Seen,
        now: &Seen,
        fan: &ZoneTurn,
        config: &DepthStepConfig,
    ) -> bool {
        let late = self.late_us;
        let fit = |shift: i32| spread(&before.scan, &now.scan, shift, config.min_zones);
        let then_before = self.heading_at(before.moment_us.wrapping_sub(late), now);
        let then_now = self.heading_at(now.moment_us.wrapping_sub(late), now);
        let (Some(then_before), Some(then_now)) = (then_before, then_now) else {
            return false;
        };
        let late_shift = fan.shift(then_before, then_now);
        let Some(as_late) = fit(late_shift) else {
            return false;
        };
        // Only a turn that differs from the late one by a quarter zone can tell them
        // apart: driving straight, both say the fan did not turn.
        let as_fresh = [
            fan.shift(before.heading, now.heading),
            fan.shift(then_before, now.heading),
        ]
        .into_iter()
        .filter(|shift| shift.abs_diff(late_shift) >= (ZoneTurn::SHIFT_ONE / 4) as u32)
        .filter_map(fit)
        .min();
        as_late >= u32::from(config.min_late_spread_mm)
            && as_fresh.is_some_and(|fresh| fresh.saturating_mul(2) < as_late)
    }

    /// Judges a frame taken at `moment_us` (microseconds on the caller's clock, wrapping)
    /// with the gyro's own integral reading `heading` then: the sensor's own checks
    /// ([`crate::plausible::check_depth`]: a range beyond the sensor's, the newest frame
    /// again bit for bit), then [`Doubt::Late`] while its frames come late, [`Doubt::Jump`]
    /// while its steps leave its ranges off where they were. A frame the own checks
    /// refuse is not held to the others; after one beyond the sensor's range, neither is
    /// the next.
    pub fn judge(
        &mut self,
        scan: &DepthScan,
        moment_us: u32,
        heading: Angle,
        fan: &ZoneTurn,
        limits: &PlausibleConfig,
    ) -> Result<(), Doubt> {
        let config = &limits.depth_step;
        let again = self.back(0).is_some_and(|newest| newest.scan == *scan);
        self.repeats = if again {
            self.repeats.saturating_add(1)
        } else {
            0
        };
        if let Err(doubt) = check_depth(scan, self.repeats, limits) {
            if doubt == Doubt::Impossible {
                self.broken();
            }
            return Err(doubt);
        }
        if again {
            return self.verdict(config);
        }
        let mut now = Seen {
            scan: *scan,
            moment_us,
            heading,
            step_mm: 0,
        };
        let was_late = self.late_us > 0;
        if let Some(before) = self.back(0).copied() {
            if !was_late {
                if let Some(came) = self.came_before(scan) {
                    self.late_us = moment_us.wrapping_sub(came).max(1);
                }
            } else if self.caught_up(&before, &now, fan, config) {
                self.late_us = 0;
            }
            // A frame late, or the first on time after late ones, is not where the turn
            // says: its ranges are not held to the one before's.
            if !was_late && self.late_us == 0 {
                now.step_mm = self.step_from_recent(&now, fan, config).unwrap_or(0);
                self.offset_mm = self.offset_mm.saturating_add(now.step_mm);
            }
        }
        self.newest = (self.newest + 1) % FRAMES_KEPT as u8;
        self.frames[usize::from(self.newest)] = Some(now);
        self.verdict(config)
    }

    /// The step `now` makes from the newest frame; if too few zones compare with it (a
    /// return lost in either), from the one before, unless the newest made a step of
    /// its own (counted once, not twice). A dropout in the frame before the sensor goes
    /// wrong must not hide the step. Frames further apart than
    /// [`DepthStepConfig::most_apart_us`] are not compared.
    fn step_from_recent(
        &self,
        now: &Seen,
        fan: &ZoneTurn,
        config: &DepthStepConfig,
    ) -> Option<i32> {
        for back in 0..2 {
            let before = self.back(back)?;
            if now.moment_us.wrapping_sub(before.moment_us) > config.most_apart_us {
                return None;
            }
            let shift = fan.shift(before.heading, now.heading);
            if let Some(stepped) = compare(&before.scan, &now.scan, shift, config) {
                return stepped;
            }
            if before.step_mm != 0 {
                return None;
            }
        }
        None
    }

    /// The verdict as the last frame left it.
    fn verdict(&self, config: &DepthStepConfig) -> Result<(), Doubt> {
        if self.late_us > 0 {
            Err(Doubt::Late)
        } else if self.offset_mm.unsigned_abs() >= u32::from(config.min_step_mm) {
            Err(Doubt::Jump)
        } else {
            Ok(())
        }
    }

    /// A frame that failed the sensor's own checks: the next is held to none before it.
    fn broken(&mut self) {
        self.frames = [None; FRAMES_KEPT];
    }

    /// Forgets what the steps summed to: a tag's distance agreed with a range (the ranges
    /// are right), or the gyro the frames were held to each other by is doubted.
    pub fn forget_steps(&mut self) {
        self.offset_mm = 0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::slam::fan;

    const C: DepthStepConfig = DepthStepConfig::SEED;
    const LIMITS: PlausibleConfig = PlausibleConfig::SEED;

    fn scan(ranges: [u16; BEAMS]) -> DepthScan {
        DepthScan {
            ranges_mm: ranges.map(Some),
        }
    }

    /// A wall facing the robot 1 m ahead, seen by the seed's fan turned `turn_mdeg`.
    fn wall(turn_mdeg: i64, offset: i32) -> DepthScan {
        let beams = fan(45_000);
        scan(core::array::from_fn(|i| {
            let a = beams[i] + Angle::from_millidegrees(turn_mdeg);
            (1_000 * crate::angle::TRIG_ONE / a.cos() + offset) as u16
        }))
    }

    #[test]
    fn a_turn_the_gyro_read_is_no_step() {
        let fan_turn = ZoneTurn::new(&fan(45_000));
        // Turned 3.15 degrees clockwise: the old zones seen 3.15 degrees further round.
        let shift = fan_turn.shift(
            Angle::from_millidegrees(-10_000),
            Angle::from_millidegrees(-6_850),
        );
        assert_eq!(shift, 3_150 * 1024 / 5_625);
        let before = wall(-10_000, 0);
        let now = wall(-10_000 + 3_150, 0);
        assert_eq!(step(&before, &now, shift, &C), None);
        // The same turn with the sensor reading 150 mm long from now on.
        let long = wall(-10_000 + 3_150, 150);
        let s = step(&before, &long, shift, &C).expect("a step");
        assert!((140..=160).contains(&s), "{s}");
        // Back again.
        let s = step(&long, &wall(-10_000 + 6_300, 0), shift, &C).expect("a step back");
        assert!((-160..=-140).contains(&s), "{s}");
    }

    #[test]
    fn some_zones_moving_is_the_world_not_the_sensor() {
        let before = scan([1_000; BEAMS]);
        // A box comes into the first three zones; the rest see the wall as before.
        let mut now = before;
        for r in now.ranges_mm.iter_mut().take(3) {
            *r = Some(600);
        }
        assert_eq!(step(&before, &now, 0, &C), None);
        // Every zone 60 mm shorter: driving, not a step.
        assert_eq!(step(&before, &scan([940; BEAMS]), 0, &C), None);
        // Every zone 80 mm shorter: a step.
        assert_eq!(step(&before, &scan([920; BEAMS]), 0, &C), Some(-80));
    }

    #[test]
    fn one_zone_at_an_edge_showing_less_of_a_step_still_shows_it() {
        let before = scan([1_000; BEAMS]);
        // Every zone 150 mm longer but one, at an edge, 70 mm: a step (the last zone has
        // no old pair around it to compare with).
        let mut now = scan([1_150; BEAMS]);
        now.ranges_mm[4] = Some(1_070);
        assert_eq!(step(&before, &now, 0, &C), Some((6 * 150 + 70) / 7));
        // That zone the other way, or two short of the step: the world.
        now.ranges_mm[4] = Some(990);
        assert_eq!(step(&before, &now, 0, &C), None);
        now.ranges_mm[4] = Some(1_070);
        now.ranges_mm[5] = Some(1_070);
        assert_eq!(step(&before, &now, 0, &C), None);
    }

    #[test]
    fn too_few_zones_compared_call_nothing() {
        let before = scan([1_000; BEAMS]);
        let mut now = scan([1_200; BEAMS]);
        for r in now.ranges_mm.iter_mut().take(4) {
            *r = None;
        }
        assert_eq!(step(&before, &now, 0, &C), None);
        // Turned two zones: six zones still look where an old pair looked; three: four.
        assert_eq!(
            step(&before, &scan([1_200; BEAMS]), 2 * 1024, &C),
            Some(200)
        );
        assert_eq!(step(&before, &scan([1_200; BEAMS]), 3 * 1024, &C), None);
        assert_eq!(
            step(&before, &scan([1_200; BEAMS]), -2 * 1024, &C),
            Some(200)
        );
        assert_eq!(step(&before, &scan([1_200; BEAMS]), 1024, &C), Some(200));
    }

    /// Frames taken 100 ms apart at the headings given, from a fresh [`DepthSteps`].
    struct Feed {
        steps: DepthSteps,
        moment_us: u32,
        fan: ZoneTurn,
    }

    impl Feed {
        fn new() -> Feed {
            Feed {
                steps: DepthSteps::default(),
                moment_us: 0,
                fan: ZoneTurn::new(&fan(45_000)),
            }
        }

        fn frame(&mut self, scan: &DepthScan, heading_mdeg: i64) -> Result<(), Doubt> {
            self.moment_us = self.moment_us.wrapping_add(100_000);
            let heading = Angle::from_millidegrees(heading_mdeg);
            self.steps
                .judge(scan, self.moment_us, heading, &self.fan, &LIMITS)
        }
    }

    /// `ranges` with the zones `lost` returning nothing.
    fn losing(ranges: u16, lost: &[usize]) -> DepthScan {
        let mut s = scan([ranges; BEAMS]);
        for &i in lost {
            s.ranges_mm[i] = None;
        }
        s
    }

    #[test]
    fn a_step_after_a_frame_with_lost_returns_is_held_to_the_frame_before() {
        let mut feed = Feed::new();
        assert_eq!(feed.frame(&scan([1_000; BEAMS]), 0), Ok(()));
        // Four returns lost: too few zones compare with it, and it steps from nothing.
        assert_eq!(feed.frame(&losing(1_001, &[1, 3, 5, 7]), 0), Ok(()));
        // The sensor goes 150 mm long: the step shows against the frame before.
        assert_eq!(feed.frame(&scan([1_152; BEAMS]), 0), Err(Doubt::Jump));
        assert_eq!(feed.frame(&scan([1_151; BEAMS]), 0), Err(Doubt::Jump));
        // And back, after another frame with lost returns: the step back shows too.
        assert_eq!(
            feed.frame(&losing(1_153, &[0, 2, 4, 6]), 0),
            Err(Doubt::Jump)
        );
        assert_eq!(feed.frame(&scan([1_003; BEAMS]), 0), Ok(()));
    }

    #[test]
    fn a_step_is_counted_once_across_a_frame_with_lost_returns() {
        let mut feed = Feed::new();
        assert_eq!(feed.frame(&scan([1_000; BEAMS]), 0), Ok(()));
        // The step, seen as it comes (five zones compare).
        assert_eq!(feed.frame(&losing(1_150, &[0, 1]), 0), Err(Doubt::Jump));
        // Three zones compare with the step's frame and five with the frame before it:
        // the same step must not be counted again against that one.
        assert_eq!(feed.frame(&losing(1_151, &[5, 6]), 0), Err(Doubt::Jump));
        // One step back (against the step's frame: four zones compare with this one's)
        // ends the doubt: 150 counted, 150 back.
        assert_eq!(feed.frame(&scan([1_002; BEAMS]), 0), Ok(()));
    }

    #[test]
    fn the_sensor_is_doubted_until_its_offset_is_back_or_vouched_for() {
        let mut feed = Feed::new();
        // A wall ahead, each frame a millimetre or two apart from the last (noise: no
        // frame comes twice).
        let mut noise = 0;
        let mut frame = |feed: &mut Feed, r: u16| {
            noise = (noise + 1) % 5;
            feed.frame(&scan([r + noise; BEAMS]), 0)
        };
        assert_eq!(frame(&mut feed, 1_000), Ok(()));
        assert_eq!(frame(&mut feed, 1_150), Err(Doubt::Jump));
        assert_eq!(frame(&mut feed, 1_150), Err(Doubt::Jump));
        assert_eq!(frame(&mut feed, 1_002), Ok(()));
        assert_eq!(frame(&mut feed, 1_150), Err(Doubt::Jump));
        feed.steps.forget_steps();
        assert_eq!(frame(&mut feed, 1_150), Ok(()));
        // Frames too far apart are not held to each other.
        feed.moment_us += 200_000;
        assert_eq!(frame(&mut feed, 1_000), Ok(()));
        // Nor is one after a frame with a range no sensor reads.
        assert_eq!(frame(&mut feed, 9_000), Err(Doubt::Impossible));
        assert_eq!(frame(&mut feed, 1_300), Ok(()));
        // A frame given again at once is a stuck sensor's, not a late one's.
        let same = scan([1_301; BEAMS]);
        assert_eq!(feed.frame(&same, 0), Ok(()));
        assert_eq!(feed.frame(&same, 0), Err(Doubt::Stuck));
        assert_eq!(feed.frame(&same, 0), Err(Doubt::Stuck));
        assert_eq!(feed.frame(&scan([1_302; BEAMS]), 0), Ok(()));
    }

    /// The frame the seed's fan sees at `heading_mdeg` in a room whose walls lie
    /// 1,000 mm +- 500 mm from the robot, three times round a turn.
    fn room(heading_mdeg: i64) -> DepthScan {
        let beams = fan(45_000);
        scan(core::array::from_fn(|i| {
            let bearing = beams[i] + Angle::from_millidegrees(heading_mdeg);
            let thrice = bearing + bearing + bearing;
            (1_000 + 500 * thrice.sin() / crate::angle::TRIG_ONE) as u16
        }))
    }

    #[test]
    fn a_frame_given_again_is_late_until_the_frames_fit_as_fresh() {
        let mut feed = Feed::new();
        // Turning at 31.5 deg/s; from frame 10 the sensor gives the frame of three
        // before, from frame 20 its own again.
        for k in 0..30i64 {
            let given = if (10..20).contains(&k) { k - 3 } else { k };
            let verdict = feed.frame(&room(given * 3_150), k * 3_150);
            let late = (10..20).contains(&k);
            assert_eq!(verdict.is_err(), late, "frame {k}: {verdict:?}");
            if late {
                assert_eq!(verdict, Err(Doubt::Late));
            }
        }
    }

    /// The frame the seed's fan sees at `heading_mdeg` and `ahead_mm` along its drive: a
    /// box's face 800 mm ahead where the bearing is within 10 degrees of the start's
    /// nose, a wall 2,500 mm ahead elsewhere; a millimetre of noise by frame `k`.
    fn boxed(heading_mdeg: i64, ahead_mm: i64, k: usize) -> DepthScan {
        let beams = fan(45_000);
        scan(core::array::from_fn(|i| {
            let bearing = beams[i] + Angle::from_millidegrees(heading_mdeg);
            let range = if bearing.to_millidegrees().abs() <= 10_000 {
                800
            } else {
                2_500 * crate::angle::TRIG_ONE / bearing.cos()
            };
            (range as i64 - ahead_mm) as u16 + u16::from(i == (k % BEAMS))
        }))
    }

    #[test]
    fn a_late_sensor_stays_late_past_a_box_edge_as_a_turn_stops_and_on_a_drive() {
        let mut feed = Feed::new();
        // Turning 3.15 degrees a frame until frame 12, then driving 10 mm a frame at the
        // box. From frame 6 the sensor gives the frame of three before, for good. Blended
        // across the box's edges, the true turn fitted the late frames worse than none
        // as the turn stopped, and driving straight a box edge entering a zone made the
        // two alike by chance: each lifted the doubt with the frames still late.
        let mut pose = [(0i64, 0i64); 40];
        for k in 0..40usize {
            pose[k] = match k {
                0 => (-30_000, 0),
                1..=12 => (pose[k - 1].0 + 3_150, 0),
                _ => (pose[k - 1].0, pose[k - 1].1 + 10),
            };
            let given = if k >= 6 { k - 3 } else { k };
            let (heading, ahead) = pose[given];
            let verdict = feed.frame(&boxed(heading, ahead, given), pose[k].0);
            assert_eq!(verdict.is_err(), k >= 6, "frame {k}: {verdict:?}");
        }
    }

    #[test]
    fn a_late_sensor_that_catches_up_standing_is_on_time_when_the_turn_starts() {
        let mut feed = Feed::new();
        // Turning until frame 15, standing until 25, turning again. The sensor gives the
        // frame of three before from frame 10 to 20.
        let mut headings = [0i64; 40];
        for k in 0..40usize {
            let turning = !(15..25).contains(&k);
            headings[k] = if k == 0 {
                0
            } else {
                headings[k - 1] + if turning { 3_150 } else { 0 }
            };
            let given = if (10..20).contains(&k) { k - 3 } else { k };
            // A millimetre of noise a frame: a standing robot's frames differ.
            let mut frame = room(headings[given]);
            if let Some(r) = frame.ranges_mm[0].as_mut() {
                *r += (k % 3) as u16;
            }
            let verdict = feed.frame(&frame, headings[k]);
            // Late from the frame given again until the first frame that shows the
            // turn starting at once.
            let late = (10..25).contains(&k);
            assert_eq!(verdict.is_err(), late, "frame {k}: {verdict:?}");
        }
    }
}
