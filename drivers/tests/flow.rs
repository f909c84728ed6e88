//! PMW3901 against SPI expectation lists.

mod common;

use drivers::flow::register::{
    self, INIT_PART1, INIT_PART2, T_AFTER_READ_NS, T_AFTER_WRITE_NS, T_SRAD_NS,
};
use drivers::flow::{
    AxisMap, Error, FlowCalibration, FlowConfig, FlowReading, FlowSample, Pmw3901, SurfaceCheck,
};
use embedded_hal::spi::ErrorKind;
use embedded_hal_mock::eh1::delay::{NoopDelay, Transaction as Delay};
use embedded_hal_mock::eh1::spi::Transaction as Spi;

fn reg_write(reg: u8, value: u8) -> Vec<Spi<u8>> {
    vec![
        Spi::transaction_start(),
        Spi::write_vec(vec![reg | 0x80, value]),
        Spi::delay(T_AFTER_WRITE_NS),
        Spi::transaction_end(),
    ]
}

fn reg_read(reg: u8, value: u8) -> Vec<Spi<u8>> {
    vec![
        Spi::transaction_start(),
        Spi::write_vec(vec![reg]),
        Spi::delay(T_SRAD_NS),
        Spi::read(value),
        Spi::delay(T_AFTER_READ_NS),
        Spi::transaction_end(),
    ]
}

fn burst(bytes: [u8; 12]) -> Vec<Spi<u8>> {
    vec![
        Spi::transaction_start(),
        Spi::write_vec(vec![0x16]),
        Spi::delay(T_SRAD_NS),
        Spi::read_vec(bytes.to_vec()),
        Spi::transaction_end(),
    ]
}

/// Motion set, deltas, SQUAL, shutter upper.
fn burst_bytes(motion: bool, dx: i16, dy: i16, squal: u8, shutter_upper: u8) -> [u8; 12] {
    let [xl, xh] = dx.to_le_bytes();
    let [yl, yh] = dy.to_le_bytes();
    [
        if motion { 0x80 } else { 0x00 },
        0xBF,
        xl,
        xh,
        yl,
        yh,
        squal,
        0x40,
        0x80,
        0x10,
        shutter_upper,
        0x20,
    ]
}

fn reset_and_probe(id: u8, inverse: Option<u8>) -> Vec<Spi<u8>> {
    let mut e = reg_write(0x3A, 0x5A);
    for reg in 0x02..=0x06 {
        e.extend(reg_read(reg, 0));
    }
    e.extend(reg_read(0x00, id));
    if let Some(inverse) = inverse {
        e.extend(reg_read(0x5F, inverse));
    }
    e
}

fn config() -> FlowConfig {
    FlowConfig::new(FlowCalibration::from_height_mm(100))
}

#[test]
fn init_sequence_is_exact() {
    let mut e = reset_and_probe(0x49, Some(0xB6));
    for (reg, value) in INIT_PART1 {
        e.extend(reg_write(reg, value));
    }
    for (reg, value) in INIT_PART2 {
        e.extend(reg_write(reg, value));
    }
    let (spi, _spi_check) = common::spi(&e);
    let (mut delay, _delay_check) = common::delay(&[Delay::delay_ms(5), Delay::delay_ms(100)]);
    let mut flow = Pmw3901::new(spi, config());
    common::block_on(flow.init(&mut delay)).unwrap();
    assert_eq!(flow.counters().bus_errors, 0);
}

#[test]
fn init_table_matches_reference() {
    // Pinned against the Bitcraze reference sequence: length, ends, pause point.
    assert_eq!(INIT_PART1.len(), 59);
    assert_eq!(INIT_PART2.len(), 14);
    assert_eq!(INIT_PART1[0], (0x7F, 0x00));
    assert_eq!(INIT_PART1[1], (0x61, 0xAD));
    assert_eq!(INIT_PART1[58], (0x70, 0x00));
    assert_eq!(INIT_PART2[0], (0x32, 0x44));
    assert_eq!(INIT_PART2[13], (0x40, 0x80));
    // Writes carry the write flag on the wire, so no entry may have bit 7 set.
    assert!(INIT_PART1
        .iter()
        .chain(&INIT_PART2)
        .all(|(r, _)| r & 0x80 == 0));
}

#[test]
fn wrong_product_id_is_typed_error() {
    let (spi, _check) = common::spi(&reset_and_probe(0x48, None));
    let mut flow = Pmw3901::new(spi, config());
    let err = common::block_on(flow.init(&mut NoopDelay::new())).unwrap_err();
    assert_eq!(err, Error::WrongProductId { found: 0x48 });
}

#[test]
fn wrong_inverse_id_is_typed_error() {
    let (spi, _check) = common::spi(&reset_and_probe(0x49, Some(0xB8)));
    let mut flow = Pmw3901::new(spi, config());
    let err = common::block_on(flow.init(&mut NoopDelay::new())).unwrap_err();
    assert_eq!(err, Error::WrongInverseProductId { found: 0xB8 });
}

#[test]
fn bus_error_in_init_is_mapped_and_counted() {
    // Reset write and first motion read succeed, the second read fails.
    let mut e = reg_write(0x3A, 0x5A);
    e.extend(reg_read(0x02, 0));
    let (inner, _check) = common::spi(&e);
    let spi = common::FailingSpi {
        inner,
        fail_at: 2,
        seen: 0,
    };
    let mut flow = Pmw3901::new(spi, config());
    let err = common::block_on(flow.init(&mut NoopDelay::new())).unwrap_err();
    assert_eq!(err, Error::Bus(ErrorKind::Other));
    assert_eq!(flow.counters().bus_errors, 1);
}

#[test]
fn bus_error_in_read_is_mapped_and_counted() {
    let (inner, _check) = common::spi(&[]);
    let spi = common::FailingSpi {
        inner,
        fail_at: 0,
        seen: 0,
    };
    let mut flow = Pmw3901::new(spi, config());
    let err = common::block_on(flow.read()).unwrap_err();
    assert_eq!(err, Error::Bus(ErrorKind::Other));
    assert_eq!(flow.counters().bus_errors, 1);
    assert_eq!(flow.counters().reads, 0);
}

#[test]
fn motion_burst_is_parsed_and_scaled() {
    let (spi, _check) = common::spi(&burst(burst_bytes(true, 10, -3, 0x60, 0x01)));
    let mut flow = Pmw3901::new(spi, config());
    let reading = common::block_on(flow.read()).unwrap();
    // 100 mm height: 2193.5 um per count.
    assert_eq!(
        reading,
        FlowReading::Motion(FlowSample {
            right_counts: 10,
            forward_counts: -3,
            right_um: 21_935,
            forward_um: -6_581,
            squal: 0x60,
        })
    );
    assert_eq!(flow.counters().reads, 1);
}

#[test]
fn raw_burst_fields_in_order() {
    let bytes = [
        0x80, 0xBF, 0x34, 0x12, 0xFE, 0xFF, 0x55, 0x66, 0x77, 0x88, 0x1F, 0x99,
    ];
    let (spi, _check) = common::spi(&burst(bytes));
    let mut flow = Pmw3901::new(spi, config());
    let b = common::block_on(flow.read_motion_burst()).unwrap();
    assert!(b.has_motion());
    assert_eq!(b.observation, 0xBF);
    assert_eq!(b.delta_x, 0x1234);
    assert_eq!(b.delta_y, -2);
    assert_eq!(
        (b.squal, b.raw_data_sum, b.max_raw, b.min_raw),
        (0x55, 0x66, 0x77, 0x88)
    );
    assert_eq!((b.shutter_upper, b.shutter_lower), (0x1F, 0x99));
}

#[test]
fn no_motion_flag_gives_zero_displacement() {
    // Stale deltas with the flag clear must not be used.
    let (spi, _check) = common::spi(&burst(burst_bytes(false, 7, 7, 0x60, 0x01)));
    let mut flow = Pmw3901::new(spi, config());
    let reading = common::block_on(flow.read()).unwrap();
    assert_eq!(
        reading,
        FlowReading::Motion(FlowSample {
            squal: 0x60,
            ..FlowSample::default()
        })
    );
}

#[test]
fn low_squal_with_open_shutter_is_no_surface() {
    let mut e = burst(burst_bytes(true, 5, 5, 0x18, 0x1F));
    // Low SQUAL but a short shutter: the datasheet rule still trusts it.
    e.extend(burst(burst_bytes(true, 5, 5, 0x18, 0x02)));
    let (spi, _check) = common::spi(&e);
    let mut flow = Pmw3901::new(spi, config());
    assert_eq!(
        common::block_on(flow.read()).unwrap(),
        FlowReading::NoSurface {
            squal: 0x18,
            shutter_upper: 0x1F
        }
    );
    assert!(matches!(
        common::block_on(flow.read()).unwrap(),
        FlowReading::Motion(_)
    ));
    assert_eq!(flow.counters().low_quality, 1);
    assert_eq!(flow.counters().reads, 2);
}

#[test]
fn squal_only_check_and_configurable_minimum() {
    let mut cfg = config();
    cfg.surface_check = SurfaceCheck::SqualOnly;
    cfg.min_squal = 0x40;
    let mut e = burst(burst_bytes(true, 5, 5, 0x3F, 0x02));
    e.extend(burst(burst_bytes(true, 5, 5, 0x40, 0x02)));
    let (spi, _check) = common::spi(&e);
    let mut flow = Pmw3901::new(spi, cfg);
    assert!(matches!(
        common::block_on(flow.read()).unwrap(),
        FlowReading::NoSurface { squal: 0x3F, .. }
    ));
    assert!(matches!(
        common::block_on(flow.read()).unwrap(),
        FlowReading::Motion(_)
    ));
}

#[test]
fn outliers_are_dropped_and_counted() {
    let mut e = burst(burst_bytes(true, 100, 0, 0x60, 0x01));
    e.extend(burst(burst_bytes(true, 0, -100, 0x60, 0x01)));
    e.extend(burst(burst_bytes(true, 99, -99, 0x60, 0x01)));
    e.extend(burst(burst_bytes(true, i16::MIN, 0, 0x60, 0x01)));
    let (spi, _check) = common::spi(&e);
    let mut flow = Pmw3901::new(spi, config());
    assert_eq!(
        common::block_on(flow.read()).unwrap(),
        FlowReading::Outlier {
            right_counts: 100,
            forward_counts: 0
        }
    );
    assert!(matches!(
        common::block_on(flow.read()).unwrap(),
        FlowReading::Outlier {
            forward_counts: -100,
            ..
        }
    ));
    assert!(matches!(
        common::block_on(flow.read()).unwrap(),
        FlowReading::Motion(FlowSample {
            right_counts: 99,
            forward_counts: -99,
            ..
        })
    ));
    assert!(matches!(
        common::block_on(flow.read()).unwrap(),
        FlowReading::Outlier { .. }
    ));
    let c = flow.counters();
    assert_eq!(
        (c.reads, c.outliers, c.low_quality, c.bus_errors),
        (4, 3, 0, 0)
    );
}

#[test]
fn axis_map_swaps_and_negates() {
    let mut cfg = config();
    cfg.axes = AxisMap {
        swap_xy: true,
        negate_right: true,
        negate_forward: false,
    };
    let (spi, _check) = common::spi(&burst(burst_bytes(true, 4, 9, 0x60, 0x01)));
    let mut flow = Pmw3901::new(spi, cfg);
    let FlowReading::Motion(s) = common::block_on(flow.read()).unwrap() else {
        panic!("expected motion");
    };
    assert_eq!((s.right_counts, s.forward_counts), (-9, 4));
    assert_eq!(AxisMap::default().apply(i16::MIN, 1), (i16::MIN, 1));
    let neg = AxisMap {
        negate_right: true,
        ..AxisMap::default()
    };
    assert_eq!(neg.apply(i16::MIN, 1), (i16::MAX, 1));
}

#[test]
fn destroy_returns_the_bus() {
    let (spi, _check) = common::spi(&reg_read(0x00, 0x49));
    let mut flow = Pmw3901::new(spi, config());
    assert_eq!(
        common::block_on(flow.read_register(register::Register::PRODUCT_ID)).unwrap(),
        0x49
    );
    // The guard checks the expectations on the bus handed back.
    let _spi: embedded_hal_mock::eh1::spi::Mock<u8> = flow.destroy();
}
