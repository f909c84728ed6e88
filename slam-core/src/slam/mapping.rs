//! The depth scans into the map: at once without matching; with it, through the sweep,
//! each scan written as it leaves.

use super::{Counters, Slam, SlamConfig};

use crate::frame::DepthScan;
use crate::grid::BeamWriter;
#[cfg(feature = "matching")]
use crate::matcher::{Sweep, SWEEP_TICKS};
use crate::pose::{mul_q16, Pose};

impl<const W: usize, const H: usize> Slam<W, H> {
    #[cfg(feature = "matching")]
    /// With matching on: the scan joins the sweep, the scan leaving the sweep goes into
    /// the map (so the map never holds a beam the sweep matches against it), and the
    /// sweep is matched, now or, deferred, by [`Slam::search_match`] and
    /// [`Slam::finish_match`]. Returns the cells written.
    pub(super) fn sweep_scan(&mut self, scan: &DepthScan, then: &Pose) -> u32 {
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
    ///
    /// [`Estimator::heading_matchable`]: crate::estimator::Estimator::heading_matchable
    #[cfg(feature = "matching")]
    #[cold]
    #[inline(never)]
    pub(super) fn withhold_leaving(&mut self) {
        if self.sweep.forget_leaving() {
            self.counters.scans_withheld += 1;
        }
    }

    /// On a tick that brings the sweep no scan, writes into the map the scans that have
    /// been in it for [`SWEEP_TICKS`] ticks, as a scan coming in would have pushed them
    /// out ([`Sweep::expired`]), or lets them go unmapped while the heading is too unsure
    /// to match ([`Estimator::heading_matchable`]); returns the cells written. Without
    /// matching, nothing.
    ///
    /// [`Estimator::heading_matchable`]: crate::estimator::Estimator::heading_matchable
    #[cold]
    #[inline(never)]
    pub(super) fn expire_sweep(&mut self) -> u32 {
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

    pub(super) fn map_scan(&mut self, scan: &DepthScan, pose: &Pose) -> u32 {
        map_scan(
            &mut self.map.beams(),
            &self.config,
            &mut self.counters,
            scan,
            pose,
        )
    }
}

/// Puts this tick's scan, taken at `then`, into the sweep; the scan it pushes out goes
/// into the grid, at its pose carried by any recorded correction. Returns the cells that
/// one wrote, `None` if none left. The leaving scan is written where it lies in the
/// ring, before its slot is taken: moved out by value it would be copied byte by byte.
/// Not generic over the grid's size (as [`carry_sweep_and_history`]).
///
/// [`carry_sweep_and_history`]: super::carry_sweep_and_history
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
