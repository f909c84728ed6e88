//! The gyro and the flow against the motion the motors were asked for: a turn or a
//! drive they did not command.
//!
//! A gyro whose bias jumps reads a turn that is plausible on its own, and a flow sensor
//! whose scale changes (another floor, another height) a plausible speed. The motors say
//! what the robot can have done: its wheels may fall short of their command (slip, a
//! stall, a wall, spinning up) but not run much beyond it, and they follow a new command
//! within a tick. So over a frame's interval the robot turned at a rate between 0 and
//! the commands in force as that interval and the two before it ended
//! ([`RecentCommands`]), and the gyro reads that rate with its scale error, bias and
//! noise. A reading outside that range, widened by [`CommandTolerance`], is doubted
//! ([`Doubt::Uncommanded`]).
//!
//! The flow alike: over a tick the robot drove no faster than the fastest drive of those
//! commands, and a turn moves the flow sensor only as far as it sits beside the turning
//! axis ([`check_flow_commanded`]).
//!
//! What is caught is a reading of more turn or more drive than commanded, or of a turn
//! the other way. A gyro or a flow that reads less than commanded is not told from a
//! wheel that slips.

use crate::frame::{DriveCommand, FlowDelta, GyroRate};
use crate::plausible::Doubt;

/// How far the gyro may read beyond the commanded motion.
///
/// At the seed's turn on the spot (31.5 deg/s) the gyro may read up to 33.568 deg/s,
/// and up to 2.068 deg/s the other way; standing, 0.5 deg/s either way; driving at
/// 86 mm/s, 4.456 deg/s either way.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CommandTolerance {
    /// How much faster than the fastest commanded turn the gyro may read, in 1,024ths of
    /// it (a shift, where per mille would cost the M0+ a division each tick): the motors
    /// running beyond their command, and the gyro's scale error.
    pub turn_per_1024: u8,
    /// How fast a straight drive may turn, millidegrees per second per millimetre per
    /// second of its speed: two open-loop wheels each off their command the other way.
    pub drive_turn_mdps_per_mm_s: u8,
    /// Added in every case for the gyro's noise, its bias and the motors' rounding,
    /// millidegrees per second.
    pub margin_mdps: u16,
    /// A tick's forward flow counts per millimetre a second of the fastest commanded
    /// drive, in 1,024ths: the count's size and the tick's length, with what the motors
    /// may run beyond their command and the flow sensor's scale may read long.
    pub drive_flow_per_1024: u16,
    /// How far the flow sensor may sit beside the turning axis, millimetres: a turn
    /// moves it forwards by this much per radian.
    pub flow_offset_mm: u8,
    /// Added in every case for the flow's noise, counts.
    pub flow_margin_counts: u8,
}

impl CommandTolerance {
    /// BugBot: 51 / 1,024 (5 %), 4 % for the motors (speed is taken as proportional to duty,
    /// with full duty the robot's measured full speed on a charged battery, so a draining
    /// one only slows it) and 1 % for the gyro's scale (the simulator's 0.75 %); a drive
    /// turns at most what two wheels 4 % apart make on the 100 mm base (2 x 0.04 / 100 mm
    /// rad/s per mm/s: 46); 500 mdps for the gyro's noise over a tick (0.1 deg/s a 5 ms
    /// sample: 0.022 deg/s over 20), the bias left after the start-up calibration and its
    /// wander (0.02 deg/s, 0.002 deg/s per root second) and the firmware's duty rounding
    /// (half a per mille of duty, 0.17 deg/s). The flow counts 100 um at 10 Hz, one count
    /// a tick per mm/s, so 1,126 / 1,024 (110 %): 4 % for the motors and 6 % for a flow
    /// scale read long (the seed's reads 4 % short); 10 mm beside the axis (a 20 mm mount
    /// error on BugBot's chassis is a loose sensor; `seed-mat-rough` has 3 mm); 6 counts
    /// for the noise (0.5 counts a 100 Hz reading: 1.6 a tick, so nearly four deviations).
    pub const SEED: CommandTolerance = CommandTolerance {
        turn_per_1024: 51,
        drive_turn_mdps_per_mm_s: 46,
        margin_mdps: 500,
        drive_flow_per_1024: 1_126,
        flow_offset_mm: 10,
        flow_margin_counts: 6,
    };
}

impl Default for CommandTolerance {
    fn default() -> Self {
        CommandTolerance::SEED
    }
}

/// How many frames' commands bound a frame's motion: its own and the two before.
pub const COMMAND_FRAMES: usize = 3;

/// Commands beyond these are taken as these, so the slack fits 32 bits: a turn of
/// 1,048 deg/s and a drive of 65 m/s, far past any robot's (and any reading that gets
/// here: [`crate::plausible::check_gyro`] refuses rates beyond the robot's first).
const TURN_LIMIT_MDPS: i32 = 1 << 20;
const SPEED_LIMIT_MM_S: u32 = 1 << 16;

/// The commands in force as the last [`COMMAND_FRAMES`] frames' intervals ended, in a
/// ring: only their range matters, not their order. A command that changed during the
/// last interval is the newest or the one before; one that changed during the interval
/// before has had at least a tick to take.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default)]
pub struct RecentCommands {
    slots: [Option<DriveCommand>; COMMAND_FRAMES],
    /// The slot the next command overwrites: the oldest.
    next: u8,
    /// [`RecentCommands::bounds`] of the slots, worked out once a push for both checks.
    bounds: Option<(i32, i32, u32)>,
    /// How many times the command has changed, wrapping: a reading taken under the same
    /// count was taken under the same command.
    changes: u8,
}

impl RecentCommands {
    /// Takes a frame's command (`None`: not known), in place of the oldest.
    pub fn push(&mut self, command: Option<DriveCommand>) {
        if command != self.newest() {
            self.changes = self.changes.wrapping_add(1);
        }
        let at = usize::from(self.next);
        if let Some(slot) = self.slots.get_mut(at) {
            *slot = command;
        }
        self.next = if at + 1 < COMMAND_FRAMES {
            at as u8 + 1
        } else {
            0
        };
        self.bounds = self.bounds_of_slots();
    }

    /// Whether the last commands are all known and all the same: the robot moves now as
    /// it moved a few ticks ago.
    pub fn steady(&self) -> bool {
        let [first, rest @ ..] = &self.slots;
        first.is_some() && rest.iter().all(|c| c == first)
    }

    /// How many times the command has changed, wrapping: the same count, the same
    /// command since.
    pub fn changes(&self) -> u8 {
        self.changes
    }

    /// The newest command, if known.
    pub fn newest(&self) -> Option<DriveCommand> {
        // The slot before the next, without the division a `%` costs the M0+.
        let newest = match usize::from(self.next) {
            0 => COMMAND_FRAMES - 1,
            next => next - 1,
        };
        self.slots.get(newest).copied().flatten()
    }

    /// The fastest turn among the last commands, millidegrees per second either way;
    /// `None` unless all are known.
    pub fn fastest_turn_mdps(&self) -> Option<u32> {
        self.bounds
            .map(|(low, high, _)| high.max(-low).unsigned_abs())
    }

    /// Whether any of the last commands turned the robot; `None` unless all are known.
    pub fn turning(&self) -> Option<bool> {
        self.bounds.map(|(low, high, _)| low != 0 || high != 0)
    }

    /// The slowest and fastest turn the robot can have been commanded over the last
    /// interval, millidegrees per second (0 always among them: a wheel may stop), and the
    /// fastest drive, millimetres per second; `None` unless all the commands are known.
    fn bounds(&self) -> Option<(i32, i32, u32)> {
        self.bounds
    }

    fn bounds_of_slots(&self) -> Option<(i32, i32, u32)> {
        let (mut low, mut high, mut speed) = (0, 0, 0);
        for command in self.slots {
            let command = command?;
            low = command.turn_mdps.min(low);
            high = command.turn_mdps.max(high);
            speed = command.speed_mm_s.unsigned_abs().max(speed);
        }
        Some((
            low.max(-TURN_LIMIT_MDPS),
            high.min(TURN_LIMIT_MDPS),
            speed.min(SPEED_LIMIT_MM_S),
        ))
    }
}

/// Whether the gyro's `rate` over the last interval is one the robot can have turned at
/// under the `recent` commands, within `tolerance`. Nothing is checked while a command
/// is unknown.
///
/// In 32 bits: the commands' limits and the tolerance's byte-wide shares keep every sum
/// below 2^30.
#[inline(never)]
pub fn check_gyro_commanded(
    rate: GyroRate,
    recent: &RecentCommands,
    tolerance: &CommandTolerance,
) -> Result<(), Doubt> {
    let Some((low, high, speed_mm_s)) = recent.bounds() else {
        return Ok(());
    };
    let fastest = high.max(-low);
    let slack = ((fastest * i32::from(tolerance.turn_per_1024)) >> 10)
        + speed_mm_s as i32 * i32::from(tolerance.drive_turn_mdps_per_mm_s)
        + i32::from(tolerance.margin_mdps);
    let rate = rate.rate_mdps;
    if rate > high + slack || rate < low - slack {
        Err(Doubt::Uncommanded)
    } else {
        Ok(())
    }
}

/// Whether the flow's forward counts over the last interval are a drive the robot can
/// have made under the `recent` commands, within `tolerance`: no faster than the fastest
/// commanded drive, plus what the fastest commanded turn moves a sensor beside the axis.
/// Nothing is checked while a command is unknown.
///
/// In 32 bits: the commands' limits keep the drive's product below 2^32 and the turn's
/// below 2^30; the sum saturates.
#[inline(never)]
pub fn check_flow_commanded(
    flow: FlowDelta,
    recent: &RecentCommands,
    tolerance: &CommandTolerance,
) -> Result<(), Doubt> {
    let Some((low, high, speed_mm_s)) = recent.bounds() else {
        return Ok(());
    };
    let fastest_turn = high.max(-low).unsigned_abs();
    // mdps x mm x 146 / 2^23 (1.74e-5): pi / 180 / 1000 rad/s per mdps, over a 0.1 s
    // tick, in 100 um counts.
    let turned = ((fastest_turn >> 6) * u32::from(tolerance.flow_offset_mm) * 146) >> 17;
    let bound = ((speed_mm_s * u32::from(tolerance.drive_flow_per_1024)) >> 10)
        .saturating_add(turned)
        .saturating_add(u32::from(tolerance.flow_margin_counts));
    if flow.forward_counts.unsigned_abs() > bound {
        Err(Doubt::Uncommanded)
    } else {
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const T: CommandTolerance = CommandTolerance::SEED;

    fn rate(mdps: i32) -> GyroRate {
        GyroRate { rate_mdps: mdps }
    }

    fn turn(mdps: i32) -> Option<DriveCommand> {
        Some(DriveCommand {
            speed_mm_s: 0,
            turn_mdps: mdps,
        })
    }

    fn drive(mm_s: i32) -> Option<DriveCommand> {
        Some(DriveCommand {
            speed_mm_s: mm_s,
            turn_mdps: 0,
        })
    }

    /// The window after `commands`, oldest first.
    fn after(commands: &[Option<DriveCommand>]) -> RecentCommands {
        let mut recent = RecentCommands::default();
        for c in commands {
            recent.push(*c);
        }
        recent
    }

    fn verdict(mdps: i32, commands: &[Option<DriveCommand>]) -> Result<(), Doubt> {
        check_gyro_commanded(rate(mdps), &after(commands), &T)
    }

    #[test]
    fn a_turn_faster_than_commanded_by_more_than_the_tolerance_is_doubted() {
        let turning = [turn(31_500); 3];
        // 31,500 + 1,568 + 500.
        assert_eq!(verdict(33_568, &turning), Ok(()));
        assert_eq!(verdict(33_569, &turning), Err(Doubt::Uncommanded));
        // The seed's gyro, 0.75 % fast with its 0.02 deg/s bias, then a 3 deg/s jump.
        assert_eq!(verdict(31_756, &turning), Ok(()));
        assert_eq!(verdict(34_756, &turning), Err(Doubt::Uncommanded));
        // Anticlockwise alike.
        let anticlockwise = [turn(-31_500); 3];
        assert_eq!(verdict(-33_568, &anticlockwise), Ok(()));
        assert_eq!(verdict(-33_569, &anticlockwise), Err(Doubt::Uncommanded));
        assert_eq!(verdict(-34_756, &anticlockwise), Err(Doubt::Uncommanded));
    }

    #[test]
    fn a_slower_turn_is_slip_and_one_the_other_way_is_doubted() {
        let turning = [turn(31_500); 3];
        // A spell of 30 % lost speed, or a stalled robot.
        assert_eq!(verdict(22_050, &turning), Ok(()));
        assert_eq!(verdict(0, &turning), Ok(()));
        // 1,568 + 500 the other way is noise and scale; beyond, a turn nobody asked for.
        assert_eq!(verdict(-2_068, &turning), Ok(()));
        assert_eq!(verdict(-2_069, &turning), Err(Doubt::Uncommanded));
    }

    #[test]
    fn standing_or_driving_straight_allows_what_the_wheels_and_gyro_explain() {
        let standing = [drive(0); 3];
        assert_eq!(verdict(500, &standing), Ok(()));
        assert_eq!(verdict(-501, &standing), Err(Doubt::Uncommanded));
        assert_eq!(verdict(3_000, &standing), Err(Doubt::Uncommanded));
        // 86 x 46 + 500, either way; backwards alike.
        let driving = [drive(86); 3];
        assert_eq!(verdict(4_456, &driving), Ok(()));
        assert_eq!(verdict(-4_457, &driving), Err(Doubt::Uncommanded));
        assert_eq!(verdict(4_456, &[drive(-86); 3]), Ok(()));
    }

    #[test]
    fn a_command_changed_within_the_window_bounds_the_turn_both_ways() {
        // A turn starting or ending in the last interval or the one before: the robot may
        // turn anywhere between standing and the turn, with a tick to follow.
        for window in [
            [drive(0), drive(0), turn(31_500)],
            [drive(0), turn(31_500), drive(0)],
            [turn(31_500), drive(0), drive(0)],
            [turn(-31_500), drive(0), turn(31_500)],
        ] {
            assert_eq!(verdict(31_500, &window), Ok(()), "{window:?}");
            assert_eq!(verdict(15_000, &window), Ok(()), "{window:?}");
            assert_eq!(verdict(34_756, &window), Err(Doubt::Uncommanded));
        }
        // Three frames after the turn ended, it is out of the window.
        let ended = [turn(31_500), drive(0), drive(0), drive(0)];
        assert_eq!(verdict(15_000, &ended), Err(Doubt::Uncommanded));
    }

    #[test]
    fn nothing_is_checked_until_the_commands_are_known() {
        assert_eq!(verdict(300_000, &[]), Ok(()));
        assert_eq!(verdict(300_000, &[drive(0), drive(0)]), Ok(()));
        assert_eq!(verdict(300_000, &[drive(0), None, drive(0)]), Ok(()));
        assert_eq!(
            verdict(300_000, &[drive(0), None, drive(0), drive(0), drive(0)]),
            Err(Doubt::Uncommanded)
        );
    }

    fn forward(counts: i32, commands: &[Option<DriveCommand>]) -> Result<(), Doubt> {
        let flow = FlowDelta {
            forward_counts: counts,
            right_counts: 0,
        };
        check_flow_commanded(flow, &after(commands), &T)
    }

    #[test]
    fn a_drive_faster_than_commanded_by_more_than_the_tolerance_is_doubted() {
        let driving = [drive(86); 3];
        // 86 x 1,126 / 1,024 = 94, and 6 for the noise.
        assert_eq!(forward(100, &driving), Ok(()));
        assert_eq!(forward(101, &driving), Err(Doubt::Uncommanded));
        // The seed's flow, 4 % short: 83 counts; scaled by 1.3 (another floor): 107.
        assert_eq!(forward(83, &driving), Ok(()));
        assert_eq!(forward(107, &driving), Err(Doubt::Uncommanded));
        // Slower is slip; backwards alike.
        assert_eq!(forward(0, &driving), Ok(()));
        assert_eq!(forward(-100, &[drive(-86); 3]), Ok(()));
        assert_eq!(forward(-101, &[drive(-86); 3]), Err(Doubt::Uncommanded));
    }

    #[test]
    fn standing_or_turning_on_the_spot_allows_what_the_mount_explains() {
        let standing = [drive(0); 3];
        assert_eq!(forward(6, &standing), Ok(()));
        assert_eq!(forward(7, &standing), Err(Doubt::Uncommanded));
        // At 31.5 deg/s, 10 mm beside the axis moves 5.5 mm/s: 5 counts a tick.
        let turning = [turn(31_500); 3];
        assert_eq!(forward(-11, &turning), Ok(()));
        assert_eq!(forward(12, &turning), Err(Doubt::Uncommanded));
        // A drive ending within the window still bounds the flow.
        assert_eq!(forward(100, &[drive(86), drive(0), drive(0)]), Ok(()));
        assert_eq!(
            forward(100, &[drive(86), drive(0), drive(0), drive(0)]),
            Err(Doubt::Uncommanded)
        );
        assert_eq!(forward(i32::MAX, &[]), Ok(()));
    }

    #[test]
    fn commands_beyond_any_robot_are_taken_at_the_limits_without_overflow() {
        let wild = [Some(DriveCommand {
            speed_mm_s: i32::MIN,
            turn_mdps: i32::MIN,
        }); 3];
        // Down to 1,048 deg/s anticlockwise and 65 m/s: 3,067,380 mdps of slack.
        assert_eq!(verdict(-(1 << 20) - 3_067_380, &wild), Ok(()));
        assert_eq!(
            verdict(-(1 << 20) - 3_067_381, &wild),
            Err(Doubt::Uncommanded)
        );
        assert_eq!(verdict(3_067_380, &wild), Ok(()));
        assert_eq!(verdict(3_067_381, &wild), Err(Doubt::Uncommanded));
        assert_eq!(verdict(i32::MIN, &wild), Err(Doubt::Uncommanded));
        assert_eq!(verdict(i32::MAX, &wild), Err(Doubt::Uncommanded));
        assert_eq!(
            verdict(i32::MAX, &[turn(i32::MAX); 3]),
            Err(Doubt::Uncommanded)
        );
        assert_eq!(verdict(1 << 20, &[turn(i32::MAX); 3]), Ok(()));
        // The flow: 65,536 mm/s x 1,126 / 1,024 + 1,048 deg/s 10 mm off the axis + 6.
        assert_eq!(forward(72_064 + 182 + 6, &wild), Ok(()));
        assert_eq!(forward(72_064 + 182 + 7, &wild), Err(Doubt::Uncommanded));
        assert_eq!(forward(i32::MIN, &wild), Err(Doubt::Uncommanded));
        assert_eq!(
            verdict(i32::MIN, &[turn(i32::MAX); 3]),
            Err(Doubt::Uncommanded)
        );
    }
}
