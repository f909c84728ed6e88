//! The log-odds grid and its cell walk against the `f64` reference.
//!
//! **Boundary grazing.** The core maps a beam between whole-millimetre end points computed
//! with Q16 sines; the reference uses the exact `f64` end points. They differ by at most
//! 0.6 mm per axis (0.5 mm rounding + 1700 mm x 2e-5 sine error + 1700 mm x 0.5 mdeg of
//! fan-angle rounding), so a cell the exact beam passes within 1 mm of (or the cell of an end
//! point within 1 mm of a cell edge) may legitimately be updated by one and not the other.
//! The reference therefore keeps, per cell, an *interval* `[lo, hi]` of the log odds any such
//! choice could give (see `reference::RefGrid`): beams that cross a cell with more than
//! `EPS_MM` to spare update both ends, beams that only come within `EPS_MM` of it widen the
//! interval. The core's value must lie in the interval (the reference adds the core's own
//! evidence, so there is no rounding to allow for), and wherever the interval sits inside
//! one class, the core's class must be that class. Cells no beam came near are compared
//! exactly.

mod reference;

use proptest::prelude::*;
use reference::{bits_to_rad, fan_angles, Class, Geometry, RefGrid};
use slam_core::grid::CellWalk;
use slam_core::{DepthScan, Evidence, GridGeometry, GridMap, Occupancy, Pose, SensorFrame, Slam};

/// Per-axis slack between the core's rounded beam end points and the exact ones, in mm.
const EPS_MM: f64 = 1.0;

/// The core's cell in log-odds units.
fn log_odds(cell: i8) -> f64 {
    f64::from(cell) / f64::from(slam_core::grid::LOG_ODDS_ONE)
}

/// The reference adds the core's evidence in sixteenths, which `f64` holds exactly: what is
/// left is noise far below a sixteenth.
const TOLERANCE: f64 = 1e-9;

fn seed_geometry() -> GridGeometry {
    world::shipped::seed_robot().config.geometry
}

fn config() -> ProptestConfig {
    ProptestConfig {
        failure_persistence: None,
        ..ProptestConfig::default()
    }
}

fn core_class(o: Occupancy) -> Class {
    match o {
        Occupancy::Free => Class::Free,
        Occupancy::Occupied => Class::Occupied,
        Occupancy::Unknown => Class::Unknown,
    }
}

/// The class every value in `[lo, hi]` has, if they all have the same one.
fn decided_class(lo: f64, hi: f64) -> Option<Class> {
    let (a, b) = (reference::classify(lo), reference::classify(hi));
    // Classes are ordered Free < Unknown < Occupied along the axis, so equal ends decide.
    (a == b).then_some(a)
}

/// A whole-millimetre sensor position: inside the grid, or anywhere around it.
fn position() -> impl Strategy<Value = i32> {
    prop_oneof![
        -150i32..2150,
        -1500i32..3650,
        (0i32..47).prop_map(|k| -150 + 50 * k)
    ]
}

/// A heading: any binary angle, or one that makes some beam of the fan axis-aligned.
fn heading() -> impl Strategy<Value = u32> {
    let fan = slam_core::slam::fan(45_000);
    prop_oneof![
        3 => any::<u32>(),
        1 => (0u32..4, 0usize..8).prop_map(move |(q, i)| (q << 30).wrapping_sub(fan[i].bits())),
    ]
}

fn range() -> impl Strategy<Value = Option<u16>> {
    prop_oneof![
        1 => Just(None),
        8 => (0u16..4000).prop_map(Some),
        1 => prop_oneof![Just(0u16), Just(1699), Just(1700), Just(u16::MAX)].prop_map(Some),
    ]
}

#[derive(Clone, Debug)]
struct Shot {
    x_mm: i32,
    y_mm: i32,
    heading_bits: u32,
    ranges: [Option<u16>; 8],
    repeat: u8,
}

fn shot() -> impl Strategy<Value = Shot> {
    (
        position(),
        position(),
        heading(),
        proptest::array::uniform8(range()),
        prop_oneof![4 => Just(1u8), 1 => 2u8..=6],
    )
        .prop_map(|(x_mm, y_mm, heading_bits, ranges, repeat)| Shot {
            x_mm,
            y_mm,
            heading_bits,
            ranges,
            repeat,
        })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..config() })]

    /// Random scans mapped by `Slam::step` (external pose, so exactly at the given pose) into
    /// `GridMap<46, 46>`, and by the reference: for every cell,
    /// the core's log odds lie in `[lo, hi]`, its class is the reference's wherever that is
    /// decided, and it never leaves the clamp.
    #[test]
    fn scans_match_reference(shots in proptest::collection::vec(shot(), 1..10)) {
        let config = unchecked(world::shipped::seed_robot().config);
        let max = config.depth.max_range_mm as f64;
        let mut slam: Slam<46, 46> = Slam::new(config, Pose::default()).unwrap();
        let mut grid = RefGrid::new(Geometry::SEED, 46, 46);
        let fan = fan_angles();
        for s in &shots {
            let pose = Pose {
                x_um: s.x_mm * 1000,
                y_um: s.y_mm * 1000,
                heading: slam_core::Angle::from_bits(s.heading_bits),
            };
            for _ in 0..s.repeat {
                let mut frame = SensorFrame::empty(100_000);
                frame.external_pose = Some(pose);
                frame.depth = Some(DepthScan { ranges_mm: s.ranges });
                slam.step(&frame);
                for (range, beam) in s.ranges.iter().zip(fan) {
                    if let Some(r) = range {
                        let angle = bits_to_rad(s.heading_bits) + beam;
                        grid.insert_beam((s.x_mm as f64, s.y_mm as f64), angle, *r as f64, max, EPS_MM);
                    }
                }
            }
        }
        let map = slam.map();
        let mut decided = 0;
        for r in 0..46 {
            for c in 0..46 {
                let l = map.log_odds(c, r).unwrap();
                let clamp = Evidence::SEED.clamp;
                prop_assert!((-clamp..=clamp).contains(&l), "cell ({c}, {r}) = {l} beyond the clamp");
                let (lo, hi, n) = grid.cell((c, r));
                let tol = TOLERANCE;
                let v = log_odds(l);
                prop_assert!(
                    v >= lo - tol && v <= hi + tol,
                    "cell ({}, {}): core {} not in reference [{}, {}] +- {} ({} updates)",
                    c, r, v, lo, hi, tol, n
                );
                if let Some(class) = decided_class(lo - tol, hi + tol) {
                    prop_assert_eq!(core_class(map.occupancy(c, r)), class, "cell ({}, {})", c, r);
                    if n > 0 {
                        decided += 1;
                    }
                }
            }
        }
        // The comparison must not be vacuous: a scan that maps a beam from inside the grid
        // decides some cell's class.
        let inside = shots.iter().any(|s| {
            (-100..2100).contains(&s.x_mm) && (-100..2100).contains(&s.y_mm)
                && s.ranges.iter().any(|r| r.is_some_and(|r| r >= 100))
        });
        if inside {
            prop_assert!(decided > 0, "no cell decided");
        }
    }

    /// One cell hit or passed in any order: the same log odds and class as in `f64`.
    #[test]
    fn single_cell_sequence_matches_reference(hits in proptest::collection::vec(any::<bool>(), 0..300)) {
        let mut g: GridMap<1, 1> = GridMap::new(seed_geometry(), Evidence::SEED);
        let mut l = 0.0f64;
        for (n, &hit) in hits.iter().enumerate() {
            g.add(0, 0, if hit { Evidence::SEED.hit } else { Evidence::SEED.miss });
            l = reference::update(l, if hit { reference::HIT } else { reference::MISS });
            let core = g.log_odds(0, 0).unwrap();
            prop_assert!((log_odds(core) - l).abs() <= TOLERANCE, "after {} updates", n + 1);
            prop_assert!((-Evidence::SEED.clamp..=Evidence::SEED.clamp).contains(&core));
            prop_assert_eq!(core_class(g.occupancy(0, 0)), reference::classify(l));
        }
    }
}

/// 10,000 hits on one cell (by `add` and by `insert_beam`) stay at the clamp, 10,000
/// misses at minus the clamp: never beyond it, never wrapped. Evidence at the very limits
/// of `i8` saturates too.
#[test]
fn hammered_cell_saturates_without_wrapping() {
    let geo = seed_geometry();
    let seed = Evidence::SEED;
    let mut g: GridMap<46, 46> = GridMap::new(geo, seed);
    let (c, r) = geo.cell_of(1000, 1000);
    for i in 0..10_000 {
        assert!(g.add(c, r, seed.hit));
        let l = g.log_odds(c, r).unwrap();
        assert_eq!(
            i32::from(l),
            (i32::from(seed.hit) * (i + 1)).min(seed.clamp.into())
        );
    }
    for _ in 0..10_000 {
        // A 10 mm beam: its own cell is the hit cell and is never also passed.
        g.insert_beam((1010, 1010), (1010, 1010), (1010, 1020), true);
        assert_eq!(g.log_odds(c, r), Some(seed.clamp));
        assert_eq!(g.occupancy(c, r), Occupancy::Occupied);
    }
    for _ in 0..10_000 {
        g.insert_beam((1010, 1010), (1010, 1030), (1010, 1040), false);
        let l = g.log_odds(c, r).unwrap();
        assert!((-seed.clamp..=seed.clamp).contains(&l));
    }
    assert_eq!(g.log_odds(c, r), Some(-seed.clamp));
    assert_eq!(g.occupancy(c, r), Occupancy::Free);

    let extreme = Evidence {
        hit: i8::MAX,
        miss: -i8::MAX,
        clamp: i8::MAX,
        free_below: 16,
        occupied_above: 16,
    };
    let mut g: GridMap<2, 2> = GridMap::new(geo, extreme);
    for _ in 0..10_000 {
        g.add(1, 1, i8::MAX);
        assert_eq!(g.log_odds(1, 1), Some(i8::MAX));
    }
    for _ in 0..10_000 {
        g.add(1, 1, i8::MIN);
        assert!(g.log_odds(1, 1).unwrap() >= -i8::MAX);
    }
    assert_eq!(g.log_odds(1, 1), Some(-i8::MAX));
}

// ---------------------------------------------------------------------------------------
// CellWalk
// ---------------------------------------------------------------------------------------

/// Whether the segment (integers, relative to the grid origin) touches a grid line other
/// than by crossing it: an end point on a line, or the segment through a grid corner.
/// Exact, in integers.
fn grazes(cell: i64, f: (i64, i64), t: (i64, i64)) -> bool {
    if [f.0, f.1, t.0, t.1].iter().any(|v| v.rem_euclid(cell) == 0) {
        return true;
    }
    let (dx, dy) = (t.0 - f.0, t.1 - f.1);
    if dx == 0 || dy == 0 {
        return false; // parallel to one axis and off its lines: corners only at end points
    }
    // At each vertical line X = k cell the segment meets, is y on a horizontal line?
    // y = f.1 + (X - f.0) dy / dx; y = l cell  <=>  f.1 dx + (X - f.0) dy = l cell dx.
    let (lo, hi) = (f.0.min(t.0), f.0.max(t.0));
    let mut k = lo.div_euclid(cell) + 1;
    while k * cell < hi {
        let x = k * cell;
        let num = f.1 as i128 * dx as i128 + (x - f.0) as i128 * dy as i128;
        if num.rem_euclid((cell as i128 * dx as i128).abs()) == 0 {
            return true;
        }
        k += 1;
    }
    false
}

fn geometry() -> impl Strategy<Value = GridGeometry> {
    prop_oneof![
        Just(seed_geometry()),
        (7i32..=200, -500i32..500, -500i32..500).prop_map(|(cell_mm, origin_x_mm, origin_y_mm)| {
            GridGeometry {
                cell_mm,
                origin_x_mm,
                origin_y_mm,
            }
        }),
    ]
}

fn point() -> impl Strategy<Value = (i32, i32)> {
    prop_oneof![
        (-5000i32..5000, -5000i32..5000),
        (-200i32..200, -200i32..200),
        // On the seed grid's lines and corners.
        ((-20i32..20), (-20i32..20), 0i32..3).prop_map(|(a, b, k)| match k {
            0 => (-150 + 50 * a, -150 + 50 * b),
            1 => (-150 + 50 * a, 37 * b),
            _ => (13 * a, -150 + 50 * b),
        }),
    ]
}

/// `CellWalk` starts at the start cell, ends at the end cell, moves one 4-connected step
/// at a time, visits no cell twice; it contains every cell the exact segment crosses;
/// any extra cell only touches the segment (at a corner or an end point on a line); and
/// when the segment grazes no grid line or corner it *is* the exact crossing sequence.
fn check_walk(geo: GridGeometry, from: (i32, i32), to: (i32, i32)) -> Result<(), TestCaseError> {
    let walk: Vec<(i32, i32)> = CellWalk::new(&geo, from, to).collect();
    let start = geo.cell_of(from.0, from.1);
    let end = geo.cell_of(to.0, to.1);
    prop_assert_eq!(walk.first(), Some(&start));
    prop_assert_eq!(walk.last(), Some(&end));
    let manhattan = (end.0 - start.0).abs() + (end.1 - start.1).abs();
    prop_assert_eq!(walk.len() as i32, manhattan + 1);
    for pair in walk.windows(2) {
        let d = (pair[1].0 - pair[0].0).abs() + (pair[1].1 - pair[0].1).abs();
        prop_assert_eq!(d, 1, "not 4-connected: {:?}", pair);
    }
    let mut sorted = walk.clone();
    sorted.sort();
    sorted.dedup();
    prop_assert_eq!(sorted.len(), walk.len(), "a cell visited twice");

    let rg = Geometry {
        cell: geo.cell_mm as f64,
        origin_x: geo.origin_x_mm as f64,
        origin_y: geo.origin_y_mm as f64,
    };
    let (a, b) = ((from.0 as f64, from.1 as f64), (to.0 as f64, to.1 as f64));
    let exact = reference::crossed_cells(&rg, a, b);
    for c in &exact {
        prop_assert!(
            walk.contains(c),
            "crossed cell {:?} missing from the walk {:?}",
            c,
            walk
        );
    }
    for c in walk.iter().filter(|c| !exact.contains(c)) {
        prop_assert!(
            reference::segment_meets_box(a, b, rg.square(*c, 1e-6)),
            "walk cell {:?} is nowhere near the segment",
            c
        );
    }
    let rel = |p: (i32, i32)| {
        (
            (p.0 - geo.origin_x_mm) as i64,
            (p.1 - geo.origin_y_mm) as i64,
        )
    };
    if !grazes(geo.cell_mm as i64, rel(from), rel(to)) {
        prop_assert_eq!(&walk, &exact);
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 1500, ..config() })]

    /// Every walk a beam makes (the 32-bit walk): see [`check_walk`].
    #[test]
    fn cell_walk_is_the_exact_crossing(geo in geometry(), from in point(), to in point()) {
        check_walk(geo, from, to)?;
    }

    /// Segments too long for the 32-bit walk (tens of kilometres over cells of metres),
    /// held to the same properties.
    #[test]
    fn long_cell_walk_is_the_exact_crossing(
        cell_mm in 5_000i32..60_000,
        origin in (-500_000i32..500_000, -500_000i32..500_000),
        from in (-2_000_000i32..2_000_000, -2_000_000i32..2_000_000),
        to in (-2_000_000i32..2_000_000, -2_000_000i32..2_000_000),
    ) {
        let geo = GridGeometry { cell_mm, origin_x_mm: origin.0, origin_y_mm: origin.1 };
        check_walk(geo, from, to)?;
    }
}

/// The grazing cases by hand: through a corner, along a line, from a line.
#[test]
fn cell_walk_grazing_examples() {
    let geo = seed_geometry();
    // Through the corner at (0, 0) (cells (2, 2) | (3, 3)): one side cell is added.
    let walk: Vec<_> = CellWalk::new(&geo, (-25, -25), (25, 25)).collect();
    assert_eq!(walk.len(), 3);
    assert_eq!(walk[0], (2, 2));
    assert_eq!(walk[2], (3, 3));
    // Along the line y = 0: the half-open rule keeps it in row 3.
    let walk: Vec<_> = CellWalk::new(&geo, (10, 0), (160, 0)).collect();
    assert_eq!(walk, [(3, 3), (4, 3), (5, 3), (6, 3)]);
    // Leaving downwards from a point on the line y = 0: row 3 (touched), then row 2.
    let walk: Vec<_> = CellWalk::new(&geo, (10, 0), (10, -30)).collect();
    assert_eq!(walk, [(3, 3), (3, 2)]);
}

/// A segment moving +x and -y whose end point lies exactly on a grid corner ends in the end
/// point's own cell. At `t = 1` both boundaries are due, but one reached exactly at the end
/// while moving in the negative direction is not crossed (the end point's half-open cell is
/// still on the same row), so a walk that gave the tie to the row would spend its last step
/// on a phantom crossing and end in `(end.0 - 1, end.1 - 1)`; `insert_beam` would then free
/// the wrong last cell whenever `free_end` falls on a corner with the beam heading between
/// 90 and 180 degrees. The walk counts the boundaries left on each axis and never steps an
/// axis with none left.
#[test]
fn cell_walk_ends_at_the_end_cell_when_it_ends_on_a_corner() {
    let geo = seed_geometry();
    // Relative to the grid origin: from (-450, 150) to (0, 0), the lower-left corner of
    // cell (0, 0).
    let from = (-600, 0);
    let to = (-150, -150);
    let walk: Vec<_> = CellWalk::new(&geo, from, to).collect();
    let end = geo.cell_of(to.0, to.1);
    assert_eq!(end, (0, 0));
    // The simplest instance: one cell right and down onto a corner.
    let short: Vec<_> = CellWalk::new(&geo, (-125, -125), (-100, -150)).collect();
    assert_eq!(
        short.last(),
        Some(&geo.cell_of(-100, -150)),
        "short walk {short:?} does not end at the end cell"
    );
    assert_eq!(
        walk.last(),
        Some(&end),
        "walk {walk:?} does not end at the end cell {end:?}"
    );
}

/// `config` without the plausibility checks (`slam_core::plausible`): these inputs are
/// synthetic (constant rates, repeated frames, a robot that never holds), and the checks
/// are not what this file tests.
fn unchecked(config: slam_core::SlamConfig) -> slam_core::SlamConfig {
    slam_core::SlamConfig {
        plausible: None,
        ..config
    }
}
