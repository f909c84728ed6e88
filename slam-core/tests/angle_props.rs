//! `Angle` against `f64` trigonometry.

mod reference;

use proptest::prelude::*;
use reference::{bits_to_rad, RAD_PER_BIT};
use slam_core::angle::{sin_cos_of_vector, Direction, TRIG_ONE};
use slam_core::Angle;

/// Bound on `|sin_q16 / 2^16 - sin|` and the same for cosine: 2e-5 (1.31 Q16 LSB), as the
/// doc comment of `Angle::sin` promises. (Table of 257 rounded entries, linear
/// interpolation, rounded result: 4.7e-6 chord error + 2 x 7.6e-6 rounding < 2e-5.)
const TRIG_BOUND: f64 = 2e-5;

/// Bound on `|of_vector(x, y) - atan2(x, y)|`, in degrees: the CORDIC's residual after 24
/// iterations (`atan(2^-23)` = 6.8e-6 degrees) plus the truncation of 24 shifts of a
/// 29-bit vector and of the table (about 24 x 2^-28 rad = 5e-6 degrees), plus the
/// scaling of huge inputs to 29 bits (2^-28 rad = 2e-7 degrees): 1.2e-5 degrees. We assert
/// 1.5e-5 degrees (179 binary units).
const OF_VECTOR_BOUND_DEG: f64 = 1.5e-5;

/// Bound on `|sin_cos_of_vector(x, y) / 2^16 - (x, y) / |(x, y)||` per component while both
/// components are within `2^15` (the scaling to 15 bits is then exact): 2e-5. (Inverse roots
/// by a 257-entry table in Q24 with linear interpolation, chord error 3/32 x^-2 h^2 =
/// 5.7e-6 of the value at h = 1/128; the product's rounding to Q16, 7.6e-6; the Q24
/// rounding and the 12-bit interpolation step, under 1e-7: 1.4e-5 in all.)
const UNIT_BOUND: f64 = 2e-5;

/// The same for any components: cutting each to 15 bits (towards zero, under one unit of
/// at least 2^14) turns the direction by under 2^-14 rad = 6.1e-5 on top: 8.2e-5.
const UNIT_BOUND_WIDE: f64 = 8.2e-5;

/// Bound on `Direction::of_vector(x, y).angle` against `atan2(x, y)`, in degrees, while both
/// components are within `2^15`: the unit vector's error (`UNIT_BOUND`) through an arcsine's
/// slope of at most 1.42 (the table's argument stays below 1/sqrt(2)), 2.9e-5 rad, plus the
/// arcsine table's chord error (h^2 / 8 x asin'' <= 2 at h = 1/256: 3.9e-6 rad) and its
/// CORDIC entries (1e-5 degrees): 1.9e-3 degrees. We assert 2e-3.
const DIRECTION_BOUND_DEG: f64 = 2e-3;

/// The same for any components: the 15-bit cut turns the direction by up to 6.1e-5 rad
/// itself, and its sine and cosine by as much (through the arcsine: 8.7e-5 rad): 6e-3
/// degrees in all.
const DIRECTION_BOUND_WIDE_DEG: f64 = 6e-3;

fn q16(v: i32) -> f64 {
    v as f64 / TRIG_ONE as f64
}

fn check_trig(a: Angle) -> Result<(), TestCaseError> {
    let r = bits_to_rad(a.bits());
    let (es, ec) = (
        (q16(a.sin()) - r.sin()).abs(),
        (q16(a.cos()) - r.cos()).abs(),
    );
    prop_assert!(es <= TRIG_BOUND, "sin {:#x}: error {es:e}", a.bits());
    prop_assert!(ec <= TRIG_BOUND, "cos {:#x}: error {ec:e}", a.bits());
    prop_assert!(a.sin().abs() <= TRIG_ONE && a.cos().abs() <= TRIG_ONE);
    Ok(())
}

/// The error of `of_vector(x, y)` against `atan2`, in degrees.
fn of_vector_error_deg(x: i64, y: i64) -> f64 {
    let core = Angle::of_vector(x, y);
    let truth = (x as f64).atan2(y as f64);
    reference::angle_diff(bits_to_rad(core.bits()), truth).to_degrees()
}

/// Components of every size: tiny, ordinary, huge and the extremes of `i64`.
fn component() -> impl Strategy<Value = i64> {
    prop_oneof![
        -3i64..=3,
        -10_000i64..=10_000,
        any::<i32>().prop_map(i64::from),
        any::<i64>(),
        Just(i64::MAX),
        Just(i64::MIN),
        Just(i64::MIN + 1),
    ]
}

/// A dense sweep: every 4096th binary angle (a million angles).
#[test]
fn sine_and_cosine_sweep_within_2e5() {
    let mut worst = 0.0f64;
    for k in 0..(1u32 << 20) {
        let a = Angle::from_bits(k << 12 | (k & 0xFFF));
        let r = bits_to_rad(a.bits());
        worst = worst
            .max((q16(a.sin()) - r.sin()).abs())
            .max((q16(a.cos()) - r.cos()).abs());
    }
    assert!(worst <= TRIG_BOUND, "worst trig error {worst:e}");
    println!("worst sine/cosine error over the sweep: {worst:e}");
}

/// Axis-aligned and diagonal vectors of every magnitude: exact to the bound, signs right.
#[test]
fn of_vector_axes_and_diagonals() {
    let mut m: i64 = 1;
    loop {
        for (x, y, deg) in [
            (0, m, 0.0),
            (m, 0, 90.0),
            (0, -m, 180.0),
            (-m, 0, -90.0),
            (m, m, 45.0),
            (m, -m, 135.0),
            (-m, -m, -135.0),
            (-m, m, -45.0),
        ] {
            let got = bits_to_rad(Angle::of_vector(x, y).bits()).to_degrees();
            let err = reference::angle_diff(got.to_radians(), f64::to_radians(deg))
                .to_degrees()
                .abs();
            assert!(err <= OF_VECTOR_BOUND_DEG, "({x}, {y}): {got} vs {deg}");
        }
        if m > i64::MAX / 3 {
            break;
        }
        m = m * 3 + 1;
    }
    assert_eq!(Angle::of_vector(0, 0), Angle::ZERO);
    assert!(of_vector_error_deg(i64::MIN, i64::MIN).abs() <= OF_VECTOR_BOUND_DEG);
    assert!(of_vector_error_deg(i64::MIN, 1).abs() <= OF_VECTOR_BOUND_DEG);
}

/// A million pseudo-random vectors of mixed magnitudes: report the worst `of_vector` error.
#[test]
fn of_vector_sweep() {
    let mut rng = reference::Lcg(0x9E37_79B9_7F4A_7C15u64);
    let mut next = move || rng.next_u64();
    let mut worst = 0.0f64;
    for _ in 0..1_000_000 {
        let (a, b, s) = (next() as i64, next() as i64, next());
        let (x, y) = (a >> (s % 64), b >> ((s >> 8) % 64));
        if x != 0 || y != 0 {
            worst = worst.max(of_vector_error_deg(x, y).abs());
        }
    }
    assert!(
        worst <= OF_VECTOR_BOUND_DEG,
        "worst of_vector error {worst:e} deg"
    );
    println!("worst of_vector error over the sweep: {worst:e} deg");
}

/// The worst errors of `sin_cos_of_vector` and `Direction::of_vector` against `f64` over
/// `n` pseudo-random vectors: components within `2^15`, or (`wide`) of every width.
fn direction_errors(n: u32, wide: bool) -> (f64, f64) {
    let mut rng = reference::Lcg(0x2545_F491_4F6C_DD1D);
    let (mut unit, mut angle) = (0.0f64, 0.0f64);
    for _ in 0..n {
        let s = rng.next_u64();
        let (x, y) = if wide {
            ((s >> 32) as i32 >> (s % 31), (s as i32) >> ((s >> 8) % 31))
        } else {
            ((s >> 32) as i32 >> 17, (s as i32) >> 17)
        };
        if x == 0 && y == 0 {
            continue;
        }
        let (e_unit, e_angle) = direction_error(x, y);
        unit = unit.max(e_unit);
        angle = angle.max(e_angle);
    }
    (unit, angle)
}

/// The error of `sin_cos_of_vector(x, y)` (worse component) and of
/// `Direction::of_vector(x, y)`'s angle in degrees; its sine and cosine must be the former's.
fn direction_error(x: i32, y: i32) -> (f64, f64) {
    let (sin, cos) = sin_cos_of_vector(x, y);
    assert!(sin.abs() <= TRIG_ONE && cos.abs() <= TRIG_ONE, "({x}, {y})");
    let n = (x as f64).hypot(y as f64);
    let unit = (q16(sin) - x as f64 / n)
        .abs()
        .max((q16(cos) - y as f64 / n).abs());
    let d = Direction::of_vector(x, y);
    assert_eq!((d.sin, d.cos), (sin, cos), "({x}, {y})");
    let truth = (x as f64).atan2(y as f64);
    let angle = reference::angle_diff(bits_to_rad(d.angle.bits()), truth)
        .to_degrees()
        .abs();
    (unit, angle)
}

/// Three million vectors, a million with 15-bit components and two with components of
/// every width: report the worst errors.
#[test]
fn direction_sweep() {
    let (unit, angle) = direction_errors(1_000_000, false);
    assert!(unit <= UNIT_BOUND && angle <= DIRECTION_BOUND_DEG);
    println!("worst sin_cos_of_vector error within 2^15: {unit:e}, Direction angle {angle:e} deg");
    let (unit, angle) = direction_errors(2_000_000, true);
    assert!(unit <= UNIT_BOUND_WIDE && angle <= DIRECTION_BOUND_WIDE_DEG);
    println!("worst sin_cos_of_vector error, any width: {unit:e}, Direction angle {angle:e} deg");
}

/// Axes, diagonals and the zero vector: exact where the value is exact.
#[test]
fn direction_axes() {
    for m in [1, 3, 1000, (1 << 15) - 1, 1 << 15, 1 << 20, i32::MAX] {
        assert_eq!(sin_cos_of_vector(0, m), (0, TRIG_ONE));
        assert_eq!(sin_cos_of_vector(m, 0), (TRIG_ONE, 0));
        assert_eq!(sin_cos_of_vector(0, -m), (0, -TRIG_ONE));
        assert_eq!(sin_cos_of_vector(-m, 0), (-TRIG_ONE, 0));
        assert_eq!(Direction::of_vector(m, 0).angle, Angle::QUARTER_TURN);
        assert_eq!(Direction::of_vector(0, -m).angle, Angle::HALF_TURN);
        assert_eq!(Direction::of_vector(-m, 0).angle, -Angle::QUARTER_TURN);
        assert_eq!(Direction::of_vector(0, m).angle, Angle::ZERO);
        let (ub, ab) = if m < 1 << 15 {
            (UNIT_BOUND, DIRECTION_BOUND_DEG)
        } else {
            (UNIT_BOUND_WIDE, DIRECTION_BOUND_WIDE_DEG)
        };
        for (x, y) in [(m, m), (-m, m), (m, -m), (-m, -m), (m, 1), (1, m)] {
            let (unit, angle) = direction_error(x, y);
            assert!(
                unit <= ub && angle <= ab,
                "({x}, {y}): {unit:e}, {angle:e} deg"
            );
        }
    }
    assert_eq!(sin_cos_of_vector(0, 0), (0, TRIG_ONE));
    assert_eq!(Direction::of_vector(0, 0).angle, Angle::ZERO);
    let (unit, angle) = direction_error(i32::MIN, i32::MIN);
    assert!(unit <= UNIT_BOUND_WIDE && angle <= DIRECTION_BOUND_WIDE_DEG);
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2000, failure_persistence: None, ..ProptestConfig::default() })]

    /// `sin_cos_of_vector` within 2e-5 of `(x, y) / |(x, y)|` and `Direction::of_vector`
    /// within 2e-3 degrees of `atan2(x, y)` for components within `2^15`; 8.2e-5 and 6e-3
    /// degrees for any.
    #[test]
    fn direction_within_bound(
        x in prop_oneof![-(1i32 << 15) + 1..1 << 15, any::<i32>()],
        y in prop_oneof![-(1i32 << 15) + 1..1 << 15, any::<i32>()],
    ) {
        prop_assume!(x != 0 || y != 0);
        let narrow = x.unsigned_abs() < 1 << 15 && y.unsigned_abs() < 1 << 15;
        let (unit, angle) = direction_error(x, y);
        let (ub, ab) = if narrow {
            (UNIT_BOUND, DIRECTION_BOUND_DEG)
        } else {
            (UNIT_BOUND_WIDE, DIRECTION_BOUND_WIDE_DEG)
        };
        prop_assert!(unit <= ub, "({}, {}): unit error {:e}", x, y, unit);
        prop_assert!(angle <= ab, "({}, {}): angle error {:e} deg", x, y, angle);
    }

    /// sin and cos within 2e-5 of `f64` for any binary angle.
    #[test]
    fn sine_and_cosine_within_2e5(bits in any::<u32>()) {
        check_trig(Angle::from_bits(bits))?;
    }

    /// `of_vector(x, y)` within 1.5e-5 degrees of `atan2(x, y)` for any components
    /// (tiny, huge, mixed, axis-aligned), except `(0, 0)`, which is zero by definition.
    #[test]
    fn of_vector_within_bound(x in component(), y in component()) {
        if x == 0 && y == 0 {
            prop_assert_eq!(Angle::of_vector(x, y), Angle::ZERO);
        } else {
            let err = of_vector_error_deg(x, y);
            prop_assert!(err.abs() <= OF_VECTOR_BOUND_DEG, "({}, {}): error {:e} deg", x, y, err);
        }
    }

    /// Millidegrees -> angle -> millidegrees is the identity, modulo a turn, into
    /// `[-180000, 180000)`, for any `i64`.
    #[test]
    fn millidegrees_round_trip(mdeg in prop_oneof![-720_000i64..=720_000, any::<i64>()]) {
        let expected = (mdeg + 180_000).rem_euclid(360_000) - 180_000;
        prop_assert_eq!(Angle::from_millidegrees(mdeg).to_millidegrees() as i64, expected);
    }

    /// Angle -> millidegrees is `f64` rounding (exact: `bits * 5625 / 2^26`), and back
    /// lands within half a millidegree (5966 binary units); microdegrees within 1 unit of
    /// `f64` rounding.
    #[test]
    fn angle_to_millidegrees_rounds_to_nearest(bits in any::<u32>()) {
        let a = Angle::from_bits(bits);
        let exact_mdeg = a.signed_bits() as f64 * 360_000.0 / 4_294_967_296.0;
        prop_assert_eq!(a.to_millidegrees() as f64, (exact_mdeg + 0.5).floor());
        let back = Angle::from_millidegrees(a.to_millidegrees() as i64);
        let half_mdeg_bits = (0.0005f64).to_radians() / RAD_PER_BIT;
        prop_assert!((back.diff(a) as f64).abs() <= half_mdeg_bits + 0.5);
        let udeg = a.to_microdegrees() as f64;
        prop_assert!((udeg - (exact_mdeg * 1000.0).round()).abs() <= 1.0);
    }

    /// Angles given in millidegrees have the trigonometry of those millidegrees.
    #[test]
    fn millidegree_sines(mdeg in -10_000_000i64..=10_000_000) {
        let a = Angle::from_millidegrees(mdeg);
        let r = (mdeg as f64 / 1000.0).to_radians();
        // Quantisation to a binary unit adds at most 0.5 x 1.5e-9 rad.
        prop_assert!((q16(a.sin()) - r.sin()).abs() <= TRIG_BOUND + 1e-9);
        prop_assert!((q16(a.cos()) - r.cos()).abs() <= TRIG_BOUND + 1e-9);
    }
}
