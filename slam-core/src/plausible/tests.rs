use super::*;
use crate::frame::BEAMS;

const C: PlausibleConfig = PlausibleConfig::SEED;

/// A turn on the spot and a straight drive, as the route commands them.
const TURN: DriveCommand = DriveCommand {
    speed_mm_s: 0,
    turn_mdps: 31_500,
};
const DRIVE: DriveCommand = DriveCommand {
    speed_mm_s: 86,
    turn_mdps: 0,
};
/// Standing.
const STOP: DriveCommand = DriveCommand {
    speed_mm_s: 0,
    turn_mdps: 0,
};

/// Checks that have seen four ticks of a steady turn on the spot, its readings
/// trusted (the flow's a count or so: the sensor sits on the axis).
fn after_a_turn() -> Plausibility {
    let mut p = Plausibility::default();
    for i in 0..4 {
        p.judge(
            Some(rate(31_500 + i)),
            Some(flow(i, 0)),
            None,
            Some(TURN),
            &C,
        );
    }
    p
}

fn rate(mdps: i32) -> GyroRate {
    GyroRate { rate_mdps: mdps }
}

fn flow(forward: i32, right: i32) -> FlowDelta {
    FlowDelta {
        forward_counts: forward,
        right_counts: right,
    }
}

#[test]
fn a_rate_no_robot_turns_at_is_impossible() {
    assert_eq!(check_gyro(rate(31_500), None, 0, false, &C), Ok(()));
    assert_eq!(check_gyro(rate(-344_000), None, 0, false, &C), Ok(()));
    assert_eq!(
        check_gyro(rate(344_001), None, 0, false, &C),
        Err(Doubt::Impossible)
    );
    assert_eq!(
        check_gyro(rate(i32::MIN), None, 0, false, &C),
        Err(Doubt::Impossible)
    );
}

#[test]
fn a_rate_that_jumps_more_than_a_turn_starts_is_a_jump() {
    // Starting or ending a 31.5 deg/s turn is a step the robot makes.
    assert_eq!(
        check_gyro(rate(31_500), Some(rate(0)), 0, false, &C),
        Ok(())
    );
    assert_eq!(
        check_gyro(rate(-20_000), Some(rate(31_500)), 0, false, &C),
        Err(Doubt::Jump)
    );
}

#[test]
fn a_gyro_on_one_value_for_n_ticks_is_stuck() {
    let mut repeats = Repeats::default();
    let verdicts: std::vec::Vec<_> = (0..6)
        .map(|_| {
            let (before, n) = repeats.push(rate(31_512));
            check_gyro(rate(31_512), before, n, false, &C)
        })
        .collect();
    assert_eq!(verdicts[..4], [Ok(()); 4]);
    assert_eq!(verdicts[4..], [Err(Doubt::Stuck); 2]);
    // A new value starts the count again.
    assert_eq!(repeats.push(rate(31_490)).1, 0);
}

#[test]
fn a_turn_read_while_held_is_doubted() {
    assert_eq!(check_gyro(rate(1_500), Some(rate(0)), 0, true, &C), Ok(()));
    assert_eq!(
        check_gyro(rate(3_000), Some(rate(0)), 0, true, &C),
        Err(Doubt::MovedWhileHeld)
    );
}

#[test]
fn flow_faster_than_a_drive_or_sideways_is_impossible() {
    assert_eq!(check_flow(flow(86, -3), 0, false, &C), Ok(()));
    assert_eq!(
        check_flow(flow(-401, 0), 0, false, &C),
        Err(Doubt::Impossible)
    );
    assert_eq!(
        check_flow(flow(10, 101), 0, false, &C),
        Err(Doubt::Impossible)
    );
    assert_eq!(
        check_flow(flow(i32::MIN, 0), 0, false, &C),
        Err(Doubt::Impossible)
    );
}

#[test]
fn flow_stuck_or_moving_while_held_is_doubted() {
    assert_eq!(check_flow(flow(86, 1), 4, false, &C), Err(Doubt::Stuck));
    assert_eq!(check_flow(flow(86, 1), 3, false, &C), Ok(()));
    assert_eq!(
        check_flow(flow(86, 1), 0, true, &C),
        Err(Doubt::MovedWhileHeld)
    );
    assert_eq!(check_flow(flow(2, -1), 0, true, &C), Ok(()));
}

fn scan(ranges: &[Option<u16>]) -> DepthScan {
    let mut s = DepthScan::default();
    for (slot, r) in s.ranges_mm.iter_mut().zip(ranges) {
        *slot = *r;
    }
    s
}

#[test]
fn a_depth_frame_repeated_bit_for_bit_is_stuck() {
    let full = scan(&[Some(812); BEAMS]);
    assert_eq!(check_depth(&full, 0, &C), Ok(()));
    assert_eq!(check_depth(&full, 1, &C), Err(Doubt::Stuck));
    // One return may repeat by chance: only a long run is stuck.
    let sparse = scan(&[Some(812), None]);
    assert_eq!(check_depth(&sparse, 3, &C), Ok(()));
    assert_eq!(check_depth(&sparse, 4, &C), Err(Doubt::Stuck));
    // No return at all writes nothing: never stuck.
    assert_eq!(check_depth(&DepthScan::default(), 9, &C), Ok(()));
}

#[test]
fn a_range_beyond_the_sensor_is_impossible() {
    assert_eq!(check_depth(&scan(&[Some(4_500)]), 0, &C), Ok(()));
    assert_eq!(
        check_depth(&scan(&[None, Some(4_501)]), 0, &C),
        Err(Doubt::Impossible)
    );
}

#[test]
fn trust_comes_back_after_enough_good_readings_in_a_row() {
    let mut p = Plausibility::default();
    let tick = |p: &mut Plausibility, g: Option<i32>| p.judge(g.map(rate), None, None, None, &C);
    // Never heard: not doubted, nothing known.
    let first = tick(&mut p, None);
    assert_eq!((first.trust, first.gyro), (Trust::default(), Known::Lost));
    assert_eq!(tick(&mut p, Some(31_500)).gyro, Known::Read(rate(31_500)));
    // Lost while turning: the last trusted rate stands in, then the robot is held.
    let lost = tick(&mut p, None);
    assert_eq!(lost.trust.gyro, Some(Doubt::Missing));
    assert_eq!(lost.trust.lacking(true, false), Some(Input::Gyro));
    assert_eq!(lost.gyro, Known::StandIn(rate(31_500)));
    assert_eq!(tick(&mut p, None).gyro, Known::Still);
    // Back, still: two good readings are not yet enough, a third is.
    for _ in 0..2 {
        let j = tick(&mut p, Some(10));
        assert_eq!((j.trust.gyro, j.gyro), (Some(Doubt::Missing), Known::Still));
    }
    // A turn while held resets the count.
    assert_eq!(tick(&mut p, Some(31_500)).gyro, Known::Still);
    for _ in 0..2 {
        assert!(tick(&mut p, Some(20)).trust.gyro.is_some());
    }
    let back = tick(&mut p, Some(-20));
    assert_eq!(
        (back.trust, back.gyro),
        (Trust::default(), Known::Read(rate(-20)))
    );
}

#[test]
fn a_stand_in_is_a_reading_while_the_commands_are_steady_and_a_guess_after_a_change() {
    let turning = || {
        let mut p = Plausibility::default();
        for _ in 0..4 {
            let j = p.judge(Some(rate(31_500)), None, None, Some(TURN), &C);
            assert_eq!(j.trust, Trust::default());
        }
        p
    };
    // Lost in a steady turn: the robot turns as it did.
    let lost = turning().judge(None, None, None, Some(TURN), &C);
    assert_eq!(lost.gyro, Known::Read(rate(31_500)));
    // Lost as the turn gives way to a drive: the turn's rate was not read under the
    // drive, whose own (none) is the guess.
    let lost = turning().judge(None, None, None, Some(DRIVE), &C);
    assert_eq!(lost.gyro, Known::StandIn(rate(0)));
    // With the commands not known, the last rate is.
    let lost = turning().judge(None, None, None, None, &C);
    assert_eq!(lost.gyro, Known::StandIn(rate(31_500)));
}

#[test]
fn a_sensor_behind_its_command_stands_in_for_the_window_it_missed() {
    // Standing, then a drive the flow reads nothing of, three ticks late: the robot
    // is not held in the first two, the second's scan is not vouched for, and at
    // the third every one of the window's commands asked for a drive.
    let still = Some(STOP);
    let mut p = Plausibility::default();
    for i in 0..4 {
        let j = p.judge(Some(rate(i)), Some(flow(i % 2, 0)), None, still, &C);
        assert!(!j.unfollowed.any());
    }
    // On the first frame of the drive the motors may not have followed it yet; a
    // frame later a reading short of it is trusted but only a guess.
    let j = p.judge(Some(rate(0)), Some(flow(0, 0)), None, Some(DRIVE), &C);
    assert_eq!((j.trust, j.unfollowed.any()), (Trust::default(), false));
    assert_eq!(j.flow, Known::Read(flow(0, 0)));
    let j = p.judge(Some(rate(1)), Some(flow(1, 0)), None, Some(DRIVE), &C);
    assert_eq!(j.trust, Trust::default());
    assert_eq!((j.unfollowed.gyro, j.unfollowed.flow), (false, true));
    assert_eq!(j.flow, Known::StandIn(flow(1, 0)));
    assert_eq!(j.gyro, Known::Read(rate(1)));
    let j = p.judge(Some(rate(5)), Some(flow(1, 0)), None, Some(DRIVE), &C);
    assert_eq!(j.trust.flow, Some(Doubt::Unmoved));
    assert_eq!(j.flow, Known::StandIn(flow(3 * 86, 0)));
    assert_eq!(j.gyro, Known::Read(rate(5)));
    // From the next tick the drive is held: the flow's late counts are no motion.
    let j = p.judge(Some(rate(6)), Some(flow(86, 0)), None, Some(DRIVE), &C);
    assert_eq!(j.flow, Known::Still);
    // The gyro alike, in a turn.
    let mut p = Plausibility::default();
    for i in 0..4 {
        p.judge(Some(rate(i)), Some(flow(i % 2, 0)), None, still, &C);
    }
    for i in 0..2 {
        p.judge(Some(rate(i)), Some(flow(i % 2, 0)), None, Some(TURN), &C);
    }
    let j = p.judge(Some(rate(2)), Some(flow(0, 0)), None, Some(TURN), &C);
    assert_eq!(j.trust.gyro, Some(Doubt::Unmoved));
    assert_eq!(j.gyro, Known::StandIn(rate(3 * 31_500)));
}

#[test]
fn a_sensor_behind_its_command_as_the_motion_ends_is_taken_back() {
    // A turn on the spot ends; the gyro, three ticks late, reads it on. On the first
    // frame after the stop the motors may still have turned: the reading is the
    // motion. A frame later a reading past the stop is a sensor behind: what the
    // frame before read past it is taken back, so that the two frames together hold
    // the stop's motion (none), and the scan is not vouched for.
    // As the core judges: a guessed tick's readings past a command stand in for it.
    let judge = |p: &mut Plausibility, g: i32, f: i32, c: DriveCommand| {
        let mut j = p.judge(Some(rate(g)), Some(flow(f, 0)), None, Some(c), &C);
        if j.guessed() {
            p.stand_in_past(&mut j);
        }
        j
    };
    let mut p = after_a_turn();
    let j = judge(&mut p, 31_504, 0, STOP);
    assert_eq!(j.gyro, Known::Read(rate(31_504)));
    let j = judge(&mut p, 31_505, 1, STOP);
    assert_eq!(j.trust, Trust::default());
    assert_eq!((j.unfollowed.gyro, j.unfollowed.flow), (true, false));
    assert_eq!(j.gyro, Known::StandIn(rate(-31_504)));
    // The third reads past every command of the window: doubted, and the robot is
    // taken as standing.
    let j = judge(&mut p, 31_506, 0, STOP);
    assert_eq!(j.trust.gyro, Some(Doubt::Uncommanded));
    assert_eq!(j.gyro, Known::Still);

    // The flow alike as a drive gives way to a turn on the spot.
    let mut p = Plausibility::default();
    for i in 0..4 {
        p.judge(Some(rate(i)), Some(flow(86 - i, 0)), None, Some(DRIVE), &C);
    }
    let j = judge(&mut p, 31_500, 84, TURN);
    assert_eq!(j.flow, Known::Read(flow(84, 0)));
    let j = judge(&mut p, 31_501, 85, TURN);
    assert_eq!(j.flow, Known::StandIn(flow(-84, 0)));
    assert_eq!(j.gyro, Known::Read(rate(31_501)));

    // Only a frame right after its own change is taken back: a reading past the
    // command two changes on takes back nothing.
    let mut p = after_a_turn();
    judge(&mut p, 31_504, 0, STOP);
    judge(&mut p, 0, 0, DRIVE);
    let j = judge(&mut p, 31_505, 86, DRIVE);
    assert_eq!(j.gyro, Known::StandIn(rate(0)));
}

/// A flow three ticks late: a drive of two ticks reads nothing, too short to be found
/// short of its commands, and its counts come under the turn after it, past every
/// command the window holds: integrated, as it was owed. A drive long enough to be
/// found short has its window stood in, so the counts that come after it owe nothing;
/// nor does a still robot's noise.
#[test]
fn a_drives_late_counts_are_integrated_once() {
    // As the core judges: a guessed tick's readings past a command stand in for it,
    // then the flow is settled.
    let judge_under = |p: &mut Plausibility, f: i32, c: DriveCommand, config| {
        let read = Some(flow(f, 0));
        let mut j = p.judge(Some(rate(c.turn_mdps)), read, None, Some(c), config);
        if j.guessed() {
            p.stand_in_past(&mut j);
        }
        p.settle_flow(read, &mut j, config);
        j.flow.reading().map_or(0, |r| r.forward_counts)
    };
    let judge = |p: &mut Plausibility, f: i32, c: DriveCommand| judge_under(p, f, c, &C);
    let standing = || {
        let mut p = Plausibility::default();
        for i in 0..6 {
            p.judge(
                Some(rate(i % 2)),
                Some(flow(i % 2, 0)),
                None,
                Some(STOP),
                &C,
            );
        }
        p
    };
    // Two ticks of drive read as nothing, then a turn: the late counts are the drive's.
    let mut p = standing();
    let hop: Vec<i32> = [
        (0, DRIVE),
        (1, DRIVE),
        (2, TURN),
        (86, TURN),
        (85, TURN),
        (1, TURN),
    ]
    .into_iter()
    .map(|(f, c)| judge(&mut p, f, c))
    .collect();
    assert_eq!(hop.get(3..5), Some(&[86, 85][..]), "{hop:?}");

    // A drive found short on its third tick stands in its window: the counts that
    // come after it are that window's, and owe nothing.
    let mut p = standing();
    let mut drive = Vec::new();
    for (f, c) in [
        (0, DRIVE),
        (1, DRIVE),
        (0, DRIVE),
        (86, STOP),
        (85, STOP),
        (84, STOP),
    ] {
        drive.push(judge(&mut p, f, c));
    }
    for _ in 0..6 {
        drive.push(judge(&mut p, 0, STOP));
    }
    assert_eq!(drive.get(2..6), Some(&[3 * 86, 0, 0, 0][..]), "{drive:?}");
    assert_eq!(drive.iter().skip(6).sum::<i32>(), 0, "{drive:?}");

    // Limits as wide as a config may set them bound what is owed without overflow.
    let wide = PlausibleConfig {
        max_flow_counts: u32::MAX,
        ..C
    };
    let mut p = standing();
    let late: Vec<i32> = [(0, DRIVE), (1, DRIVE), (2, TURN), (300, TURN)]
        .into_iter()
        .map(|(f, c)| judge_under(&mut p, f, c, &wide))
        .collect();
    assert_eq!(late.last(), Some(&300), "{late:?}");

    // A flow reading long drives the robot no further than its stand-in: the counts
    // past the drive it was read under are not owed, then or after it.
    let mut p = standing();
    let long: Vec<i32> = [
        (1, STOP),
        (112, DRIVE),
        (1, STOP),
        (112, DRIVE),
        (0, STOP),
        (3, STOP),
        (1, STOP),
    ]
    .into_iter()
    .map(|(f, c)| judge(&mut p, f, c))
    .collect();
    assert!(long.iter().all(|&f| f <= 86), "{long:?}");

    // Standing, the noise is not motion, however long.
    let mut p = standing();
    let still: i32 = (0..20).map(|i| judge(&mut p, 2 * (i % 3) - 2, STOP)).sum();
    assert_eq!(still, 0);
}

#[test]
fn a_reading_from_another_command_is_not_one_for_this() {
    let mut p = Plausibility::default();
    // Readings as noisy as a real sensor's: one repeated bit for bit is stuck.
    for i in 0..4 {
        p.judge(Some(rate(i)), Some(flow(86 - i, 0)), None, Some(DRIVE), &C);
    }
    // The flow drops out as the drive ends and the turn on the spot begins; its
    // readings in the turn are trusted again while the robot is still held for it,
    // so none of them is the newest taken while moving...
    p.judge(Some(rate(0)), None, None, Some(DRIVE), &C);
    for i in 0..3 {
        p.judge(
            Some(rate(31_500 + i)),
            Some(flow(1 - i, 0)),
            None,
            Some(TURN),
            &C,
        );
    }
    // ...and when it is lost again in the steady turn, the last drive's counts are
    // not this tick's: the turn's commands say the robot does not drive.
    let lost = p.judge(Some(rate(31_490)), None, None, Some(TURN), &C);
    assert!(lost.trust.flow.is_some());
    assert_eq!(lost.flow, Known::Still);
}

#[test]
fn a_drive_resumed_after_a_hold_stands_in_its_command_unless_it_was_read_under_it() {
    // Read in a turn (no drive), then in a drive when `drive_first`; the flow then
    // reads a third long, is doubted and the drive held; standing, it is trusted
    // again; the drive resumes and it reads long again.
    let resumed = |drive_first: bool| {
        let mut p = after_a_turn();
        if drive_first {
            for i in 0..4 {
                p.judge(Some(rate(i)), Some(flow(86 - i, 0)), None, Some(DRIVE), &C);
            }
        }
        let long = p.judge(Some(rate(0)), Some(flow(115, 0)), None, Some(DRIVE), &C);
        assert_eq!(long.trust.flow, Some(Doubt::Uncommanded));
        for i in 0..3 {
            p.judge(Some(rate(i)), Some(flow(i % 2, 0)), None, Some(STOP), &C);
        }
        assert_eq!(p.trust(), Trust::default());
        let again = p.judge(Some(rate(0)), Some(flow(115, 0)), None, Some(DRIVE), &C);
        assert_eq!(again.trust.flow, Some(Doubt::Uncommanded));
        again.flow
    };
    // The turn's counts are no drive's: the drive's own stand in...
    assert_eq!(resumed(false), Known::StandIn(flow(86, 0)));
    // ...unless a reading was taken under this very drive.
    assert_eq!(resumed(true), Known::StandIn(flow(83, 0)));
}

#[test]
fn a_stopped_robot_holds_its_pose_whatever_its_trusted_gyro_and_flow_read() {
    let mut p = after_a_turn();
    // The turn has stopped, but the window still holds it: the readings are the motion.
    let stopping = p.judge(Some(rate(25)), Some(flow(0, 1)), None, Some(STOP), &C);
    assert_eq!(
        (stopping.gyro, stopping.flow),
        (Known::Read(rate(25)), Known::Read(flow(0, 1)))
    );
    p.judge(Some(rate(-5)), Some(flow(1, 0)), None, Some(STOP), &C);
    // Every command of the window standing: the bias and the noise are no motion.
    for i in 0..3 {
        let j = p.judge(Some(rate(20 + i)), Some(flow(i, -i)), None, Some(STOP), &C);
        assert_eq!(
            (j.trust, j.gyro, j.flow),
            (Trust::default(), Known::Still, Known::Still)
        );
    }
    // With the commands not known, the readings are the motion.
    let unknown = p.judge(Some(rate(23)), Some(flow(2, 0)), None, None, &C);
    assert_eq!(
        (unknown.gyro, unknown.flow),
        (Known::Read(rate(23)), Known::Read(flow(2, 0)))
    );
}

#[test]
fn a_doubted_flow_holds_drives_not_turns() {
    let mut p = Plausibility::default();
    let mut not_turning_with_flow =
        |forward: i32| p.judge(Some(rate(0)), Some(flow(forward, 0)), None, None, &C);
    not_turning_with_flow(86);
    let garbage = not_turning_with_flow(9_000);
    assert_eq!(garbage.trust.flow, Some(Doubt::Impossible));
    assert_eq!(garbage.flow, Known::StandIn(flow(86, 0)));
    assert_eq!(garbage.trust.lacking(true, false), None);
    assert_eq!(garbage.trust.lacking(false, true), Some(Input::Flow));
    assert!(!garbage.trust.pose());
    let held = not_turning_with_flow(1);
    assert_eq!(held.flow, Known::Still);
}

#[test]
fn trust_packs_into_sixteen_bits_and_back() {
    let t = Trust {
        gyro: Some(Doubt::Stuck),
        flow: None,
        depth: Some(Doubt::MovedWhileHeld),
    };
    assert_eq!(t.packed(), 2 | (5 << 8));
    assert_eq!(Trust::unpacked(t.packed()), t);
    assert_eq!(Trust::unpacked(0), Trust::default());
    for d in Doubt::ALL {
        assert_eq!(Doubt::from_code(d.code()), Some(d));
    }
    assert_eq!(Doubt::from_code(0), None);
    assert_eq!(Doubt::from_code(Doubt::ALL.len() as u8 + 1), None);
}
