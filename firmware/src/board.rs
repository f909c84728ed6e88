//! The board map: which RP2040 pin, bus and peripheral each part of BugBot is wired to.
//!
//! This is the only file that names pins. [`Board::split`] hands each part's resources to
//! the task that owns that part, so a wiring change is an edit here and nowhere else, and
//! the compiler checks that every pin can do its job (an SDA pin that is not on I2C0's
//! pin list does not type-check in the task that builds the bus).

use embassy_rp::peripherals::{
    CORE1, DMA_CH0, DMA_CH1, DMA_CH2, FLASH, I2C0, I2C1, PIN_0, PIN_1, PIN_10, PIN_11, PIN_12,
    PIN_13, PIN_16, PIN_17, PIN_18, PIN_19, PIN_2, PIN_25, PIN_3, PIN_4, PIN_5, PIN_6, PIN_7,
    PIN_8, PWM_SLICE5, PWM_SLICE6, SPI0, UART0, UART1, USB, WATCHDOG,
};
use embassy_rp::{Peri, Peripherals};

/// VL53L5CX bus clock, in hertz. The part allows 1 MHz, but only with stronger pull-ups
/// than a hand-wired board has; 400 kHz still moves an 8x8 frame in a few milliseconds.
pub const DEPTH_I2C_HZ: u32 = 400_000;

/// IMU bus clock, in hertz (fast mode).
pub const IMU_I2C_HZ: u32 = 400_000;

/// PMW3901 SPI clock, in hertz: the part's maximum is 2 MHz, SPI mode 3.
pub const FLOW_SPI_HZ: u32 = 2_000_000;

/// Camera co-processor link speed, in baud (8N1).
pub const CAMERA_BAUD: u32 = 115_200;

/// Telemetry link speed, in baud (8N1): 92 KB/s, over ten times the stream's worst case.
pub const TELEMETRY_BAUD: u32 = 921_600;

/// Motor PWM counter wrap: 125 MHz / (6249 + 1) = 20 kHz, above hearing and within the
/// DRV8833's 50 kHz limit. Duty is `compare / (TOP + 1)`.
pub const MOTOR_PWM_TOP: u16 = 6_249;

/// VL53L5CX 8x8 time-of-flight depth sensor on I2C0.
pub struct DepthSensorPins {
    /// The I2C0 block.
    pub i2c: Peri<'static, I2C0>,
    /// GP4: I2C0 SDA.
    pub sda: Peri<'static, PIN_4>,
    /// GP5: I2C0 SCL.
    pub scl: Peri<'static, PIN_5>,
    /// GP6: the sensor's LPn (low power, active low): high enables its I2C interface.
    pub lpn: Peri<'static, PIN_6>,
    /// The second core: ST's driver is blocking, so it runs there (feature `vl53l5cx`).
    pub core1: Peri<'static, CORE1>,
}

/// ICM-42688-P IMU (its gyro gives the yaw rate) on I2C1.
pub struct ImuPins {
    /// The I2C1 block.
    pub i2c: Peri<'static, I2C1>,
    /// GP2: I2C1 SDA.
    pub sda: Peri<'static, PIN_2>,
    /// GP3: I2C1 SCL.
    pub scl: Peri<'static, PIN_3>,
    /// GP7: the IMU's data-ready interrupt line (input).
    pub int: Peri<'static, PIN_7>,
}

/// PMW3901 optical flow sensor on SPI0, with two DMA channels for async transfers.
pub struct FlowSensorPins {
    /// The SPI0 block.
    pub spi: Peri<'static, SPI0>,
    /// GP18: SPI0 SCK.
    pub sck: Peri<'static, PIN_18>,
    /// GP19: SPI0 TX (MOSI).
    pub mosi: Peri<'static, PIN_19>,
    /// GP16: SPI0 RX (MISO).
    pub miso: Peri<'static, PIN_16>,
    /// GP17: chip select, driven as a GPIO (active low) so a transaction can span reads.
    pub cs: Peri<'static, PIN_17>,
    /// DMA channel 0: SPI0 transmit.
    pub tx_dma: Peri<'static, DMA_CH0>,
    /// DMA channel 1: SPI0 receive.
    pub rx_dma: Peri<'static, DMA_CH1>,
}

/// Camera co-processor (AprilTag detections) on UART0 at [`CAMERA_BAUD`].
pub struct CameraLinkPins {
    /// The UART0 block.
    pub uart: Peri<'static, UART0>,
    /// GP0: UART0 TX, to the co-processor's RX.
    pub tx: Peri<'static, PIN_0>,
    /// GP1: UART0 RX, from the co-processor's TX.
    pub rx: Peri<'static, PIN_1>,
}

/// Telemetry link on UART1 at [`TELEMETRY_BAUD`], transmit only, written by DMA.
/// GP9 (UART1 RX) is left unclaimed until the host has commands to send.
pub struct TelemetryLinkPins {
    /// The UART1 block.
    pub uart: Peri<'static, UART1>,
    /// GP8: UART1 TX, robot to host.
    pub tx: Peri<'static, PIN_8>,
    /// DMA channel 2: UART1 transmit.
    pub tx_dma: Peri<'static, DMA_CH2>,
}

/// The USB device port (the Pico's micro-USB socket): telemetry as a CDC ACM serial port.
pub struct UsbLinkPins {
    /// The USB controller. D+/D- are dedicated pins, not GPIOs.
    pub usb: Peri<'static, USB>,
    /// The flash chip, read once at boot for its 64-bit unique ID: the RP2040 has none of
    /// its own, and the ID becomes the USB serial number.
    pub flash: Peri<'static, FLASH>,
}

/// DRV8833 dual H-bridge, driven by two PWM slices (one per motor, inputs IN1/IN2 on the
/// slice's A/B channels). Both channels low is coast.
pub struct MotorPins {
    /// PWM slice 5: the left motor.
    pub left_slice: Peri<'static, PWM_SLICE5>,
    /// GP10: PWM5 A, DRV8833 AIN1 (left motor forward).
    pub left_in1: Peri<'static, PIN_10>,
    /// GP11: PWM5 B, DRV8833 AIN2 (left motor reverse).
    pub left_in2: Peri<'static, PIN_11>,
    /// PWM slice 6: the right motor.
    pub right_slice: Peri<'static, PWM_SLICE6>,
    /// GP12: PWM6 A, DRV8833 BIN1 (right motor forward).
    pub right_in1: Peri<'static, PIN_12>,
    /// GP13: PWM6 B, DRV8833 BIN2 (right motor reverse).
    pub right_in2: Peri<'static, PIN_13>,
}

/// Everything on the board, grouped by the part it belongs to.
pub struct Board {
    /// VL53L5CX depth sensor: I2C0 on GP4/GP5, LPn on GP6.
    pub depth: DepthSensorPins,
    /// ICM-42688-P IMU: I2C1 on GP2/GP3, INT on GP7.
    pub imu: ImuPins,
    /// PMW3901 flow sensor: SPI0 on GP18/GP19/GP16, CS on GP17.
    pub flow: FlowSensorPins,
    /// Camera co-processor: UART0 on GP0/GP1.
    pub camera: CameraLinkPins,
    /// Telemetry: UART1 TX on GP8, DMA channel 2.
    pub telemetry: TelemetryLinkPins,
    /// USB device port: telemetry again, as a CDC ACM serial port.
    pub usb: UsbLinkPins,
    /// DRV8833 motor driver: PWM5 on GP10/GP11, PWM6 on GP12/GP13.
    pub motors: MotorPins,
    /// GP25: the Pico's green status LED (active high).
    pub status_led: Peri<'static, PIN_25>,
    /// The hardware watchdog, fed by the SLAM loop.
    pub watchdog: Peri<'static, WATCHDOG>,
}

impl Board {
    /// Splits the chip's peripherals by part. Anything not named here stays unused.
    pub fn split(p: Peripherals) -> Board {
        Board {
            depth: DepthSensorPins {
                i2c: p.I2C0,
                sda: p.PIN_4,
                scl: p.PIN_5,
                lpn: p.PIN_6,
                core1: p.CORE1,
            },
            imu: ImuPins {
                i2c: p.I2C1,
                sda: p.PIN_2,
                scl: p.PIN_3,
                int: p.PIN_7,
            },
            flow: FlowSensorPins {
                spi: p.SPI0,
                sck: p.PIN_18,
                mosi: p.PIN_19,
                miso: p.PIN_16,
                cs: p.PIN_17,
                tx_dma: p.DMA_CH0,
                rx_dma: p.DMA_CH1,
            },
            camera: CameraLinkPins {
                uart: p.UART0,
                tx: p.PIN_0,
                rx: p.PIN_1,
            },
            telemetry: TelemetryLinkPins {
                uart: p.UART1,
                tx: p.PIN_8,
                tx_dma: p.DMA_CH2,
            },
            usb: UsbLinkPins {
                usb: p.USB,
                flash: p.FLASH,
            },
            motors: MotorPins {
                left_slice: p.PWM_SLICE5,
                left_in1: p.PIN_10,
                left_in2: p.PIN_11,
                right_slice: p.PWM_SLICE6,
                right_in1: p.PIN_12,
                right_in2: p.PIN_13,
            },
            status_led: p.PIN_25,
            watchdog: p.WATCHDOG,
        }
    }
}
