//! The sweep: the last ticks' depth scans, each with the pose it was taken at, so that a
//! second of beams can be matched as one scan.
//!
//! Eight beams over 45 degrees pin little alone; ten ticks of them, placed relative to each
//! other by the odometry, see a corner or two walls. The poses stored are the believed
//! ones; only their differences matter (the sweep is matched relative to its newest pose),
//! and a correction that moves the believed past moves these too ([`Sweep::carry`]), so
//! those differences stay the odometry's.

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
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub struct Sweep<const N: usize> {
    scans: [Option<SweepScan>; N],
    /// Slot the next scan goes into.
    next: usize,
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
        }
    }

    /// Forgets every scan.
    pub fn clear(&mut self) {
        self.scans = [None; N];
        self.next = 0;
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
        let left = self.leaving().copied();
        self.push_in_place(tick, &pose, &scan);
        left
    }

    /// The scan the next push takes out, if the ring is full.
    pub fn leaving(&self) -> Option<&SweepScan> {
        self.scans.get(self.next)?.as_ref()
    }

    /// [`Sweep::push`] without handing the oldest back: written into its slot field by
    /// field, where a scan moved in and out by value is copied byte by byte on the M0+.
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
    }

    /// The newest scan: the sweep's reference.
    pub fn newest(&self) -> Option<&SweepScan> {
        let newest = if self.next == 0 {
            N.checked_sub(1)?
        } else {
            self.next - 1
        };
        self.scans.get(newest)?.as_ref()
    }

    /// The scans held, oldest first.
    pub fn oldest_first(&self) -> impl Iterator<Item = &SweepScan> {
        let (newer, older) = self.scans.split_at(self.next.min(N));
        older.iter().chain(newer.iter()).flatten()
    }

    /// Takes the oldest scan out.
    pub fn pop_oldest(&mut self) -> Option<SweepScan> {
        for i in 0..N {
            let at = if self.next + i >= N {
                self.next + i - N
            } else {
                self.next + i
            };
            if let Some(scan) = self.scans.get_mut(at).and_then(Option::take) {
                return Some(scan);
            }
        }
        None
    }

    /// Moves every stored pose by `motion`, as a correction moves the believed past.
    pub fn carry(&mut self, motion: &RigidMotion) {
        for s in self.scans.iter_mut().flatten() {
            s.pose = motion.apply(&s.pose);
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
        for s in self.oldest_first() {
            // The scan's place relative to the reference, in millimetres (a sweep spans
            // centimetres, so 32 bits hold every product below).
            let dx = s.pose.x_mm().saturating_sub(reference.x_mm());
            let dy = s.pose.y_mm().saturating_sub(reference.y_mm());
            for (range, angle) in s.scan.ranges_mm.iter().zip(beam_angles.iter()) {
                let Some(range) = range.filter(|&r| r < max_range_mm) else {
                    continue;
                };
                let Some(slot) = out.get_mut(written) else {
                    return written;
                };
                let range = i32::from(range);
                let dir = s.pose.heading + *angle;
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
    use super::q16;

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
