//! The two-tag fix against the truth and against the `f64` reference.

mod reference;

use proptest::prelude::*;
use reference::{bits_to_rad, Seen};
use slam_core::tagfix::{self, CameraConfig, FixConfig, FixRejection, KnownTag};
use slam_core::{Angle, FixOutcome, Pose, SensorFrame, Slam, TagDetection};

fn t11() -> KnownTag {
    world::shipped::seed_robot().tags[0]
}
fn t12() -> KnownTag {
    world::shipped::seed_robot().tags[1]
}

fn config() -> ProptestConfig {
    ProptestConfig {
        failure_persistence: None,
        ..ProptestConfig::default()
    }
}

fn place(t: &KnownTag) -> (f64, f64) {
    (t.x_mm as f64, t.y_mm as f64)
}

/// A true pose on the mat, facing the far wall, from which both tags are in the picture
/// (bearings within +-55 degrees of the 120 degree view).
#[derive(Clone, Copy, Debug)]
struct Truth {
    x_mm: f64,
    y_mm: f64,
    heading: f64,
}

fn truth() -> impl Strategy<Value = Truth> {
    (150.0f64..1850.0, 150.0f64..1500.0, -50.0f64..50.0)
        .prop_map(|(x_mm, y_mm, deg)| Truth {
            x_mm,
            y_mm,
            heading: deg.to_radians(),
        })
        .prop_filter("both tags in view", |t| {
            [t11(), t12()].iter().all(|tag| {
                let s = reference::see(t.x_mm, t.y_mm, t.heading, place(tag));
                reference::bearing(s.cx_px).abs() < 55f64.to_radians()
            })
        })
}

/// The detection a perfect camera reports, quantised as the driver does: the column to a
/// hundredth of a pixel, the distance to a millimetre.
fn detect(t: &Truth, tag: &KnownTag) -> TagDetection {
    let s = reference::see(t.x_mm, t.y_mm, t.heading, place(tag));
    TagDetection {
        id: tag.id,
        cx_centipx: (s.cx_px * 100.0).round() as i32,
        distance_mm: s.distance_mm.round() as u32,
    }
}

/// The same detection in the reference's units.
fn seen(d: &TagDetection) -> Seen {
    Seen {
        cx_px: d.cx_centipx as f64 / 100.0,
        distance_mm: d.distance_mm as f64,
    }
}

/// Errors of a core fix against a reference pose: (position mm, heading degrees).
fn errors(fix: &Pose, x_mm: f64, y_mm: f64, heading: f64) -> (f64, f64) {
    let pos = (fix.x_um as f64 / 1000.0 - x_mm).hypot(fix.y_um as f64 / 1000.0 - y_mm);
    let head = reference::angle_diff(bits_to_rad(fix.heading.bits()), heading)
        .to_degrees()
        .abs();
    (pos, head)
}

/// Bound of the core fix against the reference fix from the same detections:
/// **1.5 mm and 0.03 degrees.**
///
/// Each tag's place in the robot frame is the range along the column's ray, the ray's
/// sine and cosine within 2e-5 of the reference's (`CameraConfig::ray`), rounded to a
/// sixteenth of a millimetre: with tags at most 2.3 m away, each place is off by at most
/// 2.3 m x 2e-5 x sqrt(2) + 0.044 mm = 0.11 mm, the seen baseline by 0.22 mm, which on the
/// 800 mm baseline turns it by at most 2.8e-4 rad. The turn between the baselines comes
/// from their product cut to 15 bits, 1.05e-4 rad (`Direction::of_vector` of any components,
/// 6e-3 degrees): 3.8e-4 rad = 0.022 degrees of heading in all. The position is the tags'
/// midpoint less the robot-frame midpoint turned by the heading: 2.3 m x 3.8e-4 = 0.9 mm,
/// plus the places' own 0.11 mm, plus the turn's sine and cosine (8.2e-5 off) over 2.3 m,
/// 0.2 mm: 1.2 mm.
const VS_REFERENCE_MM: f64 = 1.5;
const VS_REFERENCE_DEG: f64 = 0.03;

/// Bound of the reference fix against the truth, from the detections' own quantisation
/// (0.5 mm of distance and 0.005 px of column, i.e. at most 0.55 mm per tag position and
/// 1.4e-3 rad = 0.08 degrees of baseline direction, about 3 mm of position): **3 mm and
/// 0.1 degrees**, as this test has always held it. Asserted, so that the next bound holds
/// for the right reason.
const REFERENCE_VS_TRUTH_MM: f64 = 3.0;
const REFERENCE_VS_TRUTH_DEG: f64 = 0.1;

/// Bound of the core fix against the truth: **7 mm and 0.25 degrees**, the fix's contract
/// that `latency_props.rs` and `seed_route.rs` build on. The two bounds above add up to
/// 4.5 mm and 0.13 degrees (it was 7 mm and 0.25 when the fix rounded to whole
/// millimetres).
const VS_TRUTH_MM: f64 = 7.0;
const VS_TRUTH_DEG: f64 = 0.25;

/// Bound on `CameraConfig::ray` against the sine and cosine of the reference bearing, per
/// component: 2e-5 wherever the column is within 2^15 centipixels (327 px) of the centre,
/// as every column of the picture is, and 8.2e-5 beyond (`sin_cos_of_vector`'s bounds).
const RAY_BOUND: f64 = 2e-5;
const RAY_BOUND_FAR: f64 = 8.2e-5;

/// The worse component of `CameraConfig::SEED.ray(cx)`'s error.
fn ray_error(cx: i32) -> f64 {
    let (sin, cos) = CameraConfig::SEED.ray(cx);
    let want = reference::bearing(cx as f64 / 100.0);
    let q16 = |v: i32| v as f64 / 65536.0;
    (q16(sin) - want.sin())
        .abs()
        .max((q16(cos) - want.cos()).abs())
}

/// `within_gate` as first written, the model for the faster one: squared distances in
/// 128 bits and the heading limit through `Angle::from_millidegrees`.
fn within_gate_model(fix: &Pose, predicted: &Pose, config: &FixConfig) -> bool {
    let (dx, dy) = (
        fix.x_um as i64 - predicted.x_um as i64,
        fix.y_um as i64 - predicted.y_um as i64,
    );
    let gate_um = config.gate_position_mm as u64 * 1000;
    let far = (dx.unsigned_abs() as u128).pow(2) + (dy.unsigned_abs() as u128).pow(2)
        > (gate_um as u128).pow(2);
    let turned = fix.heading.diff(predicted.heading).unsigned_abs()
        > Angle::from_millidegrees(config.gate_heading_mdeg as i64).bits();
    !far && !turned
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2000, ..config() })]

    /// Exactly synthesised detections of tags 11 and 12 (in either order): the fix is
    /// within 1.5 mm / 0.03 degrees of the reference's and within 7 mm / 0.25 degrees of
    /// the truth.
    #[test]
    fn fix_matches_truth_and_reference(t in truth(), swap in any::<bool>()) {
        let (mut a, mut b, mut ta, mut tb) = (detect(&t, &t11()), detect(&t, &t12()), t11(), t12());
        if swap {
            core::mem::swap(&mut a, &mut b);
            core::mem::swap(&mut ta, &mut tb);
        }
        let fix = tagfix::two_tag_pose((&a, &ta), (&b, &tb), &CameraConfig::SEED, &FixConfig::SEED);
        prop_assert!(fix.is_ok(), "{:?}", fix);
        let fix = fix.unwrap();
        let want = reference::two_tag_fix(seen(&a), place(&ta), seen(&b), place(&tb));
        let (p, h) = errors(&fix, want.x_mm, want.y_mm, want.heading);
        prop_assert!(p <= VS_REFERENCE_MM && h <= VS_REFERENCE_DEG, "vs reference: {p} mm, {h} deg");
        let (p, h) = errors(&fix, t.x_mm, t.y_mm, t.heading);
        prop_assert!(p <= VS_TRUTH_MM && h <= VS_TRUTH_DEG, "vs truth: {p} mm, {h} deg");
        // The reference itself, from the same quantised detections, is within the
        // quantisation part of the budget.
        let rp = (want.x_mm - t.x_mm).hypot(want.y_mm - t.y_mm);
        let rh = reference::angle_diff(want.heading, t.heading).to_degrees().abs();
        prop_assert!(rp <= REFERENCE_VS_TRUTH_MM && rh <= REFERENCE_VS_TRUTH_DEG);
    }

    /// `CameraConfig::ray` is the sine and cosine of `atan((cx - 160) / 92.4)` within 2e-5
    /// over the picture and 8.2e-5 anywhere.
    #[test]
    fn ray_matches_reference(cx in prop_oneof![0i32..32_000, any::<i32>()]) {
        let near = (cx as i64 - 16_000).unsigned_abs() < 1 << 15;
        let err = ray_error(cx);
        prop_assert!(err <= if near { RAY_BOUND } else { RAY_BOUND_FAR }, "cx {}: {:e}", cx, err);
    }

    /// `within_gate` decides as its model does, everywhere and on the edges: fixes on the
    /// gate's circle and a unit either side, turns of the limit's bits and a unit either
    /// side, gates of any size.
    #[test]
    fn gate_matches_model(
        px in any::<i32>(), py in any::<i32>(), ph in any::<u32>(),
        angle in any::<u32>(), edge in -2i64..=2, turn_edge in -1i64..=1,
        gate_mm in prop_oneof![0u32..1000, any::<u32>()],
        gate_mdeg in prop_oneof![0u32..400_000, any::<u32>()],
        offsets in (any::<i32>(), any::<i32>(), any::<u32>()),
    ) {
        let config = FixConfig { gate_position_mm: gate_mm, gate_heading_mdeg: gate_mdeg, ..FixConfig::SEED };
        let predicted = Pose { x_um: px, y_um: py, heading: Angle::from_bits(ph) };
        let gate_um = gate_mm as f64 * 1000.0;
        let a = angle as f64 * reference::RAD_PER_BIT;
        let limit = Angle::from_millidegrees(gate_mdeg as i64).bits() as i64;
        let saturate = |v: f64| v.clamp(i32::MIN as f64, i32::MAX as f64) as i32;
        let candidates = [
            // On the circle (and a unit out or in), at the limit's turn (and a unit either side).
            Pose {
                x_um: saturate(px as f64 + (gate_um * a.sin()).round() + edge as f64),
                y_um: saturate(py as f64 + (gate_um * a.cos()).round()),
                heading: Angle::from_bits((ph as i64 + (limit + turn_edge) * if angle & 1 == 0 { 1 } else { -1 }) as u32),
            },
            // Anywhere.
            Pose { x_um: offsets.0, y_um: offsets.1, heading: Angle::from_bits(offsets.2) },
            Pose { x_um: px.wrapping_add(offsets.0 >> 12), y_um: py.wrapping_add(offsets.1 >> 12), heading: Angle::from_bits(ph.wrapping_add(offsets.2 >> 4)) },
        ];
        for fix in candidates {
            prop_assert_eq!(
                tagfix::within_gate(&fix, &predicted, &config),
                within_gate_model(&fix, &predicted, &config),
                "{:?} vs {:?}", fix, predicted
            );
        }
    }

    /// `CameraConfig::bearing` is `atan((cx - 160) / 92.4)` within 1.5e-5 degrees, over
    /// the whole picture and far beyond it.
    #[test]
    fn bearing_matches_reference(cx in prop_oneof![0i32..32_000, any::<i32>()]) {
        let core = bits_to_rad(CameraConfig::SEED.bearing(cx).bits());
        let want = reference::bearing(cx as f64 / 100.0);
        let err = reference::angle_diff(core, want).to_degrees().abs();
        prop_assert!(err <= 1.5e-5, "cx {}: {} deg", cx, err);
    }

    /// Through `Slam::step` (predicted pose = truth, so inside the gate) with unknown tags
    /// mixed in: the fix is taken and is exactly `two_tag_pose` of the longest known pair.
    #[test]
    fn step_takes_the_fix(t in truth(), junk in proptest::collection::vec((13u16..1000, any::<i32>(), any::<u32>()), 0..4)) {
        let start = Pose {
            x_um: (t.x_mm * 1000.0).round() as i32,
            y_um: (t.y_mm * 1000.0).round() as i32,
            heading: Angle::from_bits((t.heading.rem_euclid(std::f64::consts::TAU) / reference::RAD_PER_BIT) as u32),
        };
        let mut slam: Slam<46, 46> = Slam::new(world::shipped::seed_robot().config, start).unwrap();
        let mut frame = SensorFrame::empty(100_000);
        for (id, cx, d) in &junk {
            frame.tags.push(TagDetection { id: *id, cx_centipx: *cx, distance_mm: *d }).unwrap();
        }
        let (a, b) = (detect(&t, &t11()), detect(&t, &t12()));
        frame.tags.push(a).unwrap();
        frame.tags.push(b).unwrap();
        let report = slam.step(&frame);
        prop_assert_eq!(report.fix, FixOutcome::Taken);
        let fix = tagfix::two_tag_pose((&a, &t11()), (&b, &t12()), &CameraConfig::SEED, &FixConfig::SEED).unwrap();
        prop_assert_eq!(report.pose, fix);
        prop_assert_eq!(report.counters.fixes_taken, 1);
    }

    /// Degenerate sightings never give a fix and never panic: the same tag twice, one tag
    /// alone, a seen baseline twice the true one.
    #[test]
    fn degenerate_sightings_are_refused(t in truth()) {
        let (a, b) = (detect(&t, &t11()), detect(&t, &t12()));
        let cam = CameraConfig::SEED;
        let cfg = FixConfig::SEED;
        // The same id twice: best_pair finds no pair; forced through two_tag_pose the true
        // baseline is zero.
        prop_assert!(tagfix::best_pair(&[a, a], &world::shipped::seed_robot().config.tags).is_none());
        prop_assert_eq!(tagfix::two_tag_pose((&a, &t11()), (&a, &t11()), &cam, &cfg), Err(FixRejection::Geometry));
        // The seen baseline twice the true one (both ranges doubled).
        let (a2, b2) = (
            TagDetection { distance_mm: a.distance_mm * 2, ..a },
            TagDetection { distance_mm: b.distance_mm * 2, ..b },
        );
        prop_assert_eq!(tagfix::two_tag_pose((&a2, &t11()), (&b2, &t12()), &cam, &cfg), Err(FixRejection::Geometry));

        let step = |tags: &[TagDetection]| {
            let mut slam: Slam<46, 46> = Slam::new(world::shipped::seed_robot().config, Pose::from_mm_mdeg(1000, 800, 0)).unwrap();
            let mut frame = SensorFrame::empty(100_000);
            frame.tags = tags.iter().copied().collect();
            let report = slam.step(&frame);
            (report.fix, report.pose)
        };
        let still = Pose::from_mm_mdeg(1000, 800, 0);
        prop_assert_eq!(step(&[a, a]), (FixOutcome::NotAttempted, still));
        prop_assert_eq!(step(&[b]), (FixOutcome::NotAttempted, still));
        prop_assert_eq!(step(&[]), (FixOutcome::NotAttempted, still));
        prop_assert_eq!(step(&[a2, b2]), (FixOutcome::Rejected(FixRejection::Geometry), still));
    }
}

/// A tag reported at distance 0 (a misread: a camera cannot see a tag it is touching)
/// should not produce a fix. `two_tag_pose` does not look at the distances, so whenever the
/// other tag happens to be 640..960 mm away (within the 20 % baseline tolerance of the
/// 800 mm baseline) it returns a pose: the zero-range tag's own place averaged with a
/// position computed from a heading that is off by the angle between the true baseline and
/// the line to the other tag. Here from (1500, 1150) mm facing the far wall, tag 12 straight
/// ahead 800 mm away and tag 11 "at 0 mm": the fix is (700, 1950) mm facing +x, 1.1 m and 90
/// degrees from the truth.
///
/// Regression test for a bug, now fixed, in `slam-core/src/tagfix.rs` (`two_tag_pose`): it should reject a sighting
/// at zero range (e.g. `FixRejection::Geometry` when either distance is below some minimum,
/// or below `min_baseline_mm`). Through `Slam::step` the gate rejects this fix five times and
/// then, by design, relocalises onto it on the sixth frame.
#[test]
fn tag_at_distance_zero_gives_no_fix() {
    let t = Truth {
        x_mm: 1500.0,
        y_mm: 1150.0,
        heading: 0.0,
    };
    let (mut a, b) = (detect(&t, &t11()), detect(&t, &t12()));
    a.distance_mm = 0;
    let fix = tagfix::two_tag_pose(
        (&a, &t11()),
        (&b, &t12()),
        &CameraConfig::SEED,
        &FixConfig::SEED,
    );
    let mut slam: Slam<46, 46> = Slam::new(
        world::shipped::seed_robot().config,
        Pose::from_mm_mdeg(1500, 1150, 0),
    )
    .unwrap();
    let mut frame = SensorFrame::empty(100_000);
    frame.tags = [a, b].into_iter().collect();
    let outcomes: Vec<FixOutcome> = (0..6).map(|_| slam.step(&frame).fix).collect();
    assert!(
        fix.is_err(),
        "a tag at 0 mm gave the fix {fix:?}; through Slam::step: {outcomes:?}, pose {:?}",
        slam.pose()
    );
}

/// Zero range on both tags, or a zero range where the other tag is far: refused (the
/// baseline check catches these), never a panic.
#[test]
fn zero_ranges_elsewhere_are_refused() {
    let t = Truth {
        x_mm: 1000.0,
        y_mm: 300.0,
        heading: 0.0,
    };
    let (a, b) = (detect(&t, &t11()), detect(&t, &t12()));
    for (a, b) in [
        (
            TagDetection {
                distance_mm: 0,
                ..a
            },
            TagDetection {
                distance_mm: 0,
                ..b
            },
        ),
        (
            TagDetection {
                distance_mm: 0,
                ..a
            },
            b,
        ),
    ] {
        assert_eq!(
            tagfix::two_tag_pose(
                (&a, &t11()),
                (&b, &t12()),
                &CameraConfig::SEED,
                &FixConfig::SEED
            ),
            Err(FixRejection::Geometry)
        );
    }
}

/// 20,000 pseudo-random poses: report the worst errors seen against the stated bounds.
#[test]
fn fix_error_survey() {
    let mut rng = reference::Lcg(0x2545_F491_4F6C_DD1Du64);
    let mut unit = move || (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
    let (mut wr, mut wt) = ((0.0f64, 0.0f64), (0.0f64, 0.0f64));
    let mut n = 0;
    while n < 20_000 {
        let t = Truth {
            x_mm: 150.0 + 1700.0 * unit(),
            y_mm: 150.0 + 1350.0 * unit(),
            heading: (-50.0 + 100.0 * unit()).to_radians(),
        };
        let in_view = [t11(), t12()].iter().all(|tag| {
            let s = reference::see(t.x_mm, t.y_mm, t.heading, place(tag));
            reference::bearing(s.cx_px).abs() < 55f64.to_radians()
        });
        if !in_view {
            continue;
        }
        n += 1;
        let (a, b) = (detect(&t, &t11()), detect(&t, &t12()));
        let fix = tagfix::two_tag_pose(
            (&a, &t11()),
            (&b, &t12()),
            &CameraConfig::SEED,
            &FixConfig::SEED,
        )
        .unwrap();
        let want = reference::two_tag_fix(seen(&a), place(&t11()), seen(&b), place(&t12()));
        let (p, h) = errors(&fix, want.x_mm, want.y_mm, want.heading);
        wr = (wr.0.max(p), wr.1.max(h));
        let (p, h) = errors(&fix, t.x_mm, t.y_mm, t.heading);
        wt = (wt.0.max(p), wt.1.max(h));
    }
    println!(
        "worst fix error vs reference {:.2} mm {:.3} deg, vs truth {:.2} mm {:.3} deg",
        wr.0, wr.1, wt.0, wt.1
    );
    assert!(wr.0 <= VS_REFERENCE_MM && wr.1 <= VS_REFERENCE_DEG);
    assert!(wt.0 <= VS_TRUTH_MM && wt.1 <= VS_TRUTH_DEG);
}

/// Every column of the picture, to a hundredth of a pixel: report the worst ray error.
#[test]
fn ray_sweep() {
    let worst = (0..32_000).map(ray_error).fold(0.0f64, f64::max);
    println!("worst ray error over the picture: {worst:e}");
    assert!(worst <= RAY_BOUND);
}
