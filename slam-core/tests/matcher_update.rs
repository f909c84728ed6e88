//! A match as a filter update (`Estimator::apply_match`), on hand-made matches: it moves
//! the pose only along what it pins, by how sure it is against the filter, and a match far
//! from the prediction is refused by the gate.

use slam_core::estimator::State;
use slam_core::estimator::{MapUncertainty, MatchNoise, MATCH_STEP_UM};
use slam_core::matcher::{Match, MatchCovariance, MatchRefusal, MatchStats, Pins};
use slam_core::{Angle, Estimator, EstimatorConfig, Pose};

/// A match of the pose at (1000, 1000) mm facing +y, moved by `(dx, dy)` um and `dh`
/// millidegrees, with standard deviations `sd` (um, um, mdeg) and no correlation.
fn hand_made(dx: i32, dy: i32, dh: i64, sd: (i64, i64, i64), pins: Pins) -> Match {
    let prediction = Pose::from_mm_mdeg(1000, 1000, 0);
    Match {
        tick: 7,
        prediction,
        pose: Pose {
            x_um: prediction.x_um + dx,
            y_um: prediction.y_um + dy,
            heading: prediction.heading + Angle::from_millidegrees(dh),
        },
        covariance: MatchCovariance {
            xx_um2: sd.0 * sd.0,
            yy_um2: sd.1 * sd.1,
            hh_mdeg2: sd.2 * sd.2,
            ..MatchCovariance::default()
        },
        pins,
        wide: -Angle::QUARTER_TURN,
        best_score: 1,
        worst_score: 0,
        stats: MatchStats::default(),
    }
}

/// A filter 10 mm and 1 degree unsure.
fn unsure() -> Estimator {
    Estimator::new(EstimatorConfig {
        initial_position_mm: 10,
        initial_heading_mdeg: 1000,
        ..EstimatorConfig::SEED
    })
}

/// What the match only widens by the noise's floors: no scaling.
const NOISE: MatchNoise = MatchNoise {
    position_um: 1_000,
    heading_mdeg: 100,
    scale_pct: 100,
    floor_position_um: 0,
    floor_heading_mdeg: 0,
};

#[test]
fn a_flat_wall_moves_the_pose_across_it_only() {
    let mut filter = unsure();
    let before = filter.covariance().get(State::X, State::X);
    // A wall along x (the wider spread along x): 20 mm off in x and y, 0.5 degrees.
    let m = hand_made(
        20_000,
        20_000,
        500,
        (30_000, 2_000, 300),
        Pins::AllButAlong(-Angle::QUARTER_TURN),
    );
    let corrected = filter
        .apply_match(&m, &NOISE, &MapUncertainty::default())
        .expect("within the gate");
    let moved_x = corrected.x_um - m.prediction.x_um;
    let moved_y = corrected.y_um - m.prediction.y_um;
    let turned = (corrected.heading - m.prediction.heading).to_millidegrees();
    println!("moved {moved_x} um, {moved_y} um, {turned} mdeg");
    // Across (y): most of the way, the filter being five times less sure than the match.
    assert!(moved_y > 15_000 && moved_y < 20_000, "{moved_y}");
    // Along (x): not at all, and the filter no surer of it.
    assert_eq!(moved_x, 0);
    assert_eq!(filter.covariance().get(State::X, State::X), before);
    assert!(turned > 250 && turned <= 500, "{turned}");
}

#[test]
fn a_corner_moves_all_three_by_their_certainty() {
    let mut filter = unsure();
    let m = hand_made(10_000, -10_000, -400, (2_000, 2_000, 200), Pins::All);
    let corrected = filter
        .apply_match(&m, &NOISE, &MapUncertainty::default())
        .expect("within the gate");
    let moved_x = corrected.x_um - m.prediction.x_um;
    let moved_y = corrected.y_um - m.prediction.y_um;
    let turned = (corrected.heading - m.prediction.heading).to_millidegrees();
    println!("moved {moved_x} um, {moved_y} um, {turned} mdeg");
    assert!(moved_x > 8_000 && moved_x <= 10_000, "{moved_x}");
    assert!((-10_000..-8_000).contains(&moved_y), "{moved_y}");
    assert!((-400..-300).contains(&turned), "{turned}");
    // Surer after than before.
    assert!(
        filter.covariance().get(State::Y, State::Y) < unsure().covariance().get(State::Y, State::Y)
    );
}

#[test]
fn a_match_far_from_the_prediction_is_gated() {
    let mut filter = unsure();
    let before = *filter.covariance();
    // 15 cm off where the filter is sure to 1 cm and the match to 2 mm.
    let m = hand_made(150_000, 0, 0, (2_000, 2_000, 200), Pins::All);
    assert_eq!(
        filter.apply_match(&m, &NOISE, &MapUncertainty::default()),
        Err(MatchRefusal::Gate)
    );
    assert_eq!(filter.covariance(), &before);
}

#[test]
fn a_match_that_would_jump_moves_the_pose_a_step_and_is_believed_less() {
    // A filter 100 mm unsure and a sure corner 60 mm off: taken whole, it would move the
    // pose nearly all of the way in one tick.
    let lost = || {
        Estimator::new(EstimatorConfig {
            initial_position_mm: 100,
            initial_heading_mdeg: 1000,
            ..EstimatorConfig::SEED
        })
    };
    let m = hand_made(60_000, 0, 0, (3_000, 3_000, 300), Pins::All);
    let moved = |filter: &mut Estimator, step_um: u32| {
        let corrected = filter
            .apply_match_within(&m, &NOISE, &MapUncertainty::default(), step_um)
            .expect("within the gate");
        i64::from(corrected.x_um - m.prediction.x_um).abs()
    };
    let (mut whole, mut stepped) = (lost(), lost());
    assert!(moved(&mut whole, u32::MAX) > 50_000);
    let step = moved(&mut stepped, MATCH_STEP_UM);
    assert!(
        (5_000..=i64::from(MATCH_STEP_UM)).contains(&step),
        "moved {step} um"
    );
    // Widened, not clipped: the filter is left as unsure as a match that far trusted less.
    let xx = |f: &Estimator| f.covariance().get(State::X, State::X);
    assert!(xx(&stepped) > 4 * xx(&whole));
    // The next match, from where this one left the pose, steps on.
    let mut again = stepped.clone();
    assert!(moved(&mut again, MATCH_STEP_UM) > 0);
}

#[test]
fn heading_only_leaves_the_position() {
    let mut filter = unsure();
    let m = hand_made(
        30_000,
        30_000,
        600,
        (40_000, 40_000, 200),
        Pins::HeadingOnly,
    );
    let corrected = filter
        .apply_match(&m, &NOISE, &MapUncertainty::default())
        .expect("within the gate");
    assert_eq!(
        (corrected.x_um, corrected.y_um),
        (m.prediction.x_um, m.prediction.y_um)
    );
    assert!((corrected.heading - m.prediction.heading).to_millidegrees() > 400);
}

/// A match whose heading and position are correlated (a sweep turned against a wall moves
/// its ends across it) still leaves the filter no surer of its position than the map
/// is: the heading, measured given the position, carries some position in it, and its
/// floor counts that.
#[test]
fn a_correlated_match_leaves_the_position_no_surer_than_the_map() {
    // Unsure of its place in the world by 30 cm; the map it matches against is off by up
    // to 25 cm (drawn while dead reckoning), its heading known to 0.1 degrees.
    let mut filter = Estimator::new(EstimatorConfig {
        initial_position_mm: 300,
        initial_heading_mdeg: 2_000,
        ..EstimatorConfig::SEED
    });
    let sixteenths = |mm: i64| mm * 16;
    let radians_q16 = |mdeg: i64| mdeg * 65_536 * 314_159 / (180_000 * 100_000);
    let map = MapUncertainty {
        xx: sixteenths(250) * sixteenths(250),
        yy: sixteenths(250) * sixteenths(250),
        xy: 0,
        heading: radians_q16(100) * radians_q16(100),
    };
    let (sx, sh) = (5_000i64, 500i64);
    let mut m = hand_made(
        20_000,
        0,
        800,
        (sx, 40_000, sh),
        Pins::AllButAlong(Angle::ZERO),
    );
    m.wide = Angle::ZERO;
    m.covariance.xh_um_mdeg = sx * sh * 9 / 10;
    filter
        .apply_match(&m, &NOISE, &map)
        .expect("within the gate");
    let xx = filter.covariance().get(State::X, State::X);
    assert!(
        xx >= map.xx * 99 / 100,
        "x deviation {:.0} mm, the map's {:.0} mm",
        (xx as f64).sqrt() / 16.0,
        (map.xx as f64).sqrt() / 16.0
    );
}

/// A map drawn down a corridor while unsure along it (x, 25 cm) but sure across it (y,
/// 2 mm): a match across the corridor may leave the filter as sure across it as the map
/// is, not as unsure as the map is along it; a match along it is held at the map's 25 cm.
/// With the correlation, a map unsure along the diagonal x = y and sure across it floors
/// a match measured along and across that diagonal the same way. (The floor holds along
/// each measurement's own row: two rows along x and y each keep the map's variance
/// along x and y, not the diagonal's.)
#[test]
fn the_map_floors_each_direction_by_its_own_uncertainty() {
    let sixteenths = |mm: i64| mm * 16;
    let corridor = MapUncertainty {
        xx: sixteenths(250) * sixteenths(250),
        yy: sixteenths(2) * sixteenths(2),
        xy: 0,
        heading: 0,
    };
    let diagonal = MapUncertainty {
        xx: sixteenths(250) * sixteenths(250) / 2,
        yy: sixteenths(250) * sixteenths(250) / 2,
        xy: sixteenths(250) * sixteenths(250) / 2,
        heading: 0,
    };
    // The filter 30 cm unsure; a match 5 mm sure along x and y alike.
    let apply = |map: &MapUncertainty, wide: Angle| {
        let mut filter = Estimator::new(EstimatorConfig {
            initial_position_mm: 300,
            ..EstimatorConfig::SEED
        });
        let mut m = hand_made(2_000, 2_000, 0, (5_000, 5_000, 300), Pins::PositionOnly);
        m.wide = wide;
        filter
            .apply_match(&m, &NOISE, map)
            .expect("within the gate");
        let p = filter.covariance();
        let mm = |v: i64| (v as f64).sqrt() / 16.0;
        let (xx, yy, xy) = (
            p.get(State::X, State::X),
            p.get(State::Y, State::Y),
            p.get(State::X, State::Y),
        );
        // Along (1, 1) / sqrt 2 and across it.
        (
            mm(xx),
            mm(yy),
            mm((xx + yy + 2 * xy) / 2),
            mm((xx + yy - 2 * xy) / 2),
        )
    };
    let (x, y, _, _) = apply(&corridor, -Angle::QUARTER_TURN);
    assert!(x >= 0.99 * 250.0, "along the corridor {x:.1} mm");
    assert!(y < 10.0, "across the corridor {y:.1} mm");
    let (_, _, along, across) = apply(&diagonal, Angle::from_millidegrees(45_000));
    assert!(along >= 0.99 * 250.0, "along the diagonal {along:.1} mm");
    assert!(across < 10.0, "across the diagonal {across:.1} mm");
}

/// A match that turns the heading further from its prediction than four of the filter's
/// own heading deviations is refused, however wide its own spread says it is: a filter
/// sure of its heading to 0.5 degrees takes a wall's pull of 1.5 degrees and refuses one of
/// 2.5, whose spread (2 degrees) would pass the chi-square gate. A match that pins only
/// the position is not held to it.
#[test]
fn a_match_that_turns_further_than_the_filter_believes_is_refused() {
    let sure_heading = || {
        Estimator::new(EstimatorConfig {
            initial_position_mm: 10,
            initial_heading_mdeg: 500,
            ..EstimatorConfig::SEED
        })
    };
    let map = MapUncertainty::default();
    let near = hand_made(0, 0, -1_500, (30_000, 30_000, 2_000), Pins::HeadingOnly);
    let turned = sure_heading()
        .apply_match(&near, &NOISE, &map)
        .map(|p| (p.heading - near.prediction.heading).to_millidegrees());
    assert!(turned.is_ok_and(|t| (-1_500..0).contains(&t)), "{turned:?}");
    let mut filter = sure_heading();
    let before = *filter.covariance();
    let far = hand_made(0, 0, -2_500, (30_000, 30_000, 2_000), Pins::HeadingOnly);
    assert_eq!(
        filter.apply_match(&far, &NOISE, &map),
        Err(MatchRefusal::Gate)
    );
    assert_eq!(filter.covariance(), &before);
    let position_only = hand_made(5_000, 0, -2_500, (2_000, 2_000, 2_000), Pins::PositionOnly);
    assert!(sure_heading()
        .apply_match(&position_only, &NOISE, &map)
        .is_ok());
}
