//! `Angle` against `f64` trigonometry.

mod reference;

use proptest::prelude::*;
use reference::{bits_to_rad, RAD_PER_BIT};
use slam_core::angle::TRIG_ONE;
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
    let mut state = 0x9E37_79B9_7F4A_7C15u64;
    let mut next = move || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        state
    };
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

proptest! {
    #![proptest_config(ProptestConfig { cases: 2000, failure_persistence: None, ..ProptestConfig::default() })]

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
