//! The seed's evidence in one-byte cells believes what the seed's evidence believes.
//!
//! What the map does with a cell (the matcher's scores, the guard, known %, the pictures)
//! depends only on its belief: free, occupied or unknown. So the one-byte cell is held to
//! the seed's cell belief for belief, over every sequence of hits and misses up to a
//! length, by walking the pairs of cell values both can reach together (a finite set,
//! since both saturate), breadth first.

use std::collections::{HashMap, VecDeque};

use slam_core::{Evidence, GridGeometry, GridMap, Occupancy};

/// A cell model in whole units: hit, miss, clamp, and the thresholds free and occupied.
#[derive(Clone, Copy, Debug)]
struct Rule {
    hit: i32,
    miss: i32,
    clamp: i32,
    free_below: i32,
    occupied_above: i32,
}

impl Rule {
    fn update(&self, l: i32, hit: bool) -> i32 {
        let amount = if hit { self.hit } else { self.miss };
        (l + amount).clamp(-self.clamp, self.clamp)
    }

    fn belief(&self, l: i32) -> Occupancy {
        if l < -self.free_below {
            Occupancy::Free
        } else if l > self.occupied_above {
            Occupancy::Occupied
        } else {
            Occupancy::Unknown
        }
    }
}

/// The seed as it states it, in hundredths: +0.85, -0.4, +-8, +-1 (exact in integers).
const STATED: Rule = Rule {
    hit: 85,
    miss: -40,
    clamp: 800,
    free_below: 100,
    occupied_above: 100,
};

/// The seed's evidence in a two-byte Q8 cell: +218, -102, +-2048, +-256.
const Q8: Rule = Rule {
    hit: 218,
    miss: -102,
    clamp: 2048,
    free_below: 256,
    occupied_above: 256,
};

/// The core's seed evidence, as the core's own grid applies it.
fn core_rule() -> Rule {
    let e = Evidence::SEED;
    Rule {
        hit: e.hit.into(),
        miss: e.miss.into(),
        clamp: e.clamp.into(),
        free_below: e.free_below.into(),
        occupied_above: e.occupied_above.into(),
    }
}

/// The shortest sequence of hits (`h`) and misses (`m`) after which `a` and `b` believe
/// differently, or `None` when none exists.
fn first_disagreement(a: Rule, b: Rule) -> Option<String> {
    let mut seen: HashMap<(i32, i32), String> = HashMap::new();
    let mut queue = VecDeque::from([(0, 0)]);
    seen.insert((0, 0), String::new());
    while let Some((x, y)) = queue.pop_front() {
        let path = seen[&(x, y)].clone();
        if a.belief(x) != b.belief(y) {
            return Some(path);
        }
        for (hit, letter) in [(true, 'h'), (false, 'm')] {
            let next = (a.update(x, hit), b.update(y, hit));
            if let std::collections::hash_map::Entry::Vacant(slot) = seen.entry(next) {
                slot.insert(format!("{path}{letter}"));
                queue.push_back(next);
            }
        }
    }
    None
}

#[test]
fn the_core_cell_follows_its_rule() {
    // The model below is the grid's own arithmetic: every value a cell can reach, by `add`.
    let rule = core_rule();
    let geometry = GridGeometry {
        cell_mm: 50,
        origin_x_mm: 0,
        origin_y_mm: 0,
    };
    let mut grid: GridMap<1, 1> = GridMap::new(geometry, Evidence::SEED);
    let mut l = 0;
    let mut rng = 0x2545_f491_4f6c_dd1d_u64;
    for _ in 0..5_000 {
        rng ^= rng << 13;
        rng ^= rng >> 7;
        rng ^= rng << 17;
        let hit = rng.is_multiple_of(3);
        let amount = if hit {
            Evidence::SEED.hit
        } else {
            Evidence::SEED.miss
        };
        assert!(grid.add(0, 0, amount));
        l = rule.update(l, hit);
        assert_eq!(grid.log_odds(0, 0).map(i32::from), Some(l));
        assert_eq!(grid.occupancy(0, 0), rule.belief(l));
    }
}

#[test]
fn one_byte_cells_believe_what_the_seed_believes() {
    // Against the seed as stated, the one-byte cell agrees as long as the Q8 cell did:
    // both first differ after four hits and six misses, which sums to exactly +1.0 in the
    // stated rule (not above it) and lands just above the threshold in both integer cells.
    let stated = first_disagreement(STATED, core_rule()).expect("a tie the integers break");
    assert_eq!(stated, "hhhhmmmmmm");
    assert_eq!(
        first_disagreement(STATED, Q8).as_deref(),
        Some("hhhhmmmmmm")
    );
    // Against the Q8 cell, no sequence of fewer than 25 beams tells them apart.
    let q8 = first_disagreement(Q8, core_rule()).expect("cells of different sizes");
    assert!(q8.len() >= 25, "differs from the Q8 cell after {q8}");
}

#[test]
fn each_value_rounded_alone_would_not() {
    // The check above can fail: the seed's values each rounded to the nearest sixteenth
    // (+14, -6, thresholds 16) turn a cell hit once free only at the sixth miss, not the
    // fifth.
    let rounded = Rule {
        hit: 14,
        miss: -6,
        clamp: 127,
        free_below: 16,
        occupied_above: 16,
    };
    assert_eq!(first_disagreement(Q8, rounded).as_deref(), Some("hmmmmm"));
}
