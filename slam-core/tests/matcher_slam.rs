//! The matcher inside `Slam::step`: refused without the filter, off by default, the map
//! written only with scans that have left the sweep, and a drive with a flow sensor
//! 4 % off held nearer the truth than dead reckoning.

mod reference;

use std::mem::{size_of, MaybeUninit};

use reference::RefPose;
use slam_core::matcher::SWEEP_TICKS;
use slam_core::wall_rate::{WallCounters, WallRate};
use slam_core::{
    ConfigError, DepthScan, FlowDelta, GyroRate, Localiser, MatchingConfig, Pose, SensorFrame,
    Slam, SlamConfig, StepReport, BEAMS,
};

const DT_US: u32 = 100_000;

/// The seed's configuration with `localiser` and, if `matching`, the matcher; the start
/// known to the shipped 1 mm.
fn config(localiser: Localiser, matching: bool) -> SlamConfig {
    SlamConfig {
        localiser,
        matching: matching.then_some(MatchingConfig::SEED),
        ..unchecked(world::shipped::seed_robot().config)
    }
}

#[test]
fn matching_needs_the_filter_and_is_off_by_default() {
    assert_eq!(world::shipped::seed_robot().config.matching, None);
    let start = Pose::from_mm_mdeg(500, 500, 0);
    for localiser in [Localiser::DeadReckoning, Localiser::TwoTagFix] {
        let r = Slam::<46, 46>::new(config(localiser, true), start);
        assert_eq!(r.err(), Some(ConfigError::Matching));
    }
    assert!(Slam::<46, 46>::new(config(Localiser::Filter, true), start).is_ok());
}

/// A square of 1 m sides from (500, 500) mm, clockwise, the first side after a turn on the
/// spot: flow counts forward and gyro millidegrees per second per tick.
fn route() -> Vec<(i32, i32)> {
    let mut ticks = vec![(0, 36_000); 100];
    for _ in 0..4 {
        ticks.extend(std::iter::repeat_n((100, 0), 100));
        ticks.extend(std::iter::repeat_n((0, 90_000), 10));
    }
    ticks
}

/// Drives the route with the flow sensor reading 4 % short and the gyro 1 % high; returns
/// the largest position error on the way, in millimetres, and the core.
fn drive(localiser: Localiser, matching: bool) -> (f64, Slam<46, 46>) {
    let ((worst, slam, _), _) = drive_matching(localiser, matching, None);
    (worst, slam)
}

/// [`drive`], the drives at a wall judged, and each tick's report; with `pieces`, each
/// match deferred and searched that many pieces at a time before it is finished.
fn drive_matching(
    localiser: Localiser,
    matching: bool,
    pieces: Option<usize>,
) -> ((f64, Slam<46, 46>, WallCounters), Vec<StepReport>) {
    let start = Pose::from_mm_mdeg(500, 500, 0);
    let mut slam: Slam<46, 46> = Slam::new(config(localiser, matching), start).unwrap();
    let (worst, walls, reports) = run_route(&mut slam, pieces);
    ((worst, slam, walls), reports)
}

/// Drives `slam` round [`route`]: the largest position error on the way, in millimetres,
/// the drives at a wall judged, and each tick's report.
fn run_route(
    slam: &mut Slam<46, 46>,
    pieces: Option<usize>,
) -> (f64, WallCounters, Vec<StepReport>) {
    slam.defer_matching(pieces.is_some());
    let mut reports = Vec::new();
    let mut truth = RefPose {
        x_um: 500_000.0,
        y_um: 500_000.0,
        heading: 0.0,
    };
    let mut worst: f64 = 0.0;
    let mut walls = WallRate::default();
    let mut turn = slam_core::wall_turn::WallTurn::default();
    for (counts, rate) in route() {
        truth = reference::odometry_tick(truth, Some((counts, 0)), Some(rate), DT_US, 100.0);
        let ranges_mm = reference::mat_scan(&truth);
        let mut frame = SensorFrame::empty(DT_US);
        frame.flow = Some(FlowDelta {
            forward_counts: counts * 96 / 100,
            right_counts: 0,
        });
        frame.gyro = Some(GyroRate {
            rate_mdps: rate * 101 / 100,
        });
        frame.depth = Some(DepthScan { ranges_mm });
        let mut report = slam.step(&frame);
        if let Some(pieces) = pieces {
            while !slam.search_match(pieces) {}
            report = slam.finish_match(report);
        }
        report = slam.measure_walls(&mut walls, &mut turn, &frame, report);
        reports.push(report);
        let p = report.pose;
        let error = (p.x_um as f64 - truth.x_um).hypot(p.y_um as f64 - truth.y_um) / 1000.0;
        worst = worst.max(error);
    }
    (worst, walls.counters, reports)
}

#[test]
fn a_core_built_in_place_over_leftover_ram_is_the_one_built_by_value() {
    let start = Pose::from_mm_mdeg(500, 500, 0);
    let config = config(Localiser::Filter, true);
    let mut by_value: Slam<46, 46> = Slam::new(config, start).unwrap();
    // What a watchdog reset leaves in the retained block: anything.
    let mut slot = Box::new(MaybeUninit::<Slam<46, 46>>::uninit());
    // SAFETY: bytes written into the slot's own memory.
    unsafe {
        slot.as_mut_ptr()
            .cast::<u8>()
            .write_bytes(0xA5, size_of::<Slam<46, 46>>())
    };
    let in_place = Slam::new_in(&mut slot, config, start).unwrap();
    assert_eq!(format!("{in_place:?}"), format!("{by_value:?}"));
    let (_, in_place_walls, in_place_reports) = run_route(in_place, Some(3));
    let (_, by_value_walls, by_value_reports) = run_route(&mut by_value, Some(3));
    assert_eq!(in_place_reports, by_value_reports);
    assert_eq!(in_place.map().rows(), by_value.map().rows());
    assert_eq!(in_place_walls, by_value_walls);
    assert!(in_place.match_counters().used > 300);
    let mut refused = Box::new(MaybeUninit::<Slam<46, 46>>::uninit());
    let r = Slam::new_in(
        &mut refused,
        self::config(Localiser::TwoTagFix, true),
        start,
    );
    assert_eq!(r.err(), Some(ConfigError::Matching));
}

#[test]
fn a_match_searched_in_pieces_is_the_steps_own_bit_for_bit() {
    let ((_, whole, whole_walls), whole_reports) = drive_matching(Localiser::Filter, true, None);
    for at_a_time in [1, 2, 5] {
        let ((_, pieces, piece_walls), piece_reports) =
            drive_matching(Localiser::Filter, true, Some(at_a_time));
        assert_eq!(piece_reports, whole_reports, "{at_a_time} pieces at a time");
        assert_eq!(pieces.map().rows(), whole.map().rows());
        assert_eq!(pieces.match_counters(), whole.match_counters());
        assert_eq!(pieces.last_match(), whole.last_match());
        assert_eq!(piece_walls, whole_walls);
    }
    assert!(whole.match_counters().used > 300);
    assert!(whole_walls.taken > 0, "{whole_walls:?}");
}

#[test]
fn matching_holds_a_drive_that_dead_reckoning_loses() {
    let (dead, _) = drive(Localiser::Filter, false);
    let (matched, slam) = drive(Localiser::Filter, true);
    let c = slam.match_counters();
    println!("largest error: filter without matching {dead:.1} mm, with it {matched:.1} mm; {c:?}");
    assert!(dead > 100.0, "{dead}");
    // Matches pull the pose no nearer the map than the map's own cells and drift allow
    // (`MatchNoise`'s floors, `MapUncertainty`), and pin a position only where the score
    // surface is narrow (`MatcherConfig::unpinned_pct`, strict so that a corridor claims
    // nothing along it), so on this drive they take off a tenth of the drift's worst.
    assert!(matched < dead * 0.9, "{matched}");
    assert!(c.used > 300, "{c:?}");
    // The map holds only the scans that have left the sweep.
    let ticks = route().len() as u32;
    assert_eq!(
        slam.counters().beams_mapped,
        (ticks - SWEEP_TICKS as u32) * BEAMS as u32
    );
    // Every match is for the tick of its sweep's newest scan: the last one.
    assert_eq!(slam.last_match().map(|m| m.tick), Some(ticks));
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
