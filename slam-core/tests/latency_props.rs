//! Tag fixes from pictures older than the tick: placed at the picture's moment, carried to
//! the tick by the odometry since, against the truth, the `f64` reference and the
//! behaviour before pictures had an age.

mod reference;

use proptest::prelude::*;
use reference::{bits_to_rad, RAD_PER_BIT};
use slam_core::history::HISTORY_LEN;
use slam_core::odometry;
use slam_core::tagfix::{self, FixRejection};
use slam_core::{
    Angle, FixOutcome, FlowDelta, GyroRate, OdometryConfig, Pose, SensorFrame, Slam, SlamConfig,
    StepReport, TagDetection, TagDetections,
};

const DT_US: u32 = 100_000;
const DT_S: f64 = 0.1;
const TAGS: [(u16, (f64, f64)); 2] = [(11, (700.0, 1950.0)), (12, (1500.0, 1950.0))];

fn config() -> ProptestConfig {
    ProptestConfig {
        failure_persistence: None,
        ..ProptestConfig::default()
    }
}

/// A true pose in millimetres and radians (heading unwrapped).
#[derive(Clone, Copy, Debug)]
struct Truth {
    x_mm: f64,
    y_mm: f64,
    heading: f64,
}

/// A robot driving at `speed_mm_s` while turning at `rate_mdps` (both constant) from
/// `start`: its true pose `t_s` seconds in, on the exact arc.
#[derive(Clone, Copy, Debug)]
struct Motion {
    start: Truth,
    speed_mm_s: f64,
    rate_mdps: i32,
}

impl Motion {
    fn rate(&self) -> f64 {
        (self.rate_mdps as f64 / 1000.0).to_radians()
    }

    fn at(&self, t_s: f64) -> Truth {
        let (s, v, w) = (self.start, self.speed_mm_s, self.rate());
        let h = s.heading + w * t_s;
        let (x, y) = if w.abs() < 1e-12 {
            (
                s.x_mm + v * t_s * s.heading.sin(),
                s.y_mm + v * t_s * s.heading.cos(),
            )
        } else {
            // d/dt (x, y) = v (sin h, cos h) with h = h0 + w t.
            (
                s.x_mm + v / w * (s.heading.cos() - h.cos()),
                s.y_mm + v / w * (h.sin() - s.heading.sin()),
            )
        };
        Truth {
            x_mm: x,
            y_mm: y,
            heading: h,
        }
    }

    /// Tick `k`'s odometry (k from 1): the flow counts of 100 um travelled since tick
    /// `k - 1` (whole counts, the fraction carried as the sensor does) and the gyro's rate.
    fn odometry(&self, k: u32) -> (FlowDelta, GyroRate) {
        let counts = |k: u32| (self.speed_mm_s * k as f64 * DT_S * 10.0).round() as i32;
        (
            FlowDelta {
                forward_counts: counts(k) - counts(k - 1),
                right_counts: 0,
            },
            GyroRate {
                rate_mdps: self.rate_mdps,
            },
        )
    }
}

fn to_pose(t: &Truth) -> Pose {
    Pose {
        x_um: (t.x_mm * 1000.0).round() as i32,
        y_um: (t.y_mm * 1000.0).round() as i32,
        heading: Angle::from_bits(
            (t.heading.rem_euclid(std::f64::consts::TAU) / RAD_PER_BIT) as u32,
        ),
    }
}

/// Both tags as a perfect camera at `t` reads them (quantised to 0.01 px and 1 mm), or
/// `None` unless both are well inside the 120 degree view.
fn seen_from(t: &Truth) -> Option<TagDetections> {
    let mut out = TagDetections::default();
    for (id, place) in TAGS {
        let s = reference::see(t.x_mm, t.y_mm, t.heading, place);
        if reference::bearing(s.cx_px).abs() > 55f64.to_radians() {
            return None;
        }
        let dir = reference::heading_of(place.0 - t.x_mm, place.1 - t.y_mm);
        if reference::angle_diff(dir, t.heading).abs() > 55f64.to_radians() {
            return None;
        }
        out.push(TagDetection {
            id,
            cx_centipx: (s.cx_px * 100.0).round() as i32,
            distance_mm: s.distance_mm.round() as u32,
        })
        .ok()?;
    }
    Some(out)
}

/// Errors of `p` against `t`: (position mm, heading degrees, both absolute).
fn errors(p: &Pose, t: &Truth) -> (f64, f64) {
    let pos = (p.x_um as f64 / 1000.0 - t.x_mm).hypot(p.y_um as f64 / 1000.0 - t.y_mm);
    let head = reference::angle_diff(bits_to_rad(p.heading.bits()), t.heading)
        .to_degrees()
        .abs();
    (pos, head)
}

/// Drives `m` for `ticks` ticks from its start with perfect odometry; from tick
/// `first_tags` on, each tick carries the picture taken `age_us` before it, and the core
/// is told the picture's age is `told_age_us`. Returns the state and each tick's report.
fn drive(
    m: &Motion,
    ticks: u32,
    first_tags: u32,
    age_us: u32,
    told_age_us: u32,
) -> (Slam<46, 46>, Vec<StepReport>) {
    let mut slam: Slam<46, 46> = Slam::new(
        unchecked(world::shipped::seed_robot().config),
        to_pose(&m.start),
    )
    .unwrap();
    let mut reports = Vec::new();
    for k in 1..=ticks {
        let (flow, gyro) = m.odometry(k);
        let mut frame = SensorFrame::empty(DT_US);
        frame.flow = Some(flow);
        frame.gyro = Some(gyro);
        if k >= first_tags {
            let seen_at = k as f64 * DT_S - age_us as f64 / 1e6;
            frame.tags = seen_from(&m.at(seen_at)).expect("both tags in view");
            frame.tags_age_us = told_age_us;
        }
        reports.push(slam.step(&frame));
    }
    (slam, reports)
}

/// The worst error against the truth at the tick over ticks `from..`: (mm, degrees).
fn worst(m: &Motion, reports: &[StepReport], from: u32) -> (f64, f64) {
    let mut w = (0.0f64, 0.0f64);
    for (i, r) in reports.iter().enumerate().skip(from as usize - 1) {
        assert_eq!(r.fix, FixOutcome::Taken, "tick {}", i + 1);
        let (p, h) = errors(&r.pose, &m.at((i + 1) as f64 * DT_S));
        w = (w.0.max(p), w.1.max(h));
    }
    w
}

/// Driving straight up the mat at the seed's 86 mm/s with pictures 100 ms old: the
/// compensated pose is within 2 mm of the truth at every tick; told the pictures are
/// new, the core is 8.6 mm (speed x age) behind, give or take the fix's own error.
#[test]
fn driving_with_old_pictures() {
    let m = Motion {
        start: Truth {
            x_mm: 1100.0,
            y_mm: 500.0,
            heading: 0.0,
        },
        speed_mm_s: 86.0,
        rate_mdps: 0,
    };
    let (_, compensated) = drive(&m, 20, 2, 100_000, 100_000);
    let (_, stale) = drive(&m, 20, 2, 100_000, 0);
    let (c, _) = worst(&m, &compensated, 2);
    assert!(c <= 2.0, "compensated: {c} mm");
    for (i, r) in stale.iter().enumerate().skip(1) {
        let truth_now = m.at((i + 1) as f64 * DT_S);
        let (p, _) = errors(&r.pose, &truth_now);
        assert!((p - 8.6).abs() <= 2.0, "tick {}: {p} mm behind", i + 1);
        assert!(
            r.pose.y_um < (truth_now.y_mm * 1000.0) as i32,
            "behind, not ahead"
        );
    }
}

/// Turning on the spot at the seed's 31.5 deg/s across north (-30 to +20 degrees) with
/// pictures 100 ms old: the compensated heading is within 0.25 degrees at every tick;
/// uncompensated it lags 3.15 degrees (rate x age).
#[test]
fn turning_across_north_with_old_pictures() {
    let m = Motion {
        start: Truth {
            x_mm: 1100.0,
            y_mm: 900.0,
            heading: (-30f64).to_radians(),
        },
        speed_mm_s: 0.0,
        rate_mdps: 31_500,
    };
    let (slam, compensated) = drive(&m, 16, 2, 100_000, 100_000);
    let (_, stale) = drive(&m, 16, 2, 100_000, 0);
    let (p, h) = worst(&m, &compensated, 2);
    assert!(p <= 3.0 && h <= 0.25, "compensated: {p} mm, {h} deg");
    // The run ends past north: the heading wrapped through 0 / 360.
    let end = slam.pose().heading.to_millidegrees();
    assert!((19_000..=21_000).contains(&end), "{end} mdeg");
    for (i, r) in stale.iter().enumerate().skip(1) {
        let truth_now = m.at((i + 1) as f64 * DT_S);
        let lag = reference::angle_diff(truth_now.heading, bits_to_rad(r.pose.heading.bits()))
            .to_degrees();
        assert!((lag - 3.15).abs() <= 0.25, "tick {}: lags {lag} deg", i + 1);
    }
}

/// Turning at 80 deg/s with pictures 300 ms old: the robot turned 24 degrees since the
/// picture, past the 20 degree gate. Compared with the pose of the picture's moment the
/// fix is taken and lands on the truth; compared with the pose at the tick (the age
/// hidden) it is refused.
#[test]
fn the_gate_compares_the_picture_with_its_own_moment() {
    let m = Motion {
        start: Truth {
            x_mm: 1100.0,
            y_mm: 900.0,
            heading: (-40f64).to_radians(),
        },
        speed_mm_s: 0.0,
        rate_mdps: 80_000,
    };
    let (_, compensated) = drive(&m, 8, 4, 300_000, 300_000);
    let (p, h) = worst(&m, &compensated, 4);
    assert!(p <= 3.0 && h <= 0.25, "compensated: {p} mm, {h} deg");
    let (_, hidden) = drive(&m, 8, 4, 300_000, 0);
    assert_eq!(hidden[3].fix, FixOutcome::Rejected(FixRejection::Gate));
}

/// Believed 50 mm and 15 degrees off at the start, driving and turning, pictures 300 ms
/// old every tick from the fourth: the first fix moves the poses remembered since the
/// picture with the pose, so the next pictures (whose moments lie between remembered
/// poses from before that fix) are placed against corrected poses, and every tick from
/// the first fix on is within 2 mm and 0.2 degrees of the truth. Were the old poses left
/// where they were, the second fix would be gated and carried from a pose 50 mm and 15
/// degrees off.
#[test]
fn a_fix_moves_the_remembered_poses_too() {
    let m = Motion {
        start: Truth {
            x_mm: 1000.0,
            y_mm: 700.0,
            heading: (-10f64).to_radians(),
        },
        speed_mm_s: 120.0,
        rate_mdps: 10_000,
    };
    let wrong_start = Pose {
        x_um: 1_040_000,
        y_um: 670_000,
        heading: to_pose(&m.start).heading - Angle::from_millidegrees(15_000),
    };
    let mut slam: Slam<46, 46> =
        Slam::new(unchecked(world::shipped::seed_robot().config), wrong_start).unwrap();
    for k in 1..=10 {
        let (flow, gyro) = m.odometry(k);
        let mut frame = SensorFrame::empty(DT_US);
        frame.flow = Some(flow);
        frame.gyro = Some(gyro);
        if k >= 4 {
            frame.tags = seen_from(&m.at(k as f64 * DT_S - 0.3)).expect("in view");
            frame.tags_age_us = 300_000;
        }
        let r = slam.step(&frame);
        if k >= 4 {
            assert_eq!(r.fix, FixOutcome::Taken, "tick {k}");
            let (p, h) = errors(&r.pose, &m.at(k as f64 * DT_S));
            assert!(p <= 2.0 && h <= 0.2, "tick {k}: {p} mm, {h} deg");
        }
    }
}

/// A picture older than the history reaches is refused and counted, the pose left at
/// the prediction; at exactly the reach it is used. Pictures with fewer than two known
/// tags are not fixes at all, however old.
#[test]
fn too_old_pictures_are_refused_and_counted() {
    let m = Motion {
        start: Truth {
            x_mm: 1100.0,
            y_mm: 800.0,
            heading: 0.0,
        },
        speed_mm_s: 50.0,
        rate_mdps: 0,
    };
    let reach = (HISTORY_LEN as u32 - 1) * DT_US;
    let tags_then = |k: u32, age_us: u32| {
        seen_from(&m.at(k as f64 * DT_S - age_us as f64 / 1e6)).expect("in view")
    };

    // At the first tick the history holds the start and this tick: one tick back.
    let mut slam: Slam<46, 46> = Slam::new(
        unchecked(world::shipped::seed_robot().config),
        to_pose(&m.start),
    )
    .unwrap();
    let mut frame = SensorFrame::empty(DT_US);
    frame.tags = tags_then(0, 0);
    frame.tags_age_us = DT_US + 1;
    let r = slam.step(&frame);
    assert_eq!(r.fix, FixOutcome::Rejected(FixRejection::TooOld));
    assert_eq!(r.pose, to_pose(&m.start), "no odometry, no fix: the start");
    assert_eq!(r.counters.fixes_rejected_too_old, 1);

    // Further on, the reach is HISTORY_LEN - 1 ticks.
    let (mut slam, _) = drive(&m, 6, u32::MAX, 0, 0);
    let before = *slam.pose();
    let (flow, gyro) = m.odometry(7);
    let mut frame = SensorFrame::empty(DT_US);
    frame.flow = Some(flow);
    frame.gyro = Some(gyro);
    frame.tags = tags_then(7, reach + 1);
    frame.tags_age_us = reach + 1;
    let r = slam.step(&frame);
    assert_eq!(r.fix, FixOutcome::Rejected(FixRejection::TooOld));
    assert_eq!(r.counters.fixes_rejected_too_old, 1);
    assert_eq!(r.counters.fixes_taken, 0);
    let predicted = odometry::apply(
        &before,
        &odometry::motion(Some(flow), Some(gyro), DT_US, &OdometryConfig::NOMINAL),
    );
    assert_eq!(r.pose, predicted);

    // One tag, or none, is no fix at any age: nothing counted.
    let mut frame = SensorFrame::empty(DT_US);
    frame.tags = tags_then(8, 0).as_slice()[..1].iter().copied().collect();
    frame.tags_age_us = u32::MAX;
    assert_eq!(slam.step(&frame).fix, FixOutcome::NotAttempted);
    frame.tags = TagDetections::default();
    let r = slam.step(&frame);
    assert_eq!(r.fix, FixOutcome::NotAttempted);
    assert_eq!(r.counters.fixes_rejected_too_old, 1);

    // Exactly at the reach: used, and lands on the truth.
    let (_, reports) = drive(&m, 8, 8, reach, reach);
    let last = reports.last().unwrap();
    assert_eq!(last.fix, FixOutcome::Taken);
    let (p, h) = errors(&last.pose, &m.at(0.8));
    assert!(p <= 2.0 && h <= 0.2, "{p} mm, {h} deg");
}

/// A moving start pose from which both tags stay in view for the whole run.
fn motion() -> impl Strategy<Value = Motion> {
    (
        300.0f64..1700.0,
        300.0f64..1300.0,
        -40.0f64..40.0,
        0.0f64..150.0,
        -40_000i32..40_000,
    )
        .prop_map(|(x_mm, y_mm, deg, speed_mm_s, rate_mdps)| Motion {
            start: Truth {
                x_mm,
                y_mm,
                heading: deg.to_radians(),
            },
            speed_mm_s,
            rate_mdps,
        })
        .prop_filter("both tags in view from start to end", |m| {
            seen_from(&m.start).is_some() && seen_from(&m.at(TICKS as f64 * DT_S)).is_some()
        })
}

/// Ticks driven before the one whose picture is checked: the history then reaches back
/// to the start.
const TICKS: u32 = HISTORY_LEN as u32 - 1;

proptest! {
    #![proptest_config(ProptestConfig { cases: 1000, ..config() })]

    /// Any constant drive and turn (0 to 150 mm/s, +-40 deg/s) and any picture age the
    /// history reaches: the pose after the fix is the core's own fix of the picture
    /// carried by the true motion since the picture (the `f64` reference), within 0.3 mm
    /// and 0.002 degrees, and within the fix's bound against the truth (7 mm, 0.25
    /// degrees; tagfix_props) plus that of the truth at the tick.
    ///
    /// The 0.3 mm: the pose at the picture's moment is interpolated linearly between tick
    /// poses on an arc: at most the arc's sagitta, (15 mm x 0.07 rad) / 8 = 0.13 mm, plus
    /// 0.1 mm of flow-count rounding at its two ends and a few micrometres of Q16 rotation;
    /// the heading is interpolated exactly at a constant rate, so only its quantisation
    /// and the Q16 of the gyro integration remain.
    #[test]
    fn old_picture_fix_is_the_fix_carried_forward(m in motion(), age_us in 0u32..=TICKS * DT_US) {
        let now = m.at(TICKS as f64 * DT_S);
        let then = m.at(TICKS as f64 * DT_S - age_us as f64 / 1e6);
        let seen = seen_from(&then);
        prop_assume!(seen.is_some());
        let seen = seen.unwrap_or_default();
        let (slam, reports) = drive(&m, TICKS, TICKS, age_us, age_us);
        let r = reports.last().unwrap();
        prop_assert_eq!(r.fix, FixOutcome::Taken);
        prop_assert_eq!(r.pose, *slam.pose());

        let config = unchecked(world::shipped::seed_robot().config);
        let (a, b) = tagfix::best_pair(seen.as_slice(), &config.tags).unwrap();
        let fix = tagfix::two_tag_pose(a, b, &config.camera, &config.fix).unwrap();
        let (fx, fy, fh) = (fix.x_um as f64 / 1000.0, fix.y_um as f64 / 1000.0, bits_to_rad(fix.heading.bits()));
        let phi = fh - then.heading;
        let (dx, dy) = (now.x_mm - then.x_mm, now.y_mm - then.y_mm);
        let want = Truth {
            x_mm: fx + dx * phi.cos() + dy * phi.sin(),
            y_mm: fy + dy * phi.cos() - dx * phi.sin(),
            heading: now.heading + phi,
        };
        let (p, h) = errors(&r.pose, &want);
        prop_assert!(p <= 0.3 && h <= 0.002, "vs reference: {} mm, {} deg", p, h);
        let (p, h) = errors(&r.pose, &now);
        prop_assert!(p <= 7.3 && h <= 0.26, "vs truth: {} mm, {} deg", p, h);
    }
}

/// The core before pictures had an age, copied from it: predict by odometry, gate the
/// fix against the prediction, take it as the pose. Age-0 runs must match it bit for bit.
struct AgelessCore {
    pose: Pose,
    taken: u32,
    geometry: u32,
    gate: u32,
    relocalisations: u32,
    gate_in_a_row: u8,
}

impl AgelessCore {
    fn step(&mut self, frame: &SensorFrame, config: &SlamConfig) -> FixOutcome {
        if let Some(p) = frame.external_pose {
            self.pose = p;
            return FixOutcome::NotAttempted;
        }
        let motion = odometry::motion(frame.flow, frame.gyro, frame.dt_us, &config.odometry);
        self.pose = odometry::apply(&self.pose, &motion);
        if config.localiser != slam_core::Localiser::TwoTagFix {
            return FixOutcome::NotAttempted;
        }
        let Some((a, b)) = tagfix::best_pair(frame.tags.as_slice(), &config.tags) else {
            return FixOutcome::NotAttempted;
        };
        let fix = match tagfix::two_tag_pose(a, b, &config.camera, &config.fix) {
            Ok(fix) => fix,
            Err(reason) => {
                self.geometry += 1;
                return FixOutcome::Rejected(reason);
            }
        };
        if !tagfix::within_gate(&fix, &self.pose, &config.fix) {
            self.gate_in_a_row = self.gate_in_a_row.saturating_add(1);
            let limit = config.fix.relocalise_after;
            if limit == 0 || self.gate_in_a_row <= limit {
                self.gate += 1;
                return FixOutcome::Rejected(FixRejection::Gate);
            }
            self.relocalisations += 1;
        }
        self.gate_in_a_row = 0;
        self.pose = fix;
        self.taken += 1;
        FixOutcome::Taken
    }
}

/// A tick of a wandering robot: odometry of any size (sometimes stale), and a picture of
/// both tags from somewhere near (or far from) the middle of the mat, sometimes with a
/// range misread, sometimes none, now and then an external pose.
fn ageless_frame() -> impl Strategy<Value = SensorFrame> {
    (
        proptest::option::weighted(0.9, (-300i32..300, -30i32..30)),
        proptest::option::weighted(0.9, -90_000i32..90_000),
        proptest::option::weighted(0.7, (300.0f64..1700.0, 300.0f64..1300.0, -40.0f64..40.0)),
        prop_oneof![8 => Just(1.0f64), 1 => 0.5f64..2.0],
        proptest::option::weighted(0.05, (0i32..2_000_000, 0i32..2_000_000, any::<u32>())),
    )
        .prop_map(|(flow, gyro, seen, misread, external)| {
            let mut frame = SensorFrame::empty(DT_US);
            frame.flow = flow.map(|(f, r)| FlowDelta {
                forward_counts: f,
                right_counts: r,
            });
            frame.gyro = gyro.map(|rate_mdps| GyroRate { rate_mdps });
            if let Some((x_mm, y_mm, deg)) = seen {
                let t = Truth {
                    x_mm,
                    y_mm,
                    heading: deg.to_radians(),
                };
                if let Some(tags) = seen_from(&t) {
                    let mut first = tags.as_slice()[0];
                    first.distance_mm = (first.distance_mm as f64 * misread) as u32;
                    frame.tags = std::iter::once(first)
                        .chain(tags.as_slice()[1..].iter().copied())
                        .collect();
                }
            }
            frame.external_pose = external.map(|(x_um, y_um, h)| Pose {
                x_um,
                y_um,
                heading: Angle::from_bits(h),
            });
            frame
        })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 300, ..config() })]

    /// Age 0 is the core as it was: over random runs (fixes taken, rejected by geometry
    /// and by the gate, relocalisations, external poses) every tick's pose and outcome and
    /// the fix counters are exactly those of the ageless core.
    #[test]
    fn age_zero_is_the_ageless_core(
        start in (300i32..1700, 300i32..1300, -40_000i64..40_000),
        frames in proptest::collection::vec(ageless_frame(), 1..60),
    ) {
        let config = unchecked(world::shipped::seed_robot().config);
        let start = Pose::from_mm_mdeg(start.0, start.1, start.2);
        let mut slam: Slam<46, 46> = Slam::new(config, start).unwrap();
        let mut old = AgelessCore {
            pose: start,
            taken: 0,
            geometry: 0,
            gate: 0,
            relocalisations: 0,
            gate_in_a_row: 0,
        };
        for (i, f) in frames.iter().enumerate() {
            prop_assert_eq!(f.tags_age_us, 0);
            let r = slam.step(f);
            let want = old.step(f, &config);
            prop_assert_eq!(r.fix, want, "tick {}", i);
            prop_assert_eq!(r.pose, old.pose, "tick {}", i);
            let c = r.counters;
            prop_assert_eq!(
                (c.fixes_taken, c.fixes_rejected_geometry, c.fixes_rejected_gate, c.relocalisations),
                (old.taken, old.geometry, old.gate, old.relocalisations)
            );
            prop_assert_eq!(c.fixes_rejected_too_old, 0);
        }
    }
}

/// A scan one tick old goes in at the pose of one tick ago: the same map, cell for cell,
/// as mapping it then, while turning (where an unplaced scan smears the walls most); and
/// one older than the history is counted stale and maps nothing.
#[test]
fn old_scans_map_at_the_pose_of_their_moment() {
    let scan = slam_core::DepthScan {
        ranges_mm: [
            Some(900),
            Some(1200),
            None,
            Some(1500),
            Some(700),
            Some(2500),
            Some(800),
            None,
        ],
    };
    let turning = |frame: &mut SensorFrame| {
        frame.flow = Some(FlowDelta {
            forward_counts: 0,
            right_counts: 0,
        });
        frame.gyro = Some(GyroRate { rate_mdps: 31_500 });
    };
    let start = Pose::from_mm_mdeg(700, 500, 10_000);

    // Mapped when taken: on the tick it was measured, then a tick of turning.
    let mut then =
        Slam::<46, 46>::new(unchecked(world::shipped::seed_robot().config), start).unwrap();
    let mut f = SensorFrame::empty(DT_US);
    turning(&mut f);
    then.step(&f);
    f.depth = Some(scan);
    then.step(&f);
    f.depth = None;
    then.step(&f);

    // Mapped a tick late, told its age.
    let mut late =
        Slam::<46, 46>::new(unchecked(world::shipped::seed_robot().config), start).unwrap();
    let mut f = SensorFrame::empty(DT_US);
    turning(&mut f);
    late.step(&f);
    late.step(&f);
    f.depth = Some(scan);
    f.depth_age_us = DT_US;
    let report = late.step(&f);
    assert!(!report.stale.depth);
    assert_eq!(late.pose(), then.pose());
    assert_eq!(late.map().rows(), then.map().rows());

    // Mapped a tick late as if new: a different (smeared) map.
    let mut blind =
        Slam::<46, 46>::new(unchecked(world::shipped::seed_robot().config), start).unwrap();
    let mut f = SensorFrame::empty(DT_US);
    turning(&mut f);
    blind.step(&f);
    blind.step(&f);
    f.depth = Some(scan);
    blind.step(&f);
    assert_ne!(blind.map().rows(), then.map().rows());

    // Older than the history reaches: stale, nothing written.
    let before = late.counters().depth_stale;
    f.depth_age_us = DT_US * (HISTORY_LEN as u32 + 1);
    let report = late.step(&f);
    assert!(report.stale.depth);
    assert_eq!(report.cells_written, 0);
    assert_eq!(late.counters().depth_stale, before + 1);
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
