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
//! the other way; and one of far less than every command of the window asked for
//! ([`Doubt::Unmoved`], [`CommandTolerance::least_per_1024`]): a wheel that slips loses a
//! share of its motion, a sensor fallen behind (or a robot stalled) all of it. The window
//! leaves a new command a tick or two to take, so such a sensor is found out only on the
//! window's last tick: the core then stands in the commanded motion for the whole window
//! ([`crate::plausible`]). Before that, and while a command just ended still bounds the
//! window, a reading outside what the newest command alone allows ([`unfollowed`]) a
//! frame after it changed ([`RecentCommands::taken`]: on the first the motors may not
//! have followed it at all) is taken as a guess, and no scan is vouched for on its tick.
//! A guess of what: short of the command, the reading (a wheel may slip); past it, the
//! command's own motion less what the frame before read past it ([`unfollowed_past`]):
//! with the motors following within a tick, only a sensor behind the robot reads a motion
//! ended a tick ago, and it read the same on the frame before.

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
    /// The share of the least motion every one of the last commands asked for
    /// ([`RecentCommands::least`]) that the gyro and the flow must read, in 1,024ths,
    /// less their margins: a reading short of it is a sensor fallen behind, or a robot
    /// stalled, not a wheel that slips.
    pub least_per_1024: u16,
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
    /// Half the least commanded motion must be read (less the same margins): a spell of
    /// slip loses a third of it (`seed-mat-rough`), the flow reads 4 % short and the
    /// gyro's scale 1 %; a sensor fallen behind reads none.
    pub const SEED: CommandTolerance = CommandTolerance {
        turn_per_1024: 51,
        drive_turn_mdps_per_mm_s: 46,
        margin_mdps: 500,
        drive_flow_per_1024: 1_126,
        flow_offset_mm: 10,
        flow_margin_counts: 6,
        least_per_1024: 512,
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

/// The motion some commands allow over a frame's interval: a turn between `low` and
/// `high` (0 always among them: a wheel may stop) and a drive no faster than `speed`
/// either way; and at least `least_turn` and `least_speed` (signed, 0: nothing), what
/// every one of them asked for the same way. Within the commands' limits.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
struct Reach {
    low: i32,
    high: i32,
    speed: u32,
    least_turn: i32,
    least_speed: i32,
}

impl Reach {
    /// What `command` alone allows: what it asks, and less by slip.
    fn of(command: &DriveCommand) -> Reach {
        let (turn, speed) = (command.turn_mdps, command.speed_mm_s);
        Reach::between(turn, turn, speed, speed)
    }

    /// What each of `commands` allows, together: `None` if one is not known.
    fn of_all(commands: &[Option<DriveCommand>; COMMAND_FRAMES]) -> Option<Reach> {
        let (mut turn_low, mut turn_high) = (i32::MAX, i32::MIN);
        let (mut speed_low, mut speed_high) = (i32::MAX, i32::MIN);
        for command in commands {
            let command = command.as_ref()?;
            turn_low = turn_low.min(command.turn_mdps);
            turn_high = turn_high.max(command.turn_mdps);
            speed_low = speed_low.min(command.speed_mm_s);
            speed_high = speed_high.max(command.speed_mm_s);
        }
        Some(Reach::between(turn_low, turn_high, speed_low, speed_high))
    }

    /// Commands whose turns lie between `turn_low` and `turn_high` and whose drives
    /// between `speed_low` and `speed_high`.
    fn between(turn_low: i32, turn_high: i32, speed_low: i32, speed_high: i32) -> Reach {
        let turn = |t: i32| t.clamp(-TURN_LIMIT_MDPS, TURN_LIMIT_MDPS);
        let speed = |v: i32| v.clamp(-(SPEED_LIMIT_MM_S as i32), SPEED_LIMIT_MM_S as i32);
        // All the same way: the one nearest standing; else nothing.
        let least = |low: i32, high: i32| {
            if low > 0 {
                low
            } else if high < 0 {
                high
            } else {
                0
            }
        };
        Reach {
            low: turn(turn_low.min(0)),
            high: turn(turn_high.max(0)),
            speed: speed(speed_low)
                .unsigned_abs()
                .max(speed(speed_high).unsigned_abs()),
            least_turn: turn(least(turn_low, turn_high)),
            least_speed: speed(least(speed_low, speed_high)),
        }
    }
}

/// What the gyro and the flow may read under a [`Reach`], with a [`CommandTolerance`]'s
/// margins: worked out when the commands change, so that a tick's checks are compares.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
struct Limits {
    /// The gyro's rate lies between these, millidegrees per second.
    rate_low: i32,
    rate_high: i32,
    /// And reads at least this much of the turn every command asked for, along `turn_way`
    /// (1 clockwise, -1 anticlockwise, 0: none asked).
    rate_least: i32,
    turn_way: i8,
    /// The flow's forward counts are at most this many either way...
    flow_bound: u32,
    /// ... and at least this many along `drive_way` (1 forwards, -1 backwards, 0: none
    /// asked).
    flow_least: i32,
    drive_way: i8,
}

impl Limits {
    /// In 32 bits: the commands' limits and the tolerance's byte-wide shares keep every
    /// turn's sum below 2^30; the drive's products stay below 2^32, its sum saturates.
    fn of(reach: &Reach, tolerance: &CommandTolerance) -> Limits {
        let fastest = reach.high.max(-reach.low);
        let slack = ((fastest * i32::from(tolerance.turn_per_1024)) >> 10)
            + reach.speed as i32 * i32::from(tolerance.drive_turn_mdps_per_mm_s)
            + i32::from(tolerance.margin_mdps);
        let fastest_turn = fastest.unsigned_abs();
        // mdps x mm x 146 / 2^23 (1.74e-5): pi / 180 / 1000 rad/s per mdps, over a 0.1 s
        // tick, in 100 um counts.
        let turned = ((fastest_turn >> 6) * u32::from(tolerance.flow_offset_mm) * 146) >> 17;
        let flow_bound = ((reach.speed * u32::from(tolerance.drive_flow_per_1024)) >> 10)
            .saturating_add(turned)
            .saturating_add(u32::from(tolerance.flow_margin_counts));
        // A share of the least motion, less the margin; a count a tick per mm/s.
        let share = i32::from(tolerance.least_per_1024.min(1024));
        let least = |motion: i32, margin: u16| ((motion.abs() * share) >> 10) - i32::from(margin);
        Limits {
            rate_low: reach.low - slack,
            rate_high: reach.high + slack,
            rate_least: least(reach.least_turn, tolerance.margin_mdps),
            turn_way: reach.least_turn.signum() as i8,
            flow_bound,
            flow_least: least(reach.least_speed, u16::from(tolerance.flow_margin_counts)),
            drive_way: reach.least_speed.signum() as i8,
        }
    }

    /// The gyro's check.
    fn turn(&self, rate: i32) -> Result<(), Doubt> {
        if rate > self.rate_high || rate < self.rate_low {
            return Err(Doubt::Uncommanded);
        }
        short_of(rate, self.turn_way, self.rate_least)
    }

    /// The flow's check.
    fn drive(&self, forward: i32) -> Result<(), Doubt> {
        if forward.unsigned_abs() > self.flow_bound {
            return Err(Doubt::Uncommanded);
        }
        short_of(forward, self.drive_way, self.flow_least)
    }
}

/// Whether `read`, along `way` (1, -1; 0: nothing asked), is less than `least`:
/// [`Doubt::Unmoved`].
fn short_of(read: i32, way: i8, least: i32) -> Result<(), Doubt> {
    let along = match way {
        0 => return Ok(()),
        1 => read,
        _ => read.saturating_neg(),
    };
    if along < least {
        Err(Doubt::Unmoved)
    } else {
        Ok(())
    }
}

/// The commands in force as the last [`COMMAND_FRAMES`] frames' intervals ended, in a
/// ring: only their range matters, not their order. A command that changed during the
/// last interval is the newest or the one before; one that changed during the interval
/// before has had at least a tick to take.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default)]
pub struct RecentCommands {
    slots: [Option<DriveCommand>; COMMAND_FRAMES],
    /// The slot the next command overwrites: the oldest.
    next: u8,
    /// What the slots allow together, and what the gyro and the flow may read then,
    /// worked out when a push changes the slots.
    reach: Option<(Reach, Limits)>,
    /// How many times the command has changed, wrapping: a reading taken under the same
    /// count was taken under the same command.
    changes: u8,
    /// [`RecentCommands::steady`], worked out once a push.
    steady: bool,
    /// [`RecentCommands::taken`], worked out once a push.
    taken: bool,
    /// [`RecentCommands::stopped`], worked out once a push.
    stopped: bool,
    /// [`RecentCommands::newest`], kept at each push.
    newest: Option<DriveCommand>,
}

impl RecentCommands {
    /// Takes a frame's command (`None`: not known), in place of the oldest; the readings
    /// are then held to the commands within `tolerance`.
    pub fn push(&mut self, command: Option<DriveCommand>, tolerance: &CommandTolerance) {
        let before = self.newest();
        // Steady and the same again: every slot already holds it.
        if self.steady && command == before {
            return;
        }
        self.taken = command.is_some() && command == before;
        if command != before {
            self.changes = self.changes.wrapping_add(1);
        }
        let at = usize::from(self.next);
        if let Some(slot) = self.slots.get_mut(at) {
            *slot = command;
        }
        self.newest = command;
        self.next = if at + 1 < COMMAND_FRAMES {
            at as u8 + 1
        } else {
            0
        };
        self.reach = Reach::of_all(&self.slots).map(|r| (r, Limits::of(&r, tolerance)));
        let [first, rest @ ..] = &self.slots;
        self.steady = first.is_some() && rest.iter().all(|c| c == first);
        self.stopped = self.steady && *first == Some(DriveCommand::default());
    }

    /// Whether the last commands are all known and all the same: the robot moves now as
    /// it moved a few ticks ago.
    pub fn steady(&self) -> bool {
        self.steady
    }

    /// Whether the last commands all stood the robot still (steady at no drive and no
    /// turn): the motors cannot have moved it.
    pub fn stopped(&self) -> bool {
        self.stopped
    }

    /// Whether the newest command was in force as the frame before ended too: it has had
    /// a whole interval to take. On the first frame after a change the motors may have
    /// followed the new command for all of the interval, part of it or none (the
    /// firmware's motion task changes it as the tick ends).
    pub fn taken(&self) -> bool {
        self.taken
    }

    /// How many times the command has changed, wrapping: the same count, the same
    /// command since.
    pub fn changes(&self) -> u8 {
        self.changes
    }

    /// The newest command, if known.
    pub fn newest(&self) -> Option<DriveCommand> {
        self.newest
    }

    /// The fastest turn among the last commands, millidegrees per second either way;
    /// `None` unless all are known.
    pub fn fastest_turn_mdps(&self) -> Option<u32> {
        self.reach.map(|(r, _)| r.high.max(-r.low).unsigned_abs())
    }

    /// How far a guess of the robot's turn rate, `guess_mdps`, can be from its true rate
    /// under the last commands (which lies between the slowest and the fastest they allow,
    /// within the tolerance they were pushed with), millidegrees per second; `None` unless
    /// all are known.
    pub fn turn_guess_bound_mdps(&self, guess_mdps: i32) -> Option<u32> {
        self.reach.map(|(_, l)| {
            let g = i64::from(guess_mdps);
            let below = (g - i64::from(l.rate_low)).unsigned_abs();
            let above = (i64::from(l.rate_high) - g).unsigned_abs();
            below.max(above).min(u64::from(u32::MAX)) as u32
        })
    }

    /// Whether any of the last commands turned the robot; `None` unless all are known.
    pub fn turning(&self) -> Option<bool> {
        self.reach.map(|(r, _)| r.low != 0 || r.high != 0)
    }

    /// The slowest turn (millidegrees per second) and the slowest drive (millimetres per
    /// second) that every one of the last commands asked for the same way, signed; 0
    /// where one did not (a command unknown, stopping, or the other way): the least
    /// motion the robot must have made, but for slip, over the window.
    pub fn least(&self) -> (i32, i32) {
        self.reach
            .map_or((0, 0), |(r, _)| (r.least_turn, r.least_speed))
    }
}

/// Whether the gyro's `rate` over the last interval is one the robot can have turned at
/// under the `recent` commands, within the tolerance they were pushed with: no faster than
/// the fastest commanded turn either way ([`Doubt::Uncommanded`]), and at least a share
/// of the slowest turn every command asked for ([`Doubt::Unmoved`]). Nothing is checked
/// while a command is unknown.
#[inline(never)]
pub fn check_gyro_commanded(rate: GyroRate, recent: &RecentCommands) -> Result<(), Doubt> {
    match &recent.reach {
        Some((_, limits)) => limits.turn(rate.rate_mdps),
        None => Ok(()),
    }
}

/// Whether the flow's forward counts over the last interval are a drive the robot can
/// have made under the `recent` commands, within the tolerance they were pushed with: no
/// faster than the fastest commanded drive, plus what the fastest commanded turn moves a
/// sensor beside the axis ([`Doubt::Uncommanded`]), and at least a share of the slowest
/// drive every command asked for ([`Doubt::Unmoved`]). Nothing is checked while a command
/// is unknown.
#[inline(never)]
pub fn check_flow_commanded(flow: FlowDelta, recent: &RecentCommands) -> Result<(), Doubt> {
    match &recent.reach {
        Some((_, limits)) => limits.drive(flow.forward_counts),
        None => Ok(()),
    }
}

/// Which readings do not follow the newest command alone ([`unfollowed`]).
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default)]
pub struct Unfollowed {
    /// The gyro's rate.
    pub gyro: bool,
    /// The flow's forward counts.
    pub flow: bool,
}

impl Unfollowed {
    /// Whether either does not: the pose may be behind the robot, or ahead of it.
    pub fn any(&self) -> bool {
        self.gyro || self.flow
    }
}

/// Which of the gyro's `rate` and the flow's `flow` are outside what `command` alone
/// allows ([`check_gyro_commanded`] and [`check_flow_commanded`] on the newest command
/// rather than on the window's): a frame after the command changed, the motion of one
/// just ended, or a sensor fallen behind that the window cannot yet tell from it. A
/// reading missing is outside nothing.
pub fn unfollowed(
    rate: Option<GyroRate>,
    flow: Option<FlowDelta>,
    command: &DriveCommand,
    tolerance: &CommandTolerance,
) -> Unfollowed {
    unfollowed_past(rate, flow, command, tolerance).0
}

/// [`unfollowed`], and which of those read past `command` ([`Doubt::Uncommanded`]: more
/// motion than it allows, or motion the other way) rather than short of it
/// ([`Doubt::Unmoved`]).
pub fn unfollowed_past(
    rate: Option<GyroRate>,
    flow: Option<FlowDelta>,
    command: &DriveCommand,
    tolerance: &CommandTolerance,
) -> (Unfollowed, Unfollowed) {
    let limits = Limits::of(&Reach::of(command), tolerance);
    let gyro = rate.map_or(Ok(()), |r| limits.turn(r.rate_mdps));
    let flow = flow.map_or(Ok(()), |f| limits.drive(f.forward_counts));
    let past = Err(Doubt::Uncommanded);
    (
        Unfollowed {
            gyro: gyro.is_err(),
            flow: flow.is_err(),
        },
        Unfollowed {
            gyro: gyro == past,
            flow: flow == past,
        },
    )
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
            recent.push(*c, &T);
        }
        recent
    }

    fn verdict(mdps: i32, commands: &[Option<DriveCommand>]) -> Result<(), Doubt> {
        check_gyro_commanded(rate(mdps), &after(commands))
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
        // A spell of 30 % lost speed.
        assert_eq!(verdict(22_050, &turning), Ok(()));
        // 1,568 + 500 the other way is noise and scale; beyond, a turn nobody asked for.
        let starting = [drive(0), drive(0), turn(31_500)];
        assert_eq!(verdict(-2_068, &starting), Ok(()));
        assert_eq!(verdict(-2_069, &starting), Err(Doubt::Uncommanded));
    }

    #[test]
    fn far_short_of_every_command_in_the_window_is_unmoved() {
        // Half of 31.5 deg/s less 0.5: a gyro fallen behind, or a robot stalled.
        let turning = [turn(31_500); 3];
        assert_eq!(verdict(15_250, &turning), Ok(()));
        assert_eq!(verdict(15_249, &turning), Err(Doubt::Unmoved));
        assert_eq!(verdict(0, &turning), Err(Doubt::Unmoved));
        assert_eq!(verdict(-2_068, &turning), Err(Doubt::Unmoved));
        assert_eq!(verdict(-15_250, &[turn(-31_500); 3]), Ok(()));
        assert_eq!(verdict(-15_249, &[turn(-31_500); 3]), Err(Doubt::Unmoved));
        // The slowest of the window's turns the same way is what must be read.
        let slowing = [turn(31_500), turn(20_000), turn(31_500)];
        assert_eq!(verdict(9_500, &slowing), Ok(()));
        assert_eq!(verdict(9_499, &slowing), Err(Doubt::Unmoved));
        // A turn just begun or ended within the window may not have been made yet.
        for window in [
            [drive(0), turn(31_500), turn(31_500)],
            [turn(31_500), turn(31_500), drive(0)],
            [turn(-31_500), turn(31_500), turn(31_500)],
        ] {
            assert_eq!(verdict(0, &window), Ok(()), "{window:?}");
        }
        // The flow: half of 86 counts less 6.
        let driving = [drive(86); 3];
        assert_eq!(forward(37, &driving), Ok(()));
        assert_eq!(forward(36, &driving), Err(Doubt::Unmoved));
        assert_eq!(forward(-37, &[drive(-86); 3]), Ok(()));
        assert_eq!(forward(37, &[drive(-86); 3]), Err(Doubt::Unmoved));
        assert_eq!(forward(0, &[drive(0), drive(86), drive(86)]), Ok(()));
    }

    #[test]
    fn the_newest_command_alone_says_which_readings_do_not_follow_it() {
        let command = |speed_mm_s, turn_mdps| DriveCommand {
            speed_mm_s,
            turn_mdps,
        };
        let rate = |mdps| Some(GyroRate { rate_mdps: mdps });
        let flow = |counts| {
            Some(FlowDelta {
                forward_counts: counts,
                right_counts: 0,
            })
        };
        let (turning, driving) = (command(0, 31_500), command(86, 0));
        let (both, standing) = (command(86, 31_500), command(0, 0));
        // (rate, flow, command, gyro astray, flow astray)
        let cases = [
            (rate(15_250), flow(0), turning, false, false),
            (rate(15_249), flow(0), turning, true, false),
            // A drive just ended: its counts are more than a turn on the spot allows.
            (rate(31_500), flow(86), turning, false, true),
            (rate(0), flow(37), driving, false, false),
            (rate(0), flow(36), driving, false, true),
            // A turn just ended: its rate is more than a straight drive allows.
            (rate(31_500), flow(86), driving, true, false),
            (rate(0), flow(0), both, true, true),
            // A reading missing is outside nothing; standing allows only standing.
            (None, None, both, false, false),
            (rate(0), flow(0), standing, false, false),
            (rate(0), flow(86), standing, false, true),
        ];
        for (r, f, c, gyro_astray, flow_astray) in cases {
            let off = Unfollowed {
                gyro: gyro_astray,
                flow: flow_astray,
            };
            assert_eq!(unfollowed(r, f, &c, &T), off, "{r:?} {f:?} {c:?}");
        }
    }

    #[test]
    fn the_least_motion_is_what_every_command_of_the_window_asks_the_same_way() {
        let least = |commands: &[Option<DriveCommand>]| after(commands).least();
        assert_eq!(least(&[turn(31_500); 3]), (31_500, 0));
        assert_eq!(least(&[drive(-86); 3]), (0, -86));
        assert_eq!(least(&[drive(86), drive(40), drive(86)]), (0, 40));
        assert_eq!(least(&[drive(86), drive(-40), drive(86)]), (0, 0));
        assert_eq!(least(&[drive(86), drive(0), drive(86)]), (0, 0));
        assert_eq!(least(&[drive(86), None, drive(86)]), (0, 0));
        assert_eq!(least(&[drive(86), drive(86)]), (0, 0));
    }

    #[test]
    fn a_command_is_taken_once_it_was_in_force_as_two_frames_ended() {
        assert!(!after(&[drive(86)]).taken());
        assert!(!after(&[drive(0), drive(86)]).taken());
        assert!(after(&[drive(0), drive(86), drive(86)]).taken());
        assert!(after(&[drive(86); 5]).taken());
        assert!(!after(&[None, None]).taken());
        assert!(!after(&[drive(86), drive(86), turn(31_500)]).taken());
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
        check_flow_commanded(flow, &after(commands))
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
        assert_eq!(forward(60, &driving), Ok(()));
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
        // The other way it is short of the turn, unless beyond the slack.
        assert_eq!(verdict(3_067_380, &wild), Err(Doubt::Unmoved));
        assert_eq!(verdict(3_067_381, &wild), Err(Doubt::Uncommanded));
        // Half of 1,048 deg/s less 0.5 is read.
        assert_eq!(verdict(-(1 << 19) + 500, &wild), Ok(()));
        assert_eq!(verdict(-(1 << 19) + 501, &wild), Err(Doubt::Unmoved));
        assert_eq!(verdict(i32::MIN, &wild), Err(Doubt::Uncommanded));
        assert_eq!(verdict(i32::MAX, &wild), Err(Doubt::Uncommanded));
        assert_eq!(
            verdict(i32::MAX, &[turn(i32::MAX); 3]),
            Err(Doubt::Uncommanded)
        );
        assert_eq!(verdict(1 << 20, &[turn(i32::MAX); 3]), Ok(()));
        // The flow: 65,536 mm/s x 1,126 / 1,024 + 1,048 deg/s 10 mm off the axis + 6.
        assert_eq!(forward(-72_064 - 182 - 6, &wild), Ok(()));
        assert_eq!(forward(-72_064 - 182 - 7, &wild), Err(Doubt::Uncommanded));
        assert_eq!(forward(-32_768 + 6, &wild), Ok(()));
        assert_eq!(forward(-32_768 + 7, &wild), Err(Doubt::Unmoved));
        assert_eq!(forward(i32::MIN, &wild), Err(Doubt::Uncommanded));
        assert_eq!(
            verdict(i32::MIN, &[turn(i32::MAX); 3]),
            Err(Doubt::Uncommanded)
        );
    }
}
