//! How a map cell is squeezed into one byte.

use slam_core::{Evidence, LogOdds, Occupancy};

/// How a map cell is squeezed into one byte without changing what it means.
///
/// A cell is sent as it is held, its log odds in sixteenths (the core's one-byte cell),
/// nudged only where thresholds past a byte's reach would hide a belief: the viewer's map
/// agrees with the robot's belief for belief.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CellScale {
    /// A cell below `-free_below` is free, cell units (0 to 127).
    pub free_below: i8,
    /// A cell above `occupied_above` is occupied, cell units (0 to 126).
    pub occupied_above: i8,
}

impl CellScale {
    /// The thresholds for a grid using `evidence`, kept where both beliefs stay reachable
    /// in an `i8`.
    pub fn new(evidence: &Evidence) -> CellScale {
        CellScale {
            free_below: evidence.free_below.clamp(0, 127),
            occupied_above: evidence.occupied_above.clamp(0, 126),
        }
    }

    /// The byte sent for a cell of `log_odds` that the robot believes is `belief`.
    pub fn encode(&self, log_odds: LogOdds, belief: Occupancy) -> i8 {
        // In i16 so that no threshold, however set, can overflow.
        let shifted = i16::from(log_odds);
        let free = (self.free_below as i16).clamp(0, 127);
        let occupied = (self.occupied_above as i16).clamp(0, 126);
        let cell = match belief {
            Occupancy::Free => shifted.min(-free - 1),
            Occupancy::Occupied => shifted.max(occupied + 1),
            Occupancy::Unknown => shifted.clamp(-free, occupied),
        };
        cell.clamp(i8::MIN as i16, i8::MAX as i16) as i8
    }

    /// What a received cell byte means.
    pub fn belief(&self, cell: i8) -> Occupancy {
        if (cell as i16) < -(self.free_below as i16) {
            Occupancy::Free
        } else if cell > self.occupied_above {
            Occupancy::Occupied
        } else {
            Occupancy::Unknown
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cells_keep_their_belief() {
        let scale = CellScale::new(&Evidence::SEED);
        let e = Evidence::SEED;
        assert_eq!(
            (scale.free_below, scale.occupied_above),
            (e.free_below, e.occupied_above)
        );
        for l in -e.clamp..=e.clamp {
            let belief = if l < -e.free_below {
                Occupancy::Free
            } else if l > e.occupied_above {
                Occupancy::Occupied
            } else {
                Occupancy::Unknown
            };
            let q = scale.encode(l, belief);
            assert_eq!(scale.belief(q), belief, "log odds {l}");
            // A cell is sent as it is.
            assert_eq!(q, l);
        }
        // Thresholds past the byte's reach still leave room for both beliefs.
        let odd = Evidence {
            free_below: 127,
            occupied_above: 127,
            ..Evidence::SEED
        };
        let s = CellScale::new(&odd);
        assert_eq!(
            s.belief(s.encode(i8::MIN, Occupancy::Free)),
            Occupancy::Free
        );
        assert_eq!(
            s.belief(s.encode(127, Occupancy::Occupied)),
            Occupancy::Occupied
        );
        assert_eq!(
            s.belief(s.encode(127, Occupancy::Unknown)),
            Occupancy::Unknown
        );
    }
}
