//! BugBot firmware for the RP2040: embassy tasks round the `slam-core` step.
//!
//! `main` only brings the chip up, binds interrupts, splits the board by part
//! ([`board::Board`]) and spawns one task per part. The tasks own their hardware and
//! talk through [`inputs`] (sensors to the SLAM tick, gyro yaw to motion),
//! [`slam_task::REPORTS`] (the tick's heartbeat and the guard's decision to motion),
//! [`motion::DRIVE_SPEED_MM_S`] (the drive motion is about to make, for the guard),
//! [`slam_task::TELEMETRY_FRAMES`] (encoded frames to telemetry),
//! [`usb::USB_FRAMES`] (telemetry's copies for the USB serial port) and [`health::HEALTH`]
//! (every task's fault counters).
//!
//! Boot: the robot must stand still for about 1.1 s after reset while the IMU task
//! calibrates the gyro bias; the motion task starts the route only after that. Before
//! anything is spawned, [`reset_cause`] says why the chip started and [`retained`] takes
//! up the map, pose and route from before a watchdog reset, or starts them afresh.
#![no_std]
#![no_main]
#![deny(unsafe_code)]
#![warn(missing_docs)]

use embassy_executor::Spawner;
use embassy_rp::peripherals::{DMA_CH0, DMA_CH1, DMA_CH2, I2C0, I2C1, UART0, USB};
use embassy_rp::watchdog::Watchdog;
use embassy_rp::{bind_interrupts, dma, i2c, uart};
use defmt_rtt as _;

mod board;
mod health;
mod inputs;
mod motion;
mod panic;
mod reset_cause;
mod retained;
mod sensors;
mod slam_task;
mod status_led;
mod telemetry;
mod usb;
mod world;

bind_interrupts!(
    /// Every interrupt the firmware uses, and the driver that handles it.
    pub struct Irqs {
        I2C0_IRQ => i2c::InterruptHandler<I2C0>;
        I2C1_IRQ => i2c::InterruptHandler<I2C1>;
        DMA_IRQ_0 => dma::InterruptHandler<DMA_CH0>, dma::InterruptHandler<DMA_CH1>, dma::InterruptHandler<DMA_CH2>;
        UART0_IRQ => uart::BufferedInterruptHandler<UART0>;
        USBCTRL_IRQ => embassy_rp::usb::InterruptHandler<USB>;
    }
);

#[embassy_executor::main]
async fn main(spawner: Spawner) {
    let board = board::Board::split(embassy_rp::init(Default::default()));
    defmt::info!("BugBot firmware {}", env!("CARGO_PKG_VERSION"));

    let Some(motion_reports) = slam_task::REPORTS.receiver() else {
        defmt::panic!("no report receiver left for motion");
    };
    let inputs = &inputs::INPUTS;
    // First, while only core 0 runs: it reads the flash chip's ID for the serial number.
    let (usb_device, usb_serial) = usb::build(board.usb, Irqs);

    // Why the chip started, read before the watchdog is started again; then the state.
    let watchdog = Watchdog::new(board.watchdog);
    let (saved, start) = retained::open(reset_cause::read(&watchdog), slam_task::fresh_slam);
    let resume = start.route;
    motion::ROUTE_POINT.store(resume.0, portable_atomic::Ordering::Relaxed);
    spawner.spawn(defmt::unwrap!(slam_task::slam_task(
        watchdog, inputs, saved, start
    )));
    #[cfg(feature = "vl53l5cx")]
    {
        sensors::depth::start_core1(board.depth);
        spawner.spawn(defmt::unwrap!(sensors::depth::depth_task(inputs)));
    }
    #[cfg(not(feature = "vl53l5cx"))]
    spawner.spawn(defmt::unwrap!(sensors::depth::depth_task(
        board.depth,
        Irqs,
        &inputs.depth
    )));
    spawner.spawn(defmt::unwrap!(sensors::imu::imu_task(
        board.imu, Irqs, inputs
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
        Irqs
    )));
    spawner.spawn(defmt::unwrap!(usb::usb_device_task(usb_device)));
    spawner.spawn(defmt::unwrap!(usb::usb_telemetry_task(usb_serial)));
    spawner.spawn(defmt::unwrap!(motion::motion_task(
        board.motors,
        inputs,
        motion_reports,
        resume
    )));
    spawner.spawn(defmt::unwrap!(status_led::status_led_task(
        board.status_led
    )));
}
