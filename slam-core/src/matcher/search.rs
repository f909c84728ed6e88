//! The fine level: every translation of the window at every heading, scored by integer
//! lookups (through the footprint) and adds, headings from the prediction outwards and
//! skipped when their bound cannot reach a weight in the surface.

use super::divide::Divider;
use super::footprint::{Footprint, FOOTPRINT};
use super::sweep::{q16, SweepPoint};
use super::{MatchStats, MatcherConfig, SWEEP_POINTS};
use crate::angle::Angle;
use crate::grid::GridMap;
use crate::pose::Pose;

/// A heading's scores were never computed: its bound showed none could carry weight.
pub(super) const PRUNED: i32 = i32::MIN;

/// Scores of every candidate pose: `[heading][y step][x step]`, the prediction in the
/// middle of each axis.
pub(super) type Surface<const SIDE: usize, const TURNS: usize> = [[[i32; SIDE]; SIDE]; TURNS];

/// Fills `surface` around `prediction`; a pruned heading holds [`PRUNED`] throughout.
/// `None` if the window is wider than the footprint allows.
///
/// `cutoff` is the score drop past which a candidate's weight is zero: a heading whose
/// bound is that far below the best so far changes nothing in the result, so skipping it
/// keeps the covariance exact.
pub(super) fn search<const W: usize, const H: usize, const SIDE: usize, const TURNS: usize>(
    map: &GridMap<W, H>,
    points: &[SweepPoint],
    prediction: &Pose,
    config: &MatcherConfig,
    cutoff: i32,
    surface: &mut Surface<SIDE, TURNS>,
) -> Option<MatchStats> {
    let geometry = map.geometry();
    let cell = geometry.cell_mm;
    let divider = Divider::new(cell)?;
    // Each end's footprint at the heading in hand: worked out once for the bound and kept
    // for the fine level (a few kilobytes of stack).
    let mut feet = [Footprint::<SIDE>::EMPTY; SWEEP_POINTS];
    let feet = feet.get_mut(..points.len())?;
    let half_side = (SIDE / 2) as i32;
    let half_turns = (TURNS / 2) as i32;
    // The prediction's place from the grid's corner, less half the window.
    let low_x = prediction.x_mm() - geometry.origin_x_mm - half_side * config.step_mm;
    let low_y = prediction.y_mm() - geometry.origin_y_mm - half_side * config.step_mm;
    let mut stats = MatchStats {
        points: points.len() as u32,
        ..MatchStats::default()
    };
    let mut best = PRUNED;
    // The prediction's heading first, then alternately either side: the best is usually
    // near the middle, which lets the bound prune the rest.
    for n in 0..TURNS as i32 {
        let offset = if n % 2 == 1 { n / 2 + 1 } else { -(n / 2) };
        let Ok(k) = usize::try_from(offset + half_turns) else {
            continue;
        };
        let Some(scores) = surface.get_mut(k) else {
            continue;
        };
        let heading = prediction.heading
            + Angle::from_millidegrees(i64::from(offset) * i64::from(config.step_mdeg));
        let (sin, cos) = (heading.sin(), heading.cos());
        let place = |p: &SweepPoint| {
            (
                low_x + q16(p.right_mm, cos) + q16(p.forward_mm, sin),
                low_y - q16(p.right_mm, sin) + q16(p.forward_mm, cos),
            )
        };
        // Coarse: the bound over the window, from each end's footprint.
        let mut bound = 0i32;
        for (f, p) in feet.iter_mut().zip(points) {
            if !f.fill(map, &config.scores, place(p), config.step_mm, &divider) {
                return None;
            }
            stats.lookups += f.lookups;
            bound += i32::from(f.max) * cell * cell;
        }
        if best != PRUNED && bound <= best - cutoff {
            *scores = [[PRUNED; SIDE]; SIDE];
            stats.headings_pruned += 1;
            continue;
        }
        // Fine: every translation, interpolated along x in each row of the block, then
        // between rows along y. Scores come out in cells squared (`cell^2` per point of
        // class score).
        *scores = [[0; SIDE]; SIDE];
        for f in feet.iter() {
            // Only the block's rows the translations reach (the rest were not filled).
            let rows = f.y.cell.last().map_or(0, |&r| usize::from(r) + 2);
            let mut along = [[0i32; SIDE]; FOOTPRINT];
            for (out, row) in along.iter_mut().zip(f.scores.iter()).take(rows) {
                for ((o, &c), &past) in out.iter_mut().zip(f.x.cell.iter()).zip(f.x.past.iter()) {
                    let c = usize::from(c);
                    let lo = row.get(c).map_or(0, |&v| i32::from(v));
                    let hi = row.get(c + 1).map_or(0, |&v| i32::from(v));
                    *o = lo * cell + (hi - lo) * i32::from(past);
                }
            }
            for ((row, &r), &past) in scores.iter_mut().zip(f.y.cell.iter()).zip(f.y.past.iter()) {
                let r = usize::from(r);
                let (Some(lo), Some(hi)) = (along.get(r), along.get(r + 1)) else {
                    continue;
                };
                let past = i32::from(past);
                for ((s, &a), &b) in row.iter_mut().zip(lo.iter()).zip(hi.iter()) {
                    *s += a * cell + (b - a) * past;
                }
            }
            stats.adds += (SIDE * SIDE) as u32;
        }
        for row in scores.iter() {
            for &s in row.iter() {
                best = best.max(s);
            }
        }
        stats.headings_searched += 1;
    }
    Some(stats)
}
