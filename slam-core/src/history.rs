//! The believed poses of the last few ticks, so that a camera picture taken between two
//! ticks can be compared with where the robot was believed to be when it was taken.
//!
//! The camera runs on its own schedule, so its newest picture is up to a tick old when the
//! tick uses it. A fix from that picture is the pose *then*: gating it against the pose now
//! and taking it as the pose now puts the estimate a tick behind (9 mm at 86 mm/s, 3
//! degrees in a 31.5 deg/s turn).

use crate::pose::{mul_q16, mul_q16_32, Pose, RigidMotion};
use crate::Angle;

/// Poses kept, the current tick's included: pictures up to the last `HISTORY_LEN - 1`
/// ticks old (400 ms at 10 Hz) can be placed; older ones are refused.
pub const HISTORY_LEN: usize = 5;

/// One remembered tick.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default)]
struct Entry {
    /// The pose at the end of the tick.
    pose: Pose,
    /// Time from the previous entry to this one, in microseconds (the tick's `dt_us`).
    dt_us: u32,
}

/// A ring of the newest poses, each with the time since the one before it.
///
/// Times are kept as gaps rather than clock readings, so ages add up with saturation and
/// stay ordered whatever the ticks' lengths (a clock would wrap).
///
/// With matching, a correction can be recorded (`carry_later`) and applied by `settle`;
/// until then every pose read out is carried on the way, bit for bit the pose a history
/// that had applied it at once would give. A step that settles later, off its own time,
/// pays only for the poses it reads. Without matching nothing settles later, and the
/// bookkeeping is left out of the step.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub struct PoseHistory {
    entries: [Entry; HISTORY_LEN],
    /// Index of the newest entry.
    newest: usize,
    /// Entries held, at most `HISTORY_LEN`.
    len: usize,
    /// A correction not yet applied to the entries recorded before it.
    #[cfg(feature = "matching")]
    pending: Option<RigidMotion>,
    /// Entries pushed since `pending` was recorded: the newest ones, already in its frame.
    #[cfg(feature = "matching")]
    fresh: usize,
}

impl PoseHistory {
    /// A history holding only `pose`, at age 0.
    pub const fn new(pose: Pose) -> PoseHistory {
        PoseHistory {
            entries: [Entry { pose, dt_us: 0 }; HISTORY_LEN],
            newest: 0,
            len: 1,
            #[cfg(feature = "matching")]
            pending: None,
            #[cfg(feature = "matching")]
            fresh: 0,
        }
    }

    /// Records the pose at the end of a tick `dt_us` after the previous entry; the oldest
    /// entry goes when the ring is full.
    pub fn push(&mut self, pose: Pose, dt_us: u32) {
        // A compare, not `%`: the M0+ has no divider.
        self.newest = if self.newest + 1 >= HISTORY_LEN {
            0
        } else {
            self.newest + 1
        };
        if let Some(slot) = self.entries.get_mut(self.newest) {
            *slot = Entry { pose, dt_us };
        }
        self.len = (self.len + 1).min(HISTORY_LEN);
        #[cfg(feature = "matching")]
        if self.pending.is_some() {
            self.fresh += 1;
            if self.fresh >= HISTORY_LEN {
                // Every entry held came after the correction.
                self.pending = None;
                self.fresh = 0;
            }
        }
    }

    /// The newest pose.
    pub fn newest(&self) -> Pose {
        self.entries
            .get(self.newest)
            .map_or_else(Pose::default, |e| self.carried(0, &e.pose))
    }

    /// The pose `age_us` before the newest entry: linear in time between the two entries
    /// around that moment (heading by the shorter turn), exactly an entry's pose at its own
    /// age (so age 0 is the newest pose, bit for bit). `None` if the history does not
    /// reach that far back.
    pub fn at(&self, age_us: u32) -> Option<Pose> {
        let mut newer: Option<(u32, usize, &Entry)> = None;
        let mut age = 0u32;
        // Newest first, by index round the ring: no chained iterators in the step.
        let mut index = self.newest;
        for rank in 0..self.len {
            let e = self.entries.get(index)?;
            index = index.checked_sub(1).unwrap_or(HISTORY_LEN - 1);
            if age >= age_us {
                let pose = self.carried(rank, &e.pose);
                return Some(match newer {
                    // Here `newer_age < age_us <= age`, so the span is never zero.
                    Some((newer_age, newer_rank, n)) if age > age_us => interpolate(
                        &pose,
                        &self.carried(newer_rank, &n.pose),
                        age - age_us,
                        age - newer_age,
                    ),
                    _ => pose,
                });
            }
            newer = Some((age, rank, e));
            age = age.saturating_add(e.dt_us);
        }
        None
    }

    /// Carries every remembered pose by `motion`: after a fix the past is re-expressed in
    /// the corrected frame, so a later, older picture is compared with consistent poses.
    pub fn carry(&mut self, motion: &RigidMotion) {
        #[cfg(feature = "matching")]
        self.settle();
        for e in self.entries.iter_mut().take(self.len) {
            e.pose = motion.apply(&e.pose);
        }
    }

    /// [`PoseHistory::carry`], recorded: applied by [`PoseHistory::settle`], and until
    /// then to each pose as it is read.
    #[cfg(feature = "matching")]
    pub fn carry_later(&mut self, motion: &RigidMotion) {
        self.settle();
        self.pending = Some(*motion);
        self.fresh = 0;
    }

    /// Applies the recorded correction to the entries it concerns.
    #[cfg(feature = "matching")]
    pub fn settle(&mut self) {
        let Some(motion) = self.pending.take() else {
            return;
        };
        let mut index = self.newest;
        for rank in 0..self.len {
            if rank >= self.fresh {
                if let Some(e) = self.entries.get_mut(index) {
                    e.pose = motion.apply(&e.pose);
                }
            }
            index = index.checked_sub(1).unwrap_or(HISTORY_LEN - 1);
        }
        self.fresh = 0;
    }

    /// `pose`, held `rank` entries back from the newest, with the recorded correction if
    /// it came after the entry was pushed.
    #[cfg(feature = "matching")]
    fn carried(&self, rank: usize, pose: &Pose) -> Pose {
        match &self.pending {
            Some(motion) if rank >= self.fresh => motion.apply(pose),
            _ => *pose,
        }
    }

    /// Without matching nothing is recorded ([`PoseHistory::carry`] applies at once).
    #[cfg(not(feature = "matching"))]
    #[inline(always)]
    fn carried(&self, _: usize, pose: &Pose) -> Pose {
        *pose
    }

    /// The held entries, newest first.
    #[cfg(test)]
    fn newest_first(&self) -> impl Iterator<Item = &Entry> {
        let (recent, older) = self.entries.split_at((self.newest + 1).min(HISTORY_LEN));
        recent.iter().rev().chain(older.iter().rev()).take(self.len)
    }
}

/// The pose `back_us` after `older` on the way to `newer`, which came `span_us` after it
/// (`0 <= back_us <= span_us`, `span_us > 0`).
fn interpolate(older: &Pose, newer: &Pose, back_us: u32, span_us: u32) -> Pose {
    // The fraction in Q16: both scaled down until the span fits 15 bits (a 100 ms span
    // loses 4 us of resolution), by a loop of shifts (two for a tick) rather than a
    // count of leading zeros, a library call on the M0+.
    let (mut back, mut span) = (back_us, span_us);
    while span >= 1 << 15 {
        back >>= 1;
        span >>= 1;
    }
    let fraction = fraction_q16(back, span.max(1));
    let part = |from: i32, to: i32| match to.checked_sub(from) {
        // Between `from` and `to`, so it fits an `i32`.
        Some(d) if d != i32::MIN => from + mul_q16_32(d, fraction),
        _ => (from as i64 + mul_q16(to as i64 - from as i64, fraction)) as i32,
    };
    let turn = match newer.heading.diff(older.heading) {
        i32::MIN => mul_q16(i32::MIN as i64, fraction) as i32,
        turn => mul_q16_32(turn, fraction),
    };
    Pose {
        x_um: part(older.x_um, newer.x_um),
        y_um: part(older.y_um, newer.y_um),
        heading: older.heading + Angle::from_bits(turn as u32),
    }
}

/// `part / whole` in Q16 for `whole` in `1..2^15`, `part` clamped to `whole`: sixteen steps
/// of long division, with none of the cases the library's general division must handle
/// (the M0+ has no divide instruction).
fn fraction_q16(part: u32, whole: u32) -> i32 {
    if part >= whole {
        return 1 << 16;
    }
    // One register holds the remainder (top half, always below `whole`, so its double
    // fits) and the quotient's bits as they come (bottom half): each step doubles both,
    // and where the remainder reaches `whole` takes it off and sets the new bit.
    let divisor = whole << 16;
    let mut both = part << 16;
    for _ in 0..16 {
        both <<= 1;
        if both >= divisor {
            both = both - divisor + 1;
        }
    }
    (both & 0xFFFF) as i32
}

#[cfg(test)]
mod tests {
    use super::*;

    const TICK_US: u32 = 100_000;

    /// Driving +x at 100 mm per tick while turning 10 degrees clockwise per tick,
    /// `n + 1` poses from tick 0.
    fn driven(n: u32) -> PoseHistory {
        let mut h = PoseHistory::new(Pose::from_mm_mdeg(0, 0, 0));
        for i in 1..=n {
            h.push(
                Pose::from_mm_mdeg(100 * i as i32, 0, 10_000 * i as i64),
                TICK_US,
            );
        }
        h
    }

    /// [`PoseHistory::at`] as it was written with chained iterators.
    fn at_by_iterators(h: &PoseHistory, age_us: u32) -> Option<Pose> {
        let mut newer: Option<(u32, &Entry)> = None;
        let mut age = 0u32;
        for e in h.newest_first() {
            if age >= age_us {
                return Some(match newer {
                    Some((newer_age, n)) if age > age_us => {
                        interpolate(&e.pose, &n.pose, age - age_us, age - newer_age)
                    }
                    _ => e.pose,
                });
            }
            newer = Some((age, e));
            age = age.saturating_add(e.dt_us);
        }
        None
    }

    #[test]
    fn the_ring_is_walked_as_by_iterators() {
        // Every fill and every place of the newest entry in the ring, ticks of uneven
        // lengths, ages across the whole history and past it.
        for n in 0..3 * HISTORY_LEN as u32 {
            let mut h = PoseHistory::new(Pose::from_mm_mdeg(0, 0, 0));
            for i in 1..=n {
                h.push(
                    Pose::from_mm_mdeg(37 * i as i32, -11 * i as i32, 7_000 * i as i64),
                    TICK_US + 1_000 * i,
                );
            }
            for age in (0..700_000).step_by(4_999).chain([u32::MAX]) {
                assert_eq!(h.at(age), at_by_iterators(&h, age), "{n} {age}");
            }
        }
    }

    #[test]
    fn age_zero_is_the_newest_pose() {
        let h = driven(3);
        assert_eq!(h.at(0), Some(Pose::from_mm_mdeg(300, 0, 30_000)));
        assert_eq!(h.at(0), Some(h.newest()));
    }

    #[test]
    fn ages_at_entries_are_exact_and_between_them_linear() {
        let h = driven(3);
        assert_eq!(h.at(TICK_US), Some(Pose::from_mm_mdeg(200, 0, 20_000)));
        assert_eq!(h.at(3 * TICK_US), Some(Pose::from_mm_mdeg(0, 0, 0)));
        let p = h.at(25_000).unwrap();
        assert!((p.x_um - 275_000).abs() <= 10, "{p:?}");
        assert_eq!(p.y_um, 0);
        assert!((p.heading.to_millidegrees() - 27_500).abs() <= 1, "{p:?}");
    }

    #[test]
    fn too_old_is_none() {
        let h = driven(2);
        assert!(h.at(2 * TICK_US).is_some());
        assert_eq!(h.at(2 * TICK_US + 1), None);
        // The ring keeps HISTORY_LEN poses: HISTORY_LEN - 1 ticks back, no further.
        let h = driven(20);
        let reach = (HISTORY_LEN as u32 - 1) * TICK_US;
        assert_eq!(h.at(reach), Some(Pose::from_mm_mdeg(1600, 0, 160_000)));
        assert_eq!(h.at(reach + 1), None);
        assert_eq!(h.at(u32::MAX), None);
    }

    #[test]
    fn heading_interpolates_across_north_by_the_short_way() {
        let mut h = PoseHistory::new(Pose::from_mm_mdeg(0, 0, 356_000));
        h.push(Pose::from_mm_mdeg(0, 0, 4_000), TICK_US);
        let mid = h.at(TICK_US / 2).unwrap();
        assert_eq!(mid.heading.to_millidegrees(), 0);
        let mut h = PoseHistory::new(Pose::from_mm_mdeg(0, 0, 4_000));
        h.push(Pose::from_mm_mdeg(0, 0, -4_000), TICK_US);
        let quarter = h.at(3 * TICK_US / 4).unwrap();
        assert_eq!(quarter.heading.to_millidegrees(), 2_000);
    }

    #[test]
    fn zero_length_and_huge_ticks_do_not_divide_by_zero() {
        let mut h = PoseHistory::new(Pose::from_mm_mdeg(0, 0, 0));
        h.push(Pose::from_mm_mdeg(10, 0, 0), 0);
        h.push(Pose::from_mm_mdeg(20, 0, 0), u32::MAX);
        h.push(Pose::from_mm_mdeg(30, 0, 0), u32::MAX);
        assert_eq!(h.at(0), Some(Pose::from_mm_mdeg(30, 0, 0)));
        assert!(h.at(u32::MAX / 2).is_some());
        assert_eq!(h.at(u32::MAX), Some(Pose::from_mm_mdeg(20, 0, 0)));
        let mut h = PoseHistory::new(Pose::from_mm_mdeg(0, 0, 0));
        h.push(Pose::from_mm_mdeg(10, 0, 0), 0);
        assert_eq!(h.at(0), Some(Pose::from_mm_mdeg(10, 0, 0)));
        assert_eq!(h.at(1), None);
    }

    #[test]
    fn fractions_match_division() {
        for whole in (1..1 << 15).step_by(7).chain([1, 2, (1 << 15) - 1]) {
            for part in [0, 1, whole / 3, whole / 2, whole - 1, whole, whole + 5] {
                let want = ((part.min(whole) << 16) / whole) as i32;
                assert_eq!(fraction_q16(part, whole), want, "{part} / {whole}");
            }
        }
    }

    /// Pushes, corrections, settles and reads in a random order: every pose read out of a
    /// history that records its corrections is the pose of one that applies each at once.
    #[cfg(feature = "matching")]
    #[test]
    fn a_recorded_correction_reads_as_one_applied_at_once() {
        let mut rng = crate::lcg::Lcg::new(10);
        let pose = |rng: &mut crate::lcg::Lcg| {
            Pose::from_mm_mdeg(
                rng.within(3000) as i32,
                rng.within(3000) as i32,
                rng.within(180_000),
            )
        };
        let start = pose(&mut rng);
        let mut lazy = PoseHistory::new(start);
        // Oldest first, each correction applied to every entry at once.
        let mut eager: Vec<(Pose, u32)> = vec![(start, 0)];
        for step in 0..3000 {
            match rng.within(2) {
                -2 | -1 => {
                    let (p, dt) = (pose(&mut rng), (50_000 + rng.within(50_000)) as u32);
                    lazy.push(p, dt);
                    eager.push((p, dt));
                    if eager.len() > HISTORY_LEN {
                        eager.remove(0);
                    }
                }
                0 => {
                    let motion = RigidMotion::carrying(&pose(&mut rng), &pose(&mut rng));
                    if rng.within(1) == 0 {
                        lazy.carry_later(&motion);
                    } else {
                        lazy.carry(&motion);
                    }
                    for (p, _) in &mut eager {
                        *p = motion.apply(p);
                    }
                }
                _ => lazy.settle(),
            }
            let mut reference = PoseHistory::new(eager[0].0);
            for &(p, dt) in &eager[1..] {
                reference.push(p, dt);
            }
            assert_eq!(lazy.newest(), reference.newest(), "step {step}");
            for age in (0..600_000).step_by(7_919) {
                assert_eq!(lazy.at(age), reference.at(age), "step {step}, age {age}");
            }
        }
    }

    #[test]
    fn carry_moves_every_pose() {
        let mut h = driven(2);
        let motion = RigidMotion::carrying(
            &Pose::from_mm_mdeg(0, 0, 0),
            &Pose::from_mm_mdeg(1000, 0, 0),
        );
        h.carry(&motion);
        assert_eq!(h.at(0), Some(Pose::from_mm_mdeg(1200, 0, 20_000)));
        assert_eq!(h.at(2 * TICK_US), Some(Pose::from_mm_mdeg(1000, 0, 0)));
    }
}
