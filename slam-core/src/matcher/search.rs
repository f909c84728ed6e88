//! The fine level: every translation of the window at every heading, scored by integer
//! lookups (through the footprint) and adds, headings from the prediction outwards and
//! skipped when their bound cannot reach a weight in the surface.
//!
//! The search goes in pieces, each a few hundred microseconds on the M0+ at most: a
//! heading's bound, then its translations [`ENDS_A_PIECE`] beam ends at a time, so that a
//! caller can let other work run between them.

use super::divide::Divider;
use super::footprint::{Footprint, FOOTPRINT};
use super::score::ScoreTable;
use super::sweep::{q16, SweepPoint};
use super::{MatchStats, MatcherConfig};
use crate::angle::Angle;
use crate::grid::GridView;
use crate::pose::Pose;

/// A heading's scores were never computed: its bound showed none could carry weight.
pub(super) const PRUNED: i32 = i32::MIN;

/// Beam ends scored at every translation in one piece of the search.
pub const ENDS_A_PIECE: usize = 16;

/// Scores of every candidate pose: `[heading][y step][x step]`, the prediction in the
/// middle of each axis.
pub(super) type Surface<const SIDE: usize, const TURNS: usize> = [[[i32; SIDE]; SIDE]; TURNS];

/// Where a search has got.
#[derive(Clone, Copy, Debug)]
pub(super) struct Progress {
    /// Headings finished, in search order (the prediction's first, then alternately
    /// either side: the best is usually near the middle, which lets the bound prune the
    /// rest).
    pub headings: usize,
    /// Beam ends of the heading in hand scored so far; `None` before its bound.
    pub ends: Option<usize>,
    /// The best score so far.
    pub best: i32,
    /// The work done.
    pub stats: MatchStats,
}

impl Progress {
    /// A search not yet begun.
    pub fn new(points: usize) -> Progress {
        Progress {
            headings: 0,
            ends: None,
            best: PRUNED,
            stats: MatchStats {
                points: points as u32,
                ..MatchStats::default()
            },
        }
    }
}

/// The search of `points` around `prediction` on `map`, one piece at a time.
pub(super) struct Search<'a, const SIDE: usize> {
    pub map: &'a GridView<'a>,
    /// What an end scores in each cell of `map`.
    pub table: &'a ScoreTable,
    pub points: &'a [SweepPoint],
    /// Each end's footprint at the heading in hand: filled for the bound, kept for the
    /// translations.
    pub feet: &'a mut [Footprint<SIDE>],
    pub prediction: &'a Pose,
    pub config: &'a MatcherConfig,
    /// The score drop past which a candidate's weight is zero: a heading whose bound is
    /// that far below the best so far changes nothing in the result, so skipping it keeps
    /// the covariance exact.
    pub cutoff: i32,
}

impl<const SIDE: usize> Search<'_, SIDE> {
    /// Does the next piece of the search into `surface` (a pruned heading holds
    /// [`PRUNED`] throughout). `Some(true)` once every heading is done; `None` if the
    /// window is wider than the footprint allows.
    pub fn piece<const TURNS: usize>(
        &mut self,
        surface: &mut Surface<SIDE, TURNS>,
        progress: &mut Progress,
    ) -> Option<bool> {
        if progress.headings >= TURNS {
            return Some(true);
        }
        let n = progress.headings as i32;
        let offset = if n % 2 == 1 { n / 2 + 1 } else { -(n / 2) };
        let k = usize::try_from(offset + (TURNS / 2) as i32).ok()?;
        let scores = surface.get_mut(k)?;
        let heading = self.prediction.heading
            + Angle::from_millidegrees(i64::from(offset) * i64::from(self.config.step_mdeg));
        let place = Place::new::<SIDE>(self.map, self.prediction, self.config, heading);
        let stats = &mut progress.stats;
        match progress.ends {
            None => {
                // Coarse: the bound over the window, from each end's footprint.
                let divider = Divider::new(place.cell)?;
                let mut bound = 0i32;
                for (foot, p) in self.feet.iter_mut().zip(self.points) {
                    let low = place.of(p);
                    if !foot.fill(self.map, self.table, low, self.config.step_mm, &divider) {
                        return None;
                    }
                    stats.lookups += foot.lookups;
                    bound += i32::from(foot.max) * place.cell * place.cell;
                }
                if progress.best != PRUNED && bound <= progress.best - self.cutoff {
                    *scores = [[PRUNED; SIDE]; SIDE];
                    stats.headings_pruned += 1;
                    progress.headings += 1;
                } else {
                    *scores = [[0; SIDE]; SIDE];
                    progress.ends = Some(0);
                }
            }
            Some(from) => {
                let to = from.saturating_add(ENDS_A_PIECE).min(self.points.len());
                for foot in self.feet.get(from..to).unwrap_or(&[]) {
                    if foot.scores_any {
                        add_translations(scores, foot, place.cell);
                        stats.adds += (SIDE * SIDE) as u32;
                    }
                }
                if to < self.points.len() {
                    progress.ends = Some(to);
                } else {
                    for row in scores.iter() {
                        for &s in row.iter() {
                            progress.best = progress.best.max(s);
                        }
                    }
                    stats.headings_searched += 1;
                    progress.headings += 1;
                    progress.ends = None;
                }
            }
        }
        Some(progress.headings >= TURNS)
    }
}

/// Where the window's lowest translation puts a beam end at one heading, in millimetres
/// from the grid's corner.
struct Place {
    cell: i32,
    low_x: i32,
    low_y: i32,
    sin: i32,
    cos: i32,
}

impl Place {
    fn new<const SIDE: usize>(
        map: &GridView,
        prediction: &Pose,
        config: &MatcherConfig,
        heading: Angle,
    ) -> Place {
        let geometry = map.geometry();
        let half_side = (SIDE / 2) as i32;
        Place {
            cell: geometry.cell_mm,
            // The prediction's place from the grid's corner, less half the window.
            low_x: prediction.x_mm() - geometry.origin_x_mm - half_side * config.step_mm,
            low_y: prediction.y_mm() - geometry.origin_y_mm - half_side * config.step_mm,
            sin: heading.sin(),
            cos: heading.cos(),
        }
    }

    #[inline]
    fn of(&self, p: &SweepPoint) -> (i32, i32) {
        (
            self.low_x + q16(p.right_mm, self.cos) + q16(p.forward_mm, self.sin),
            self.low_y - q16(p.right_mm, self.sin) + q16(p.forward_mm, self.cos),
        )
    }
}

/// Adds one end's score at every translation to `scores`: interpolated along x in each
/// row of its block, then between rows along y, in cells squared (`cell^2` per point of
/// class score). Every row of the block is worked whether the translations reach it or
/// not (a few multiplies more, and no zeroed scratch); indices are clamped into the
/// block, which they never leave, so that none is checked.
#[inline]
fn add_translations<const SIDE: usize>(
    scores: &mut [[i32; SIDE]; SIDE],
    f: &Footprint<SIDE>,
    cell: i32,
) {
    let last = FOOTPRINT - 2;
    // Along x: each block row at each x translation.
    let along: [[i32; SIDE]; FOOTPRINT] = core::array::from_fn(|r| {
        let row = f.scores.get(r).copied().unwrap_or_default();
        core::array::from_fn(|i| {
            let c = f.x.cell.get(i).map_or(0, |&c| usize::from(c).min(last));
            let past = f.x.past.get(i).map_or(0, |&p| i32::from(p));
            let (lo, hi) = (i32::from(row[c]), i32::from(row[c + 1]));
            lo * cell + (hi - lo) * past
        })
    });
    // Between each row and the next: the lower one's share and the rise to the upper.
    let base: [[i32; SIDE]; FOOTPRINT - 1] = core::array::from_fn(|r| along[r].map(|a| a * cell));
    let rise: [[i32; SIDE]; FOOTPRINT - 1] =
        core::array::from_fn(|r| core::array::from_fn(|i| along[r + 1][i] - along[r][i]));
    for ((row, &r), &past) in scores.iter_mut().zip(f.y.cell.iter()).zip(f.y.past.iter()) {
        let r = usize::from(r).min(last);
        let past = i32::from(past);
        for ((s, &b), &d) in row.iter_mut().zip(base[r].iter()).zip(rise[r].iter()) {
            *s += b + d * past;
        }
    }
}
