//! USB telemetry: the same COBS frames as UART1, on a USB CDC ACM serial port, so a PC
//! the robot is plugged into sees `/dev/ttyACM0` (a COM port on Windows) carrying the
//! stream that `host-sim view /dev/ttyACM0 --out DIR` decodes. The baud rate the host
//! sets is ignored: USB full speed moves the stream (at most about 7 KB/s) whatever it says.
//!
//! Three parts: [`build`] sets the device up (descriptors, the CDC ACM class), the
//! [`usb_device_task`] answers the host (enumeration, control requests) for good, and the
//! [`usb_telemetry_task`] writes the frames the telemetry task [`offer`]s.
//!
//! # Never in the way
//!
//! USB is the optional path: UART1 stays the primary link (the emulator harness reads it,
//! as does whatever serial link is wired to GP8) and the SLAM loop must not notice whether
//! a PC is there. So nothing
//! waits on USB except [`usb_telemetry_task`]:
//!
//! - [`offer`] never waits. With no host (not plugged in, not configured, bus suspended)
//!   it drops the frame and counts it in `HEALTH.usb_no_host`; with a host it copies the
//!   frame into [`USB_FRAMES`] or, if that is full, drops and counts it in
//!   `HEALTH.usb_dropped`. Both counters are in the once-a-second defmt line.
//! - A configured host that does not read (Linux and Windows only read while the port is
//!   open) leaves [`usb_telemetry_task`] waiting on the endpoint; the queue fills and
//!   further frames are dropped. When the host reads again the writer finishes the frame
//!   in hand and throws away the queued ones as stale (counted), so the viewer gets the
//!   live stream, not a backlog from minutes ago.
//!
//! # Frame boundaries
//!
//! Each new host session (a USB reset or configuration) starts with a lone `0x00`, so the
//! decoder starts clean; a frame cut off by a reset is abandoned, never finished into the
//! next session. A viewer that opens the port while the robot is mid-frame, or reopens it
//! after closing it mid-frame, gets the frame's tail first: the decoder counts that as one
//! bad frame and resynchronises at its `0x00`, as with joining the UART mid-stream.

use embassy_futures::select::{select, Either};
use embassy_rp::flash::{Blocking, Flash};
use embassy_rp::peripherals::{FLASH, USB};
use embassy_rp::usb::Driver;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::channel::Channel;
use embassy_sync::signal::Signal;
use embassy_time::{Duration, Instant};
use embassy_usb::class::cdc_acm::{CdcAcmClass, Sender, State};
use embassy_usb::{Builder, Config, Handler, UsbDevice};
use portable_atomic::{AtomicBool, AtomicU32, Ordering};
use static_cell::StaticCell;

use crate::board::UsbLinkPins;
use crate::health::HEALTH;
use crate::slam_task::TelemetryFrame;
use crate::Irqs;

/// The RP2040's USB device driver, as the tasks hold it.
pub type UsbDriver = Driver<'static, USB>;

/// Vendor ID: pid.codes, which gives product IDs to open-source hardware.
pub const USB_VID: u16 = 0x1209;

/// Product ID: pid.codes' test PID 0x0001, which they reserve for private testing and
/// never allocate. Fine on the bench; before BugBots leave the lab, ask pid.codes for a
/// PID of our own and put it here.
pub const USB_PID: u16 = 0x0001;

/// The manufacturer string descriptor.
pub const USB_MANUFACTURER: &str = "BugBot";

/// The product string descriptor (Linux names the port
/// `/dev/serial/by-id/usb-BugBot_BugBot_telemetry_<serial>-if00`).
pub const USB_PRODUCT: &str = "BugBot telemetry";

/// Largest bulk packet at full speed, in bytes: the most one `write_packet` may carry.
const MAX_PACKET_LEN: u16 = 64;

/// Frames queued for USB: one tick's worth (at most seven) with room to spare, as for the
/// UART. 10 frames of up to `MAX_FRAME_LEN` bytes: about 2 KB of RAM.
pub const USB_QUEUE: usize = 10;

/// A packet that waits longer than this for the host means it stopped reading; the frames
/// queued meanwhile are stale and are dropped once it reads again. Three ticks.
const STALE_AFTER: Duration = Duration::from_millis(300);

/// The flash chip's size, in bytes (the Pico's W25Q16, as in `memory.x`). Only the type of
/// the flash driver needs it: the unique ID read does not depend on it.
const FLASH_SIZE: usize = 2 * 1024 * 1024;

/// Frames from the telemetry task to [`usb_telemetry_task`]. A bounded `Channel`, in order;
/// [`offer`] only ever `try_send`s.
pub static USB_FRAMES: Channel<CriticalSectionRawMutex, TelemetryFrame, USB_QUEUE> = Channel::new();

/// Whether a host has the device configured and the bus is not suspended: only then are
/// frames queued.
static HOST_READY: AtomicBool = AtomicBool::new(false);

/// Bumped at every USB reset and deconfiguration: a frame begun in one session must not be
/// finished in the next.
static SESSION: AtomicU32 = AtomicU32::new(0);

/// Raised when [`SESSION`] changes, to wake a writer waiting on the endpoint.
static SESSION_ENDED: Signal<CriticalSectionRawMutex, ()> = Signal::new();

/// Hands `frame` to the USB writer without waiting: dropped and counted when no host is
/// there or the queue is full. Called by the telemetry task for every frame.
pub fn offer(frame: &TelemetryFrame) {
    if !HOST_READY.load(Ordering::Relaxed) {
        HEALTH.usb_no_host.bump();
    } else if USB_FRAMES.try_send(frame.clone()).is_err() {
        HEALTH.usb_dropped.bump();
    }
}

/// Builds the USB device: pid.codes VID/PID, "BugBot" / "BugBot telemetry", the flash
/// chip's unique ID as serial number, one CDC ACM function. Returns the device (for
/// [`usb_device_task`]) and the serial port's sending half (for [`usb_telemetry_task`]).
///
/// Call it once, before core 1 starts: reading the flash ID stops execute-in-place for a
/// few microseconds. A second call panics (the descriptor buffers are `StaticCell`s).
pub fn build(
    pins: UsbLinkPins,
    irqs: Irqs,
) -> (UsbDevice<'static, UsbDriver>, Sender<'static, UsbDriver>) {
    static SERIAL: StaticCell<[u8; 16]> = StaticCell::new();
    static CONFIG_DESCRIPTOR: StaticCell<[u8; 256]> = StaticCell::new();
    static BOS_DESCRIPTOR: StaticCell<[u8; 256]> = StaticCell::new();
    static CONTROL_BUF: StaticCell<[u8; 64]> = StaticCell::new();
    static CDC_STATE: StaticCell<State<'static>> = StaticCell::new();
    static HOST_WATCH: StaticCell<HostWatch> = StaticCell::new();

    let serial = serial_number(pins.flash, SERIAL.init([0; 16]));
    defmt::info!("usb: serial number {=str}", serial);

    let mut config = Config::new(USB_VID, USB_PID);
    config.manufacturer = Some(USB_MANUFACTURER);
    config.product = Some(USB_PRODUCT);
    config.serial_number = Some(serial);
    // 100 mA covers the Pico itself. If the board ever draws more from VBUS (motors,
    // sensors powered from USB), this must say so, up to 500.
    config.max_power = 100;
    // The defaults (class 0xEF/0x02/0x01 with an interface association descriptor) let
    // Windows load its CDC driver for the two-interface ACM function without an .inf.

    let driver = Driver::new(pins.usb, irqs);
    let mut builder = Builder::new(
        driver,
        config,
        CONFIG_DESCRIPTOR.init([0; 256]),
        BOS_DESCRIPTOR.init([0; 256]),
        &mut [], // no Microsoft OS descriptors
        CONTROL_BUF.init([0; 64]),
    );
    builder.handler(HOST_WATCH.init(HostWatch {
        configured: false,
        suspended: false,
    }));
    let class = CdcAcmClass::new(&mut builder, CDC_STATE.init(State::new()), MAX_PACKET_LEN);
    // The host's bytes (if a terminal sends any) are never read: the OUT endpoint NAKs
    // them, which does not hold up the IN direction.
    let (sender, _receiver) = class.split();
    (builder.build(), sender)
}

/// Answers the host for good: enumeration, configuration, the CDC control requests.
#[embassy_executor::task]
pub async fn usb_device_task(mut device: UsbDevice<'static, UsbDriver>) -> ! {
    device.run().await
}

/// Writes the queued frames to the serial port for good, a session at a time: wait for a
/// host to configure the device, drop whatever queued before, send a lone `0x00`, then
/// each frame in 64-byte packets until the session ends.
#[embassy_executor::task]
pub async fn usb_telemetry_task(mut sender: Sender<'static, UsbDriver>) -> ! {
    loop {
        sender.wait_connection().await;
        let session = SESSION.load(Ordering::Relaxed);
        defmt::info!("usb: host connected");
        drop_stale_frames();
        if write_packet(&mut sender, &[0], session).await.is_err() {
            continue;
        }
        loop {
            let frame = USB_FRAMES.receive().await;
            match write_frame(&mut sender, frame.as_bytes(), session).await {
                Ok(Sent::OnTime) => HEALTH.usb_frames_sent.bump(),
                Ok(Sent::Late) => {
                    HEALTH.usb_frames_sent.bump();
                    drop_stale_frames();
                }
                Err(SessionEnded) => {
                    HEALTH.usb_dropped.bump();
                    defmt::info!("usb: host gone");
                    break;
                }
            }
        }
    }
}

/// Follows the device's state for [`offer`] and [`usb_telemetry_task`]: runs inside
/// [`usb_device_task`], so it only stores and signals.
struct HostWatch {
    /// A host has set our configuration.
    configured: bool,
    /// The bus is suspended.
    suspended: bool,
}

impl HostWatch {
    /// Publishes whether frames are worth queueing.
    fn publish(&self) {
        HOST_READY.store(self.configured && !self.suspended, Ordering::Relaxed);
    }

    /// Marks the current session over.
    fn end_session(&mut self) {
        self.configured = false;
        self.publish();
        SESSION.fetch_add(1, Ordering::Relaxed);
        SESSION_ENDED.signal(());
    }
}

impl Handler for HostWatch {
    fn reset(&mut self) {
        self.suspended = false;
        self.end_session();
    }

    fn configured(&mut self, configured: bool) {
        if configured {
            self.configured = true;
            self.publish();
        } else {
            self.end_session();
        }
    }

    /// A suspended bus (the PC asleep, or the cable pulled: the RP2040 driver cannot see
    /// VBUS, so an unplug looks like a suspend) reads nothing: stop queueing, but keep the
    /// session, since a resume carries on with the configuration it had.
    fn suspended(&mut self, suspended: bool) {
        self.suspended = suspended;
        self.publish();
    }
}

/// How a frame went out.
enum Sent {
    /// Every packet was taken within [`STALE_AFTER`].
    OnTime,
    /// Some packet waited longer: the host had stopped reading for a while.
    Late,
}

/// The USB session ended (reset or deconfigured) before the write finished.
struct SessionEnded;

/// Writes one frame as full packets and a short one; a frame that ends on a packet
/// boundary gets a zero-length packet, or the host would hold it until the next frame.
async fn write_frame(
    sender: &mut Sender<'static, UsbDriver>,
    bytes: &[u8],
    session: u32,
) -> Result<Sent, SessionEnded> {
    let mut sent = Sent::OnTime;
    let packet_len = usize::from(MAX_PACKET_LEN);
    for packet in bytes.chunks(packet_len) {
        let started = Instant::now();
        write_packet(sender, packet, session).await?;
        if started.elapsed() > STALE_AFTER {
            sent = Sent::Late;
        }
    }
    if bytes.len().is_multiple_of(packet_len) {
        write_packet(sender, &[], session).await?;
    }
    Ok(sent)
}

/// Writes one packet, waiting as long as the host takes to read it, unless the session
/// ends first. The write is only ever abandoned before its bytes reach the endpoint buffer.
async fn write_packet(
    sender: &mut Sender<'static, UsbDriver>,
    packet: &[u8],
    session: u32,
) -> Result<(), SessionEnded> {
    loop {
        if SESSION.load(Ordering::Relaxed) != session {
            return Err(SessionEnded);
        }
        match select(sender.write_packet(packet), SESSION_ENDED.wait()).await {
            Either::First(Ok(())) => return Ok(()),
            // `Disabled`: the host deconfigured the device; `BufferOverflow` cannot happen
            // (packets are at most `MAX_PACKET_LEN`), but would not get better on retry.
            Either::First(Err(_)) => return Err(SessionEnded),
            // A signal left over from before this session is harmless: check and go on.
            Either::Second(()) => {}
        }
    }
}

/// Empties [`USB_FRAMES`], counting each frame as dropped.
fn drop_stale_frames() {
    while USB_FRAMES.try_receive().is_ok() {
        HEALTH.usb_dropped.bump();
    }
}

/// The flash chip's 64-bit unique ID in hex (16 characters, in `buf`): the RP2040 has no
/// ID of its own, and Pico boards use the flash's. All zeros if the read fails.
fn serial_number(
    flash: embassy_rp::Peri<'static, FLASH>,
    buf: &'static mut [u8; 16],
) -> &'static str {
    let mut uid = [0u8; 8];
    // The read first waits for streaming XIP to go idle. This firmware never starts a
    // stream, so on a chip the count is 0; a non-zero count would be waited on for ever.
    // (The rp2040js emulator has no XIP_CTRL block and reads it as all ones.)
    let streaming = embassy_rp::pac::XIP_CTRL.stream_ctr().read().0;
    if streaming != 0 {
        defmt::warn!(
            "usb: XIP stream count {=u32}, flash unique ID not read",
            streaming
        );
    } else if let Err(e) =
        Flash::<_, Blocking, FLASH_SIZE>::new_blocking(flash).blocking_unique_id(&mut uid)
    {
        defmt::warn!("usb: flash unique ID not read: {}", e);
        uid = [0; 8];
    }
    for (pair, byte) in buf.chunks_exact_mut(2).zip(uid) {
        if let [high, low] = pair {
            *high = hex_digit(byte >> 4);
            *low = hex_digit(byte & 0x0f);
        }
    }
    match core::str::from_utf8(buf) {
        Ok(serial) => serial,
        Err(_) => "0000000000000000",
    }
}

/// The upper-case hex digit for the low four bits of `nibble`.
const fn hex_digit(nibble: u8) -> u8 {
    match nibble & 0x0f {
        n @ 0..=9 => b'0' + n,
        n => b'A' + (n - 10),
    }
}
