//! Scan-to-map matching: where the last second of depth beams fits the map best, and how
//! sure that is.
//!
//! - `sweep`: the last ticks' scans, placed relative to each other by the odometry;
//! - `divide`: floor division by a number fixed for the search, without a divide;
//! - `score`: what a beam end scores in an occupied, a free or an unknown cell;
//! - `runs`: where the window's translations cross cell lines;
//! - `footprint`: the coarse level, the cells each end can reach over the window and
//!   their maximum;
//! - `search`: the fine level, every candidate pose by lookups and adds;
//! - `spread`: the ends' interpolated scores added over the translations;
//! - `surface`: the pose, covariance and unpinned directions the scores show.
//!
//! **Correlative, not Gauss-Newton.** A correlative search (Olson 2009, "Real-time
//! correlative scan matching"; Cartographer's real-time correlative matcher) scores every
//! pose of a small window by table lookups and integer adds, which the M0+ does in a cycle
//! or two each, with a cost known before it starts; and its score surface is a covariance
//! for free, flat where the sweep cannot tell poses apart. Gauss-Newton on an interpolated
//! grid (Hector) needs gradients, products and a 3 x 3 solve per iteration in fixed
//! point, a number of iterations nobody can bound, and a Hessian that says nothing honest
//! about a corridor. With 5 cm cells and a 1 cm step the window of +-3 cm is about one
//! cell wide, so each beam end's few cells are looked up once, and again only when a
//! heading moves the end into another cell (`footprint`), and spread over the
//! translations (`spread`).
//!
//! **The window.** Ten ticks (one second) of scans make one sweep ([`SWEEP_TICKS`]): see
//! there. The search is [`SIDE`] steps along x and y and [`TURNS`] headings: 7 x 7 x 17
//! (+-3 cm in 1 cm steps, +-4 degrees in half-degree steps).
//!
//! **In pieces.** A match takes milliseconds on the M0+, which must not hold up the tasks
//! that read the sensors: [`Matcher::start`], then [`Matcher::search`] a few headings at a
//! time (the caller may yield between), then [`Matcher::finish`]. The map must not change
//! in between. [`Matcher::match_sweep`] does all three at once. None of it is generic over
//! the grid's size (the map is read through a [`GridView`]), so it is compiled in this
//! crate at this crate's optimisation.
//!
//! **The map's edge.** The map lags the sweep, so a sweep's newest ends run past the walls
//! mapped so far: along a wall driven beside, round a turn on the spot. Pulling them back
//! onto those walls scores, and the surface rises towards the window's edge whatever the
//! truth. A surface whose best lies on a face of the window pins nothing along the
//! direction it rises (`surface::Rising`).
//!
//! **Evidence kept apart.** A sweep matched against the beams it has just written matches
//! itself. With matching on, a scan is written into the map only when it leaves the sweep,
//! at its pose as every match since has corrected it: the map never holds a beam that the
//! sweep matched against it. The map lags the robot by a second, which costs a second of
//! mapping at the start and nothing after.
//!
//! **The result** carries the tick of the sweep's newest scan: the pose it gives is that
//! tick's, so a match computed later (on the other core) is applied at that moment
//! through the pose history, as a tag picture is.

mod divide;
mod footprint;
mod runs;
mod score;
mod search;
mod spread;
mod surface;
mod sweep;

pub use footprint::FOOTPRINT;
pub use score::EndpointScores;

use footprint::{Footprint, Window};
use score::ScoreTable;
pub use search::ENDS_A_PIECE;
pub use sweep::{Sweep, SweepPoint, SweepScan, SWEEP_TICKS};

use core::mem::MaybeUninit;
use core::ptr::addr_of_mut;

use crate::angle::Angle;
use crate::frame::BEAMS;
use crate::grid::GridView;
use crate::pose::Pose;
use search::Surface;

/// Most beam ends a sweep of [`SWEEP_TICKS`] ticks holds.
pub const SWEEP_POINTS: usize = SWEEP_TICKS * BEAMS;

/// Translations searched along each axis: +-3 cm in the seed's 1 cm steps.
pub const SIDE: usize = 7;

/// Headings searched: +-4 degrees in the seed's half-degree steps. A spin on the spot that
/// comes back to walls mapped a turn before finds them turned by the gyro's scale error
/// (up to 3.6 degrees a turn at 1 %), inside the window rather than on its edge.
pub const TURNS: usize = 17;

// Odd (the prediction in the middle), at least 3, and small enough for the footprint's
// byte indices and the moments' 32-bit products.
const _: () = assert!(SIDE >= 3 && SIDE % 2 == 1 && SIDE <= 255);
const _: () = assert!(TURNS >= 3 && TURNS % 2 == 1 && TURNS <= 255);

/// The search's steps, scores and thresholds.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MatcherConfig {
    /// Translation step, millimetres.
    pub step_mm: i32,
    /// Heading step, millidegrees.
    pub step_mdeg: i32,
    /// Beam ends at or past this range are not matched, millimetres. Longer than the
    /// mapping range: a far wall mapped earlier from nearer still pins the pose.
    pub max_range_mm: u16,
    /// A sweep with fewer ends than this is refused.
    pub min_points: u16,
    /// Scores of a beam end by its cell's class.
    pub scores: EndpointScores,
    /// The score drop that halves a candidate's weight in the surface: the larger, the
    /// wider (more cautious) the covariance.
    pub halving: i32,
    /// A position direction whose spread reaches this share of the whole window's, in per
    /// cent, is not pinned.
    pub unpinned_pct: u8,
    /// The same for the heading, of the heading window's spread: the seed's 20 % of
    /// +-4 degrees leaves a heading whose deviation reaches 1.1 degrees unpinned.
    pub unpinned_heading_pct: u8,
}

impl MatcherConfig {
    /// The seed's matcher.
    pub const SEED: MatcherConfig = MatcherConfig {
        step_mm: 10,
        step_mdeg: 500,
        max_range_mm: 4000,
        min_points: 12,
        scores: EndpointScores::SEED,
        halving: 4,
        unpinned_pct: 20,
        unpinned_heading_pct: 20,
    };
}

impl Default for MatcherConfig {
    fn default() -> Self {
        Self::SEED
    }
}

/// A matcher configuration or window the matcher cannot run.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum MatcherConfigError {
    /// Steps must be positive, and the translation window no wider than
    /// [`FOOTPRINT`] - 2 cells.
    Step,
    /// The halving must be positive.
    Halving,
}

/// What a match pins.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Pins {
    /// Position and heading.
    All,
    /// Heading, and position across a line but not along it: one flat wall, a corridor.
    AllButAlong(Angle),
    /// Position across a line only, not the heading.
    AcrossOnly(Angle),
    /// Position, not the heading.
    PositionOnly,
    /// Heading only.
    HeadingOnly,
}

impl Pins {
    /// These pins less the position along `rising` (a line); `wide` is the line the
    /// position was already unpinned along, if it was. Two lines apart by more than an
    /// eighth of a turn leave no position pinned.
    fn unpinning(self, rising: Angle, wide: Angle) -> Result<Pins, MatchRefusal> {
        // Lines: within an eighth of a turn of each other, or of each other reversed.
        let apart = (rising - wide).signed_bits().unsigned_abs();
        let eighth = 1u32 << 29;
        let near = apart <= eighth || apart >= (1u32 << 31) - eighth;
        Ok(match self {
            Pins::All => Pins::AllButAlong(rising),
            Pins::PositionOnly => Pins::AcrossOnly(rising),
            Pins::AllButAlong(_) if near => Pins::AllButAlong(rising),
            Pins::AcrossOnly(_) if near => Pins::AcrossOnly(rising),
            Pins::AllButAlong(_) | Pins::HeadingOnly => Pins::HeadingOnly,
            Pins::AcrossOnly(_) => return Err(MatchRefusal::NothingPinned),
        })
    }

    /// These pins less the heading.
    fn without_heading(self) -> Result<Pins, MatchRefusal> {
        match self {
            Pins::All | Pins::PositionOnly => Ok(Pins::PositionOnly),
            Pins::AllButAlong(line) | Pins::AcrossOnly(line) => Ok(Pins::AcrossOnly(line)),
            Pins::HeadingOnly => Err(MatchRefusal::NothingPinned),
        }
    }
}

/// Why a sweep gave no match.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum MatchRefusal {
    /// No scan in the sweep had a beam end.
    EmptySweep,
    /// Fewer beam ends than [`MatcherConfig::min_points`].
    TooFewPoints,
    /// No candidate scored above zero: the ends fall on nothing the map knows.
    NoFit,
    /// The surface pins no direction.
    NothingPinned,
    /// The window spans more cells than the footprint holds.
    Window,
    /// The filter found the match beyond its chi-square gate.
    Gate,
    /// The sweep's newest scan is older than the pose history reaches.
    TooOld,
}

/// The match's covariance: position in micrometres, heading in millidegrees (clockwise
/// positive, as the heading).
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MatchCovariance {
    /// Variance of x, um^2.
    pub xx_um2: i64,
    /// Covariance of x and y, um^2.
    pub xy_um2: i64,
    /// Variance of y, um^2.
    pub yy_um2: i64,
    /// Covariance of x and heading, um mdeg.
    pub xh_um_mdeg: i64,
    /// Covariance of y and heading, um mdeg.
    pub yh_um_mdeg: i64,
    /// Variance of the heading, mdeg^2.
    pub hh_mdeg2: i64,
}

/// The work a match did: what the cost is made of.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MatchStats {
    /// Beam ends matched.
    pub points: u32,
    /// Grid cells looked up.
    pub lookups: u32,
    /// Ends' scores added over the translations: the translations each end that scores
    /// reaches, whether spread on its own or summed with others first (`spread`).
    pub adds: u32,
    /// Headings whose translations were all scored.
    pub headings_searched: u32,
    /// Headings skipped on their bound.
    pub headings_pruned: u32,
}

/// Where the sweep fits, for the tick of its newest scan.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Match {
    /// The tick of the sweep's newest scan: the moment `pose` is for.
    pub tick: u32,
    /// The pose the prediction was, at that tick.
    pub prediction: Pose,
    /// The surface's weighted mean: the matched pose at that tick.
    pub pose: Pose,
    /// The surface's spread about it.
    pub covariance: MatchCovariance,
    /// The directions it pins; the covariance along the others is the window's.
    pub pins: Pins,
    /// The direction (a line, within a quarter turn of +y) of the position's wider
    /// spread: the position's covariance has no cross term along it and across it.
    pub wide: Angle,
    /// The best candidate's score and the lowest one computed.
    pub best_score: i32,
    /// See `best_score`.
    pub worst_score: i32,
    /// The work done.
    pub stats: MatchStats,
}

/// A match in progress: the sweep's ends and what the search has found so far.
#[derive(Clone, Debug)]
struct Work {
    points: [SweepPoint; SWEEP_POINTS],
    count: usize,
    /// The tick of the sweep's newest scan, and the pose believed then.
    tick: u32,
    prediction: Pose,
    progress: search::Progress,
    /// What the search works out once, when it first sees the map.
    setup: Option<search::Setup>,
    /// Each end's footprints, either side of the prediction's heading.
    feet: [[Footprint; 2]; SWEEP_POINTS],
}

/// A correlative matcher over [`SIDE`] x [`SIDE`] translations and [`TURNS`] headings,
/// with its score surface and the ends' sums as scratch (no allocation).
#[derive(Clone, Debug)]
pub struct Matcher {
    config: MatcherConfig,
    cell_mm: i32,
    surface: Surface<SIDE, TURNS>,
    /// The heading in hand's ends, summed by the patterns of their runs.
    patterns: spread::Patterns,
    /// The match in progress, when `live`. Kept in place rather than as an
    /// `Option<Work>`: a new one built whole would pass through the stack and be copied
    /// in at every match's start.
    work: Work,
    live: bool,
}

impl Work {
    /// Writes an idle work area at `w`, its arrays element by element.
    ///
    /// # Safety
    /// `w` is aligned and valid for writes.
    #[allow(unsafe_code)]
    unsafe fn write_idle(w: *mut Work) {
        // SAFETY: the caller's `w`; each array element and field is written once, in
        // place, and the check after this impl names every field.
        unsafe {
            let points = addr_of_mut!((*w).points).cast::<SweepPoint>();
            for i in 0..SWEEP_POINTS {
                points.add(i).write(SweepPoint::default());
            }
            addr_of_mut!((*w).count).write(0);
            addr_of_mut!((*w).tick).write(0);
            addr_of_mut!((*w).prediction).write(Pose::default());
            addr_of_mut!((*w).progress).write(search::Progress::new(0));
            addr_of_mut!((*w).setup).write(None);
            let feet = addr_of_mut!((*w).feet).cast::<[Footprint; 2]>();
            for i in 0..SWEEP_POINTS {
                feet.add(i).write([Footprint::EMPTY; 2]);
            }
        }
    }
}

/// Builds only while [`Matcher::new_in`] and [`Work::write_idle`] write every field: a
/// field added to either struct stops the build here until it is written there too.
const _: fn(Matcher, Work) = |m, w| {
    let Matcher {
        config: _,
        cell_mm: _,
        surface: _,
        patterns: _,
        work: _,
        live: _,
    } = m;
    let Work {
        points: _,
        count: _,
        tick: _,
        prediction: _,
        progress: _,
        setup: _,
        feet: _,
    } = w;
};

impl Matcher {
    /// A matcher, once its configuration is checked against `cell_mm`.
    pub fn new(config: MatcherConfig, cell_mm: i32) -> Result<Self, MatcherConfigError> {
        let mut slot = MaybeUninit::uninit();
        Self::new_in(&mut slot, config, cell_mm)?;
        // SAFETY: `new_in` wrote every field (it returned `Ok`).
        #[allow(unsafe_code)]
        Ok(unsafe { slot.assume_init() })
    }

    /// [`Matcher::new`] built in `slot`, field by field and its arrays element by element:
    /// never whole on the stack, where a robot's few tens of kilobytes cannot hold it twice.
    #[allow(unsafe_code)]
    pub fn new_in(
        slot: &mut MaybeUninit<Self>,
        config: MatcherConfig,
        cell_mm: i32,
    ) -> Result<&mut Self, MatcherConfigError> {
        let span = (SIDE as i32 - 1).saturating_mul(config.step_mm);
        if config.step_mm < 1
            || config.step_mdeg < 1
            || cell_mm < 1
            || span > (FOOTPRINT as i32 - 2) * cell_mm
        {
            return Err(MatcherConfigError::Step);
        }
        if config.halving < 1 {
            return Err(MatcherConfigError::Halving);
        }
        let m = slot.as_mut_ptr();
        // SAFETY: every field of `*m` is written once, through raw pointers into `slot`
        // (no reference to the unwritten whole is made); the check after `Work::write_idle`
        // names them. The surface is `i32`s, for which zero bytes are a valid value.
        unsafe {
            addr_of_mut!((*m).config).write(config);
            addr_of_mut!((*m).cell_mm).write(cell_mm);
            addr_of_mut!((*m).surface).write_bytes(0, 1);
            addr_of_mut!((*m).patterns).write(spread::Patterns::EMPTY);
            Work::write_idle(addr_of_mut!((*m).work));
            addr_of_mut!((*m).live).write(false);
            Ok(slot.assume_init_mut())
        }
    }

    /// Headings searched at most.
    pub const HEADINGS: usize = TURNS;

    /// The configuration in use.
    pub fn config(&self) -> &MatcherConfig {
        &self.config
    }

    /// Matches `sweep` against `map` around its newest scan's pose, taken as the
    /// prediction: [`Matcher::start`], [`Matcher::search`] and [`Matcher::finish`] at once.
    pub fn match_sweep(
        &mut self,
        sweep: &Sweep<SWEEP_TICKS>,
        beam_angles: &[Angle; BEAMS],
        map: &GridView,
    ) -> Result<Match, MatchRefusal> {
        self.start(sweep, beam_angles)?;
        self.search(map, usize::MAX)?;
        self.finish()
    }

    /// Matches beam ends given relative to `prediction` (the pose at `tick`) against
    /// `map`, all at once.
    pub fn match_points(
        &mut self,
        points: &[SweepPoint],
        prediction: &Pose,
        tick: u32,
        map: &GridView,
    ) -> Result<Match, MatchRefusal> {
        self.start_points(points, prediction, tick)?;
        self.search(map, usize::MAX)?;
        self.finish()
    }

    /// Starts matching `sweep`, around its newest scan's pose; forgets any match in
    /// progress. Refuses a sweep with no end, or too few.
    #[inline(never)]
    pub fn start(
        &mut self,
        sweep: &Sweep<SWEEP_TICKS>,
        beam_angles: &[Angle; BEAMS],
    ) -> Result<(), MatchRefusal> {
        self.live = false;
        let Some(newest) = sweep.newest() else {
            return Err(MatchRefusal::EmptySweep);
        };
        let (tick, prediction) = (newest.tick, newest.pose);
        let mut points = [SweepPoint::default(); SWEEP_POINTS];
        let n = sweep.points(beam_angles, self.config.max_range_mm, &mut points);
        self.begin(points, n, prediction, tick)
    }

    /// Starts matching beam ends given relative to `prediction`, the pose at `tick`.
    fn start_points(
        &mut self,
        points: &[SweepPoint],
        prediction: &Pose,
        tick: u32,
    ) -> Result<(), MatchRefusal> {
        self.live = false;
        let mut kept = [SweepPoint::default(); SWEEP_POINTS];
        let mut n = 0;
        for (slot, p) in kept.iter_mut().zip(points) {
            *slot = *p;
            n += 1;
        }
        self.begin(kept, n, *prediction, tick)
    }

    fn begin(
        &mut self,
        points: [SweepPoint; SWEEP_POINTS],
        count: usize,
        prediction: Pose,
        tick: u32,
    ) -> Result<(), MatchRefusal> {
        if count == 0 {
            return Err(MatchRefusal::EmptySweep);
        }
        if count < usize::from(self.config.min_points) {
            return Err(MatchRefusal::TooFewPoints);
        }
        let work = &mut self.work;
        work.points = points;
        work.count = count;
        work.tick = tick;
        work.prediction = prediction;
        work.progress = search::Progress::new(count);
        work.setup = None;
        for feet in work.feet.iter_mut() {
            *feet = [Footprint::EMPTY; 2];
        }
        self.live = true;
        Ok(())
    }

    /// Whether the match in progress has every heading searched.
    pub fn searched(&self) -> bool {
        self.live && self.work.progress.headings >= TURNS
    }

    /// Whether a match is started and not yet finished.
    pub fn in_progress(&self) -> bool {
        self.live
    }

    /// Does up to `pieces` more pieces of the match in progress against `map`, which
    /// must be the map it started against and unchanged since: a heading's bound, or its
    /// translations for [`ENDS_A_PIECE`] beam ends. `Ok(true)` once every heading is
    /// searched (or none is in progress).
    #[inline(never)]
    pub fn search(&mut self, map: &GridView, pieces: usize) -> Result<bool, MatchRefusal> {
        if !self.live {
            return Ok(true);
        }
        let work = &mut self.work;
        if work.setup.is_none() {
            let cell = map.geometry().cell_mm;
            let Some(window) = Window::new(SIDE, self.config.step_mm, cell) else {
                self.live = false;
                return Err(MatchRefusal::Window);
            };
            work.setup = Some(search::Setup {
                table: ScoreTable::new(&self.config.scores, map.evidence()),
                window,
                cutoff: surface::cutoff(self.config.halving.saturating_mul(cell * cell)),
            });
        }
        let Some(setup) = work.setup.as_ref() else {
            return Err(MatchRefusal::Window);
        };
        let count = work.count.min(SWEEP_POINTS);
        let mut search = search::Search {
            map,
            setup,
            points: work.points.get(..count).unwrap_or(&[]),
            feet: work.feet.get_mut(..count).unwrap_or(&mut []),
            prediction: &work.prediction,
            config: &self.config,
            patterns: &mut self.patterns,
        };
        for _ in 0..pieces {
            match search.piece(&mut self.surface, &mut work.progress) {
                Some(false) => {}
                Some(true) => return Ok(true),
                None => {
                    self.live = false;
                    return Err(MatchRefusal::Window);
                }
            }
        }
        Ok(work.progress.headings >= TURNS)
    }

    /// The match, from the surface the search filled; ends the match in progress.
    #[inline(never)]
    pub fn finish(&mut self) -> Result<Match, MatchRefusal> {
        if !core::mem::take(&mut self.live) {
            return Err(MatchRefusal::EmptySweep);
        }
        let work = &self.work;
        if work.progress.headings < TURNS {
            return Err(MatchRefusal::Window);
        }
        let c = &self.config;
        // The surface is in class score times cells squared (the interpolation's weights).
        let cell = self.cell_mm;
        let halving = c.halving.saturating_mul(cell * cell);
        let m = surface::moments(&self.surface, halving).ok_or(MatchRefusal::NoFit)?;
        if m.best <= 0 {
            return Err(MatchRefusal::NoFit);
        }
        let pins = self.pins(&m.covariance_q16, m.best == m.worst)?;
        let wide = surface::spread(&m.covariance_q16).wide.1;
        let rising = surface::rising(&self.surface, &m.peak);
        let (pins, wide) = match rising.position {
            Some(line) => (pins.unpinning(line, wide)?, line),
            None => (pins, wide),
        };
        let pins = if rising.heading {
            pins.without_heading()?
        } else {
            pins
        };

        let prediction = work.prediction;
        let (step_um, step_mdeg) = (i64::from(c.step_mm) * 1000, i64::from(c.step_mdeg));
        let q8 = |v: i32, unit: i64| (i64::from(v) * unit + 128) >> 8;
        let dx = q8(m.mean_q8[0], step_um);
        let dy = q8(m.mean_q8[1], step_um);
        let dh = q8(m.mean_q8[2], step_mdeg);
        let pose = Pose {
            x_um: prediction.x_um.saturating_add(dx as i32),
            y_um: prediction.y_um.saturating_add(dy as i32),
            heading: prediction.heading + Angle::from_millidegrees(dh),
        };
        let q = &m.covariance_q16;
        let q16 = |v: i64, a: i64, b: i64| (v * a / 256) * b / 256;
        let covariance = MatchCovariance {
            xx_um2: q16(q[0][0], step_um, step_um),
            xy_um2: q16(q[0][1], step_um, step_um),
            yy_um2: q16(q[1][1], step_um, step_um),
            xh_um_mdeg: q16(q[0][2], step_um, step_mdeg),
            yh_um_mdeg: q16(q[1][2], step_um, step_mdeg),
            hh_mdeg2: q16(q[2][2], step_mdeg, step_mdeg),
        };
        Ok(Match {
            tick: work.tick,
            prediction,
            pose,
            covariance,
            pins,
            wide,
            best_score: m.best,
            worst_score: m.worst,
            stats: work.progress.stats,
        })
    }

    /// The directions the surface's covariance (Q16 steps squared) pins.
    fn pins(&self, c: &[[i64; 3]; 3], flat: bool) -> Result<Pins, MatchRefusal> {
        if flat {
            return Err(MatchRefusal::NothingPinned);
        }
        let share = i64::from(self.config.unpinned_pct);
        let heading_share = i64::from(self.config.unpinned_heading_pct);
        let position_limit = surface::uniform_q16((SIDE / 2) as i64) * share / 100;
        let heading_limit = surface::uniform_q16((TURNS / 2) as i64) * heading_share / 100;
        let spread = surface::spread(c);
        let heading = c[2][2] < heading_limit;
        let (wide, along) = spread.wide;
        let pins = match (
            spread.narrow < position_limit,
            wide < position_limit,
            heading,
        ) {
            (true, true, true) => Pins::All,
            (true, true, false) => Pins::PositionOnly,
            (true, false, true) => Pins::AllButAlong(along),
            (true, false, false) => Pins::AcrossOnly(along),
            (false, _, true) => Pins::HeadingOnly,
            (false, _, false) => return Err(MatchRefusal::NothingPinned),
        };
        Ok(pins)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const ALONG_X: Angle = Angle::QUARTER_TURN;

    #[test]
    fn a_rising_line_unpins_the_position_along_it() {
        assert_eq!(
            Pins::All.unpinning(ALONG_X, Angle::ZERO),
            Ok(Pins::AllButAlong(ALONG_X))
        );
        assert_eq!(
            Pins::PositionOnly.unpinning(ALONG_X, Angle::ZERO),
            Ok(Pins::AcrossOnly(ALONG_X))
        );
        // Already unpinned along nearly the same line: the same pins, the rising line.
        let near = ALONG_X + Angle::from_millidegrees(20_000);
        assert_eq!(
            Pins::AllButAlong(near).unpinning(ALONG_X, near),
            Ok(Pins::AllButAlong(ALONG_X))
        );
        // Along another line: no position left.
        assert_eq!(
            Pins::AllButAlong(Angle::ZERO).unpinning(ALONG_X, Angle::ZERO),
            Ok(Pins::HeadingOnly)
        );
        assert_eq!(
            Pins::AcrossOnly(Angle::ZERO).unpinning(ALONG_X, Angle::ZERO),
            Err(MatchRefusal::NothingPinned)
        );
    }

    #[test]
    fn a_rising_heading_unpins_the_heading() {
        assert_eq!(Pins::All.without_heading(), Ok(Pins::PositionOnly));
        assert_eq!(
            Pins::AllButAlong(ALONG_X).without_heading(),
            Ok(Pins::AcrossOnly(ALONG_X))
        );
        assert_eq!(
            Pins::HeadingOnly.without_heading(),
            Err(MatchRefusal::NothingPinned)
        );
    }
}
