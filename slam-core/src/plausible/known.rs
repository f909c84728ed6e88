//! What of each reading the odometry integrates: the reading, a stand-in for it, the
//! robot held still, or nothing.

use super::following::Following;
use super::Doubt;
use crate::commanded::RecentCommands;
use crate::frame::{DriveCommand, FlowDelta, GyroRate};

/// What the odometry knows of one input this tick.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Known<T> {
    /// A reading to integrate: the sensor's own, or the last trusted one on the tick a
    /// doubt began while the commands were steady (the robot moving as it was).
    Read(T),
    /// The last trusted reading on the tick a doubt began just after the commands
    /// changed: integrated, but a guess, so the filter takes it with the noise of a tick
    /// it knows nothing of.
    StandIn(T),
    /// The robot was held: it did not move this way.
    Still,
    /// Nothing is known: no reading, and the robot was not held.
    Lost,
}

impl<T: Copy> Known<T> {
    /// [`Known::Still`] in place of a reading when the robot is `stopped` (every command
    /// of the window standing): the motors cannot move it, so a trusted gyro or flow reads
    /// only its bias and noise. Integrated, the gyro's would drift the heading by the bias
    /// not yet learned, and the flow's would walk the position and, corrected by the
    /// tags, teach the filter that the flow reads motion that is not there.
    pub fn still_if(self, stopped: bool) -> Self {
        match self {
            Known::Read(_) if stopped => Known::Still,
            k => k,
        }
    }

    /// The reading to integrate, if any.
    pub fn reading(&self) -> Option<T> {
        match self {
            Known::Read(r) | Known::StandIn(r) => Some(*r),
            _ => None,
        }
    }

    /// Whether the tick's motion this way is known (read or held still).
    pub fn is_known(&self) -> bool {
        matches!(self, Known::Read(_) | Known::Still)
    }

    /// Which of the three it is, without the reading.
    pub fn kind(&self) -> Known<()> {
        match self {
            Known::Read(_) => Known::Read(()),
            Known::StandIn(_) => Known::StandIn(()),
            Known::Still => Known::Still,
            Known::Lost => Known::Lost,
        }
    }
}

/// A trusted reading taken while the robot was not held, with the command it was taken
/// under.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub(super) struct Moving<T> {
    reading: T,
    /// The commands' change count then ([`RecentCommands::changes`]).
    changes: u8,
    /// The newest command then, if known.
    command: Option<DriveCommand>,
}

/// The gyro's rate under `command`: its turn.
pub(super) fn commanded_gyro(command: &DriveCommand) -> GyroRate {
    GyroRate {
        rate_mdps: command.turn_mdps,
    }
}

/// The flow a tick of `command`'s drive reads: one count a tick per millimetre a second
/// (100 um counts at 10 Hz, as [`CommandTolerance`] takes them), nothing sideways.
///
/// [`CommandTolerance`]: crate::commanded::CommandTolerance
pub(super) fn commanded_flow(command: &DriveCommand) -> FlowDelta {
    FlowDelta {
        forward_counts: command.speed_mm_s,
        right_counts: 0,
    }
}

/// What to integrate of an input: its reading when trusted (or absent unheard: lost), only
/// as a guess when it strays from the newest command a frame after it changed (short of it,
/// the reading: the robot may have made the motion, a sensor behind, or not; past it, the
/// reading until [`Plausibility::stand_in_past`] puts in its place what [`Behind`] works
/// out), and no reference for a doubt to come on the frame it changed; when doubted, still
/// if the robot was held, else the reading of the last trusted tick on which it was not
/// held: a held motion resumes as it was when it stopped. That reading is as good as one
/// while the `commands` are steady and the same as when it was read; when they changed of
/// late (a turn ending, a drive beginning) it only stands in, and only if it was read under
/// the newest command: read under another (a turn's flow, for a drive resumed after a
/// hold), the newest command's own motion (`commanded`) stands in, since the motors follow
/// a command within a tick.
/// (The reading is the better guess where there is one: the command's counts leave out
/// the flow sensor's scale.)
/// Steady at a command that does not move the robot this way (`idle`: a turn on the spot
/// for the flow), the robot is still this way, whatever the reading was.
///
/// [`Plausibility::stand_in_past`]: super::Plausibility::stand_in_past
/// [`Behind`]: super::following::Behind
#[allow(clippy::too_many_arguments)]
#[inline(never)]
pub(super) fn known<T: Copy>(
    reading: Option<T>,
    doubt: Option<Doubt>,
    held: bool,
    following: Following,
    commands: &RecentCommands,
    idle: impl Fn(&DriveCommand) -> bool,
    commanded: impl Fn(&DriveCommand) -> T,
    moving: &mut Option<Moving<T>>,
) -> Known<T> {
    match (doubt, reading) {
        (None, Some(r)) if following == Following::Astray => Known::StandIn(r),
        (None, Some(r)) if following == Following::Changing => Known::Read(r),
        (None, Some(r)) => {
            if !held {
                // The command is taken once a change: tick after tick, only the reading.
                match moving {
                    Some(m) if m.changes == commands.changes() => m.reading = r,
                    _ => {
                        *moving = Some(Moving {
                            reading: r,
                            changes: commands.changes(),
                            command: commands.newest(),
                        })
                    }
                }
            }
            Known::Read(r)
        }
        (None, None) => Known::Lost,
        (Some(_), _) if held => Known::Still,
        (Some(_), _) => {
            let Some(then) = *moving else {
                return Known::Lost;
            };
            let now = commands.newest();
            if commands.steady() {
                if then.changes == commands.changes() {
                    return Known::Read(then.reading);
                }
                if now.is_some_and(|now| idle(&now)) {
                    return Known::Still;
                }
            }
            match now {
                Some(now) if then.command != Some(now) => Known::StandIn(commanded(&now)),
                _ => Known::StandIn(then.reading),
            }
        }
    }
}
