//! Plausibility checks on the inputs the pose and the map depend on, and the trust the
//! core keeps in each.
//!
//! A reading can be there and still be wrong: a gyro stuck on one value, a rate or a
//! flow no robot can make, a reading that moves while the robot was told to stand,
//! depth frames that repeat bit for bit, a turn the motors were not asked for
//! ([`crate::commanded`]). Each check here turns one reading into a verdict; [`Plausibility`] keeps, per input, whether it is trusted: an input is doubted
//! from its first implausible (or, for the gyro and the flow, missing) reading and
//! trusted again after [`PlausibleConfig::trust_after_ticks`] plausible readings in a row.
//!
//! While the gyro or the flow is doubted the motion code holds the motion that needs it
//! ([`crate::guard`]), so the core takes a doubted input as reading "still" from the tick
//! after the doubt began; on that first tick the robot was still moving, and the last
//! trusted reading stands in for it if it was read under the command then in force, else
//! that command's own motion (for a sensor found short of every command of the window,
//! [`Doubt::Unmoved`], the commanded motion of the whole window). Stopped, every command
//! of the window standing, the motors cannot turn the robot: a trusted gyro reads only its
//! bias and noise, and the heading holds. A tag that
//! disagrees with the estimate is the estimator's gate's to refuse (`crate::estimator`);
//! a depth range that disagrees with a tag's distance doubts the depth sensor until the
//! two agree again ([`crate::tag_range`]). Where each frame arrives, the frames are held
//! to each other ([`crate::depth_step`]): every range stepping the same way at once, or a
//! frame given again late, comes with the scan as its doubt
//! ([`crate::SensorFrame::depth_doubt`]).

use crate::commanded::{
    check_flow_commanded, check_gyro_commanded, unfollowed_past, CommandTolerance, RecentCommands,
    Unfollowed, COMMAND_FRAMES,
};
use crate::depth_step::DepthStepConfig;
use crate::frame::{DepthScan, DriveCommand, FlowDelta, GyroRate, BEAMS};
use crate::tag_range::{TagRangeConfig, Witness};

/// The limits the checks hold the readings to.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PlausibleConfig {
    /// Fastest the robot can turn, millidegrees per second: a rate beyond is no robot's.
    pub max_turn_mdps: u32,
    /// Most the turn rate can change between two readings, millidegrees per second.
    pub max_turn_step_mdps: u32,
    /// Largest rate the gyro may read while the robot is held, millidegrees per second.
    pub still_turn_mdps: u32,
    /// Most flow counts a tick can see forwards or backwards: the fastest drive.
    pub max_flow_counts: u32,
    /// Most flow counts a tick can see sideways: a wheeled robot does not crab.
    pub max_side_flow_counts: u32,
    /// Most flow counts a tick may see on either axis while drives are held.
    pub still_flow_counts: u32,
    /// Readings equal bit for bit this many ticks running are a stuck sensor.
    pub stuck_ticks: u8,
    /// Furthest the depth sensor can read, millimetres, its noise included: a longer
    /// range is garbage.
    pub max_depth_mm: u16,
    /// Plausible readings in a row before a doubted input is trusted again.
    pub trust_after_ticks: u8,
    /// How far the gyro and the flow may read beyond the commanded motion.
    pub command: CommandTolerance,
    /// How the depth sensor's ranges are held to the tags' distances.
    pub tag_range: TagRangeConfig,
    /// How each depth frame is held to the ones before, where it arrives
    /// ([`crate::depth_step`]).
    pub depth_step: DepthStepConfig,
}

impl PlausibleConfig {
    /// BugBot: wheels at most 300 mm/s on a 100 mm base (344 deg/s flat out; routes
    /// turn at 31.5), 100 um a flow count, a VL53L5CX ranging to 4 m (a wall there reads
    /// a little beyond with noise: 4.5 m allowed), 10 Hz ticks.
    pub const SEED: PlausibleConfig = PlausibleConfig {
        max_turn_mdps: 344_000,
        max_turn_step_mdps: 40_000,
        still_turn_mdps: 2_000,
        max_flow_counts: 400,
        max_side_flow_counts: 100,
        still_flow_counts: 30,
        stuck_ticks: 5,
        max_depth_mm: 4_500,
        trust_after_ticks: 3,
        command: CommandTolerance::SEED,
        tag_range: TagRangeConfig::SEED,
        depth_step: DepthStepConfig::SEED,
    };
}

impl Default for PlausibleConfig {
    fn default() -> Self {
        PlausibleConfig::SEED
    }
}

/// Why an input is not trusted.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Doubt {
    /// No reading (after the first): the pose cannot follow the robot.
    Missing,
    /// The same reading, bit for bit, tick after tick.
    Stuck,
    /// A value the robot or the sensor cannot produce.
    Impossible,
    /// A change between two readings faster than the robot can make (of the depth
    /// sensor: every range stepping the same way at once, [`crate::depth_step`]).
    Jump,
    /// Motion read while the robot was held still.
    MovedWhileHeld,
    /// A turn or a drive beyond what the motors were commanded to make
    /// ([`crate::commanded`]).
    Uncommanded,
    /// A depth range that disagrees with the distance the camera reads to a tag in its
    /// beam ([`crate::tag_range`]); only a tag that agrees lifts it.
    DisagreesWithTag,
    /// Depth frames that come late: a frame given again after others
    /// ([`crate::depth_step`]); lifted when the frames fit the turn as fresh ones.
    Late,
    /// A turn the walls in the depth sensor's fan did not make ([`crate::wall_turn`]).
    UnseenTurn,
    /// Far less turn or drive than every one of the last commands asked for
    /// ([`crate::commanded`]): a sensor fallen behind, or a robot stalled.
    Unmoved,
}

impl Doubt {
    /// Every doubt, in the order of [`Doubt::code`].
    pub const ALL: [Doubt; 10] = [
        Doubt::Missing,
        Doubt::Stuck,
        Doubt::Impossible,
        Doubt::Jump,
        Doubt::MovedWhileHeld,
        Doubt::Uncommanded,
        Doubt::DisagreesWithTag,
        Doubt::Late,
        Doubt::UnseenTurn,
        Doubt::Unmoved,
    ];

    /// A small number for the wire: 1 to 10 (0 is "trusted").
    pub fn code(self) -> u8 {
        self as u8 + 1
    }

    /// The doubt of a [`Doubt::code`]; `None` for 0 or an unknown code.
    pub fn from_code(code: u8) -> Option<Doubt> {
        Doubt::ALL.get(usize::from(code).checked_sub(1)?).copied()
    }
}

/// The inputs the core checks.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Input {
    /// The gyro: the heading.
    Gyro,
    /// The flow sensor: the position.
    Flow,
    /// The depth sensor: the map.
    Depth,
}

/// Which inputs are doubted after a tick, and why.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Trust {
    /// Why the gyro is doubted; `None`: trusted.
    pub gyro: Option<Doubt>,
    /// Why the flow is doubted; `None`: trusted.
    pub flow: Option<Doubt>,
    /// Why the depth sensor is doubted; `None`: trusted.
    pub depth: Option<Doubt>,
}

impl Trust {
    /// Whether the pose follows the robot: the gyro and the flow are trusted.
    pub fn pose(&self) -> bool {
        self.gyro.is_none() && self.flow.is_none()
    }

    /// The input a motion needs and does not have: turning needs the gyro, driving the
    /// gyro and the flow. `None`: the motion may go.
    pub fn lacking(&self, turns: bool, drives: bool) -> Option<Input> {
        if (turns || drives) && self.gyro.is_some() {
            Some(Input::Gyro)
        } else if drives && self.flow.is_some() {
            Some(Input::Flow)
        } else {
            None
        }
    }

    /// The three doubts in one number, four bits each (gyro lowest, then flow, then
    /// depth), each a [`Doubt::code`] or 0: the telemetry's form.
    pub fn packed(&self) -> u16 {
        let code = |d: Option<Doubt>| u16::from(d.map_or(0, Doubt::code));
        code(self.gyro) | (code(self.flow) << 4) | (code(self.depth) << 8)
    }

    /// The trust [`Trust::packed`] gave; unknown codes read as trusted.
    pub fn unpacked(packed: u16) -> Trust {
        let doubt = |shift: u16| Doubt::from_code(((packed >> shift) & 0xF) as u8);
        Trust {
            gyro: doubt(0),
            flow: doubt(4),
            depth: doubt(8),
        }
    }
}

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

/// One input's trust: doubted from a bad reading until enough good ones in a row.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default)]
struct Watch {
    doubt: Option<Doubt>,
    good_in_a_row: u8,
}

impl Watch {
    #[inline(never)]
    fn judge(&mut self, verdict: Result<(), Doubt>, trust_after: u8) {
        match verdict {
            Err(doubt) => {
                self.doubt = self.doubt.or(Some(doubt));
                self.good_in_a_row = 0;
            }
            Ok(()) if self.doubt.is_some() => {
                self.good_in_a_row = self.good_in_a_row.saturating_add(1);
                if self.good_in_a_row >= trust_after {
                    *self = Watch::default();
                }
            }
            Ok(()) => {}
        }
    }
}

/// How many ticks running a reading has been equal to the one before.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default)]
struct Repeats<T> {
    last: Option<T>,
    repeats: u8,
}

impl<T: PartialEq + Copy> Repeats<T> {
    /// Takes a reading; returns the reading before it and how many repeats end here.
    #[inline(never)]
    fn push(&mut self, reading: T) -> (Option<T>, u8) {
        let before = self.last.replace(reading);
        self.repeats = if before == Some(reading) {
            self.repeats.saturating_add(1)
        } else {
            0
        };
        (before, self.repeats)
    }

    /// Takes a reading; returns how many repeats end here ([`Repeats::push`] without
    /// handing back the reading before).
    #[inline(never)]
    fn count(&mut self, reading: T) -> u8 {
        self.repeats = if self.last == Some(reading) {
            self.repeats.saturating_add(1)
        } else {
            0
        };
        self.last = Some(reading);
        self.repeats
    }
}

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

/// A tick's depth scan, as the checks take it.
#[derive(Clone, Copy, Debug)]
pub struct DepthReading<'a> {
    /// The scan.
    pub scan: &'a DepthScan,
    /// What the depth sensor's task made of it against the frames before it
    /// ([`crate::depth_step`]; [`crate::SensorFrame::depth_doubt`]).
    pub steps: Option<Doubt>,
    /// What the camera's tags say of it ([`crate::tag_range::witness`]).
    pub tags: Witness,
}

/// What the checks made of a tick's odometry.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub struct Judged {
    /// The turn to integrate.
    pub gyro: Known<GyroRate>,
    /// The travel to integrate.
    pub flow: Known<FlowDelta>,
    /// The trust after this tick.
    pub trust: Trust,
    /// Which of the gyro and the flow read outside what the newest command allows a frame
    /// after it changed ([`crate::commanded::unfollowed`]): the pose may be behind the
    /// robot or ahead.
    pub unfollowed: Unfollowed,
}

impl Judged {
    /// Whether the tick's motion is a guess: a reading that stands in, or none.
    pub fn guessed(&self) -> bool {
        matches!(self.gyro, Known::StandIn(_) | Known::Lost)
            || matches!(self.flow, Known::StandIn(_) | Known::Lost)
    }

    /// Every reading believed, as with no checks at all.
    pub fn believing(gyro: Option<GyroRate>, flow: Option<FlowDelta>) -> Judged {
        Judged {
            gyro: gyro.map_or(Known::Lost, Known::Read),
            flow: flow.map_or(Known::Lost, Known::Read),
            trust: Trust::default(),
            unfollowed: Unfollowed::default(),
        }
    }
}

/// The checks' state across ticks.
///
/// Laid out in the order written (`repr(C)`): what every tick reads first, within the
/// M0+'s short load offsets, and what only a change of command reads last.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default)]
#[repr(C)]
pub struct Plausibility {
    gyro: Watch,
    flow: Watch,
    depth: Watch,
    /// Whether a tag's distance agreed with the last tick's scan.
    depth_vouched: bool,
    gyro_repeats: Repeats<GyroRate>,
    flow_repeats: Repeats<FlowDelta>,
    /// The motors' last commands, to check the gyro against.
    commands: RecentCommands,
    /// The newest trusted readings taken while the robot was not held, to stand in for
    /// the tick a doubt begins.
    moving_gyro: Option<Moving<GyroRate>>,
    moving_flow: Option<Moving<FlowDelta>>,
    /// What the first frame after the newest command's change read past its motion.
    behind: Behind,
    /// Forward counts the flow read and no tick integrated, less those integrated and not
    /// read, over the drive in hand and the few ticks after it ([`Plausibility::settle_flow`]).
    flow_owed: i32,
    /// Ticks since the newest command drove, up to [`LATE_TICKS`] and one.
    since_drive: u8,
}

/// Ticks after a drive's last command in which the flow's readings of it may still come:
/// a sensor as late as a command's window.
const LATE_TICKS: u8 = COMMAND_FRAMES as u8;

impl Plausibility {
    /// Whether a tag's distance agreed with the last tick's scan: its ranges are right.
    pub fn depth_vouched(&self) -> bool {
        self.depth_vouched
    }

    /// The motors' last commands ([`RecentCommands`]).
    pub fn recent_commands(&self) -> &RecentCommands {
        &self.commands
    }

    /// Whether the motors were commanded to turn over the last ticks (their intervals and
    /// the two before, [`RecentCommands`]); `None` unless every command is known.
    pub fn turning_of_late(&self) -> Option<bool> {
        self.commands.turning()
    }

    /// Doubts the gyro for what was found after its tick was judged (the walls'
    /// turn, [`crate::wall_turn`]): from the next tick the motion that needs it holds,
    /// and it is trusted again after plausible readings as after any doubt.
    pub fn doubt_gyro(&mut self, doubt: Doubt) {
        self.gyro = Watch {
            doubt: Some(doubt),
            good_in_a_row: 0,
        };
    }

    /// The trust the last tick ended with.
    pub fn trust(&self) -> Trust {
        Trust {
            gyro: self.gyro.doubt,
            flow: self.flow.doubt,
            depth: self.depth.doubt,
        }
    }

    /// Judges a tick's readings, with the command the motors were driven with as the
    /// tick's interval ended (`None`: not known). The robot is taken as held since the
    /// last tick where the trust then lacked what its motion needs (turns: the gyro;
    /// drives: the flow as well). An input never heard from is not doubted for being
    /// missing: the robot waits for its sensors before it moves.
    ///
    /// Out of line: once a tick, and the firmware builds the core for speed.
    #[inline(never)]
    pub fn judge(
        &mut self,
        gyro: Option<GyroRate>,
        flow: Option<FlowDelta>,
        depth: Option<DepthReading<'_>>,
        commanded: Option<DriveCommand>,
        config: &PlausibleConfig,
    ) -> Judged {
        let before = self.trust();
        let turn_held = before.lacking(true, false).is_some();
        let drive_held = before.lacking(false, true).is_some();
        let after = config.trust_after_ticks;
        self.commands.push(commanded, &config.command);

        let gyro_verdict = match gyro {
            Some(g) => {
                let (last, repeats) = self.gyro_repeats.push(g);
                check_gyro(g, last, repeats, turn_held, config)
                    .and_then(|()| check_gyro_commanded(g, &self.commands))
            }
            None if self.gyro_repeats.last.is_none() => Ok(()),
            None => Err(Doubt::Missing),
        };
        self.gyro.judge(gyro_verdict, after);
        let flow_verdict = match flow {
            Some(f) => {
                let repeats = self.flow_repeats.count(f);
                check_flow(f, repeats, drive_held, config)
                    .and_then(|()| check_flow_commanded(f, &self.commands))
            }
            None if self.flow_repeats.last.is_none() => Ok(()),
            None => Err(Doubt::Missing),
        };
        self.flow.judge(flow_verdict, after);
        self.depth_vouched = depth.is_some_and(|d| d.tags == Witness::Agrees);
        if let Some(DepthReading { scan, steps, tags }) = depth {
            // A repeated frame is the depth task's to count (`steps`): here only the
            // ranges themselves.
            let steps = steps.map_or(Ok(()), Err);
            let verdict = check_depth(scan, 0, config).and(steps).and(match tags {
                Witness::Disagrees => Err(Doubt::DisagreesWithTag),
                Witness::Agrees | Witness::Silent | Witness::Discredited => Ok(()),
            });
            // A sensor doubted for what a tag showed is trusted again only on tags'
            // word, whatever else doubted it first: a frame no tag checks says nothing
            // of its ranges.
            if tags == Witness::Disagrees {
                self.depth.doubt = Some(Doubt::DisagreesWithTag);
            }
            let unheard = verdict.is_ok()
                && tags == Witness::Silent
                && self.depth.doubt == Some(Doubt::DisagreesWithTag);
            if !unheard {
                self.depth.judge(verdict, after);
            }
        }

        let trust = self.trust();
        let commands = &self.commands;
        // Steady, the newest command allows what the window does, and the checks have
        // held the readings to it.
        let (unfollowed, gyro_following, flow_following) = if commands.steady() {
            let follows = Following::Follows;
            (Unfollowed::default(), follows, follows)
        } else {
            following(
                (gyro, flow),
                trust,
                commands,
                &config.command,
                &mut self.behind,
            )
        };
        // Short of a steady command over the whole window: its every tick was missed.
        let (least_turn, least_speed) = commands.least();
        let window = COMMAND_FRAMES as i32;
        let gyro = match trust.gyro {
            Some(Doubt::Unmoved) if !turn_held => Known::StandIn(GyroRate {
                rate_mdps: least_turn.saturating_mul(window),
            }),
            _ => known(
                gyro,
                trust.gyro,
                turn_held,
                gyro_following,
                commands,
                |c| c.turn_mdps == 0,
                commanded_gyro,
                &mut self.moving_gyro,
            ),
        };
        let stopped = commands.stopped();
        let gyro = gyro.still_if(stopped);
        let flow = match trust.flow {
            Some(Doubt::Unmoved) if !drive_held => Known::StandIn(FlowDelta {
                forward_counts: least_speed.saturating_mul(window),
                right_counts: 0,
            }),
            _ => known(
                flow,
                trust.flow,
                drive_held,
                flow_following,
                commands,
                |c| c.speed_mm_s == 0,
                commanded_flow,
                &mut self.moving_flow,
            ),
        };
        let flow = flow.still_if(stopped);
        Judged {
            gyro,
            flow,
            trust,
            unfollowed,
        }
    }

    /// Integrates the flow's readings of a drive that the checks dropped as they came, late:
    /// after a drive too short for its readings' lag to be found ([`Doubt::Unmoved`] needs
    /// a window of it), they come under the next command, read as motion it does not make,
    /// and the pose is left behind by the whole drive. The counts read and not integrated,
    /// less those integrated and not read (a drive's window stood in for a sensor found
    /// behind), are owed; a reading dropped while some are owed, within three ticks of
    /// the drive, stands in for what it pays. Readings doubted for what they are on their
    /// own or for more drive than the drive they were read under (a scale gone long: a
    /// late reading comes under the next command), and drops within the still robot's
    /// noise, neither owe nor pay. Called on every tick after [`Plausibility::judge`] (and
    /// [`Plausibility::stand_in_past`]), with the tick's reading `read`.
    #[inline(never)]
    pub fn settle_flow(
        &mut self,
        read: Option<FlowDelta>,
        judged: &mut Judged,
        config: &PlausibleConfig,
    ) {
        let driving = self.commands.newest().is_some_and(|c| c.speed_mm_s != 0);
        self.since_drive = match driving {
            true => 0,
            false => self.since_drive.saturating_add(1).min(LATE_TICKS + 1),
        };
        if self.since_drive > LATE_TICKS {
            self.flow_owed = 0;
            return;
        }
        let plausible = match judged.trust.flow {
            None | Some(Doubt::Unmoved) => true,
            // Past the drive it was read under: a sensor reading long, not late.
            Some(Doubt::Uncommanded) => !driving,
            Some(_) => false,
        };
        let Some(r) = read.filter(|_| plausible).map(|f| f.forward_counts) else {
            return;
        };
        let integrated = judged.flow.reading().map_or(0, |f| f.forward_counts);
        let dropped = r.saturating_sub(integrated);
        if dropped.unsigned_abs() <= config.still_flow_counts {
            return;
        }
        // At most what the window's ticks can read: the clamp's bounds stay ordered.
        let most = config.max_flow_counts.saturating_mul(u32::from(LATE_TICKS));
        let most = i32::try_from(most).unwrap_or(i32::MAX);
        let owed = self.flow_owed.saturating_add(dropped).clamp(-most, most);
        // Only a reading of motion pays, and only the way it reads.
        let moving = r.unsigned_abs() > config.still_flow_counts;
        let pay = match (moving, r.signum(), dropped.signum()) {
            (true, 1, 1) => dropped.min(owed.max(0)),
            (true, -1, -1) => dropped.max(owed.min(0)),
            _ => 0,
        };
        self.flow_owed = owed - pay;
        if pay != 0 {
            judged.flow = Known::StandIn(FlowDelta {
                forward_counts: integrated.saturating_add(pay),
                right_counts: 0,
            });
        }
    }

    /// On a tick whose motion [`Judged::guessed`]: stands in for a reading past the newest
    /// command a frame after it changed (a guess of the reading until now) that command's
    /// motion, less what the frame before read past it. Out of the judging,
    /// and cold: only on guessed ticks, which it leaves guessed.
    #[cold]
    #[inline(never)]
    pub fn stand_in_past(&mut self, judged: &mut Judged) {
        let behind = &mut self.behind;
        let motion = behind.stand_in;
        if core::mem::take(&mut behind.past.0) {
            judged.gyro = Known::StandIn(commanded_gyro(&motion));
        }
        if core::mem::take(&mut behind.past.1) {
            judged.flow = Known::StandIn(commanded_flow(&motion));
        }
    }
}

/// How a trusted reading stands to the newest command.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Following {
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
struct Behind {
    changes: u8,
    rate_mdps: i32,
    forward_counts: i32,
    /// Which of the gyro and the flow read past the newest command a frame after it
    /// changed, and the motion that stands in for them: the command's, less what the
    /// frame before read past it.
    past: (bool, bool),
    stand_in: DriveCommand,
}

/// How the gyro's and the flow's readings stand to the newest of `commands`, which are
/// not steady: on the first frame after a change the motors may not have followed it at
/// all (what a trusted reading holds past it is kept in `behind`); a frame later a reading
/// outside what it allows ([`unfollowed_past`]) strays, and one trusted and past it has its
/// stand-in worked out in `behind`. Commands not known check nothing, as in the checks.
/// Out of line and cold: only while the commands change.
#[cold]
#[inline(never)]
fn following(
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

/// A trusted reading taken while the robot was not held, with the command it was taken
/// under.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
struct Moving<T> {
    reading: T,
    /// The commands' change count then ([`RecentCommands::changes`]).
    changes: u8,
    /// The newest command then, if known.
    command: Option<DriveCommand>,
}

/// The gyro's rate under `command`: its turn.
fn commanded_gyro(command: &DriveCommand) -> GyroRate {
    GyroRate {
        rate_mdps: command.turn_mdps,
    }
}

/// The flow a tick of `command`'s drive reads: one count a tick per millimetre a second
/// (100 um counts at 10 Hz, as [`CommandTolerance`] takes them), nothing sideways.
fn commanded_flow(command: &DriveCommand) -> FlowDelta {
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
#[allow(clippy::too_many_arguments)]
#[inline(never)]
fn known<T: Copy>(
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

#[cfg(test)]
mod tests {
    use super::*;

    const C: PlausibleConfig = PlausibleConfig::SEED;

    /// A turn on the spot and a straight drive, as the route commands them.
    const TURN: DriveCommand = DriveCommand {
        speed_mm_s: 0,
        turn_mdps: 31_500,
    };
    const DRIVE: DriveCommand = DriveCommand {
        speed_mm_s: 86,
        turn_mdps: 0,
    };
    /// Standing.
    const STOP: DriveCommand = DriveCommand {
        speed_mm_s: 0,
        turn_mdps: 0,
    };

    /// Checks that have seen four ticks of a steady turn on the spot, its readings
    /// trusted (the flow's a count or so: the sensor sits on the axis).
    fn after_a_turn() -> Plausibility {
        let mut p = Plausibility::default();
        for i in 0..4 {
            p.judge(
                Some(rate(31_500 + i)),
                Some(flow(i, 0)),
                None,
                Some(TURN),
                &C,
            );
        }
        p
    }

    fn rate(mdps: i32) -> GyroRate {
        GyroRate { rate_mdps: mdps }
    }

    fn flow(forward: i32, right: i32) -> FlowDelta {
        FlowDelta {
            forward_counts: forward,
            right_counts: right,
        }
    }

    #[test]
    fn a_rate_no_robot_turns_at_is_impossible() {
        assert_eq!(check_gyro(rate(31_500), None, 0, false, &C), Ok(()));
        assert_eq!(check_gyro(rate(-344_000), None, 0, false, &C), Ok(()));
        assert_eq!(
            check_gyro(rate(344_001), None, 0, false, &C),
            Err(Doubt::Impossible)
        );
        assert_eq!(
            check_gyro(rate(i32::MIN), None, 0, false, &C),
            Err(Doubt::Impossible)
        );
    }

    #[test]
    fn a_rate_that_jumps_more_than_a_turn_starts_is_a_jump() {
        // Starting or ending a 31.5 deg/s turn is a step the robot makes.
        assert_eq!(
            check_gyro(rate(31_500), Some(rate(0)), 0, false, &C),
            Ok(())
        );
        assert_eq!(
            check_gyro(rate(-20_000), Some(rate(31_500)), 0, false, &C),
            Err(Doubt::Jump)
        );
    }

    #[test]
    fn a_gyro_on_one_value_for_n_ticks_is_stuck() {
        let mut repeats = Repeats::default();
        let verdicts: std::vec::Vec<_> = (0..6)
            .map(|_| {
                let (before, n) = repeats.push(rate(31_512));
                check_gyro(rate(31_512), before, n, false, &C)
            })
            .collect();
        assert_eq!(verdicts[..4], [Ok(()); 4]);
        assert_eq!(verdicts[4..], [Err(Doubt::Stuck); 2]);
        // A new value starts the count again.
        assert_eq!(repeats.push(rate(31_490)).1, 0);
    }

    #[test]
    fn a_turn_read_while_held_is_doubted() {
        assert_eq!(check_gyro(rate(1_500), Some(rate(0)), 0, true, &C), Ok(()));
        assert_eq!(
            check_gyro(rate(3_000), Some(rate(0)), 0, true, &C),
            Err(Doubt::MovedWhileHeld)
        );
    }

    #[test]
    fn flow_faster_than_a_drive_or_sideways_is_impossible() {
        assert_eq!(check_flow(flow(86, -3), 0, false, &C), Ok(()));
        assert_eq!(
            check_flow(flow(-401, 0), 0, false, &C),
            Err(Doubt::Impossible)
        );
        assert_eq!(
            check_flow(flow(10, 101), 0, false, &C),
            Err(Doubt::Impossible)
        );
        assert_eq!(
            check_flow(flow(i32::MIN, 0), 0, false, &C),
            Err(Doubt::Impossible)
        );
    }

    #[test]
    fn flow_stuck_or_moving_while_held_is_doubted() {
        assert_eq!(check_flow(flow(86, 1), 4, false, &C), Err(Doubt::Stuck));
        assert_eq!(check_flow(flow(86, 1), 3, false, &C), Ok(()));
        assert_eq!(
            check_flow(flow(86, 1), 0, true, &C),
            Err(Doubt::MovedWhileHeld)
        );
        assert_eq!(check_flow(flow(2, -1), 0, true, &C), Ok(()));
    }

    fn scan(ranges: &[Option<u16>]) -> DepthScan {
        let mut s = DepthScan::default();
        for (slot, r) in s.ranges_mm.iter_mut().zip(ranges) {
            *slot = *r;
        }
        s
    }

    #[test]
    fn a_depth_frame_repeated_bit_for_bit_is_stuck() {
        let full = scan(&[Some(812); BEAMS]);
        assert_eq!(check_depth(&full, 0, &C), Ok(()));
        assert_eq!(check_depth(&full, 1, &C), Err(Doubt::Stuck));
        // One return may repeat by chance: only a long run is stuck.
        let sparse = scan(&[Some(812), None]);
        assert_eq!(check_depth(&sparse, 3, &C), Ok(()));
        assert_eq!(check_depth(&sparse, 4, &C), Err(Doubt::Stuck));
        // No return at all writes nothing: never stuck.
        assert_eq!(check_depth(&DepthScan::default(), 9, &C), Ok(()));
    }

    #[test]
    fn a_range_beyond_the_sensor_is_impossible() {
        assert_eq!(check_depth(&scan(&[Some(4_500)]), 0, &C), Ok(()));
        assert_eq!(
            check_depth(&scan(&[None, Some(4_501)]), 0, &C),
            Err(Doubt::Impossible)
        );
    }

    #[test]
    fn trust_comes_back_after_enough_good_readings_in_a_row() {
        let mut p = Plausibility::default();
        let tick =
            |p: &mut Plausibility, g: Option<i32>| p.judge(g.map(rate), None, None, None, &C);
        // Never heard: not doubted, nothing known.
        let first = tick(&mut p, None);
        assert_eq!((first.trust, first.gyro), (Trust::default(), Known::Lost));
        assert_eq!(tick(&mut p, Some(31_500)).gyro, Known::Read(rate(31_500)));
        // Lost while turning: the last trusted rate stands in, then the robot is held.
        let lost = tick(&mut p, None);
        assert_eq!(lost.trust.gyro, Some(Doubt::Missing));
        assert_eq!(lost.trust.lacking(true, false), Some(Input::Gyro));
        assert_eq!(lost.gyro, Known::StandIn(rate(31_500)));
        assert_eq!(tick(&mut p, None).gyro, Known::Still);
        // Back, still: two good readings are not yet enough, a third is.
        for _ in 0..2 {
            let j = tick(&mut p, Some(10));
            assert_eq!((j.trust.gyro, j.gyro), (Some(Doubt::Missing), Known::Still));
        }
        // A turn while held resets the count.
        assert_eq!(tick(&mut p, Some(31_500)).gyro, Known::Still);
        for _ in 0..2 {
            assert!(tick(&mut p, Some(20)).trust.gyro.is_some());
        }
        let back = tick(&mut p, Some(-20));
        assert_eq!(
            (back.trust, back.gyro),
            (Trust::default(), Known::Read(rate(-20)))
        );
    }

    #[test]
    fn a_stand_in_is_a_reading_while_the_commands_are_steady_and_a_guess_after_a_change() {
        let turning = || {
            let mut p = Plausibility::default();
            for _ in 0..4 {
                let j = p.judge(Some(rate(31_500)), None, None, Some(TURN), &C);
                assert_eq!(j.trust, Trust::default());
            }
            p
        };
        // Lost in a steady turn: the robot turns as it did.
        let lost = turning().judge(None, None, None, Some(TURN), &C);
        assert_eq!(lost.gyro, Known::Read(rate(31_500)));
        // Lost as the turn gives way to a drive: the turn's rate was not read under the
        // drive, whose own (none) is the guess.
        let lost = turning().judge(None, None, None, Some(DRIVE), &C);
        assert_eq!(lost.gyro, Known::StandIn(rate(0)));
        // With the commands not known, the last rate is.
        let lost = turning().judge(None, None, None, None, &C);
        assert_eq!(lost.gyro, Known::StandIn(rate(31_500)));
    }

    #[test]
    fn a_sensor_behind_its_command_stands_in_for_the_window_it_missed() {
        // Standing, then a drive the flow reads nothing of, three ticks late: the robot
        // is not held in the first two, the second's scan is not vouched for, and at
        // the third every one of the window's commands asked for a drive.
        let still = Some(STOP);
        let mut p = Plausibility::default();
        for i in 0..4 {
            let j = p.judge(Some(rate(i)), Some(flow(i % 2, 0)), None, still, &C);
            assert!(!j.unfollowed.any());
        }
        // On the first frame of the drive the motors may not have followed it yet; a
        // frame later a reading short of it is trusted but only a guess.
        let j = p.judge(Some(rate(0)), Some(flow(0, 0)), None, Some(DRIVE), &C);
        assert_eq!((j.trust, j.unfollowed.any()), (Trust::default(), false));
        assert_eq!(j.flow, Known::Read(flow(0, 0)));
        let j = p.judge(Some(rate(1)), Some(flow(1, 0)), None, Some(DRIVE), &C);
        assert_eq!(j.trust, Trust::default());
        assert_eq!((j.unfollowed.gyro, j.unfollowed.flow), (false, true));
        assert_eq!(j.flow, Known::StandIn(flow(1, 0)));
        assert_eq!(j.gyro, Known::Read(rate(1)));
        let j = p.judge(Some(rate(5)), Some(flow(1, 0)), None, Some(DRIVE), &C);
        assert_eq!(j.trust.flow, Some(Doubt::Unmoved));
        assert_eq!(j.flow, Known::StandIn(flow(3 * 86, 0)));
        assert_eq!(j.gyro, Known::Read(rate(5)));
        // From the next tick the drive is held: the flow's late counts are no motion.
        let j = p.judge(Some(rate(6)), Some(flow(86, 0)), None, Some(DRIVE), &C);
        assert_eq!(j.flow, Known::Still);
        // The gyro alike, in a turn.
        let mut p = Plausibility::default();
        for i in 0..4 {
            p.judge(Some(rate(i)), Some(flow(i % 2, 0)), None, still, &C);
        }
        for i in 0..2 {
            p.judge(Some(rate(i)), Some(flow(i % 2, 0)), None, Some(TURN), &C);
        }
        let j = p.judge(Some(rate(2)), Some(flow(0, 0)), None, Some(TURN), &C);
        assert_eq!(j.trust.gyro, Some(Doubt::Unmoved));
        assert_eq!(j.gyro, Known::StandIn(rate(3 * 31_500)));
    }

    #[test]
    fn a_sensor_behind_its_command_as_the_motion_ends_is_taken_back() {
        // A turn on the spot ends; the gyro, three ticks late, reads it on. On the first
        // frame after the stop the motors may still have turned: the reading is the
        // motion. A frame later a reading past the stop is a sensor behind: what the
        // frame before read past it is taken back, so that the two frames together hold
        // the stop's motion (none), and the scan is not vouched for.
        // As the core judges: a guessed tick's readings past a command stand in for it.
        let judge = |p: &mut Plausibility, g: i32, f: i32, c: DriveCommand| {
            let mut j = p.judge(Some(rate(g)), Some(flow(f, 0)), None, Some(c), &C);
            if j.guessed() {
                p.stand_in_past(&mut j);
            }
            j
        };
        let mut p = after_a_turn();
        let j = judge(&mut p, 31_504, 0, STOP);
        assert_eq!(j.gyro, Known::Read(rate(31_504)));
        let j = judge(&mut p, 31_505, 1, STOP);
        assert_eq!(j.trust, Trust::default());
        assert_eq!((j.unfollowed.gyro, j.unfollowed.flow), (true, false));
        assert_eq!(j.gyro, Known::StandIn(rate(-31_504)));
        // The third reads past every command of the window: doubted, and the robot is
        // taken as standing.
        let j = judge(&mut p, 31_506, 0, STOP);
        assert_eq!(j.trust.gyro, Some(Doubt::Uncommanded));
        assert_eq!(j.gyro, Known::Still);

        // The flow alike as a drive gives way to a turn on the spot.
        let mut p = Plausibility::default();
        for i in 0..4 {
            p.judge(Some(rate(i)), Some(flow(86 - i, 0)), None, Some(DRIVE), &C);
        }
        let j = judge(&mut p, 31_500, 84, TURN);
        assert_eq!(j.flow, Known::Read(flow(84, 0)));
        let j = judge(&mut p, 31_501, 85, TURN);
        assert_eq!(j.flow, Known::StandIn(flow(-84, 0)));
        assert_eq!(j.gyro, Known::Read(rate(31_501)));

        // Only a frame right after its own change is taken back: a reading past the
        // command two changes on takes back nothing.
        let mut p = after_a_turn();
        judge(&mut p, 31_504, 0, STOP);
        judge(&mut p, 0, 0, DRIVE);
        let j = judge(&mut p, 31_505, 86, DRIVE);
        assert_eq!(j.gyro, Known::StandIn(rate(0)));
    }

    /// A flow three ticks late: a drive of two ticks reads nothing, too short to be found
    /// short of its commands, and its counts come under the turn after it, past every
    /// command the window holds: integrated, as it was owed. A drive long enough to be
    /// found short has its window stood in, so the counts that come after it owe nothing;
    /// nor does a still robot's noise.
    #[test]
    fn a_drives_late_counts_are_integrated_once() {
        // As the core judges: a guessed tick's readings past a command stand in for it,
        // then the flow is settled.
        let judge_under = |p: &mut Plausibility, f: i32, c: DriveCommand, config| {
            let read = Some(flow(f, 0));
            let mut j = p.judge(Some(rate(c.turn_mdps)), read, None, Some(c), config);
            if j.guessed() {
                p.stand_in_past(&mut j);
            }
            p.settle_flow(read, &mut j, config);
            j.flow.reading().map_or(0, |r| r.forward_counts)
        };
        let judge = |p: &mut Plausibility, f: i32, c: DriveCommand| judge_under(p, f, c, &C);
        let standing = || {
            let mut p = Plausibility::default();
            for i in 0..6 {
                p.judge(
                    Some(rate(i % 2)),
                    Some(flow(i % 2, 0)),
                    None,
                    Some(STOP),
                    &C,
                );
            }
            p
        };
        // Two ticks of drive read as nothing, then a turn: the late counts are the drive's.
        let mut p = standing();
        let hop: Vec<i32> = [
            (0, DRIVE),
            (1, DRIVE),
            (2, TURN),
            (86, TURN),
            (85, TURN),
            (1, TURN),
        ]
        .into_iter()
        .map(|(f, c)| judge(&mut p, f, c))
        .collect();
        assert_eq!(hop.get(3..5), Some(&[86, 85][..]), "{hop:?}");

        // A drive found short on its third tick stands in its window: the counts that
        // come after it are that window's, and owe nothing.
        let mut p = standing();
        let mut drive = Vec::new();
        for (f, c) in [
            (0, DRIVE),
            (1, DRIVE),
            (0, DRIVE),
            (86, STOP),
            (85, STOP),
            (84, STOP),
        ] {
            drive.push(judge(&mut p, f, c));
        }
        for _ in 0..6 {
            drive.push(judge(&mut p, 0, STOP));
        }
        assert_eq!(drive.get(2..6), Some(&[3 * 86, 0, 0, 0][..]), "{drive:?}");
        assert_eq!(drive.iter().skip(6).sum::<i32>(), 0, "{drive:?}");

        // Limits as wide as a config may set them bound what is owed without overflow.
        let wide = PlausibleConfig {
            max_flow_counts: u32::MAX,
            ..C
        };
        let mut p = standing();
        let late: Vec<i32> = [(0, DRIVE), (1, DRIVE), (2, TURN), (300, TURN)]
            .into_iter()
            .map(|(f, c)| judge_under(&mut p, f, c, &wide))
            .collect();
        assert_eq!(late.last(), Some(&300), "{late:?}");

        // A flow reading long drives the robot no further than its stand-in: the counts
        // past the drive it was read under are not owed, then or after it.
        let mut p = standing();
        let long: Vec<i32> = [
            (1, STOP),
            (112, DRIVE),
            (1, STOP),
            (112, DRIVE),
            (0, STOP),
            (3, STOP),
            (1, STOP),
        ]
        .into_iter()
        .map(|(f, c)| judge(&mut p, f, c))
        .collect();
        assert!(long.iter().all(|&f| f <= 86), "{long:?}");

        // Standing, the noise is not motion, however long.
        let mut p = standing();
        let still: i32 = (0..20).map(|i| judge(&mut p, 2 * (i % 3) - 2, STOP)).sum();
        assert_eq!(still, 0);
    }

    #[test]
    fn a_reading_from_another_command_is_not_one_for_this() {
        let mut p = Plausibility::default();
        // Readings as noisy as a real sensor's: one repeated bit for bit is stuck.
        for i in 0..4 {
            p.judge(Some(rate(i)), Some(flow(86 - i, 0)), None, Some(DRIVE), &C);
        }
        // The flow drops out as the drive ends and the turn on the spot begins; its
        // readings in the turn are trusted again while the robot is still held for it,
        // so none of them is the newest taken while moving...
        p.judge(Some(rate(0)), None, None, Some(DRIVE), &C);
        for i in 0..3 {
            p.judge(
                Some(rate(31_500 + i)),
                Some(flow(1 - i, 0)),
                None,
                Some(TURN),
                &C,
            );
        }
        // ...and when it is lost again in the steady turn, the last drive's counts are
        // not this tick's: the turn's commands say the robot does not drive.
        let lost = p.judge(Some(rate(31_490)), None, None, Some(TURN), &C);
        assert!(lost.trust.flow.is_some());
        assert_eq!(lost.flow, Known::Still);
    }

    #[test]
    fn a_drive_resumed_after_a_hold_stands_in_its_command_unless_it_was_read_under_it() {
        // Read in a turn (no drive), then in a drive when `drive_first`; the flow then
        // reads a third long, is doubted and the drive held; standing, it is trusted
        // again; the drive resumes and it reads long again.
        let resumed = |drive_first: bool| {
            let mut p = after_a_turn();
            if drive_first {
                for i in 0..4 {
                    p.judge(Some(rate(i)), Some(flow(86 - i, 0)), None, Some(DRIVE), &C);
                }
            }
            let long = p.judge(Some(rate(0)), Some(flow(115, 0)), None, Some(DRIVE), &C);
            assert_eq!(long.trust.flow, Some(Doubt::Uncommanded));
            for i in 0..3 {
                p.judge(Some(rate(i)), Some(flow(i % 2, 0)), None, Some(STOP), &C);
            }
            assert_eq!(p.trust(), Trust::default());
            let again = p.judge(Some(rate(0)), Some(flow(115, 0)), None, Some(DRIVE), &C);
            assert_eq!(again.trust.flow, Some(Doubt::Uncommanded));
            again.flow
        };
        // The turn's counts are no drive's: the drive's own stand in...
        assert_eq!(resumed(false), Known::StandIn(flow(86, 0)));
        // ...unless a reading was taken under this very drive.
        assert_eq!(resumed(true), Known::StandIn(flow(83, 0)));
    }

    #[test]
    fn a_stopped_robot_holds_its_pose_whatever_its_trusted_gyro_and_flow_read() {
        let mut p = after_a_turn();
        // The turn has stopped, but the window still holds it: the readings are the motion.
        let stopping = p.judge(Some(rate(25)), Some(flow(0, 1)), None, Some(STOP), &C);
        assert_eq!(
            (stopping.gyro, stopping.flow),
            (Known::Read(rate(25)), Known::Read(flow(0, 1)))
        );
        p.judge(Some(rate(-5)), Some(flow(1, 0)), None, Some(STOP), &C);
        // Every command of the window standing: the bias and the noise are no motion.
        for i in 0..3 {
            let j = p.judge(Some(rate(20 + i)), Some(flow(i, -i)), None, Some(STOP), &C);
            assert_eq!(
                (j.trust, j.gyro, j.flow),
                (Trust::default(), Known::Still, Known::Still)
            );
        }
        // With the commands not known, the readings are the motion.
        let unknown = p.judge(Some(rate(23)), Some(flow(2, 0)), None, None, &C);
        assert_eq!(
            (unknown.gyro, unknown.flow),
            (Known::Read(rate(23)), Known::Read(flow(2, 0)))
        );
    }

    #[test]
    fn a_doubted_flow_holds_drives_not_turns() {
        let mut p = Plausibility::default();
        let mut not_turning_with_flow =
            |forward: i32| p.judge(Some(rate(0)), Some(flow(forward, 0)), None, None, &C);
        not_turning_with_flow(86);
        let garbage = not_turning_with_flow(9_000);
        assert_eq!(garbage.trust.flow, Some(Doubt::Impossible));
        assert_eq!(garbage.flow, Known::StandIn(flow(86, 0)));
        assert_eq!(garbage.trust.lacking(true, false), None);
        assert_eq!(garbage.trust.lacking(false, true), Some(Input::Flow));
        assert!(!garbage.trust.pose());
        let held = not_turning_with_flow(1);
        assert_eq!(held.flow, Known::Still);
    }

    #[test]
    fn trust_packs_into_sixteen_bits_and_back() {
        let t = Trust {
            gyro: Some(Doubt::Stuck),
            flow: None,
            depth: Some(Doubt::MovedWhileHeld),
        };
        assert_eq!(t.packed(), 2 | (5 << 8));
        assert_eq!(Trust::unpacked(t.packed()), t);
        assert_eq!(Trust::unpacked(0), Trust::default());
        for d in Doubt::ALL {
            assert_eq!(Doubt::from_code(d.code()), Some(d));
        }
        assert_eq!(Doubt::from_code(0), None);
        assert_eq!(Doubt::from_code(Doubt::ALL.len() as u8 + 1), None);
    }
}
