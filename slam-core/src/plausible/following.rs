//! The gyro's and the flow's readings against the newest command, while the commands
//! change: on the first frame after a change the motors may not have followed it.

use super::Trust;
use crate::commanded::{unfollowed_past, CommandTolerance, RecentCommands, Unfollowed};
use crate::frame::{DriveCommand, FlowDelta, GyroRate};

/// How a trusted reading stands to the newest command.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub(super) enum Following {
    /// Within what it allows: the robot's motion, and the one a doubt to come may stand
    /// in with.
    Follows,
    /// On the first frame after it changed: the motion, but no reference for the new
    /// command's.
    Changing,
    /// Outside what it allows a frame after it changed ([`unfollowed_past`]): a guess.
    /// Short of it, the reading (the robot may have made the motion, a sensor behind, or
    /// not: a wheel may slip); past it, what [`Behind`] works out.
    Astray,
}

/// What the trusted readings of the first frame after a command changed held past its
/// motion (the gyro's rate past its turn, the flow's forward counts past its drive), and
/// the change they were read after ([`RecentCommands::changes`]). The motors follow a
/// command within a tick, so a trusted reading still past it a frame later is a sensor
/// behind the robot: the newest command's motion stands in for it, less what the frame
/// before read past it.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default)]
pub(super) struct Behind {
    changes: u8,
    rate_mdps: i32,
    forward_counts: i32,
    /// Which of the gyro and the flow read past the newest command a frame after it
    /// changed, and the motion that stands in for them: the command's, less what the
    /// frame before read past it.
    pub(super) past: (bool, bool),
    pub(super) stand_in: DriveCommand,
}

/// How the gyro's and the flow's readings stand to the newest of `commands`, which are
/// not steady: on the first frame after a change the motors may not have followed it at
/// all (what a trusted reading holds past it is kept in `behind`); a frame later a reading
/// outside what it allows ([`unfollowed_past`]) strays, and one trusted and past it has its
/// stand-in worked out in `behind`. Commands not known check nothing, as in the checks.
/// Out of line and cold: only while the commands change.
#[cold]
#[inline(never)]
pub(super) fn following(
    (gyro, flow): (Option<GyroRate>, Option<FlowDelta>),
    trust: Trust,
    commands: &RecentCommands,
    tolerance: &CommandTolerance,
    behind: &mut Behind,
) -> (Unfollowed, Following, Following) {
    let follows = Following::Follows;
    behind.past = (false, false);
    let Some(newest) = commands.newest() else {
        return (Unfollowed::default(), follows, follows);
    };
    let (off, past) = unfollowed_past(gyro, flow, &newest, tolerance);
    // A reading past the command, trusted: it was (or is to be) integrated.
    let gyro_past = past.gyro && trust.gyro.is_none();
    let flow_past = past.flow && trust.flow.is_none();
    if !commands.taken() {
        let beyond = |is_past: bool, read: Option<i32>, motion: i32| {
            read.filter(|_| is_past)
                .map_or(0, |r| r.saturating_sub(motion))
        };
        behind.changes = commands.changes();
        behind.rate_mdps = beyond(gyro_past, gyro.map(|g| g.rate_mdps), newest.turn_mdps);
        behind.forward_counts =
            beyond(flow_past, flow.map(|f| f.forward_counts), newest.speed_mm_s);
        let changing = Following::Changing;
        return (Unfollowed::default(), changing, changing);
    }
    let (rate_back, forward_back) = if behind.changes == commands.changes() {
        (behind.rate_mdps, behind.forward_counts)
    } else {
        (0, 0)
    };
    behind.past = (gyro_past, flow_past);
    behind.stand_in = DriveCommand {
        speed_mm_s: newest.speed_mm_s.saturating_sub(forward_back),
        turn_mdps: newest.turn_mdps.saturating_sub(rate_back),
    };
    let of = |astray: bool| if astray { Following::Astray } else { follows };
    (off, of(off.gyro), of(off.flow))
}
