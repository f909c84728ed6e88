//! BugBot firmware for the RP2040: embassy tasks round the `slam-core` step.
//!
//! `main` only brings the chip up, binds interrupts, splits the board by part
//! ([`board::Board`]) and spawns one task per part. The tasks own their hardware and
//! talk through [`inputs`] (sensors to the SLAM tick) and [`slam_task::REPORTS`] (the
//! tick to telemetry).
#![no_std]
#![no_main]
#![deny(unsafe_code)]
#![warn(missing_docs)]

use embassy_executor::Spawner;
use embassy_rp::peripherals::{DMA_CH0, DMA_CH1, I2C0, I2C1, UART0, UART1};
use embassy_rp::{bind_interrupts, dma, i2c, uart};
use {defmt_rtt as _, panic_probe as _};

mod board;
mod inputs;
mod motors;
mod sensors;
mod slam_task;
mod status_led;
mod telemetry;

bind_interrupts!(
    /// Every interrupt the firmware uses, and the driver that handles it.
    pub struct Irqs {
        I2C0_IRQ => i2c::InterruptHandler<I2C0>;
        I2C1_IRQ => i2c::InterruptHandler<I2C1>;
        DMA_IRQ_0 => dma::InterruptHandler<DMA_CH0>, dma::InterruptHandler<DMA_CH1>;
        UART0_IRQ => uart::BufferedInterruptHandler<UART0>;
        UART1_IRQ => uart::BufferedInterruptHandler<UART1>;
    }
);

#[embassy_executor::main]
async fn main(spawner: Spawner) {
    let board = board::Board::split(embassy_rp::init(Default::default()));
    defmt::info!("BugBot firmware {}", env!("CARGO_PKG_VERSION"));

    let Some(telemetry_reports) = slam_task::REPORTS.receiver() else {
        defmt::panic!("no report receiver left for telemetry");
    };
    let inputs = &inputs::INPUTS;

    spawner.spawn(defmt::unwrap!(slam_task::slam_task(board.watchdog, inputs)));
    spawner.spawn(defmt::unwrap!(sensors::depth::depth_task(
        board.depth,
        Irqs,
        &inputs.depth
    )));
    spawner.spawn(defmt::unwrap!(sensors::imu::imu_task(
        board.imu,
        Irqs,
        &inputs.gyro
    )));
    spawner.spawn(defmt::unwrap!(sensors::flow::flow_task(
        board.flow,
        Irqs,
        &inputs.flow
    )));
    spawner.spawn(defmt::unwrap!(sensors::camera::camera_task(
        board.camera,
        Irqs,
        &inputs.tags
    )));
    spawner.spawn(defmt::unwrap!(telemetry::telemetry_task(
        board.telemetry,
        Irqs,
        telemetry_reports
    )));
    spawner.spawn(defmt::unwrap!(motors::motor_task(board.motors)));
    spawner.spawn(defmt::unwrap!(status_led::status_led_task(
        board.status_led
    )));
}
