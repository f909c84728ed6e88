//! Plausibility checks on the inputs the pose and the map depend on, and the trust the
//! core keeps in each.
//!
//! A reading can be there and still be wrong: a gyro stuck on one value, a rate or a
//! flow no robot can make, a reading that moves while the robot was told to stand,
//! depth frames that repeat bit for bit, a turn the motors were not asked for
//! ([`crate::commanded`]). Each check turns one reading into a verdict; [`Plausibility`]
//! keeps, per input, whether it is trusted: an input is doubted from its first implausible
//! (or, for the gyro and the flow, missing) reading and trusted again after
//! [`PlausibleConfig::trust_after_ticks`] plausible readings in a row.
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
//!
//! - `checks`: each reading to a verdict;
//! - `watch`: the verdicts to each input's trust, and a reading's repeats;
//! - `following`: the readings against the newest command, while the commands change;
//! - `known`: what of each reading the odometry integrates.

mod checks;
mod following;
mod known;
mod watch;

#[cfg(test)]
mod tests;

pub use checks::{check_depth, check_flow, check_gyro};
pub use known::Known;

use crate::commanded::{
    check_flow_commanded, check_gyro_commanded, CommandTolerance, RecentCommands, Unfollowed,
    COMMAND_FRAMES,
};
use crate::depth_step::DepthStepConfig;
use crate::frame::{DepthScan, DriveCommand, FlowDelta, GyroRate};
use crate::tag_range::{TagRangeConfig, Witness};
use following::{following, Behind, Following};
use known::{commanded_flow, commanded_gyro, known, Moving};
use watch::{Repeats, Watch};

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
