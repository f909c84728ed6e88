//! The policy that keeps the map: a doubted input holds the motion that needs it, no scan
//! is written at a pose the core cannot vouch for, and trust comes back with plausible
//! readings.

use slam_core::depth_step::{DepthSteps, ZoneTurn};
use slam_core::slam::fan;
use slam_core::{
    Angle, DepthScan, Doubt, DriveCommand, FlowDelta, GyroRate, Input, Localiser, PlausibleConfig,
    Pose, SensorFrame, Slam, StepReport, BEAMS,
};

type Robot = Slam<46, 46>;

const TURN_MDPS: i32 = 31_500;

fn robot() -> Robot {
    let mut config = world::shipped::seed_robot().config;
    config.localiser = Localiser::Filter;
    Robot::new(config, Pose::from_mm_mdeg(1000, 1000, 0)).expect("config")
}

/// Tick `k`: a gyro reading (jittered as a real one is), still flow, a scan of a wall
/// whose ranges move a little from tick to tick.
fn frame(k: i32, gyro_mdps: Option<i32>) -> SensorFrame {
    let mut f = SensorFrame::empty(100_000);
    f.gyro = gyro_mdps.map(|r| GyroRate {
        rate_mdps: r + (k * 7919) % 41 - 20,
    });
    f.flow = Some(FlowDelta {
        forward_counts: k % 3 - 1,
        right_counts: 0,
    });
    f.depth = Some(DepthScan {
        ranges_mm: [Some(800 + (k % 13) as u16); BEAMS],
    });
    f
}

/// A tag straight ahead, `distance_mm` away (the picture's centre column): where the
/// wall of [`frame`]'s scan stands, at 800 mm.
fn tag_ahead(distance_mm: u32) -> slam_core::TagDetection {
    slam_core::TagDetection {
        id: 99,
        cx_centipx: 16_000 + 300,
        distance_mm,
    }
}

fn heading_mdeg(r: &StepReport) -> i32 {
    r.pose.heading.to_millidegrees()
}

#[test]
fn a_lost_gyro_holds_the_turn_withholds_scans_and_is_trusted_again() {
    let mut slam = robot();
    let mut k = 0;
    let mut step = |slam: &mut Robot, gyro: Option<i32>| {
        k += 1;
        slam.step(&frame(k, gyro))
    };
    for _ in 0..10 {
        let r = step(&mut slam, Some(TURN_MDPS));
        assert_eq!(r.trust.gyro, None);
        assert!(r.cells_written > 0);
    }
    let before = heading_mdeg(&step(&mut slam, Some(TURN_MDPS)));
    assert!(!slam.depth_steps_void());

    // The first tick without it: the robot was still turning; the last rate stands in,
    // the turn is held and the scan is not written.
    let lost = step(&mut slam, None);
    assert_eq!(lost.trust.gyro, Some(Doubt::Missing));
    assert_eq!(lost.trust.lacking(true, false), Some(Input::Gyro));
    assert_eq!(lost.cells_written, 0);
    // The depth task holds its frames to each other by the gyro's turn: what their steps
    // summed to while the gyro is doubted is void.
    assert!(slam.depth_steps_void());
    let turned = heading_mdeg(&lost) - before;
    assert!((3_000..3_300).contains(&turned), "{turned} mdeg");

    // Held: the heading stays, nothing is mapped, the withheld scans are counted.
    for _ in 0..20 {
        let r = step(&mut slam, None);
        assert_eq!(heading_mdeg(&r), heading_mdeg(&lost));
        assert_eq!(r.cells_written, 0);
    }
    assert_eq!(slam.counters().scans_withheld, 21);
    assert_eq!(slam.counters().gyro_doubted, 21);

    // Back, and still (the robot was held): trusted again after three plausible ticks,
    // with the heading's uncertainty no worse than a few ticks' worth.
    let mut trusted_after = 0;
    let mut last = lost;
    while last.trust.gyro.is_some() {
        last = step(&mut slam, Some(0));
        trusted_after += 1;
    }
    assert_eq!(trusted_after, 3);
    let hh = last.estimate.expect("filter").covariance.hh;
    let hh_lost = lost.estimate.expect("filter").covariance.hh;
    assert!(hh < 2 * hh_lost, "{hh} vs {hh_lost} when lost");
    // The turn's lost tick left the heading unsure past what the filter maps at, and no
    // tag is in view to place it again: the trusted gyro's scans still wait.
    assert!(!slam.estimator().sure_enough_to_map());
    assert_eq!(last.cells_written, 0);
    assert_eq!(slam.counters().scans_withheld, 24);
}

#[test]
fn a_gyro_stuck_or_impossible_is_doubted_and_the_guard_holds() {
    let mut slam = robot();
    let config = slam_core::GuardConfig::SEED;
    let turn = DriveCommand {
        speed_mm_s: 0,
        turn_mdps: TURN_MDPS,
    };
    let mut doubts = Vec::new();
    for k in 0..12 {
        // From tick 4 the gyro repeats one raw value; from tick 10 it reads garbage.
        let mut f = frame(k.min(4), Some(TURN_MDPS));
        if k >= 10 {
            f.gyro = Some(GyroRate {
                rate_mdps: 1_500_000,
            });
        }
        let r = slam.step(&f);
        let decision = slam_core::decide(&config, &r.pose, slam.map(), None, &r.trust, turn);
        doubts.push((r.trust.gyro, decision.is_go()));
    }
    // Ticks 4 to 8 repeat tick 4's reading: the fifth equal reading is stuck.
    assert_eq!(doubts[7], (None, true));
    assert_eq!(doubts[8], (Some(Doubt::Stuck), false));
    assert_eq!(doubts[11], (Some(Doubt::Stuck), false));
}

#[test]
fn a_repeated_or_impossible_depth_frame_is_not_mapped() {
    let mut slam = robot();
    // Each frame judged where it arrives, as the firmware's depth task and host-sim do:
    // the repeat is seen there, the impossible range there and in the core.
    let mut steps = DepthSteps::default();
    let fan = ZoneTurn::new(&fan(45_000));
    let limits = PlausibleConfig::SEED;
    let mut moment = 0u32;
    let mut step = |slam: &mut Robot, mut f: SensorFrame| {
        moment += 100_000;
        if let Some(scan) = &f.depth {
            f.depth_doubt = steps.judge(scan, moment, Angle::ZERO, &fan, &limits).err();
        }
        slam.step(&f)
    };
    let still = |k: i32| frame(k, Some(0));
    assert!(step(&mut slam, still(1)).cells_written > 0);
    let repeated = step(&mut slam, still(1));
    assert_eq!(repeated.trust.depth, Some(Doubt::Stuck));
    assert_eq!(repeated.cells_written, 0);
    let mut garbage = still(2);
    garbage.depth = Some(DepthScan {
        ranges_mm: [Some(60_000); BEAMS],
    });
    assert_eq!(step(&mut slam, garbage.clone()).cells_written, 0);
    // The core refuses an impossible range on its own too.
    garbage.depth_doubt = None;
    assert_eq!(slam.step(&garbage).trust.depth, Some(Doubt::Stuck));
    assert_eq!(slam.step(&garbage).cells_written, 0);
    // Three new frames in a row and the sensor is believed again; the pose never was
    // in doubt.
    let reports: Vec<_> = (3..6).map(|k| step(&mut slam, still(k))).collect();
    assert!(reports.iter().all(|r| r.trust.pose()));
    assert_eq!(reports[1].cells_written, 0);
    assert_eq!(reports[2].trust.depth, None);
    assert!(reports[2].cells_written > 0);
}

#[test]
fn a_gyro_reading_more_turn_than_commanded_is_doubted_and_the_turn_held() {
    let config = slam_core::GuardConfig::SEED;
    let turn = DriveCommand {
        speed_mm_s: 0,
        turn_mdps: TURN_MDPS,
    };
    let still = DriveCommand::default();
    // Tick `k`'s frame, driven with `commanded`, the gyro reading `gyro`.
    let told = |k: i32, gyro: i32, commanded: Option<DriveCommand>| SensorFrame {
        commanded,
        ..frame(k, Some(gyro))
    };
    // A 3 deg/s bias jump mid-turn, and the seed gyro's 0.75 % scale error before it.
    let honest = TURN_MDPS * 10_075 / 10_000;
    let biased = honest + 3_000;

    // Not told the command, the core believes the jump.
    let mut blind = robot();
    for k in 0..10 {
        blind.step(&told(k, honest, None));
    }
    assert_eq!(blind.step(&told(10, biased, None)).trust.gyro, None);

    let mut slam = robot();
    for k in 0..10 {
        let r = slam.step(&told(k, honest, Some(turn)));
        assert_eq!(r.trust.gyro, None);
    }
    let before = heading_mdeg(&slam.step(&told(10, honest, Some(turn))));
    // The first tick of the jump: doubted, the last trusted rate stands in, no scan, and
    // the guard holds the turn.
    let jumped = slam.step(&told(11, biased, Some(turn)));
    assert_eq!(jumped.trust.gyro, Some(Doubt::Uncommanded));
    assert_eq!(jumped.cells_written, 0);
    let turned = heading_mdeg(&jumped) - before;
    assert!((3_000..3_300).contains(&turned), "{turned} mdeg");
    let decision = slam_core::decide(&config, &jumped.pose, slam.map(), None, &jumped.trust, turn);
    assert_eq!(decision, slam_core::Decision::Hold(Input::Gyro));

    // Held, the bias reads as a turn the robot does not make: still doubted, the heading
    // stays.
    for k in 12..40 {
        let r = slam.step(&told(k, 3_000, Some(still)));
        assert_eq!(r.trust.gyro, Some(Doubt::Uncommanded));
        assert_eq!(heading_mdeg(&r), heading_mdeg(&jumped));
        assert_eq!(r.cells_written, 0);
    }
    // The bias gone: trusted after three plausible readings, and the turn goes on.
    let back: Vec<_> = (40..43)
        .map(|k| slam.step(&told(k, 20, Some(still))))
        .collect();
    assert!(back[1].trust.gyro.is_some());
    assert_eq!(back[2].trust.gyro, None);
    assert!(back[2].cells_written > 0);
    for k in 43..53 {
        assert_eq!(slam.step(&told(k, honest, Some(turn))).trust.gyro, None);
    }
}

#[test]
#[cfg(feature = "tag-range")]
fn a_depth_sensor_that_disagrees_with_a_tag_is_not_mapped_until_a_tag_agrees() {
    let mut slam = robot();
    let mut k = 0;
    let mut step = |slam: &mut Robot, offset_mm: u16, seen: Option<u32>| {
        k += 1;
        let mut f = frame(k, Some(0));
        if let Some(scan) = &mut f.depth {
            for r in scan.ranges_mm.iter_mut().flatten() {
                *r += offset_mm;
            }
        }
        if let Some(d) = seen {
            f.tags.push(tag_ahead(d)).expect("room for a tag");
        }
        slam.step(&f)
    };
    for _ in 0..5 {
        let r = step(&mut slam, 0, Some(806));
        assert_eq!(r.trust.depth, None);
        assert!(r.cells_written > 0);
    }
    // Every range 150 mm long: the tag in view says the wall is nearer.
    let lying = step(&mut slam, 150, Some(806));
    assert_eq!(lying.trust.depth, Some(Doubt::DisagreesWithTag));
    assert_eq!(lying.cells_written, 0);
    assert_eq!(lying.counters.scans_withheld, 1);
    // With no tag in view nothing vouches for the ranges, however plausible.
    for _ in 0..10 {
        let r = step(&mut slam, 0, None);
        assert_eq!(r.trust.depth, Some(Doubt::DisagreesWithTag));
        assert_eq!(r.cells_written, 0);
    }
    // Tags that agree again: trusted after the usual run of good readings.
    let agreed: Vec<StepReport> = (0..3).map(|_| step(&mut slam, 0, Some(806))).collect();
    assert_eq!(agreed[1].trust.depth, Some(Doubt::DisagreesWithTag));
    assert_eq!(agreed[2].trust.depth, None);
    assert!(agreed[2].cells_written > 0);
}

#[test]
fn a_scan_the_depth_task_doubts_is_not_mapped_and_a_tag_outranks_it() {
    let mut slam = robot();
    let mut k = 0;
    let mut step = |slam: &mut Robot, doubt: Option<Doubt>, seen: Option<u32>| {
        k += 1;
        let mut f = frame(k, Some(0));
        f.depth_doubt = doubt;
        if let Some(d) = seen {
            f.tags.push(tag_ahead(d)).expect("room for a tag");
        }
        slam.step(&f)
    };
    for _ in 0..3 {
        assert!(step(&mut slam, None, None).cells_written > 0);
    }
    // Late frames: doubted and withheld while the depth task says so; then three
    // frames it passes and the sensor is trusted again.
    for _ in 0..4 {
        let r = step(&mut slam, Some(Doubt::Late), None);
        assert_eq!((r.trust.depth, r.cells_written), (Some(Doubt::Late), 0));
    }
    for _ in 0..2 {
        assert_eq!(step(&mut slam, None, None).trust.depth, Some(Doubt::Late));
    }
    let back = step(&mut slam, None, None);
    assert_eq!(back.trust.depth, None);
    assert!(back.cells_written > 0);
    assert!(!slam.depth_vouched());
    // A step in the ranges the depth task saw, then a tag that disagrees: from then only
    // tags lift the doubt, whatever the depth task says.
    assert_eq!(
        step(&mut slam, Some(Doubt::Jump), None).trust.depth,
        Some(Doubt::Jump)
    );
    let told = step(&mut slam, Some(Doubt::Jump), Some(1_000));
    assert_eq!(told.trust.depth, Some(Doubt::DisagreesWithTag));
    assert!(!slam.depth_vouched());
    for _ in 0..5 {
        let r = step(&mut slam, None, None);
        assert_eq!(
            (r.trust.depth, r.cells_written),
            (Some(Doubt::DisagreesWithTag), 0)
        );
    }
    // A tag that agrees vouches for the ranges: the depth task is told.
    step(&mut slam, None, Some(806));
    assert!(slam.depth_vouched());
}
