//! What the firmware does when it panics: says where in the defmt log, then stops in a
//! HardFault, which the watchdog turns into a reset on the robot and the emulator reports.
//!
//! Our own handler rather than panic-probe's `print-defmt`: that one formats the message
//! through `core::fmt`, which would be the only user of `core::fmt` in the image and costs
//! its flash. Here a message is printed only when it is a plain string (the panics in this
//! firmware's own code are `defmt::panic!`s, which print their message before panicking).

use core::panic::PanicInfo;

#[panic_handler]
fn panic(info: &PanicInfo) -> ! {
    cortex_m::interrupt::disable();
    let message = info.message().as_str().unwrap_or("(formatted message)");
    match info.location() {
        Some(at) => defmt::error!(
            "panicked at {=str}:{=u32}:{=u32}: {=str}",
            at.file(),
            at.line(),
            at.column(),
            message
        ),
        None => defmt::error!("panicked: {=str}", message),
    }
    cortex_m::asm::udf()
}
