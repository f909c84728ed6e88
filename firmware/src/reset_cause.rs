//! What reset the chip: read once at start-up, before the watchdog is started again.
//!
//! The watchdog's `REASON` register says whether the watchdog timed out or was triggered
//! on purpose; both bits are clear after any other reset. Then `VREG_AND_CHIP_RESET`'s
//! `CHIP_RESET.HAD_POR` tells a power-on (or brown-out) from the RUN pin or a debugger.

use embassy_rp::pac;
use embassy_rp::watchdog::{ResetReason, Watchdog};
use wire::telemetry::ResetCause;

/// Why the chip last started, from the watchdog's and the chip's reset registers.
pub fn read(watchdog: &Watchdog) -> ResetCause {
    match watchdog.reset_reason() {
        Some(ResetReason::TimedOut) => ResetCause::Watchdog,
        Some(ResetReason::Forced) => ResetCause::Other,
        None if pac::VREG_AND_CHIP_RESET.chip_reset().read().had_por() => ResetCause::PowerOn,
        None => ResetCause::Other,
    }
}
