//! What the map gave the filter over a run: scan matches used and refused by cause, and
//! the drives at a wall that measured the flow sensor's scale, as `run --json` reports
//! them under `matching` (modes `match` and `slam`).

use serde::Serialize;
use slam_core::estimator::MatchCounters;
use slam_core::wall_rate::WallCounters;

/// The matcher's and the walls' counts at the end of a run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct MatchingFigures {
    /// Matches that updated the filter.
    pub used: u32,
    /// Sweeps and matches refused, by cause.
    pub refused: RefusedMatches,
    /// Straight drives at a flat wall judged for the flow sensor's scale
    /// ([`slam_core::wall_rate`]), by what the filter made of them.
    pub wall_drives: WallDrives,
}

/// Sweeps and matches refused, by cause ([`MatchCounters`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct RefusedMatches {
    /// Sweeps with no beam end.
    pub empty: u32,
    /// Sweeps with too few beam ends to match.
    pub too_few_points: u32,
    /// Sweeps whose ends fell on nothing the map knows.
    pub no_fit: u32,
    /// Matches that pinned no direction.
    pub nothing_pinned: u32,
    /// Matches beyond the filter's gate.
    pub gate: u32,
    /// Sweeps older than the pose history, or whose window the search cannot hold.
    pub other: u32,
}

/// The drives at a wall, by outcome ([`WallCounters`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct WallDrives {
    /// Measurements the filter took.
    pub taken: u32,
    /// Measurements beyond its gate, or moving the pose too far.
    pub refused: u32,
    /// Measurements it did not need: it knew the scale better already.
    pub known: u32,
}

impl MatchingFigures {
    /// The figures from the core's match counters and the walls' drive counters.
    pub fn of(matches: &MatchCounters, walls: &WallCounters) -> MatchingFigures {
        MatchingFigures {
            used: matches.used,
            refused: RefusedMatches {
                empty: matches.empty,
                too_few_points: matches.too_few_points,
                no_fit: matches.no_fit,
                nothing_pinned: matches.nothing_pinned,
                gate: matches.gate,
                other: matches.other,
            },
            wall_drives: WallDrives {
                taken: walls.taken,
                refused: walls.refused,
                known: walls.known,
            },
        }
    }
}
