//! ICM-42688-P against I2C expectation lists, and the bias calibrator.

mod common;

use drivers::imu::{
    Address, BiasCalibrator, CalibrationStatus, Error, FullScale, GyroBias, GyroConfig, Icm42688,
    Mounting, OutputRate, YawRate,
};
use embedded_hal::i2c::ErrorKind;
use embedded_hal_mock::eh1::delay::{NoopDelay, Transaction as Delay};
use embedded_hal_mock::eh1::i2c::Transaction as I2c;

const ADDR: u8 = 0x68;

fn who_am_i(value: u8) -> I2c {
    I2c::write_read(ADDR, vec![0x75], vec![value])
}

fn gyro_z(raw: i16) -> I2c {
    I2c::write_read(ADDR, vec![0x29], raw.to_be_bytes().to_vec())
}

#[test]
fn init_sequence_is_exact() {
    let (i2c, _check) = common::i2c(&[
        who_am_i(0x47),
        I2c::write(ADDR, vec![0x11, 0x01]),
        I2c::write_read(ADDR, vec![0x2D], vec![0x10]),
        // +-1000 dps (FS_SEL 001), 200 Hz (ODR 0111).
        I2c::write(ADDR, vec![0x4F, 0b0010_0111]),
        I2c::write(ADDR, vec![0x4E, 0b0000_1100]),
    ]);
    let (mut delay, _delay_check) = common::delay(&[Delay::delay_ms(1), Delay::delay_ms(50)]);
    let mut imu = Icm42688::new(i2c, GyroConfig::default());
    common::block_on(imu.init(&mut delay)).unwrap();
}

#[test]
fn config_register_encodings() {
    let cfg = |full_scale, rate| GyroConfig {
        full_scale,
        rate,
        ..GyroConfig::default()
    };
    assert_eq!(
        cfg(FullScale::Dps500, OutputRate::Hz1000).gyro_config0(),
        0x46
    );
    assert_eq!(
        cfg(FullScale::Dps1000, OutputRate::Hz500).gyro_config0(),
        0x2F
    );
    assert_eq!(
        cfg(FullScale::Dps500, OutputRate::Hz200).gyro_config0(),
        0x47
    );
}

#[test]
fn wrong_who_am_i_is_typed_error() {
    let (i2c, _check) = common::i2c(&[who_am_i(0x6A)]);
    let mut imu = Icm42688::new(i2c, GyroConfig::default());
    let err = common::block_on(imu.init(&mut NoopDelay::new())).unwrap_err();
    assert_eq!(err, Error::WrongDevice { found: 0x6A });
}

#[test]
fn reset_not_done_is_typed_error() {
    let (i2c, _check) = common::i2c(&[
        who_am_i(0x47),
        I2c::write(ADDR, vec![0x11, 0x01]),
        I2c::write_read(ADDR, vec![0x2D], vec![0x08]),
    ]);
    let mut imu = Icm42688::new(i2c, GyroConfig::default());
    let err = common::block_on(imu.init(&mut NoopDelay::new())).unwrap_err();
    assert_eq!(err, Error::ResetNotDone);
}

#[test]
fn bus_errors_are_mapped() {
    let (i2c, _check) = common::i2c(&[
        who_am_i(0x47),
        I2c::write(ADDR, vec![0x11, 0x01]).with_error(ErrorKind::Other),
        gyro_z(1).with_error(ErrorKind::ArbitrationLoss),
    ]);
    let mut imu = Icm42688::new(i2c, GyroConfig::default());
    let err = common::block_on(imu.init(&mut NoopDelay::new())).unwrap_err();
    assert_eq!(err, Error::Bus(ErrorKind::Other));
    let err = common::block_on(imu.read_yaw_rate()).unwrap_err();
    assert_eq!(err, Error::Bus(ErrorKind::ArbitrationLoss));
}

#[test]
fn yaw_rate_sign_and_scale() {
    // 328 counts = 10 dps at +-1000 dps; chip face up turning counter-
    // clockwise reads positive, which is a negative BugBot rate.
    let (i2c, _check) = common::i2c(&[gyro_z(328), gyro_z(-328), gyro_z(32767)]);
    let mut imu = Icm42688::new(i2c, GyroConfig::default());
    assert_eq!(
        common::block_on(imu.read_yaw_rate()).unwrap(),
        YawRate { rate_mdps: -10_000 }
    );
    assert_eq!(
        common::block_on(imu.read_yaw_rate()).unwrap().rate_mdps,
        10_000
    );
    // Full scale: 32767 / 32.8 = 998.99 dps.
    assert_eq!(
        common::block_on(imu.read_yaw_rate()).unwrap().rate_mdps,
        -998_994
    );
}

#[test]
fn face_down_and_500_dps_address_high() {
    let (i2c, _check) = common::i2c(&[I2c::write_read(0x69, vec![0x29], vec![0x02, 0x8F])]);
    let cfg = GyroConfig {
        address: Address::Ad0High,
        full_scale: FullScale::Dps500,
        mounting: Mounting::FaceDown,
        ..GyroConfig::default()
    };
    let mut imu = Icm42688::new(i2c, cfg);
    // 0x028F = 655 counts = 10 dps at 65.5 counts/dps.
    assert_eq!(
        common::block_on(imu.read_yaw_rate()).unwrap().rate_mdps,
        10_000
    );
}

#[test]
fn bias_is_subtracted() {
    let (i2c, _check) = common::i2c(&[gyro_z(356), gyro_z(28)]);
    let mut imu = Icm42688::new(i2c, GyroConfig::default());
    imu.set_bias(GyroBias::from_counts(28));
    assert_eq!(
        common::block_on(imu.read_yaw_rate()).unwrap().rate_mdps,
        -10_000
    );
    assert_eq!(common::block_on(imu.read_yaw_rate()).unwrap().rate_mdps, 0);
    // Extreme bias and sample do not overflow: 65534 / 32.8 = 1997.99 dps.
    imu.set_bias(GyroBias::from_counts(i16::MAX));
    assert_eq!(imu.yaw_rate_from_raw(-32767).rate_mdps, 1_997_988);
}

#[test]
fn invalid_sample_is_typed_error() {
    let (i2c, _check) = common::i2c(&[gyro_z(i16::MIN)]);
    let mut imu = Icm42688::new(i2c, GyroConfig::default());
    assert_eq!(
        common::block_on(imu.read_gyro_z_raw()).unwrap_err(),
        Error::InvalidSample
    );
    let _bus: embedded_hal_mock::eh1::i2c::Mock = imu.destroy();
}

#[test]
fn calibrator_needs_enough_samples() {
    let mut cal = BiasCalibrator::new(4, 10);
    assert_eq!(
        cal.status(),
        CalibrationStatus::NeedMore { have: 0, need: 4 }
    );
    assert_eq!(
        cal.push(20),
        CalibrationStatus::NeedMore { have: 1, need: 4 }
    );
    cal.push(22);
    cal.push(20);
    assert_eq!(
        cal.push(22),
        CalibrationStatus::Done(GyroBias::from_counts(21))
    );
    assert_eq!(cal.variance_counts2(), Some(1));
}

#[test]
fn calibrator_rejects_motion() {
    let mut cal = BiasCalibrator::new(4, 10);
    for s in [0, 100, -100, 0] {
        cal.push(s);
    }
    // Variance 5000 counts squared.
    assert_eq!(
        cal.status(),
        CalibrationStatus::TooNoisy {
            variance_counts2: 5000
        }
    );
    cal.reset();
    assert_eq!(cal.samples(), 0);
    for _ in 0..4 {
        cal.push(-7);
    }
    assert_eq!(
        cal.status(),
        CalibrationStatus::Done(GyroBias::from_counts(-7))
    );
}

#[test]
fn calibrator_rounds_mean_to_nearest_and_survives_extremes() {
    let mut cal = BiasCalibrator::new(2, u32::MAX);
    cal.push(-3);
    assert_eq!(
        cal.push(-4),
        CalibrationStatus::Done(GyroBias::from_counts(-4))
    );
    let mut cal = BiasCalibrator::new(1, 0);
    for _ in 0..10_000 {
        cal.push(i16::MIN);
    }
    assert_eq!(cal.mean(), Some(i16::MIN));
    assert_eq!(cal.variance_counts2(), Some(0));
    cal.push(i16::MAX);
    assert!(matches!(cal.status(), CalibrationStatus::TooNoisy { .. }));
}
