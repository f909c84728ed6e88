//! The sweep: the last ticks' depth scans, each with the pose it was taken at, so that a
//! second of beams can be matched as one scan.
//!
//! Eight beams over 45 degrees pin little alone; ten ticks of them, placed relative to each
//! other by the odometry, see a corner or two walls. The poses stored are the believed
//! ones; only their differences matter (the sweep is matched relative to its newest pose),
//! and a correction that moves the believed past moves these too ([`Sweep::carry`]), so
//! those differences stay the odometry's; but not the scans held when a tick's motion was
//! guessed ([`Sweep::anchor`]), whose poses the guess's error never touched.

use crate::angle::Angle;
use crate::frame::{DepthScan, BEAMS};
use crate::pose::{Pose, RigidMotion};

/// Ticks in the seed's sweep: one second at 10 Hz.
///
/// Long enough that a turn at the route's 31.5 deg/s adds about 30 degrees of view to the
/// 45 degree fan and a drive at 86 mm/s spreads the beams over 9 cm; short enough that the
/// odometry's own error over it (a 4 % flow scale error is 3.4 mm, a 0.75 % gyro scale
/// error a quarter of a degree) stays well inside one search step.
pub const SWEEP_TICKS: usize = 10;

/// One tick's scan and where it was taken.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SweepScan {
    /// The tick the scan belongs to (the caller's count).
    pub tick: u32,
    /// The believed pose at the scan's moment.
    pub pose: Pose,
    /// The scan.
    pub scan: DepthScan,
}

/// A beam's end relative to the sweep's newest pose, in millimetres: `right` along the
/// robot's right-hand side, `forward` along its nose.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SweepPoint {
    /// Towards the robot's right, in millimetres.
    pub right_mm: i32,
    /// Towards the robot's nose, in millimetres.
    pub forward_mm: i32,
}

/// A ring of the last `N` scans, oldest overwritten first; no allocation.
///
/// A correction is recorded, not applied ([`Sweep::carry`]): the step that corrects the
/// pose reads one stored pose (the scan leaving), so it carries that one, and the rest are
/// carried by [`Sweep::settle`] where the time is spare. Every pose read out is carried,
/// settled or not, bit for bit as if each correction had been applied at once.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub struct Sweep<const N: usize> {
    scans: [Option<SweepScan>; N],
    /// Slot the next scan goes into.
    next: usize,
    /// A correction not yet applied to the stored poses.
    pending: Option<RigidMotion>,
    /// Scans pushed since `pending` was recorded: the newest ones, already in its frame.
    fresh: usize,
    /// Scans pushed since [`Sweep::anchor`] (at most `N`): the older ones stay where they
    /// are.
    since_anchor: usize,
}

impl<const N: usize> Default for Sweep<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> Sweep<N> {
    /// An empty sweep.
    pub const fn new() -> Self {
        Sweep {
            scans: [None; N],
            next: 0,
            pending: None,
            fresh: 0,
            since_anchor: N,
        }
    }

    /// Forgets every scan.
    pub fn clear(&mut self) {
        *self = Self::new();
    }

    /// Scans held.
    pub fn len(&self) -> usize {
        self.scans.iter().flatten().count()
    }

    /// Whether no scan is held.
    pub fn is_empty(&self) -> bool {
        self.scans.iter().all(Option::is_none)
    }

    /// Adds a scan as the newest; hands back the oldest when the ring was full, so the
    /// caller can write it into the map now that it has left the sweep.
    pub fn push(&mut self, tick: u32, pose: Pose, scan: DepthScan) -> Option<SweepScan> {
        let left = self
            .scans
            .get(self.next)
            .copied()
            .flatten()
            .map(|s| SweepScan {
                pose: self.carried(0, &s.pose),
                ..s
            });
        self.push_in_place(tick, &pose, &scan);
        left
    }

    /// Takes out the oldest scan held if it was taken `max_age` ticks or more before tick
    /// `now`, with its pose: a sweep holds the last ticks' scans, not the last scans, so
    /// ticks that bring none (a scan withheld, a frame lost) must not keep old ones in
    /// it, where every correction since would carry them as if they were recent.
    pub fn expired(&mut self, now: u32, max_age: u32) -> Option<SweepScan> {
        let rank =
            (0..N).find(|&rank| matches!(self.scans.get(self.slot_of(rank)), Some(Some(_))))?;
        let at = self.slot_of(rank);
        let s = (*self.scans.get(at)?)?;
        if now.wrapping_sub(s.tick) < max_age {
            return None;
        }
        let pose = self.carried(rank, &s.pose);
        if let Some(slot) = self.scans.get_mut(at) {
            *slot = None;
        }
        Some(SweepScan { pose, ..s })
    }

    /// The scan the next push takes out, if the ring is full, with its pose.
    pub fn leaving(&self) -> Option<(&DepthScan, Pose)> {
        let s = self.scans.get(self.next)?.as_ref()?;
        Some((&s.scan, self.carried(0, &s.pose)))
    }

    /// Forgets the scan the next push would take out ([`Sweep::leaving`]), so that it is
    /// never mapped; whether there was one.
    pub fn forget_leaving(&mut self) -> bool {
        self.scans
            .get_mut(self.next)
            .is_some_and(|slot| slot.take().is_some())
    }

    /// [`Sweep::push`] without handing the oldest back: the scan is copied straight into
    /// its slot, where one moved in and out by value is copied twice on the M0+.
    pub fn push_in_place(&mut self, tick: u32, pose: &Pose, scan: &DepthScan) {
        let Some(slot) = self.scans.get_mut(self.next) else {
            return;
        };
        match slot {
            Some(s) => {
                s.tick = tick;
                s.pose = *pose;
                s.scan = *scan;
            }
            None => {
                *slot = Some(SweepScan {
                    tick,
                    pose: *pose,
                    scan: *scan,
                })
            }
        }
        // A compare, not `%`: the M0+ has no divider.
        self.next = if self.next + 1 >= N { 0 } else { self.next + 1 };
        if self.since_anchor < N {
            self.since_anchor += 1;
        }
        if self.pending.is_some() {
            self.fresh += 1;
            if self.fresh >= N {
                // Every scan held came after the correction.
                self.pending = None;
                self.fresh = 0;
            }
        }
    }

    /// The newest scan, with its pose: the sweep's reference.
    pub fn newest(&self) -> Option<SweepScan> {
        let last = N.checked_sub(1)?;
        let newest = if self.next == 0 { last } else { self.next - 1 };
        let s = self.scans.get(newest)?.as_ref()?;
        Some(SweepScan {
            pose: self.carried(last, &s.pose),
            ..*s
        })
    }

    /// The scans held, oldest first, each with its pose.
    fn oldest_first(&self) -> impl Iterator<Item = (Pose, &DepthScan)> {
        (0..N).filter_map(move |rank| {
            let s = self.scans.get(self.slot_of(rank))?.as_ref()?;
            Some((self.carried(rank, &s.pose), &s.scan))
        })
    }

    /// Moves every stored pose by `motion`, as a correction moves the believed past:
    /// recorded, and applied to the poses by [`Sweep::settle`] or as they are read.
    pub fn carry(&mut self, motion: &RigidMotion) {
        self.settle();
        self.pending = Some(*motion);
        self.fresh = 0;
    }

    /// Leaves the scans held where they are whatever corrects the pose from now on: the
    /// pose is about to become a guess (a tick's motion not read), and a correction then
    /// mends the guess, not the poses these scans were taken at.
    pub fn anchor(&mut self) {
        self.settle();
        self.since_anchor = 0;
    }

    /// Applies the recorded correction to the stored poses it concerns.
    pub fn settle(&mut self) {
        let Some(motion) = self.pending.take() else {
            return;
        };
        for rank in N.saturating_sub(self.since_anchor)..N.saturating_sub(self.fresh) {
            let at = self.slot_of(rank);
            if let Some(Some(s)) = self.scans.get_mut(at) {
                s.pose = motion.apply(&s.pose);
            }
        }
        self.fresh = 0;
    }

    /// The slot of the scan `rank` places from the oldest, empty slots counted.
    fn slot_of(&self, rank: usize) -> usize {
        let at = self.next + rank;
        if at >= N {
            at - N
        } else {
            at
        }
    }

    /// `pose`, stored `rank` places from the oldest, with the recorded correction if it
    /// came after the pose was stored.
    fn carried(&self, rank: usize, pose: &Pose) -> Pose {
        match &self.pending {
            Some(motion) if rank + self.fresh < N && rank + self.since_anchor >= N => {
                motion.apply(pose)
            }
            _ => *pose,
        }
    }

    /// Every beam end shorter than `max_range_mm`, relative to the newest pose, into
    /// `out`; returns how many were written (at most `out.len()`).
    ///
    /// A beam with no return or one at or past `max_range_mm` has no end to match.
    pub fn points(
        &self,
        beam_angles: &[Angle; BEAMS],
        max_range_mm: u16,
        out: &mut [SweepPoint],
    ) -> usize {
        let Some(reference) = self.newest().map(|s| s.pose) else {
            return 0;
        };
        let (ref_sin, ref_cos) = (reference.heading.sin(), reference.heading.cos());
        let mut written = 0;
        for (pose, scan) in self.oldest_first() {
            // The scan's place relative to the reference, in millimetres (a sweep spans
            // centimetres, so 32 bits hold every product below).
            let dx = pose.x_mm().saturating_sub(reference.x_mm());
            let dy = pose.y_mm().saturating_sub(reference.y_mm());
            for (range, angle) in scan.ranges_mm.iter().zip(beam_angles.iter()) {
                let Some(range) = range.filter(|&r| r < max_range_mm) else {
                    continue;
                };
                let Some(slot) = out.get_mut(written) else {
                    return written;
                };
                let range = i32::from(range);
                let dir = pose.heading + *angle;
                // Map-frame offset of the beam's end from the reference.
                let ex = dx + q16(range, dir.sin());
                let ey = dy + q16(range, dir.cos());
                // Into the reference's frame: nose (sin h, cos h), right (cos h, -sin h).
                *slot = SweepPoint {
                    right_mm: q16(ex, ref_cos) - q16(ey, ref_sin),
                    forward_mm: q16(ex, ref_sin) + q16(ey, ref_cos),
                };
                written += 1;
            }
        }
        written
    }
}

/// `a * f >> 16` rounded half away from zero (so a mirrored world rounds mirrored), for a
/// length `a` under `2^15` mm and a Q16 factor within `+-1.0`: one 32-bit multiply.
/// Without a branch: below zero, `floor((p + 2^15 - 1) / 2^16)` is
/// `-floor((-p + 2^15) / 2^16)`.
#[inline]
pub(crate) fn q16(a: i32, f: i32) -> i32 {
    let p = a.clamp(-(1 << 15) + 1, (1 << 15) - 1) * f;
    (p + (1 << 15) - i32::from(p < 0)) >> 16
}

#[cfg(test)]
mod tests {
    use super::{q16, Sweep, SweepScan};
    use crate::frame::DepthScan;
    use crate::lcg::Lcg;
    use crate::pose::{Pose, RigidMotion};

    /// Pushes, corrections, anchors, settles, scans expiring or forgotten and reads in a
    /// random order:
    /// every pose read out of a sweep that records its corrections is the pose of one that
    /// applies each at once to every scan pushed since the last anchor, and a scan
    /// expires, oldest first, once it is old enough.
    #[test]
    fn a_recorded_correction_reads_as_one_applied_at_once() {
        const N: usize = 4;
        let mut rng = Lcg::new(29);
        let pose = |rng: &mut Lcg| {
            Pose::from_mm_mdeg(
                rng.within(3000) as i32,
                rng.within(3000) as i32,
                rng.within(180_000),
            )
        };
        let mut lazy: Sweep<N> = Sweep::new();
        // Oldest first, each correction applied at once to every scan not anchored.
        let mut eager: Vec<(SweepScan, bool)> = Vec::new();
        let (mut anchors, mut anchored_carries) = (0, 0);
        for step in 0..4000u32 {
            match rng.within(4) {
                -4..=-1 => {
                    let (p, scan) = (pose(&mut rng), DepthScan::default());
                    let expected = (eager.len() == N).then(|| eager.remove(0).0);
                    let s = SweepScan {
                        tick: step,
                        pose: p,
                        scan,
                    };
                    eager.push((s, false));
                    assert_eq!(lazy.push(step, p, scan), expected, "step {step}");
                }
                0 | 1 => {
                    let motion = RigidMotion::carrying(&pose(&mut rng), &pose(&mut rng));
                    anchored_carries += eager.iter().any(|(_, a)| *a) as u32;
                    for (s, anchored) in &mut eager {
                        if !*anchored {
                            s.pose = motion.apply(&s.pose);
                        }
                    }
                    lazy.carry(&motion);
                }
                2 => lazy.settle(),
                3 => {
                    let max_age = 1 + rng.within(6).unsigned_abs() as u32;
                    let old_enough = |s: &SweepScan| step.wrapping_sub(s.tick) >= max_age;
                    let expected = eager
                        .first()
                        .filter(|(s, _)| old_enough(s))
                        .is_some()
                        .then(|| eager.remove(0).0);
                    assert_eq!(lazy.expired(step, max_age), expected, "step {step}");
                }
                _ if rng.within(10) == 0 => {
                    eager.clear();
                    lazy.clear();
                }
                _ if rng.within(4) == 0 => {
                    // The scan a push would take out is forgotten, never handed back.
                    let full = eager.len() == N;
                    if full {
                        eager.remove(0);
                    }
                    assert_eq!(lazy.forget_leaving(), full, "step {step}");
                }
                _ if rng.within(2) == 0 => {
                    for (_, anchored) in &mut eager {
                        *anchored = true;
                    }
                    lazy.anchor();
                    anchors += 1;
                }
                _ => {}
            }
            let read: Vec<Pose> = lazy.oldest_first().map(|(p, _)| p).collect();
            let expected: Vec<Pose> = eager.iter().map(|(s, _)| s.pose).collect();
            assert_eq!(read, expected, "step {step}");
            let newest = eager.last().map(|(s, _)| *s);
            assert_eq!(lazy.newest(), newest, "step {step}");
            let leaving = (eager.len() == N).then(|| eager[0].0.pose);
            assert_eq!(lazy.leaving().map(|(_, p)| p), leaving, "step {step}");
        }
        assert!(
            anchors > 50 && anchored_carries > 50,
            "{anchors} {anchored_carries}"
        );
    }

    /// `a * f / 2^16` rounded half away from zero, in 64 bits.
    fn reference(a: i32, f: i32) -> i32 {
        let p = i64::from(a.clamp(-(1 << 15) + 1, (1 << 15) - 1)) * i64::from(f);
        let magnitude = (p.abs() + (1 << 15)) >> 16;
        (p.signum() * magnitude) as i32
    }

    #[test]
    fn q16_rounds_half_away_from_zero_and_mirrors() {
        let factors = (-65_536..=65_536)
            .step_by(97)
            .chain([-65_536, -1, 0, 1, 65_536]);
        for f in factors {
            for a in (-40_000..=40_000)
                .step_by(313)
                .chain([-1, 0, 1, 32_767, -32_767])
            {
                assert_eq!(q16(a, f), reference(a, f), "{a} x {f}");
                assert_eq!(q16(-a, f), -q16(a, f), "mirrored {a} x {f}");
            }
        }
        // Exactly half a unit either side of zero.
        assert_eq!(q16(1, 1 << 15), 1);
        assert_eq!(q16(-1, 1 << 15), -1);
        assert_eq!(q16(1, (1 << 15) - 1), 0);
    }
}
