//! The fine level: every translation of the window at every heading, scored by integer
//! lookups (through the footprint) and adds, headings from the prediction outwards and
//! skipped when their bound cannot reach a weight in the surface.
//!
//! The search goes in pieces, each a few hundred microseconds on the M0+ at most: a
//! heading's bound, then its translations [`ENDS_A_PIECE`] beam ends at a time (the last
//! piece spreads the ends' sums over them, see `spread`), so that a caller can let other
//! work run between them.

use super::footprint::{Footprint, Window};
use super::score::ScoreTable;
use super::spread::Patterns;
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

/// What a search works out once, when it first sees the map.
#[derive(Clone, Copy, Debug)]
pub(super) struct Setup {
    /// What an end scores in each cell of the map.
    pub table: ScoreTable,
    /// The translation window on the map's cells.
    pub window: Window,
    /// The score drop past which a candidate's weight is zero: a heading whose bound is
    /// that far below the best so far changes nothing in the result, so skipping it keeps
    /// the covariance exact.
    pub cutoff: i32,
}

/// The search of `points` around `prediction` on `map`, one piece at a time.
pub(super) struct Search<'a, const SIDE: usize> {
    pub map: &'a GridView<'a>,
    pub setup: &'a Setup,
    pub points: &'a [SweepPoint],
    /// Each end's footprints on either side of the prediction's heading (`[0]` for it
    /// and the headings to its right, as the search goes out): filled for a heading's
    /// bound, kept for its translations and, along the same side, the next heading.
    pub feet: &'a mut [[Footprint; 2]],
    pub prediction: &'a Pose,
    pub config: &'a MatcherConfig,
    /// The heading in hand's ends, summed by the patterns of their runs.
    pub patterns: &'a mut Patterns,
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
        let window = &self.setup.window;
        let cell = window.cell;
        let stats = &mut progress.stats;
        let side = usize::from(offset < 0);
        match progress.ends {
            None => {
                let heading = self.prediction.heading
                    + Angle::from_millidegrees(
                        i64::from(offset) * i64::from(self.config.step_mdeg),
                    );
                let place = Place::new::<SIDE>(self.map, self.prediction, self.config, heading);
                // Coarse: the bound over the window, from each end's footprint.
                let mut bound = 0i32;
                for (sides, p) in self.feet.iter_mut().zip(self.points) {
                    let foot = &mut sides[side];
                    stats.lookups += foot.fill(self.map, &self.setup.table, place.of(p), window);
                    bound += i32::from(foot.max) * cell * cell;
                    if offset == 0 {
                        // The other side's first heading starts from this one's blocks.
                        sides[1] = sides[0];
                    }
                }
                if progress.best != PRUNED && bound <= progress.best - self.setup.cutoff {
                    *scores = [[PRUNED; SIDE]; SIDE];
                    stats.headings_pruned += 1;
                    progress.headings += 1;
                } else {
                    *scores = [[0; SIDE]; SIDE];
                    self.patterns.clear();
                    progress.ends = Some(0);
                }
            }
            Some(from) => {
                let to = from.saturating_add(ENDS_A_PIECE).min(self.points.len());
                for sides in self.feet.get(from..to).unwrap_or(&[]) {
                    let foot = &sides[side];
                    if foot.scores_any {
                        self.patterns.add(scores, foot, window);
                        stats.adds += (SIDE * SIDE) as u32;
                    }
                }
                if to < self.points.len() {
                    progress.ends = Some(to);
                } else {
                    self.patterns.spread(scores, &window.runs);
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
