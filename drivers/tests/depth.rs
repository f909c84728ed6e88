//! VL53L5CX zone reduction: statuses, empty columns, negatives, mirror.

use drivers::depth::{
    reduce, status_accepted, BeamRanges, DepthConfig, ZoneResult, BEAM_CENTRE_UDEG, FOV_MDEG,
    STATUS_NO_TARGET, STATUS_VALID, ZONE_COUNT,
};

/// All zones valid at 2000 mm.
fn uniform() -> ZoneResult {
    ZoneResult {
        distance_mm: [2000; 64],
        target_status: [5; 64],
    }
}

fn zone(row: usize, col: usize) -> usize {
    row * 8 + col
}

#[test]
fn uniform_scene_gives_all_beams() {
    let out = reduce(&uniform(), &DepthConfig::default());
    assert_eq!(out.range_mm, [Some(2000); 8]);
    assert_eq!((out.dropped_status, out.dropped_distance), (0, 0));
}

#[test]
fn sensor_column_zero_is_robot_rightmost_beam() {
    let mut r = uniform();
    r.distance_mm[zone(3, 0)] = 300; // sensor's column 0
    r.distance_mm[zone(4, 7)] = 400; // sensor's column 7
    let out = reduce(&r, &DepthConfig::default());
    assert_eq!(out.range_mm[7], Some(300));
    assert_eq!(out.range_mm[0], Some(400));
    assert_eq!(out.range_mm[1..7], [Some(2000); 6]);
}

#[test]
fn nearest_of_middle_rows_and_other_rows_ignored() {
    let mut r = uniform();
    r.distance_mm[zone(3, 2)] = 900;
    r.distance_mm[zone(4, 2)] = 800;
    r.distance_mm[zone(0, 2)] = 100; // top row: ignored
    r.distance_mm[zone(7, 2)] = 50; // bottom row (floor): ignored
    let out = reduce(&r, &DepthConfig::default());
    assert_eq!(out.range_mm[5], Some(800));
    let all_rows = DepthConfig {
        first_row: 0,
        last_row: 7,
    };
    assert_eq!(reduce(&r, &all_rows).range_mm[5], Some(50));
}

#[test]
fn statuses_five_six_nine_accepted_others_dropped() {
    for status in 0..=255u8 {
        assert_eq!(status_accepted(status), matches!(status, 5 | 6 | 9));
    }
    let mut r = uniform();
    // Beam 0 = sensor column 7: lower-confidence 6 and 9 are used.
    r.target_status[zone(3, 7)] = 6;
    r.distance_mm[zone(3, 7)] = 700;
    r.target_status[zone(4, 7)] = 9;
    r.distance_mm[zone(4, 7)] = 600;
    // Beam 1 = column 6: a near zone with status 4 (no valid target) is dropped.
    r.target_status[zone(3, 6)] = 4;
    r.distance_mm[zone(3, 6)] = 100;
    let out = reduce(&r, &DepthConfig::default());
    assert_eq!(out.range_mm[0], Some(600));
    assert_eq!(out.range_mm[1], Some(2000));
    assert_eq!(out.dropped_status, 1);
}

#[test]
fn all_invalid_column_is_none() {
    let mut r = uniform();
    for row in 0..8 {
        r.target_status[zone(row, 4)] = 255;
    }
    let out = reduce(&r, &DepthConfig::default());
    assert_eq!(out.range_mm[3], None);
    assert_eq!(out.dropped_status, 2);
    let nothing = ZoneResult {
        distance_mm: [0; 64],
        target_status: [0; 64],
    };
    let out = reduce(&nothing, &DepthConfig::default());
    assert_eq!(out.range_mm, [None; 8]);
    assert_eq!(out.dropped_status, 16);
}

#[test]
fn negative_and_zero_distances_dropped() {
    let mut r = uniform();
    r.distance_mm[zone(3, 1)] = -12;
    r.distance_mm[zone(4, 1)] = i16::MIN;
    r.distance_mm[zone(3, 3)] = 0;
    let out = reduce(&r, &DepthConfig::default());
    assert_eq!(out.range_mm[6], None);
    assert_eq!(out.range_mm[4], Some(2000));
    assert_eq!(out.dropped_distance, 3);
    assert_eq!(out.dropped_status, 0);
}

#[test]
fn odd_row_configs_do_not_panic() {
    let r = uniform();
    let past_end = DepthConfig {
        first_row: 6,
        last_row: 200,
    };
    assert_eq!(reduce(&r, &past_end).range_mm, [Some(2000); 8]);
    let empty = DepthConfig {
        first_row: 9,
        last_row: 2,
    };
    assert_eq!(reduce(&r, &empty), BeamRanges::default());
}

#[test]
fn beams_run_left_to_right_symmetrically() {
    assert_eq!(BEAM_CENTRE_UDEG[0], -19_687_500);
    assert_eq!(BEAM_CENTRE_UDEG[7], 19_687_500);
    for b in 0..8 {
        assert_eq!(BEAM_CENTRE_UDEG[b], -BEAM_CENTRE_UDEG[7 - b]);
    }
    assert!(BEAM_CENTRE_UDEG
        .windows(2)
        .all(|w| w[1] - w[0] == 5_625_000));
}

/// The SLAM core maps beam `b` along the direction its zones look: the seed's depth fan
/// is the core's `fan` of the sensor's width, and each of its angles is the zone centre
/// to within the millidegree the core's fan rounds to.
#[test]
fn the_cores_beam_angles_are_the_sensors_zone_centres() {
    let fan = slam_core::slam::fan(i64::from(FOV_MDEG));
    assert_eq!(slam_core::DepthConfig::SEED.beam_angles, fan);
    for (angle, udeg) in fan.iter().zip(BEAM_CENTRE_UDEG) {
        let off_udeg = angle.to_microdegrees() - udeg;
        assert!(off_udeg.abs() <= 1_000, "{udeg} udeg against {angle:?}");
    }
}

#[test]
fn zones_without_a_target_are_dropped_whatever_their_stale_status() {
    // The part reports 0 targets in column 2's zones but leaves a "valid" status and an
    // old distance in the buffer; those zones must not make a beam.
    let mut targets = [1u8; ZONE_COUNT];
    for row in 0..8 {
        targets[zone(row, 2)] = 0;
    }
    let z = ZoneResult::from_frame([750; ZONE_COUNT], [STATUS_VALID; ZONE_COUNT], &targets);
    assert_eq!(z.target_status[zone(3, 2)], STATUS_NO_TARGET);
    assert_eq!(z.target_status[zone(3, 3)], STATUS_VALID);
    let out = reduce(&z, &DepthConfig::default());
    // Sensor column 2 is beam 5.
    assert_eq!(out.range_mm[5], None);
    assert_eq!(out.range_mm[4], Some(750));
    assert_eq!(out.dropped_status, 2);
}
