//! The matcher alone, on synthetic grids: a corner pins everything, a flat wall and a
//! corridor pin all but the direction along them, an empty sweep is refused, a mirrored
//! world gives a mirrored match, and the cost of a match is counted and bounded.

use slam_core::grid::{Evidence, GridGeometry, GridMap};
use slam_core::matcher::{
    MatchRefusal, Matcher, MatcherConfig, Pins, Sweep, SWEEP_POINTS, SWEEP_TICKS,
};
use slam_core::pose::RigidMotion;
use slam_core::slam::DepthConfig;
use slam_core::{Angle, DepthScan, Pose, BEAMS};

/// 60 x 60 cells of 5 cm from (0, 0): 3 m square.
type Map = GridMap<60, 60>;
const CELL: i32 = 50;
const GEOMETRY: GridGeometry = GridGeometry {
    cell_mm: CELL,
    origin_x_mm: 0,
    origin_y_mm: 0,
};

/// A wall: a segment from `(x0, y0)` to `(x1, y1)`, millimetres.
type Wall = (f64, f64, f64, f64);

/// A world: its walls, and the cells its map holds free (the rest of the grid, but for
/// the walls' cells, is unknown).
struct World {
    walls: Vec<Wall>,
    free: fn(i32, i32) -> bool,
}

impl World {
    /// The map a careful robot would have built: wall cells occupied, the free cells
    /// free, both saturated.
    fn map(&self) -> Map {
        let mut map = Map::new(GEOMETRY, Evidence::SEED);
        for row in 0..60 {
            for column in 0..60 {
                let (x, y) = GEOMETRY.centre_of(column, row);
                let on_wall = self.walls.iter().any(|w| cell_touches(w, column, row));
                let amount = if on_wall {
                    Evidence::SEED.hit
                } else if (self.free)(x, y) {
                    Evidence::SEED.miss
                } else {
                    continue;
                };
                for _ in 0..20 {
                    map.add(column, row, amount);
                }
            }
        }
        map
    }

    /// The range along a beam from `(x, y)` in direction `heading` (degrees clockwise
    /// from +y) to the nearest wall, if within 4 m.
    fn cast(&self, x: f64, y: f64, heading_deg: f64) -> Option<u16> {
        let (dx, dy) = (
            heading_deg.to_radians().sin(),
            heading_deg.to_radians().cos(),
        );
        let mut nearest = f64::INFINITY;
        for &(x0, y0, x1, y1) in &self.walls {
            let (ex, ey) = (x1 - x0, y1 - y0);
            let den = dx * ey - dy * ex;
            if den.abs() < 1e-12 {
                continue;
            }
            let t = ((x0 - x) * ey - (y0 - y) * ex) / den;
            let u = ((x0 - x) * dy - (y0 - y) * dx) / den;
            if t > 0.0 && (0.0..=1.0).contains(&u) {
                nearest = nearest.min(t);
            }
        }
        (nearest < 3999.0).then(|| nearest.round() as u16)
    }
}

/// Whether an axis-aligned wall passes through cell `(column, row)`.
fn cell_touches(w: &Wall, column: i32, row: i32) -> bool {
    let (x0, y0) = ((column * CELL) as f64, (row * CELL) as f64);
    let (x1, y1) = (x0 + CELL as f64, y0 + CELL as f64);
    let (lx, hx) = (w.0.min(w.2), w.0.max(w.2));
    let (ly, hy) = (w.1.min(w.3), w.1.max(w.3));
    lx < x1 && hx >= x0 && ly < y1 && hy >= y0
}

/// A true path: `(x mm, y mm, heading deg)` per tick.
type Path = Vec<(f64, f64, f64)>;

/// A path of `SWEEP_TICKS` ticks from `start`, turning `turn_deg` and driving `drive_mm`
/// each tick.
fn path(start: (f64, f64, f64), turn_deg: f64, drive_mm: f64) -> Path {
    let mut p = start;
    let mut out = vec![];
    for _ in 0..SWEEP_TICKS {
        out.push(p);
        let h = p.2.to_radians();
        p = (
            p.0 + drive_mm * h.sin(),
            p.1 + drive_mm * h.cos(),
            p.2 + turn_deg,
        );
    }
    out
}

fn pose_of(p: &(f64, f64, f64)) -> Pose {
    Pose {
        x_um: (p.0 * 1000.0).round() as i32,
        y_um: (p.1 * 1000.0).round() as i32,
        heading: Angle::from_millidegrees((p.2 * 1000.0).round() as i64),
    }
}

fn beam_deg(beams: &[Angle; BEAMS], i: usize) -> f64 {
    beams[i].signed_bits() as f64 * 360.0 / 4294967296.0
}

/// The scans the robot takes along `truth`.
fn scans(world: &World, truth: &Path) -> Vec<DepthScan> {
    let beams = DepthConfig::SEED.beam_angles;
    truth
        .iter()
        .map(|p| DepthScan {
            ranges_mm: core::array::from_fn(|i| world.cast(p.0, p.1, p.2 + beam_deg(&beams, i))),
        })
        .collect()
}

/// The sweep the robot holds: the true scans at poses believed `offset` (x mm, y mm,
/// heading deg) off the truth at the newest tick, the odometry between them exact.
fn sweep(truth: &Path, scans: &[DepthScan], offset: (f64, f64, f64)) -> Sweep<SWEEP_TICKS> {
    let last = truth[truth.len() - 1];
    let believed_last = (last.0 + offset.0, last.1 + offset.1, last.2 + offset.2);
    let motion = RigidMotion::carrying(&pose_of(&last), &pose_of(&believed_last));
    let mut sweep = Sweep::new();
    for (tick, (p, scan)) in truth.iter().zip(scans).enumerate() {
        sweep.push(tick as u32, motion.apply(&pose_of(p)), *scan);
    }
    sweep
}

fn matcher() -> Matcher {
    Matcher::new(MatcherConfig::SEED, CELL).expect("the seed's window fits")
}

fn degrees(a: Angle) -> f64 {
    a.signed_bits() as f64 * 360.0 / 4294967296.0
}

/// A room's corner: walls along x = 2025 and y = 2025 mm (cell centres), free inside.
fn corner() -> World {
    World {
        walls: vec![
            (2025.0, -100.0, 2025.0, 2025.0),
            (-100.0, 2025.0, 2025.0, 2025.0),
        ],
        free: |x, y| x < 2000 && y < 2000,
    }
}

#[test]
fn a_corner_recovers_a_known_offset() {
    let world = corner();
    let map = world.map();
    // Facing the corner and turning across it, driving towards it.
    let truth = path((1450.0, 1350.0, 25.0), 4.0, 8.0);
    let scans = scans(&world, &truth);
    let last = truth[truth.len() - 1];
    for offset in [(25.0, -20.0, 1.5), (-20.0, 15.0, -1.8), (0.0, 0.0, 0.0)] {
        let m = matcher()
            .match_sweep(
                &sweep(&truth, &scans, offset),
                &DepthConfig::SEED.beam_angles,
                &map.view(),
            )
            .expect("a corner matches");
        let ex = m.pose.x_um as f64 / 1000.0 - last.0;
        let ey = m.pose.y_um as f64 / 1000.0 - last.1;
        let eh = degrees(m.pose.heading) - last.2;
        println!(
            "corner, offset {offset:?}: error {ex:.1} mm, {ey:.1} mm, {eh:.2} deg; sd {:.1} mm, \
             {:.1} mm, {:.2} deg; {:?}; {:?}",
            (m.covariance.xx_um2 as f64).sqrt() / 1000.0,
            (m.covariance.yy_um2 as f64).sqrt() / 1000.0,
            (m.covariance.hh_mdeg2 as f64).sqrt() / 1000.0,
            m.pins,
            m.stats
        );
        assert_eq!(m.pins, Pins::All);
        assert_eq!(m.tick, SWEEP_TICKS as u32 - 1);
        // Within a fifth of a cell, and a quarter of a degree.
        assert!(ex.abs() <= 10.0 && ey.abs() <= 10.0, "{ex} {ey}");
        assert!(eh.abs() <= 0.5, "{eh}");
    }
}

/// One long wall along y = 2025 mm, free below it.
fn flat_wall() -> World {
    World {
        walls: vec![(-2000.0, 2025.0, 5000.0, 2025.0)],
        free: |_, y| y < 2000,
    }
}

#[test]
fn a_flat_wall_pins_its_distance_but_not_along_it() {
    let world = flat_wall();
    let map = world.map();
    let truth = path((1500.0, 1300.0, -15.0), 3.0, 5.0);
    let scans = scans(&world, &truth);
    let last = truth[truth.len() - 1];
    let m = matcher()
        .match_sweep(
            &sweep(&truth, &scans, (15.0, -20.0, 1.0)),
            &DepthConfig::SEED.beam_angles,
            &map.view(),
        )
        .expect("a wall pins something");
    let ey = m.pose.y_um as f64 / 1000.0 - last.1;
    println!(
        "flat wall: y error {ey:.1} mm, {:?}, {:?}",
        m.pins, m.covariance
    );
    let Pins::AllButAlong(along) = m.pins else {
        panic!("a flat wall cannot pin along itself: {:?}", m.pins);
    };
    // Along x: 90 degrees from +y, as a line.
    assert!(
        (degrees(along).abs() - 90.0).abs() < 10.0,
        "{}",
        degrees(along)
    );
    assert!(ey.abs() <= 10.0, "{ey}");
    // Along the wall the spread is the window's, across it far less.
    assert!(m.covariance.xx_um2 > 10 * m.covariance.yy_um2);
}

/// A corridor 55 cm wide along y, walls at x = 1225 and 1775 mm.
fn corridor() -> World {
    World {
        walls: vec![
            (1225.0, -2000.0, 1225.0, 5000.0),
            (1775.0, -2000.0, 1775.0, 5000.0),
        ],
        free: |x, _| x > 1250 && x < 1750,
    }
}

#[test]
fn a_corridor_pins_across_but_not_along() {
    let world = corridor();
    let map = world.map();
    let truth = path((1480.0, 900.0, -3.0), 0.6, 8.0);
    let scans = scans(&world, &truth);
    let last = truth[truth.len() - 1];
    let m = matcher()
        .match_sweep(
            &sweep(&truth, &scans, (-18.0, 25.0, -1.2)),
            &DepthConfig::SEED.beam_angles,
            &map.view(),
        )
        .expect("a corridor pins something");
    let ex = m.pose.x_um as f64 / 1000.0 - last.0;
    let eh = degrees(m.pose.heading) - last.2;
    println!(
        "corridor: x error {ex:.1} mm, heading {eh:.2} deg, {:?}, {:?}",
        m.pins, m.covariance
    );
    let Pins::AllButAlong(along) = m.pins else {
        panic!("a corridor cannot pin along itself: {:?}", m.pins);
    };
    assert!(degrees(along).abs() < 10.0, "{}", degrees(along));
    assert!(ex.abs() <= 10.0, "{ex}");
    assert!(m.covariance.yy_um2 > 5 * m.covariance.xx_um2);
}

/// A corridor a metre wide along y, walls at x = 1025 and 2025 mm, mapped only up to
/// y = `MAPPED_TO` mm: what a robot driving up it has mapped a second behind its sweep.
const MAPPED_TO: i32 = 1740;
fn wide_corridor(mapped: bool) -> World {
    let end = if mapped { MAPPED_TO as f64 } else { 5000.0 };
    World {
        walls: vec![
            (1025.0, -2000.0, 1025.0, end),
            (2025.0, -2000.0, 2025.0, end),
        ],
        free: if mapped {
            |x, y| x > 1050 && x < 2000 && y < MAPPED_TO
        } else {
            |x, _| x > 1050 && x < 2000
        },
    }
}

#[test]
fn a_sweep_past_the_mapped_walls_pins_nothing_along_them() {
    // Driving up the corridor: the outer beams meet the walls 1.4 m ahead, so the newest
    // ends fall past the walls mapped so far. Pulling them back onto the mapped walls
    // scores, and would drag the match back along the corridor.
    let truth = path((1525.0, 300.0, 0.0), 0.0, 10.0);
    let scans = scans(&wide_corridor(false), &truth);
    let last = truth[truth.len() - 1];
    let m = matcher()
        .match_sweep(
            &sweep(&truth, &scans, (-15.0, 0.0, 0.0)),
            &DepthConfig::SEED.beam_angles,
            &wide_corridor(true).map().view(),
        )
        .expect("the walls beside pin their distance");
    let ey = m.pose.y_um as f64 / 1000.0 - last.1;
    println!("corridor's end: y error {ey:.1} mm, {:?}", m.pins);
    // Along y: 0 degrees from +y, as a line; or no position at all.
    let along = match m.pins {
        Pins::AllButAlong(along) | Pins::AcrossOnly(along) => along,
        Pins::HeadingOnly => Angle::ZERO,
        pins => panic!("the sweep cannot say where it is along the corridor: {pins:?}"),
    };
    assert!(
        degrees(along).abs() < 10.0,
        "pinned along y: {}",
        degrees(along)
    );
}

#[test]
fn an_empty_sweep_is_refused() {
    let map = corner().map();
    let beams = DepthConfig::SEED.beam_angles;
    let mut m = matcher();
    let mut sweep: Sweep<SWEEP_TICKS> = Sweep::new();
    assert_eq!(
        m.match_sweep(&sweep, &beams, &map.view()),
        Err(MatchRefusal::EmptySweep)
    );
    // Every beam missing: scans, but no ends.
    for tick in 0..SWEEP_TICKS as u32 {
        sweep.push(
            tick,
            Pose::from_mm_mdeg(1000, 1000, 0),
            DepthScan::default(),
        );
    }
    assert_eq!(
        m.match_sweep(&sweep, &beams, &map.view()),
        Err(MatchRefusal::EmptySweep)
    );
    // One beam a tick: too few to trust.
    let one = DepthScan {
        ranges_mm: [Some(1025), None, None, None, None, None, None, None],
    };
    sweep.push(99, Pose::from_mm_mdeg(1000, 1000, 0), one);
    assert_eq!(
        m.match_sweep(&sweep, &beams, &map.view()),
        Err(MatchRefusal::TooFewPoints)
    );
}

#[test]
fn ends_on_nothing_known_are_refused() {
    // An unknown map: every candidate scores zero.
    let map = Map::new(GEOMETRY, Evidence::SEED);
    let world = corner();
    let truth = path((1450.0, 1350.0, 25.0), 4.0, 8.0);
    let scans = scans(&world, &truth);
    let r = matcher().match_sweep(
        &sweep(&truth, &scans, (-18.0, 0.0, -1.2)),
        &DepthConfig::SEED.beam_angles,
        &map.view(),
    );
    assert_eq!(r, Err(MatchRefusal::NoFit));
}

#[test]
fn a_mirrored_world_gives_a_mirrored_match() {
    let world = corner();
    let map = world.map();
    let truth = path((1450.0, 1350.0, 25.0), 4.0, 8.0);
    let scans_here = scans(&world, &truth);
    // Mirrored in x = 1500 mm (a cell boundary): the map's columns reversed, the path's x
    // and headings negated, and each scan read right to left (the fan is symmetric).
    let mut mirrored = Map::new(GEOMETRY, Evidence::SEED);
    for row in 0..60 {
        for column in 0..60 {
            let l = map.log_odds(column, row).unwrap_or(0);
            for _ in 0..20 {
                mirrored.add(59 - column, row, l.signum() * Evidence::SEED.hit);
            }
        }
    }
    let truth_there: Path = truth.iter().map(|p| (3000.0 - p.0, p.1, -p.2)).collect();
    let scans_there: Vec<DepthScan> = scans_here
        .iter()
        .map(|s| {
            let mut r = s.ranges_mm;
            r.reverse();
            DepthScan { ranges_mm: r }
        })
        .collect();
    let beams = DepthConfig::SEED.beam_angles;
    for offset in [(25.0, -20.0, 1.5), (-12.0, 7.0, -0.7)] {
        let here = matcher()
            .match_sweep(&sweep(&truth, &scans_here, offset), &beams, &map.view())
            .expect("matches");
        let there = matcher()
            .match_sweep(
                &sweep(&truth_there, &scans_there, (-offset.0, offset.1, -offset.2)),
                &beams,
                &mirrored.view(),
            )
            .expect("matches");
        println!("here {:?}\nthere {:?}", here, there);
        assert_eq!(here.best_score, there.best_score);
        let (dx_here, dx_there) = (
            here.pose.x_um - here.prediction.x_um,
            there.pose.x_um - there.prediction.x_um,
        );
        assert!((dx_here + dx_there).abs() <= 500, "{dx_here} {dx_there}");
        let (dy_here, dy_there) = (
            here.pose.y_um - here.prediction.y_um,
            there.pose.y_um - there.prediction.y_um,
        );
        assert!((dy_here - dy_there).abs() <= 500, "{dy_here} {dy_there}");
        let dh_here = (here.pose.heading - here.prediction.heading).signed_bits();
        let dh_there = (there.pose.heading - there.prediction.heading).signed_bits();
        assert!(degrees(Angle::from_bits((dh_here + dh_there) as u32)).abs() < 0.02);
        assert!(
            (here.covariance.xx_um2 - there.covariance.xx_um2).abs()
                <= here.covariance.xx_um2 / 20 + 1000
        );
        assert!(
            (here.covariance.xh_um_mdeg - there.covariance.xh_um_mdeg).abs()
                <= here.covariance.xh_um_mdeg.abs() / 20 + 1000
        );
    }
}

#[test]
fn a_match_costs_a_bounded_number_of_lookups() {
    let world = corner();
    let map = world.map();
    let truth = path((1450.0, 1350.0, 25.0), 4.0, 8.0);
    let scans = scans(&world, &truth);
    let m = matcher()
        .match_sweep(
            &sweep(&truth, &scans, (10.0, 10.0, 1.0)),
            &DepthConfig::SEED.beam_angles,
            &map.view(),
        )
        .expect("matches");
    let s = m.stats;
    println!(
        "one match: {} ends, {} lookups, {} adds, {} headings searched, {} pruned",
        s.points, s.lookups, s.adds, s.headings_searched, s.headings_pruned
    );
    // Each end: at most 4 x 4 cells per heading for the bound (the window's cells and the
    // interpolation's neighbours), and again for each heading searched; 49 adds per end
    // and heading searched.
    assert!(s.points as usize <= SWEEP_POINTS);
    let headings = Matcher::HEADINGS as u32;
    assert!(s.lookups <= s.points * 16 * (headings + s.headings_searched));
    assert_eq!(s.adds, s.points * 49 * s.headings_searched);
    assert_eq!(s.headings_searched + s.headings_pruned, headings);
    // The whole search of the seed's window stays under 32,000 lookups.
    assert!(s.lookups <= 32_000, "{}", s.lookups);
}
