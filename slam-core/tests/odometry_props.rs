//! Dead reckoning against the `f64` reference: one tick, and ten minutes of ticks.

mod reference;

use proptest::prelude::*;
use reference::{bits_to_rad, RefPose, RAD_PER_BIT};
use slam_core::odometry::{self, OdometryConfig};
use slam_core::{Angle, FlowDelta, GyroRate, Pose, SensorFrame, Slam};

/// Micrometres per flow count in the nominal calibration.
const UM_PER_COUNT: f64 = 100.0;

/// Relative error of the gyro integration constant: `2^80 / 3.6e11` truncated to an integer
/// near 3.4e12 is short by under 3e-13 of itself. We use 1e-12.
const GYRO_REL: f64 = 1e-12;

/// Rounding of the turn to a binary unit, in radians (half a unit).
const TURN_ROUNDING: f64 = 0.5 * RAD_PER_BIT;

/// The Q16 sine/cosine error bound (see `angle_props.rs`).
const TRIG: f64 = 2e-5;

fn config() -> ProptestConfig {
    ProptestConfig {
        failure_persistence: None,
        ..ProptestConfig::default()
    }
}

/// Bound on one tick's heading error: `1.2e-6 |turn| + 0.5` binary unit.
fn turn_bound(turn: f64) -> f64 {
    GYRO_REL * turn.abs() + TURN_ROUNDING + 1e-15
}

/// Bound on one tick's position error per axis, in micrometres, given the heading error
/// `heading_err` (radians) already carried into the tick:
///
/// `dx = round(F sin m) + round(R cos m)`: two roundings to the micrometre (1 um), the Q16
/// sine and cosine (2e-5 of `|F| + |R|`), and the mid-tick heading's own error (the carried
/// error, half the turn's error, and one binary unit for halving the turn) times `|F| + |R|`.
fn step_bound(forward_um: f64, right_um: f64, turn: f64, heading_err: f64) -> f64 {
    let mid_err = heading_err + turn_bound(turn) / 2.0 + RAD_PER_BIT;
    1.0 + (forward_um.abs() + right_um.abs()) * (TRIG + mid_err) + 1e-6
}

fn ref_pose(p: &Pose) -> RefPose {
    RefPose {
        x_um: p.x_um as f64,
        y_um: p.y_um as f64,
        heading: bits_to_rad(p.heading.bits()),
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 3000, ..config() })]

    /// One tick from any pose: heading within `1.2e-6 |turn| + 0.5` binary unit of the
    /// reference, each position axis within
    /// `1 um + (|F| + |R|) (2e-5 + mid-tick heading error)` (at most 1.8 um for +-200
    /// counts). Checked for the seed's ranges and for flows and rates 50 times larger.
    #[test]
    fn one_tick_within_bound(
        x_um in -100_000_000i32..100_000_000,
        y_um in -100_000_000i32..100_000_000,
        heading in any::<u32>(),
        flow in prop_oneof![
            3 => (-200i32..=200, -200i32..=200).prop_map(Some),
            1 => (-10_000i32..=10_000, -10_000i32..=10_000).prop_map(Some),
            1 => Just(None),
        ],
        gyro in prop_oneof![
            3 => (-90_000i32..=90_000).prop_map(Some),
            1 => (-1_790_000i32..=1_790_000).prop_map(Some),
            1 => (-2_000_000i32..=2_000_000).prop_map(Some),
            1 => Just(None),
        ],
        dt_us in prop_oneof![Just(100_000u32), 0u32..=200_000],
    ) {
        let start = Pose { x_um, y_um, heading: Angle::from_bits(heading) };
        let m = odometry::motion(
            flow.map(|(f, r)| FlowDelta { forward_counts: f, right_counts: r }),
            gyro.map(|g| GyroRate { rate_mdps: g }),
            dt_us,
            &OdometryConfig::NOMINAL,
        );
        let core = odometry::apply(&start, &m);
        let want = reference::odometry_tick(ref_pose(&start), flow, gyro, dt_us, UM_PER_COUNT);
        let turn = want.heading - ref_pose(&start).heading;
        // `turn_bound` is derived for turns under half a revolution per tick; bigger turns
        // are checked by `half_turn_ticks_keep_their_mid_heading`.
        prop_assume!(turn.abs() < 0.999 * std::f64::consts::PI);
        let herr = reference::angle_diff(bits_to_rad(core.heading.bits()), want.heading).abs();
        prop_assert!(herr <= turn_bound(turn), "heading error {herr:e} rad, turn {turn}");
        let (f, r) = flow.map_or((0.0, 0.0), |(f, r)| (f as f64 * UM_PER_COUNT, r as f64 * UM_PER_COUNT));
        let bound = step_bound(f, r, turn, 0.0);
        let (ex, ey) = ((core.x_um as f64 - want.x_um).abs(), (core.y_um as f64 - want.y_um).abs());
        prop_assert!(ex <= bound && ey <= bound, "position error ({ex}, {ey}) um > {bound} um");
    }
}

/// 6,000 ticks (ten minutes at 10 Hz) of flow in -200..200 counts and gyro in
/// -90,000..90,000 mdps, integrated by the core (both through `odometry` and through
/// `Slam::step`, which must agree exactly) and by the reference side by side.
///
/// Bounds asserted:
///
/// 1. **Worst case, computed along the run**: the heading error after tick k is at most
///    `sum(1.2e-6 |turn_i| + 0.5 unit)`, and each axis's position error at most
///    `sum(step_bound(F_i, R_i, turn_i, heading error before i))`. This is what the rounding
///    can do if every error had the same sign; for these inputs it comes to roughly 0.03
///    degrees and 40 mm, so it is a sanity bound, not the headline.
/// 2. **The headline: heading < 0.01 degrees, position < 1 mm.** The per-tick roundings are
///    zero-mean (half a micrometre per rounding, sd 0.41 um per axis per tick: sd 32 um after
///    6,000 ticks); the 1.2 ppm gyro constant is a bias on the *net* turn, which for uniform
///    +-9 degree ticks random-walks with sd 400 degrees (10 sd = 4,000 degrees -> 0.005
///    degrees); the heading error it carries moves the position by under 0.1 mm at 10 sd;
///    the sine table's mean chord error (-3e-6) scales the net displacement (about a metre)
///    by 3 um. So both headline bounds hold by well over 5 sd for random inputs.
#[test]
fn ten_minutes_of_ticks() {
    proptest!(ProptestConfig { cases: 6, ..config() }, |(
        ticks in proptest::collection::vec((-200i32..=200, -200i32..=200, -90_000i32..=90_000), 6000),
        x_mm in 0i32..2000,
        y_mm in 0i32..2000,
        heading in any::<u32>(),
    )| {
        let start = Pose { x_um: x_mm * 1000, y_um: y_mm * 1000, heading: Angle::from_bits(heading) };
        let mut slam: Slam<46, 46> = Slam::new(unchecked(world::shipped::seed_robot().config), start).unwrap();
        let mut core = start;
        let mut want = ref_pose(&start);
        let (mut heading_bound, mut pos_bound) = (0.0f64, 0.0f64);
        let (mut worst_h, mut worst_p) = (0.0f64, 0.0f64);
        for &(f, r, g) in &ticks {
            let flow = FlowDelta { forward_counts: f, right_counts: r };
            let gyro = GyroRate { rate_mdps: g };
            let m = odometry::motion(Some(flow), Some(gyro), 100_000, &OdometryConfig::NOMINAL);
            core = odometry::apply(&core, &m);
            let mut frame = SensorFrame::empty(100_000);
            frame.flow = Some(flow);
            frame.gyro = Some(gyro);
            let report = slam.step(&frame);
            prop_assert_eq!(report.pose, core);

            let before = want.heading;
            want = reference::odometry_tick(want, Some((f, r)), Some(g), 100_000, UM_PER_COUNT);
            let turn = want.heading - before;
            pos_bound += step_bound(f as f64 * UM_PER_COUNT, r as f64 * UM_PER_COUNT, turn, heading_bound);
            heading_bound += turn_bound(turn);

            let herr = reference::angle_diff(bits_to_rad(core.heading.bits()), want.heading).abs();
            let perr = (core.x_um as f64 - want.x_um).abs().max((core.y_um as f64 - want.y_um).abs());
            prop_assert!(herr <= heading_bound, "heading error {herr:e} > worst case {heading_bound:e}");
            prop_assert!(perr <= pos_bound, "position error {perr} um > worst case {pos_bound} um");
            worst_h = worst_h.max(herr);
            worst_p = worst_p.max((core.x_um as f64 - want.x_um).hypot(core.y_um as f64 - want.y_um));
        }
        prop_assert!(worst_h.to_degrees() < 0.01, "heading drifted {} degrees", worst_h.to_degrees());
        prop_assert!(worst_p < 1000.0, "position drifted {worst_p} um");
        println!(
            "6000 ticks: worst heading error {:.2e} deg (worst case {:.2e}), worst position \
             error {:.1} um (worst case per axis {:.0} um)",
            worst_h.to_degrees(), heading_bound.to_degrees(), worst_p, pos_bound
        );
    });
}

/// Turning on the spot at 90 degrees per second for ten minutes (54,000 degrees, all one
/// way): the constant's truncation and the per-tick rounding must not accumulate past
/// `GYRO_REL x total + 0.5 unit per tick` (about 5e-5 degrees).
#[test]
fn ten_minutes_of_spinning() {
    let mut pose = Pose::default();
    let mut want = 0.0f64;
    for _ in 0..6000 {
        let m = odometry::motion(
            None,
            Some(GyroRate { rate_mdps: 90_000 }),
            100_000,
            &OdometryConfig::NOMINAL,
        );
        pose = odometry::apply(&pose, &m);
        want += reference::turn(90_000.0, 100_000.0);
    }
    let err = reference::angle_diff(bits_to_rad(pose.heading.bits()), want);
    let bound = GYRO_REL * want + 6000.0 * TURN_ROUNDING;
    assert!(err.abs() <= bound, "{} deg", err.to_degrees());
    println!("54,000 degrees of spin: error {:.4} deg", err.to_degrees());
}

/// A tick that turns more than half a revolution (here 1,800.003 degrees per second for
/// 100 ms, within a +-2,000 dps gyro's range) once aliased to the opposite turn, so the
/// mid-tick heading was 180 degrees off and the tick's displacement reversed. `Motion` now
/// carries the turn unwrapped, and the displacement goes the right way.
#[test]
fn half_turn_ticks_keep_their_mid_heading() {
    let m = odometry::motion(
        Some(FlowDelta {
            forward_counts: 0,
            right_counts: 1,
        }),
        Some(GyroRate {
            rate_mdps: -1_800_003,
        }),
        100_000,
        &OdometryConfig::NOMINAL,
    );
    let core = odometry::apply(&Pose::default(), &m);
    let want = reference::odometry_tick(
        ref_pose(&Pose::default()),
        Some((0, 1)),
        Some(-1_800_003),
        100_000,
        UM_PER_COUNT,
    );
    assert!((want.y_um - 100.0).abs() < 0.01);
    assert!(
        (core.y_um as f64 - want.y_um).abs() <= 1.0,
        "the mid-tick heading is 180 degrees off: y = {} um, want {}",
        core.y_um,
        want.y_um
    );
    let herr = reference::angle_diff(bits_to_rad(core.heading.bits()), want.heading).abs();
    assert!(herr < 1e-5);
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
