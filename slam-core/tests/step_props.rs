//! `Slam::step` on arbitrary frames: no panic, the map within its clamp, counters that add up.

mod reference;

use proptest::prelude::*;
use slam_core::odometry::{self, OdometryConfig};
use slam_core::{
    Angle, DepthScan, Doubt, DriveCommand, FlowDelta, GyroRate, Pose, SensorFrame, Slam,
    TagDetection, TagDetections, MAX_TAGS,
};

fn config() -> ProptestConfig {
    ProptestConfig {
        failure_persistence: None,
        ..ProptestConfig::default()
    }
}

fn pose() -> impl Strategy<Value = Pose> {
    (any::<i32>(), any::<i32>(), any::<u32>()).prop_map(|(x_um, y_um, h)| Pose {
        x_um,
        y_um,
        heading: Angle::from_bits(h),
    })
}

fn tags() -> impl Strategy<Value = TagDetections> {
    let id = prop_oneof![Just(11u16), Just(12u16), any::<u16>()];
    let cx = prop_oneof![0i32..32_000, any::<i32>(), Just(i32::MIN), Just(i32::MAX)];
    let d = prop_oneof![0u32..3000, any::<u32>(), Just(0u32), Just(u32::MAX)];
    proptest::collection::vec((id, cx, d), 0..=10).prop_map(|v| {
        v.iter()
            .map(|&(id, cx_centipx, distance_mm)| TagDetection {
                id,
                cx_centipx,
                distance_mm,
            })
            // More than a frame holds: the rest are dropped, as the firmware drops them.
            .take(MAX_TAGS)
            .collect()
    })
}

fn frame() -> impl Strategy<Value = SensorFrame> {
    (
        prop_oneof![Just(100_000u32), any::<u32>()],
        proptest::option::of((any::<i32>(), any::<i32>())),
        proptest::option::of(any::<i32>()),
        proptest::option::of(proptest::array::uniform8(
            proptest::option::of(any::<u16>()),
        )),
        tags(),
        prop_oneof![Just(0u32), 0u32..500_000, any::<u32>()],
        proptest::option::weighted(0.3, pose()),
        prop_oneof![Just(0u32), 0u32..500_000, any::<u32>()],
        proptest::option::of((any::<i32>(), any::<i32>())),
    )
        .prop_map(
            |(
                dt_us,
                flow,
                gyro,
                depth,
                tags,
                tags_age_us,
                external_pose,
                depth_age_us,
                commanded,
            )| {
                SensorFrame {
                    dt_us,
                    flow: flow.map(|(f, r)| FlowDelta {
                        forward_counts: f,
                        right_counts: r,
                    }),
                    gyro: gyro.map(|g| GyroRate { rate_mdps: g }),
                    depth: depth.map(|ranges_mm| DepthScan { ranges_mm }),
                    depth_age_us,
                    // Any verdict of the depth task's, none included.
                    depth_doubt: Doubt::from_code(
                        (depth_age_us % (Doubt::ALL.len() as u32 + 1)) as u8,
                    ),
                    tags,
                    tags_age_us,
                    external_pose,
                    commanded: commanded.map(|(speed_mm_s, turn_mdps)| DriveCommand {
                        speed_mm_s,
                        turn_mdps,
                    }),
                }
            },
        )
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 300, ..config() })]

    /// Any frames at all (every `i32`/`u32` value, every `Option` combination, any tag list,
    /// huge distances and columns, external poses anywhere): `step` returns, every cell stays
    /// within +-2048, and the counters add up: `ticks` = steps, `beams_mapped +
    /// beams_invalid` = 8 x frames with depth, stale counts = frames missing each input,
    /// fixes taken + rejected <= ticks, and the report's pose is the state's pose. Any
    /// picture age, including ages past the pose history and `u32::MAX`.
    ///
    /// Holds in debug builds too (overflow checks on): the overflows this once found are
    /// pinned by the deterministic regression tests below.
    #[test]
    fn step_never_panics_and_counters_add_up(start in pose(), frames in proptest::collection::vec(frame(), 1..25)) {
        let mut slam: Slam<46, 46> = Slam::new(unchecked(world::shipped::seed_robot().config), start).unwrap();
        let (mut with_depth, mut no_flow, mut no_gyro) = (0u32, 0u32, 0u32);
        let mut valid = 0u32;
        for (i, f) in frames.iter().enumerate() {
            let report = slam.step(f);
            // A scan is mapped unless it is older than the pose history (then it is stale).
            let placed = f.depth.filter(|_| !report.stale.depth);
            with_depth += placed.is_some() as u32;
            valid += placed.map_or(0, |d| d.ranges_mm.iter().filter(|r| r.is_some()).count() as u32);
            no_flow += f.flow.is_none() as u32;
            no_gyro += f.gyro.is_none() as u32;
            let c = report.counters;
            prop_assert_eq!(c, *slam.counters());
            prop_assert_eq!(report.pose, *slam.pose());
            prop_assert_eq!(c.ticks, i as u32 + 1);
            prop_assert_eq!(c.beams_mapped + c.beams_invalid, 8 * with_depth);
            prop_assert_eq!(c.beams_mapped, valid);
            if f.depth.is_some() && f.depth_age_us == 0 {
                prop_assert!(!report.stale.depth, "a scan of this very tick is always mapped");
            }
            prop_assert_eq!(c.depth_stale, c.ticks - with_depth);
            prop_assert_eq!((c.flow_stale, c.gyro_stale), (no_flow, no_gyro));
            prop_assert!(
                c.fixes_taken + c.fixes_rejected_geometry + c.fixes_rejected_gate
                    + c.fixes_rejected_too_old <= c.ticks
            );
            prop_assert!(c.relocalisations <= c.fixes_taken);
            if let Some(p) = f.external_pose {
                prop_assert_eq!(report.pose, p);
            }
            let clamp = slam.map().evidence().clamp;
            for row in slam.map().rows() {
                for &l in row {
                    prop_assert!((-clamp..=clamp).contains(&l));
                }
            }
        }
    }
}

/// Regression test for a bug, now fixed, in `slam-core/src/odometry.rs` (`turn_from_gyro`): a long tick. `rate x dt`
/// times the Q26 constant saturates at `i64::MAX` once `|rate x dt|` exceeds
/// `2^63 / 800639` = 1.15e13 mdps.us (90 degrees per second for 128 s, or any rate above
/// 2,682 mdps for the longest `u32` tick), and then `+ (1 << 25)` overflows: a panic in a
/// debug build, and in release a wrapped, meaningless turn instead of the true one modulo
/// a revolution. Here 90 deg/s for 150 s is 37.5 turns: the heading should end up
/// reversed. A fix: reduce `rate x dt` modulo one turn (3.6e11 mdeg.us) before scaling, or
/// use `i128`.
#[test]
fn long_tick_turn_wraps_instead_of_saturating() {
    let dt_us = 150_000_000;
    let rate_mdps = 90_000;
    let want = reference::turn(rate_mdps as f64, dt_us as f64);
    let got = std::panic::catch_unwind(|| {
        odometry::turn_from_gyro(GyroRate { rate_mdps }, dt_us, &OdometryConfig::NOMINAL)
    });
    let got = got.expect("turn_from_gyro panicked (integer overflow)");
    let err = reference::angle_diff(reference::bits_to_rad(got.bits()), want).to_degrees();
    assert!(
        err.abs() < 0.01,
        "37.5 turns came out as {} degrees",
        got.to_millidegrees() as f64 / 1000.0
    );
}

/// Regression test for a bug, now fixed, in `slam-core/src/pose.rs` (`round_div`) via `Pose::x_mm`/`y_mm`): within
/// 500 um of `i32::MAX`, `a + b / 2` overflows: a panic in debug, and in release a pose at
/// x = +2147.48 m reports x_mm = -2147483. `apply` clamps odometry to exactly `i32::MAX`, so
/// a runaway flow sensor (or an external pose) gets there, and `map_scan` then maps from
/// the wrong side of the world. A fix: round in `i64`.
#[test]
fn millimetres_near_the_pose_limit() {
    let p = Pose {
        x_um: i32::MAX,
        y_um: i32::MIN,
        heading: Angle::ZERO,
    };
    let got = std::panic::catch_unwind(|| (p.x_mm(), p.y_mm()));
    assert_eq!(
        got.expect("x_mm/y_mm panicked (integer overflow)"),
        (2_147_484, -2_147_484)
    );
}

/// Regression test for a bug, now fixed, in `slam-core/src/pose.rs` (`Pose::distance_um`): `dx * dx + dy * dy` in
/// `i64` overflows once the poses are more than ~2.1 km apart per axis (`|dx|` up to
/// 2^32 um): a panic in debug; in release the wrapped square root is wrong, so
/// `within_gate` can pass a fix kilometres away. A fix: square and add in `u128` and
/// saturate the root to `u32::MAX` (the widest distance, 4.8e9 um, does not fit a `u32`).
#[test]
fn distance_between_far_poses() {
    let a = Pose {
        x_um: i32::MIN,
        y_um: i32::MIN,
        heading: Angle::ZERO,
    };
    let b = Pose {
        x_um: i32::MAX,
        y_um: 0,
        heading: Angle::ZERO,
    };
    let got = std::panic::catch_unwind(|| a.distance_um(&b));
    let want = (u32::MAX as f64).hypot(2f64.powi(31));
    let got = got.expect("distance_um panicked (integer overflow)");
    // The true distance (4.8e9 um) does not fit a u32 at all: saturating would be right.
    assert_eq!(got, u32::MAX, "distance {got} um, true {want} um");
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
