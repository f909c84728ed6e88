//! Each reading's checks on its own: a verdict, or the doubt it raises.

use super::{Doubt, PlausibleConfig};
use crate::frame::{DepthScan, FlowDelta, GyroRate, BEAMS};

/// The gyro's checks: a rate no robot turns at, a jump no robot makes, one value stuck,
/// a turn while held.
#[inline(never)]
pub fn check_gyro(
    rate: GyroRate,
    before: Option<GyroRate>,
    repeats: u8,
    held: bool,
    config: &PlausibleConfig,
) -> Result<(), Doubt> {
    let rate = rate.rate_mdps;
    if rate.unsigned_abs() > config.max_turn_mdps {
        return Err(Doubt::Impossible);
    }
    if repeats.saturating_add(1) >= config.stuck_ticks {
        return Err(Doubt::Stuck);
    }
    if held && rate.unsigned_abs() > config.still_turn_mdps {
        return Err(Doubt::MovedWhileHeld);
    }
    match before {
        Some(b) if rate.abs_diff(b.rate_mdps) > config.max_turn_step_mdps => Err(Doubt::Jump),
        _ => Ok(()),
    }
}

/// The flow's checks: a drive faster than the robot's, a sideways slide, one delta
/// stuck, a drive while held.
#[inline(never)]
pub fn check_flow(
    flow: FlowDelta,
    repeats: u8,
    held: bool,
    config: &PlausibleConfig,
) -> Result<(), Doubt> {
    let (forward, side) = (
        flow.forward_counts.unsigned_abs(),
        flow.right_counts.unsigned_abs(),
    );
    if forward > config.max_flow_counts || side > config.max_side_flow_counts {
        return Err(Doubt::Impossible);
    }
    if repeats.saturating_add(1) >= config.stuck_ticks {
        return Err(Doubt::Stuck);
    }
    if held && forward.max(side) > config.still_flow_counts {
        return Err(Doubt::MovedWhileHeld);
    }
    Ok(())
}

/// The depth sensor's checks: a range beyond the sensor's, a frame repeated bit for bit
/// (at once when half its zones returned, where noise makes a repeat all but
/// impossible; after [`PlausibleConfig::stuck_ticks`] otherwise). A frame with no return
/// is never stuck: it writes nothing.
#[inline(never)]
pub fn check_depth(scan: &DepthScan, repeats: u8, config: &PlausibleConfig) -> Result<(), Doubt> {
    let returns = scan.ranges_mm.iter().flatten();
    if returns.clone().any(|r| *r > config.max_depth_mm) {
        return Err(Doubt::Impossible);
    }
    let stuck_after = match returns.count() {
        0 => return Ok(()),
        n if n >= BEAMS / 2 => 1,
        _ => config.stuck_ticks.saturating_sub(1),
    };
    if repeats >= stuck_after {
        return Err(Doubt::Stuck);
    }
    Ok(())
}
