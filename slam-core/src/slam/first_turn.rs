//! The run's first turn on the spot, drawn again once it closes.
//!
//! A run starts with an empty map, and the robot's first turn on the spot is what lays
//! it. While it turns, the matches hold the heading against the map the turn itself is
//! drawing, so the gyro's scale error goes into the map as it goes into the heading: a
//! degree or more once round. Once round, the turn's last scans see what its first saw,
//! and [`crate::spin_closure`] measures from their raw ranges how far the gyro's
//! integral ran past the true turn.
//!
//! [`FirstTurn`] keeps the turn's scans, each with the gyro's integral at its moment, from
//! the run's first tick to its first drive. At the first drive
//! ([`Slam::close_first_turn`]) the closure, weighed against the excess the filter
//! already believed ([`crate::spin_closure::Search::given`]), is taken as a measurement
//! of the gyro's scale and of the heading, and the map is drawn again from the kept scans at
//! headings that share the closure's excess along the turn in proportion to how far each
//! had turned. Only the first turn: later the map holds more than a turn laid. A turn
//! that does not close (not a full turn, its ends not agreeing), one longer than
//! [`FIRST_TURN_SCANS`] scans, one whose gyro was doubted or missing while the motors
//! drove, or a pose from outside changes nothing; a depth scan or a pose the step doubted
//! is not kept, as the step did not map it. The state is the caller's, as
//! [`crate::wall_rate::WallRate`] is, so that the step's own state keeps its layout.

use super::{Localiser, Slam, StepReport};
use crate::angle::{mdeg_of_bits, Angle};
use crate::estimator::{units, MapUncertainty, State};
use crate::frame::{DepthScan, DriveCommand, SensorFrame};
use crate::pose::{mul_q16, Pose, RigidMotion};
use crate::spin_closure::{Closure, ClosureRefusal, Prior, Search, SpinScan};

/// The most scans kept: 15 s of turning at 10 Hz, a full turn at 24 degrees a second
/// and faster.
pub const FIRST_TURN_SCANS: usize = 150;

/// Where a kept scan was ranged from: the position believed at its moment, and the
/// gyro's integral there.
#[derive(Clone, Copy, Default, Debug)]
struct Place {
    x_um: i32,
    y_um: i32,
    turned_mdeg: i32,
}

/// What came of the first turn.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Outcome {
    /// Closed: what the closure adds to the filter's belief taken, and the map drawn
    /// again at the headings the filter then believes. The closure as the turn measured
    /// it.
    Closed(Closure),
    /// Closed, but the closure adds next to nothing to what the filter believed, or the
    /// filter knew the heading better: nothing changed.
    Known(Closure),
    /// The turn did not close ([`ClosureRefusal`]): nothing changed.
    Refused(ClosureRefusal),
    /// The turn was given up before the first drive: nothing changed.
    GivenUp(GiveUp),
}

/// Why the first turn was given up before it could close.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum GiveUp {
    /// The gyro was doubted or missed a tick while the motors were driven: the integral
    /// is not the turn's.
    Doubted,
    /// More scans than are kept before the first drive.
    TooLong,
    /// The pose came from outside, or the core does not match: no map of its own to
    /// draw again.
    NotMatching,
    /// A run resumed after a reset: its map was not laid by a turn kept here.
    Resumed,
}

/// The first turn's kept scans, until its closure.
#[derive(Clone, Debug)]
pub struct FirstTurn {
    /// Whether the turn has ended, and then `outcome` says how. Two fields rather than
    /// an `Option<Outcome>`, whose `None` is not all zero bits: a `static` of a new
    /// `FirstTurn` then lies in zeroed RAM rather than in flash to be copied from.
    ended: bool,
    outcome: Outcome,
    /// The heading believed at the run's start.
    start: Option<Angle>,
    /// The gyro's integral since the start, nanodegrees, as read (no learned scale).
    turned_ndeg: i64,
    scans: [SpinScan; FIRST_TURN_SCANS],
    places: [Place; FIRST_TURN_SCANS],
    kept: usize,
    /// Whether the closure is being searched ([`FirstTurn::search`]), and the kept scans
    /// still in the sweep besides `unkept` newer ones.
    searching: bool,
    unkept: usize,
    search: Search,
}

impl Default for FirstTurn {
    fn default() -> Self {
        Self::new()
    }
}

impl FirstTurn {
    /// A run's start: nothing kept yet.
    pub const fn new() -> FirstTurn {
        FirstTurn {
            ended: false,
            // Unread until `ended`; the variant whose bits are all zero.
            outcome: Outcome::Closed(Closure {
                excess_mdeg: 0,
                turn_mdeg: 0,
                compared: 0,
                sd_mdeg: 0,
            }),
            start: None,
            turned_ndeg: 0,
            scans: [SpinScan::BLIND; FIRST_TURN_SCANS],
            places: [Place {
                x_um: 0,
                y_um: 0,
                turned_mdeg: 0,
            }; FIRST_TURN_SCANS],
            kept: 0,
            searching: false,
            unkept: 0,
            search: Search::new(),
        }
    }

    /// A run resumed after a reset: its turn is not kept (its map was laid before).
    pub fn resume(&mut self) {
        self.end(Outcome::GivenUp(GiveUp::Resumed));
    }

    /// What came of the turn; `None` while it is still kept.
    pub fn outcome(&self) -> Option<Outcome> {
        self.ended.then_some(self.outcome)
    }

    /// Whether the turn is still being kept.
    pub fn keeping(&self) -> bool {
        !self.ended
    }

    /// Ends the turn with `outcome`, letting the kept scans go.
    fn end(&mut self, outcome: Outcome) {
        self.ended = true;
        self.outcome = outcome;
        self.kept = 0;
        self.searching = false;
    }

    /// Searches up to `pieces` more readings of the closure begun at the first drive
    /// ([`Slam::close_first_turn`] with matching deferred, [`Search::search`]); `true`
    /// when nothing is left but to apply it ([`Slam::finish_first_turn`]).
    pub fn search(&mut self, pieces: usize) -> bool {
        if !self.searching {
            return true;
        }
        let scans = self.scans.get(..self.kept).unwrap_or(&[]);
        self.search.search(scans, pieces)
    }

    /// The gyro's turn over one frame, its reading `trusted` or not: `Err` if the turn
    /// cannot be followed, a reading missing or doubted while the motors were driven (or
    /// not known to be still); while they were still, the robot did not turn.
    pub(crate) fn turned(&mut self, frame: &SensorFrame, trusted: bool) -> Result<(), GiveUp> {
        match frame.gyro.filter(|_| trusted) {
            Some(g) => {
                self.turned_ndeg += crate::wall_turn::gyro_turn_ndeg(g.rate_mdps, frame.dt_us);
                Ok(())
            }
            None if frame.dt_us == 0 || frame.commanded == Some(DriveCommand::default()) => Ok(()),
            None => Err(GiveUp::Doubted),
        }
    }

    /// The gyro's integral since the start, millidegrees.
    pub(crate) fn turned_mdeg(&self) -> i64 {
        self.turned_ndeg / 1_000_000
    }

    /// Sets the start's heading from the heading believed now, less the integral so far,
    /// on the first frame the turn is followed in; returns it.
    pub(crate) fn start_at(&mut self, heading_now: Angle) -> Angle {
        let turned = Angle::from_millidegrees(self.turned_mdeg());
        *self.start.get_or_insert_with(|| {
            heading_now.wrapping_add(Angle::from_bits(turned.bits().wrapping_neg()))
        })
    }

    /// Keeps `scan`, ranged at position `(x_um, y_um)` with the gyro's integral
    /// `turned_mdeg` since the start.
    pub(crate) fn keep(
        &mut self,
        scan: &DepthScan,
        (x_um, y_um): (i32, i32),
        turned_mdeg: i32,
    ) -> Result<(), GiveUp> {
        let (Some(s), Some(p)) = (
            self.scans.get_mut(self.kept),
            self.places.get_mut(self.kept),
        ) else {
            return Err(GiveUp::TooLong);
        };
        *s = SpinScan::new(
            Angle::from_millidegrees(i64::from(turned_mdeg)),
            &scan.ranges_mm,
        );
        *p = Place {
            x_um,
            y_um,
            turned_mdeg,
        };
        self.kept += 1;
        Ok(())
    }

    /// The start's heading, once set.
    pub(crate) fn start(&self) -> Option<Angle> {
        self.start
    }

    /// The first `n` kept scans with the position each was ranged from and the gyro's
    /// integral there, millidegrees.
    pub(crate) fn kept(&self, n: usize) -> impl Iterator<Item = (DepthScan, (i32, i32), i32)> + '_ {
        let n = n.min(self.kept);
        let scans = self.scans.get(..n).unwrap_or(&[]);
        let places = self.places.get(..n).unwrap_or(&[]);
        scans.iter().zip(places).map(|(s, p)| {
            (
                DepthScan {
                    ranges_mm: s.ranges_mm(),
                },
                (p.x_um, p.y_um),
                p.turned_mdeg,
            )
        })
    }
}

/// The least deviation a closure's heading is taken with, millidegrees: the slide's own
/// step.
const LEAST_SD_MDEG: i32 = 100;

impl<const W: usize, const H: usize> Slam<W, H> {
    /// Keeps the run's first turn on the spot in `turn` (the caller's, beside
    /// [`Slam::measure_walls`]'s) from the tick `step` took `frame` in, and on the first
    /// tick that drives closes it ([`crate::slam::first_turn`]). Called after every step,
    /// after [`Slam::measure_walls`], off the step; returns `report`, with the pose and
    /// the filter's belief after the closure when there was one.
    #[inline(never)]
    pub fn close_first_turn(
        &mut self,
        turn: &mut FirstTurn,
        frame: &SensorFrame,
        report: StepReport,
    ) -> StepReport {
        if !turn.keeping() {
            return report;
        }
        if self.config.matching.is_none()
            || self.config.localiser != Localiser::Filter
            || frame.external_pose.is_some()
        {
            turn.end(Outcome::GivenUp(GiveUp::NotMatching));
            return report;
        }
        // The tick that drives closes the turn; its scan, ranged off the turn's spot, is
        // not compared with the turn's first.
        let drives = frame.commanded.is_some_and(|c| c.speed_mm_s != 0);
        let heading = self.pose.heading;
        let kept = turn
            .turned(frame, report.trust.gyro.is_none())
            .map(|()| turn.start_at(heading))
            .and_then(|_| match drives {
                // The step mapped a scan only at a pose it vouched for.
                false if report.trust.depth.is_none() && report.trust.pose() => {
                    self.keep_scan(turn, frame)
                }
                _ => Ok(()),
            });
        if let Err(why) = kept {
            turn.end(Outcome::GivenUp(why));
            return report;
        }
        if !drives {
            return report;
        }
        // The step put the tick's scan into the sweep if the pose of its moment is
        // remembered, as every trusted scan.
        turn.unkept =
            usize::from(frame.depth.is_some() && self.history.at(frame.depth_age_us).is_some());
        let scans = turn.scans.get(..turn.kept).unwrap_or(&[]);
        if let Err(why) = turn.search.start(scans, &self.config.depth.beam_angles) {
            turn.end(Outcome::Refused(why));
            return report;
        }
        turn.searching = true;
        if self.defer_matching {
            return report;
        }
        self.finish_first_turn(turn, report)
    }

    /// Applies the first turn's closure once searched ([`FirstTurn::search`]): a caller
    /// that defers matching calls it after [`Slam::close_first_turn`] and the search, on
    /// the same tick. Returns `report` with the pose and the filter's belief after it.
    #[inline(never)]
    pub fn finish_first_turn(&mut self, turn: &mut FirstTurn, report: StepReport) -> StepReport {
        if !turn.searching {
            return report;
        }
        turn.search(usize::MAX);
        let outcome = match turn.search.finish() {
            Ok(closure) => {
                let given = self
                    .believed_excess(turn)
                    .and_then(|prior| turn.search.given(&closure, prior));
                self.close(turn, closure, given)
            }
            Err(why) => Outcome::Refused(why),
        };
        turn.end(outcome);
        match outcome {
            Outcome::Closed(_) => self.with_belief(report),
            _ => report,
        }
    }

    /// The excess the filter believes the turn ran ([`believed_excess`]); `None` before
    /// the start is known.
    fn believed_excess(&self, turn: &FirstTurn) -> Option<Prior> {
        let hh = self
            .estimator
            .covariance()
            .get(State::Heading, State::Heading);
        Some(believed_excess(
            turn.start()?,
            turn.turned_mdeg(),
            self.pose.heading,
            turn.search.turn_mdeg(),
            hh,
        ))
    }

    /// Keeps the frame's depth scan, if the pose of its moment is remembered, with the
    /// gyro's integral there: the integral now less what the pose turned since.
    fn keep_scan(&self, turn: &mut FirstTurn, frame: &SensorFrame) -> Result<(), GiveUp> {
        let (Some(scan), Some(then)) = (&frame.depth, self.history.at(frame.depth_age_us)) else {
            return Ok(());
        };
        let since = mdeg_of_bits(self.pose.heading.diff(then.heading));
        let turned = (turn.turned_mdeg() - since).clamp(i64::from(i32::MIN), i64::from(i32::MAX));
        turn.keep(scan, (then.x_um, then.y_um), turned as i32)
    }

    /// Takes what the kept turn's `closure` adds to the filter's belief (`given`,
    /// [`Search::given`]) as the gyro's scale and the heading, and draws the map again
    /// from the kept scans that have left the sweep; the outcome carries the closure as
    /// the turn measured it.
    fn close(&mut self, turn: &FirstTurn, measured: Closure, given: Option<Closure>) -> Outcome {
        let Some(start) = turn.start() else {
            return Outcome::GivenUp(GiveUp::Doubted);
        };
        let Some(closure) = given else {
            return Outcome::Known(measured);
        };
        // The map drawn again is the closure's: worth it only where the closure knows the
        // heading at least as well as the filter, whose matches laid the map (with tags
        // in view in the turn it knows it better, and the map stands as laid).
        let sd = units::heading_from_mdeg(i64::from(closure.sd_mdeg.max(LEAST_SD_MDEG)));
        let known = self
            .estimator
            .covariance()
            .get(State::Heading, State::Heading);
        if known <= sd.saturating_mul(sd) {
            return Outcome::Known(measured);
        }
        let span = i64::from(closure.turn_mdeg.unsigned_abs().max(1));
        let sd_ppm = i64::from(closure.sd_mdeg) * 1_000_000 / span;
        let then = self.pose;
        if let Ok(corrected) = self.estimator.apply_gyro_scale(
            &then,
            closure.scale_ppm(),
            sd_ppm.clamp(1, i64::from(i32::MAX)) as i32,
        ) {
            self.carry_past(&RigidMotion::carrying(&then, &corrected));
        }
        self.estimator.settle();
        // The turn since the start as the closure has it: the integral less its share of
        // the excess.
        let turned = turn.turned_mdeg();
        let closed =
            turned - turned.signum() * (turned.abs() * i64::from(closure.excess_mdeg) / span);
        let then = self.pose;
        let off = mdeg_of_bits(
            start
                .wrapping_add(Angle::from_millidegrees(closed))
                .diff(then.heading),
        );
        if let Ok(corrected) =
            self.estimator
                .apply_heading(&then, off as i32, closure.sd_mdeg.max(LEAST_SD_MDEG))
        {
            self.carry_past(&RigidMotion::carrying(&then, &corrected));
        }
        self.estimator.settle();
        // The turn the filter now believes, shared along the kept scans by their integral.
        let integral_now = start.wrapping_add(Angle::from_millidegrees(turned));
        let believed = turned + mdeg_of_bits(self.pose.heading.diff(integral_now));
        let in_sweep = self.sweep.len().saturating_sub(turn.unkept);
        self.map.clear();
        for (scan, (x_um, y_um), at) in turn.kept(turn.kept.saturating_sub(in_sweep)) {
            let share = match turned {
                0 => i64::from(at),
                t => i64::from(at) * believed / t,
            };
            let pose = Pose {
                x_um,
                y_um,
                heading: start.wrapping_add(Angle::from_millidegrees(share)),
            };
            self.map_scan(&scan, &pose);
        }
        self.map_uncertainty = MapUncertainty::drawn_at(&self.estimator);
        Outcome::Closed(measured)
    }
}

/// The excess a filter believes a turn ran, along the turn, over the `searched_mdeg` the
/// closure is searched on, and its deviation: the gyro's integral since the `start`
/// (`turned_mdeg`, either way) less the turn the filter's `heading` makes of it, which its
/// heading's variance `heading_var` (the filter's units, 2^-16 rad) bounds. That variance
/// holds the start's too, so the prior is if anything wider than the filter's belief of
/// the excess.
fn believed_excess(
    start: Angle,
    turned_mdeg: i64,
    heading: Angle,
    searched_mdeg: i32,
    heading_var: i64,
) -> Prior {
    let integral_now = start.wrapping_add(Angle::from_millidegrees(turned_mdeg));
    // How far the integral ran past the filter's heading along the turn (the closure's
    // excess is measured along it, whichever way it turned); over the searched turn in
    // proportion.
    let past = -mdeg_of_bits(heading.diff(integral_now)) * turned_mdeg.signum();
    let searched = i64::from(searched_mdeg).abs();
    let excess = match turned_mdeg.abs() {
        0 => past,
        t => past * searched / t,
    };
    let sd = mul_q16(
        (heading_var.max(0) as u64).isqrt() as i64,
        units::MDEG_PER_HEADING_Q16,
    );
    Prior {
        excess_mdeg: excess.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32,
        sd_mdeg: sd.clamp(1, i64::from(i32::MAX)) as i32,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A turn's excess is along the turn, whichever way it turned: a gyro that ran 3
    /// degrees past a filter's heading over a full turn either way is an excess of +3
    /// degrees; one that fell 2 short, -2, and over a closure searched on half the turn,
    /// -1.
    #[test]
    fn the_believed_excess_runs_along_the_turn_either_way() {
        let start = Angle::from_millidegrees(40_000);
        let var = 1 << 20; // (1024 units: 895 mdeg)^2
        for way in [1, -1] {
            let heading = start.wrapping_add(Angle::from_millidegrees(way * 362_000));
            let past = believed_excess(start, way * 365_000, heading, (way * 365_000) as i32, var);
            assert!((past.excess_mdeg - 3_000).abs() <= 1, "{way}: {past:?}");
            assert!((past.sd_mdeg - 895).abs() <= 1, "{way}: {past:?}");
            let short = believed_excess(start, way * 360_000, heading, (way * 180_000) as i32, var);
            assert!((short.excess_mdeg + 1_000).abs() <= 1, "{way}: {short:?}");
        }
    }
}
