//! Dead reckoning: flow counts and gyro rate integrated into the pose.

use crate::angle::Angle;
use crate::frame::{FlowDelta, GyroRate};
use crate::pose::{mul_q16, mul_q16_32, Pose};

/// Binary angle units per (millidegree per second x microsecond), times 2^48.
///
/// One millidegree is `2^32 / 360_000` units and one microsecond is `1e-6` s, so the
/// exact factor is `2^32 / 3.6e11`; scaled by `2^48` it is `2^80 / 3.6e11` = 3.4e12, and
/// truncating it costs under 3e-13 of any turn. Rate x tick x factor stays below 2^107.
const BAM_PER_MDPS_US_Q48: i128 = (1i128 << 80) / 360_000_000_000;

/// Calibration of the dead-reckoning sensors.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct OdometryConfig {
    /// Floor distance per flow count, in micrometres, Q16 (`65536` is 1 um per count).
    pub flow_um_per_count_q16: i32,
    /// Gyro scale correction in parts per million (0 = the driver's rate is taken as is).
    pub gyro_scale_ppm: i32,
    /// Where the flow sensor sits relative to the turning axis, micrometres ahead and to
    /// the right: off the axis it sees the floor swing past in every turn, which is not
    /// the robot moving, and is taken off by the turn the gyro measured.
    pub flow_offset_um: [i32; 2],
}

impl OdometryConfig {
    /// The nominal calibration of BugBot's PMW3901 at its mounting height: 100 um per count.
    pub const NOMINAL: OdometryConfig = OdometryConfig {
        flow_um_per_count_q16: 100 << 16,
        gyro_scale_ppm: 0,
        flow_offset_um: [0, 0],
    };
}

/// How a pose moved over one tick, before it is applied.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default)]
pub struct Motion {
    /// Turn over the tick in binary angle units (`2^32` per turn), not wrapped: a tick may
    /// turn more than half a turn, and the mid-tick heading must still be right.
    pub turn_bits: i64,
    /// Displacement towards the nose, in micrometres.
    pub forward_um: i64,
    /// Displacement towards the right, in micrometres.
    pub right_um: i64,
}

/// `mul_q16(counts, um_per_count_q16)`: a tick's flow counts (under 2^16) in 32 bits.
fn counts_um(counts: i32, um_per_count_q16: i32) -> i64 {
    if counts.unsigned_abs() <= 1 << 16 && um_per_count_q16 != i32::MIN {
        i64::from(mul_q16_32(um_per_count_q16, counts))
    } else {
        mul_q16(i64::from(counts), um_per_count_q16)
    }
}

/// `mul_q16(a, trig)` for a sine or cosine (within `+-1.0`): in 32 bits when `a` fits
/// (the M0+ multiplies 64 bits in a library call).
fn along(a: i64, trig: i32) -> i64 {
    match i32::try_from(a) {
        Ok(a) if a != i32::MIN => i64::from(mul_q16_32(a, trig)),
        _ => mul_q16(a, trig),
    }
}

/// The turn a yaw rate makes in `dt_us` microseconds, with the gyro's scale correction,
/// in binary angle units, unwrapped (saturating far beyond any real tick).
pub fn turn_bits_from_gyro(gyro: GyroRate, dt_us: u32, config: &OdometryConfig) -> i64 {
    // The scale correction: an i32 times an i32 fits 64 bits and `/` truncates as 128-bit
    // division would. With none configured there is no division at all (a 64-bit one is
    // hundreds of cycles on the Cortex-M0+).
    let rate = i64::from(gyro.rate_mdps);
    let rate = match config.gyro_scale_ppm {
        0 => rate,
        ppm => rate + rate * i64::from(ppm) / 1_000_000,
    };
    // Rate x tick: an i32 times a u32 always fits 64 bits (a scaled rate past i32 takes
    // 128 bits, where no input overflows: below 2^117 with the factor).
    let Ok(rate) = i32::try_from(rate) else {
        return turn_bits_wide(i128::from(rate) * i128::from(dt_us));
    };
    let swept = i64::from(rate) * i64::from(dt_us);
    if swept.unsigned_abs() >= 1 << 41 {
        return turn_bits_wide(i128::from(swept));
    }
    // `(swept * factor + 2^47) >> 48` in two 64-bit products: with the factor split as
    // `high * 2^20 + low`, `floor((high * swept * 2^20 + low * swept + 2^47) / 2^48)` is
    // `floor((high * swept + floor((low * swept + 2^47) / 2^20)) / 2^28)`. Under 2^41
    // (2000 degrees a second for a whole second), neither product passes 2^63.
    const HIGH: i64 = (BAM_PER_MDPS_US_Q48 >> 20) as i64;
    const LOW: i64 = (BAM_PER_MDPS_US_Q48 & ((1 << 20) - 1)) as i64;
    (swept * HIGH + ((swept * LOW + (1 << 47)) >> 20)) >> 28
}

/// `turn_bits_from_gyro`'s last step in 128 bits, for sweeps past 2^41.
#[cold]
fn turn_bits_wide(swept: i128) -> i64 {
    let bits = (swept * BAM_PER_MDPS_US_Q48 + (1 << 47)) >> 48;
    bits.clamp(i64::MIN as i128, i64::MAX as i128) as i64
}

/// The turn a yaw rate makes in `dt_us` microseconds, as an angle (wrapped).
pub fn turn_from_gyro(gyro: GyroRate, dt_us: u32, config: &OdometryConfig) -> Angle {
    Angle::from_bits(turn_bits_from_gyro(gyro, dt_us, config) as u32)
}

/// The tick's motion from its (possibly stale) flow and gyro readings.
pub fn motion(
    flow: Option<FlowDelta>,
    gyro: Option<GyroRate>,
    dt_us: u32,
    config: &OdometryConfig,
) -> Motion {
    let turn_bits = gyro.map_or(0, |g| turn_bits_from_gyro(g, dt_us, config));
    let (mut forward_um, mut right_um) = flow.map_or((0, 0), |f| {
        (
            counts_um(f.forward_counts, config.flow_um_per_count_q16),
            counts_um(f.right_counts, config.flow_um_per_count_q16),
        )
    });
    if flow.is_some() && config.flow_offset_um != [0, 0] {
        // Turning clockwise by t swings a sensor `a` ahead and `r` right of the axis by
        // (-t r, t a) along (forward, right): the floor it saw move that was not the robot.
        let [ahead, right] = config.flow_offset_um;
        let turn_rad_q32 = i128::from(turn_bits) * 26_986_075_409; // 2 pi in Q32
        let lever = |offset: i32| ((i128::from(offset) * turn_rad_q32) >> 64) as i64;
        forward_um += lever(right);
        right_um -= lever(ahead);
    }
    Motion {
        turn_bits,
        forward_um,
        right_um,
    }
}

/// The heading half way through a turn of `turn_bits` from `heading`: the direction of
/// the arc's chord, which a tick's displacement takes.
#[inline]
pub fn chord_heading(heading: Angle, turn_bits: i64) -> Angle {
    heading + Angle::from_bits((turn_bits / 2) as u32)
}

/// Applies a tick's motion: the displacement is rotated by the heading half way through the
/// turn (the arc's chord direction, [`chord_heading`]), then the turn is added.
pub fn apply(pose: &Pose, m: &Motion) -> Pose {
    let mid = chord_heading(pose.heading, m.turn_bits);
    let (s, c) = mid.sin_cos();
    // nose = (sin h, cos h), right = (cos h, -sin h)
    let dx = along(m.forward_um, s) + along(m.right_um, c);
    let dy = along(m.forward_um, c) - along(m.right_um, s);
    Pose {
        x_um: (pose.x_um as i64 + dx).clamp(i32::MIN as i64, i32::MAX as i64) as i32,
        y_um: (pose.y_um as i64 + dy).clamp(i32::MIN as i64, i32::MAX as i64) as i32,
        heading: pose.heading + Angle::from_bits(m.turn_bits as u32),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The turn as one 128-bit formula: what `turn_bits_from_gyro` must equal bit for bit.
    fn turn_bits_reference(rate_mdps: i32, dt_us: u32, ppm: i32) -> i64 {
        let rate = rate_mdps as i128;
        let rate = rate + rate * ppm as i128 / 1_000_000;
        let bits = (rate * dt_us as i128 * BAM_PER_MDPS_US_Q48 + (1 << 47)) >> 48;
        bits.clamp(i64::MIN as i128, i64::MAX as i128) as i64
    }

    #[test]
    fn products_in_32_bits_equal_mul_q16() {
        let mut rng = crate::lcg::Lcg::new(0x2545_f491_4f6c_dd1d_u64);
        let mut next = || (rng.next_u64() >> 16) as u32;
        for _ in 0..100_000 {
            let (a, r) = (next() as i32, next());
            let trig = (r % (2 * 65_536 + 1)) as i32 - 65_536;
            let a = i64::from(a >> (r % 31));
            assert_eq!(along(a, trig), mul_q16(a, trig), "{a} x {trig}");
            let counts = (next() as i32) >> (r % 32);
            let factor = (next() as i32) >> (r % 24);
            assert_eq!(
                counts_um(counts, factor),
                mul_q16(i64::from(counts), factor),
                "{counts} x {factor}"
            );
        }
        for (a, b) in [
            (i64::from(i32::MIN), 65_536),
            (1 << 40, -65_536),
            (-1, -65_536),
        ] {
            assert_eq!(along(a, b), mul_q16(a, b));
        }
        assert_eq!(counts_um(65_536, i32::MIN), mul_q16(65_536, i32::MIN));
    }

    #[test]
    fn gyro_turn_equals_the_128_bit_formula() {
        let mut rng = crate::lcg::Lcg::new(0x9e37_79b9_7f4a_7c15_u64);
        let mut next = || (rng.next_u64() >> 16) as u32;
        let edges = [0, 1, -1, 999_999, -1_000_000, i32::MAX, i32::MIN];
        for _ in 0..50_000 {
            let pick = |r: u32, wide: u32| {
                if r.is_multiple_of(8) {
                    edges[(r / 8) as usize % edges.len()]
                } else {
                    (wide as i32) >> (r % 24)
                }
            };
            let rate = pick(next(), next());
            let ppm = if next() % 3 == 0 {
                0
            } else {
                pick(next(), next())
            };
            let dt = match next() % 4 {
                0 => u32::MAX >> (next() % 32),
                _ => next() % 1_000_000,
            };
            let config = OdometryConfig {
                gyro_scale_ppm: ppm,
                ..OdometryConfig::NOMINAL
            };
            let gyro = GyroRate { rate_mdps: rate };
            assert_eq!(
                turn_bits_from_gyro(gyro, dt, &config),
                turn_bits_reference(rate, dt, ppm),
                "{rate} mdps for {dt} us at {ppm} ppm"
            );
        }
    }

    #[test]
    fn gyro_turns_a_quarter() {
        // 90 degrees per second for one second.
        let t = turn_from_gyro(
            GyroRate { rate_mdps: 90_000 },
            1_000_000,
            &OdometryConfig::NOMINAL,
        );
        assert!(
            (t.to_microdegrees() - 90_000_000).abs() < 200,
            "{}",
            t.to_microdegrees()
        );
        let t = turn_from_gyro(
            GyroRate { rate_mdps: -31_500 },
            100_000,
            &OdometryConfig::NOMINAL,
        );
        assert!((t.to_microdegrees() + 3_150_000).abs() < 10);
    }

    #[test]
    fn forward_is_along_the_heading() {
        let start = Pose::from_mm_mdeg(700, 500, 90_000); // facing +x
        let m = motion(
            Some(FlowDelta {
                forward_counts: 100,
                right_counts: 0,
            }),
            None,
            100_000,
            &OdometryConfig::NOMINAL,
        );
        let p = apply(&start, &m);
        assert_eq!((p.x_um, p.y_um), (710_000, 500_000));
        let m = motion(
            Some(FlowDelta {
                forward_counts: 0,
                right_counts: 100,
            }),
            None,
            100_000,
            &OdometryConfig::NOMINAL,
        );
        let p = apply(&start, &m);
        assert_eq!((p.x_um, p.y_um), (700_000, 490_000));
    }

    #[test]
    fn stale_inputs_move_nothing() {
        let start = Pose::from_mm_mdeg(1, 2, 3);
        assert_eq!(
            apply(
                &start,
                &motion(None, None, 100_000, &OdometryConfig::NOMINAL)
            ),
            start
        );
    }
}
