//! The gyro against the walls: a turn the depth sensor does not see.
//!
//! A gyro whose bias jumps while the robot drives straight reads a slow turn that two
//! wheels off their command could have made, so the motors' commands cannot catch it
//! ([`crate::commanded`]); with no tag in view nothing else would, and the map is drawn
//! turned from then on. A flat wall in the fan can: its normal's bearing from the nose
//! ([`WallFit::tilt`]) falls by exactly as much as the robot turns clockwise, however it
//! drives. So while no turn is commanded (a scan's moment and its tick's then differ by
//! no turn) each tick on one wall gives the wall's tilt plus the gyro's turn since the
//! wall was first fitted, which stays put unless the gyro turns where the robot does
//! not. The newest [`WINDOW`] ticks' mean is held to the first ticks' mean; more than
//! [`TURN_LIMIT_MDEG`] apart on [`TICKS_TO_DOUBT`] ticks running and the gyro is doubted,
//! and the walls say by how much its turn was wrong.
//!
//! The fits' noise sets the limits: a wall at least [`NEAREST_WALL_MM`] away, fitted to
//! [`FEWEST_ENDS`] ends within [`MOST_STRAY_MM`] of their line, has its tilt within a few
//! tenths of a degree a tick. Another wall coming into the fan (a box's side, a corner)
//! moves the fitted tilt or distance at once, where a lying gyro moves the estimate a
//! few tenths of a degree a tick: such a tick starts again from the new wall. A tick
//! with no fit good enough (an end lost, a loose fit) still counts the gyro's turn, so
//! that what it turned before is not forgotten; only a gyro that cannot be checked (a
//! turn commanded, a doubt) or a wall gone for long starts again.
//!
//! The turn back when the gyro is found out carries the newest ticks' noise and lag. The
//! robot is then held still, its gyro doubted, so every tick's tilt is the same: averaged
//! over [`HELD_TICKS`] on the same wall it gives the gyro's turn past the wall again to a
//! tenth of a degree or so ([`WallTurn::held`]).

use crate::angle::Angle;
use crate::wall_rate::WallFit;

/// How far the walls' turn and the gyro's may part before the gyro is doubted,
/// millidegrees.
pub const TURN_LIMIT_MDEG: i32 = 1_500;

/// How many ticks' fits are averaged on each side of the comparison: the first ticks on
/// a wall against the newest.
pub const WINDOW: usize = 5;

/// How many ticks running they must part by [`TURN_LIMIT_MDEG`].
pub const TICKS_TO_DOUBT: u8 = 3;

/// How far a wall's fitted tilt may move in a tick beyond what the gyro turned, and its
/// distance move, and still be the same wall: the tick-to-tick scatter of a plane's fit
/// (about four deviations of it), and for each tick since the last fit what a gyro
/// lying within the drive's slack against its command (5 deg/s) adds. A fit that leaps
/// further is of another surface, or of two at once whose share of the fan changes as
/// the robot drives.
const SAME_WALL_MDEG: i32 = 2_000;
const UNFITTED_MDEG: i32 = 500;
const SAME_WALL_MM: i32 = 60;

/// How many ticks running the wall may go unfitted (an end lost, a loose fit) while the
/// gyro's turn is still counted, before the check starts again.
const MOST_UNFITTED: u8 = 5;

/// The nearest wall held to the gyro, millimetres: nearer, the fan's ends span too
/// little of it for its tilt to be known within a degree.
pub const NEAREST_WALL_MM: i32 = 800;

/// The fewest ends of a wall held to the gyro.
pub const FEWEST_ENDS: u8 = 7;

/// The most a wall's ends may stray from their line (root mean square, millimetres) for
/// it to be held to the gyro: a fit the wall-rate check takes may hold ends of two
/// surfaces a few millimetres apart, which tilt it by degrees.
pub const MOST_STRAY_MM: u16 = 7;

/// The wall the check is holding the gyro to. Each tick on it gives the wall's tilt
/// since its first fit plus the gyro's turn since, millidegrees: the same on every
/// tick, but for the fits' noise, while the gyro turns as the robot does.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
struct Reference {
    first_tilt: Angle,
    last_tilt: Angle,
    last_mm: i32,
    /// The gyro's turn since the first fit, nanodegrees clockwise, and its turn since
    /// the last fit.
    gyro_turn_ndeg: i64,
    since_last_ndeg: i64,
    /// Ticks running with no fit.
    unfitted: u8,
    /// Ticks on this wall.
    ticks: u32,
    /// The sum of the first [`WINDOW`] ticks' values, and the newest ticks' in a ring.
    first_sum: i32,
    newest: [i32; WINDOW],
}

impl Reference {
    fn at(wall: &WallFit) -> Reference {
        Reference {
            first_tilt: wall.tilt,
            last_tilt: wall.tilt,
            last_mm: wall.distance_mm,
            gyro_turn_ndeg: 0,
            since_last_ndeg: 0,
            unfitted: 0,
            ticks: 1,
            first_sum: 0,
            newest: [0; WINDOW],
        }
    }
}

/// How many ticks of a robot held still the wall's tilt is averaged over, once the gyro
/// is found out, to turn the heading back again more exactly ([`WallTurn::held`]).
pub const HELD_TICKS: u32 = 10;

/// The fewest such ticks worth a second turn back, when the gyro is trusted again sooner.
const FEWEST_HELD_TICKS: u32 = 3;

/// What a gyro found out leaves to be mended once the robot stands: the wall it was
/// found on, how far the heading was turned back, and the tilt while the robot stands.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
struct Held {
    first_tilt: Angle,
    /// The first ticks' mean value, millidegrees.
    first_mdeg: i32,
    /// The gyro's turn from the first fit until it was found out, millidegrees.
    gyro_mdeg: i32,
    /// How far the heading was turned back then, millidegrees.
    turned_back_mdeg: i32,
    last_mm: i32,
    /// The tilts since, less the first, millidegrees, summed; and how many.
    tilt_sum_mdeg: i32,
    ticks: u32,
}

/// The check's state across ticks (the caller's, beside [`crate::wall_rate::WallRate`]).
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default)]
pub struct WallTurn {
    /// Times the gyro was found turning where the walls did not.
    pub found: u32,
    reference: Option<Reference>,
    /// Ticks running the walls and the gyro have parted.
    parted: u8,
    held: Option<Held>,
}

/// The gyro's turn over a tick, nanodegrees clockwise, from its (calibrated) rate in
/// millidegrees a second over `dt_us`.
pub fn gyro_turn_ndeg(rate_mdps: i32, dt_us: u32) -> i64 {
    i64::from(rate_mdps) * i64::from(dt_us)
}

impl WallTurn {
    /// No wall held (for a `static`).
    pub const fn new() -> WallTurn {
        WallTurn {
            found: 0,
            reference: None,
            parted: 0,
            held: None,
        }
    }

    /// Forgets the wall held, keeping the count.
    fn start(&mut self, wall: Option<&WallFit>) {
        self.reference = wall.map(Reference::at);
        self.parted = 0;
    }

    /// Takes a tick: `wall`, fitted to its scan (`None`: no fit, or the depth sensor
    /// doubted; the wall held is kept for up to five such ticks running), and
    /// `gyro_ndeg`, the gyro's turn over it (`None` when the gyro cannot be checked: a
    /// doubt, a turn commanded; the check starts again). Returns how much further
    /// clockwise the gyro turned than the walls (the newest ticks' mean against the first
    /// ticks') once they have parted on [`TICKS_TO_DOUBT`] ticks running; the check then
    /// waits for the robot to stand ([`WallTurn::held`]) and starts again from the next
    /// wall.
    pub fn observe(&mut self, wall: Option<WallFit>, gyro_ndeg: Option<i64>) -> Option<Angle> {
        self.held = None;
        let wall = wall.filter(fits_well);
        let Some(turn) = gyro_ndeg else {
            self.start(None);
            return None;
        };
        let Some(mut reference) = self.reference else {
            self.start(wall.as_ref());
            return None;
        };
        reference.gyro_turn_ndeg += turn;
        reference.since_last_ndeg += turn;
        let Some(wall) = wall else {
            // The gyro's turn still counts; the wall is looked for again.
            reference.unfitted += 1;
            self.reference = Some(reference);
            if reference.unfitted > MOST_UNFITTED {
                self.start(None);
            }
            return None;
        };
        // The tilt falls as the robot turns clockwise: the tilt's change with the gyro's
        // turn added back is the walls' disagreement.
        let turned = Angle::from_millidegrees(reference.since_last_ndeg / 1_000_000);
        let step = wall.tilt.wrapping_add(turned) - reference.last_tilt;
        let unfitted = i32::from(reference.unfitted);
        let moved_mm = SAME_WALL_MM * (unfitted + 1);
        let same_wall = step.to_millidegrees().abs() <= SAME_WALL_MDEG + UNFITTED_MDEG * unfitted
            && (wall.distance_mm - reference.last_mm).abs() <= moved_mm;
        if !same_wall {
            self.start(Some(&wall));
            return None;
        }
        reference.last_tilt = wall.tilt;
        reference.last_mm = wall.distance_mm;
        reference.since_last_ndeg = 0;
        reference.unfitted = 0;
        let gyro = Angle::from_millidegrees(reference.gyro_turn_ndeg / 1_000_000);
        let value = (wall.tilt.wrapping_add(gyro) - reference.first_tilt).to_millidegrees();
        // This tick's place among the ticks on the wall (the first fit's value is 0).
        let index = reference.ticks as usize;
        reference.newest[index % WINDOW] = value;
        if index < WINDOW {
            reference.first_sum += value;
        }
        reference.ticks = reference.ticks.wrapping_add(1);
        self.reference = Some(reference);
        if index < WINDOW {
            return None;
        }
        let newest: i32 = reference.newest.iter().sum();
        let first = reference.first_sum / WINDOW as i32;
        let excess = newest / WINDOW as i32 - first;
        if excess.abs() <= TURN_LIMIT_MDEG {
            self.parted = 0;
            return None;
        }
        self.parted += 1;
        if self.parted < TICKS_TO_DOUBT {
            return None;
        }
        // What the gyro turned past the walls by now: the newest two ticks' mean, which
        // lags the newest less than the window's.
        let before = reference.newest[(index + WINDOW - 1) % WINDOW];
        let now = (value + before) / 2 - first;
        self.start(None);
        self.held = Some(Held {
            first_tilt: reference.first_tilt,
            first_mdeg: first,
            gyro_mdeg: (reference.gyro_turn_ndeg / 1_000_000) as i32,
            turned_back_mdeg: now,
            last_mm: wall.distance_mm,
            tilt_sum_mdeg: 0,
            ticks: 0,
        });
        self.found += 1;
        Some(Angle::from_millidegrees(now.into()))
    }

    /// Whether a gyro found out waits for the robot to stand on the same wall.
    pub fn holding(&self) -> bool {
        self.held.is_some()
    }

    /// Takes a tick after the gyro was found out: `wall`, fitted to its scan (`None` if
    /// none or the depth sensor is doubted), while the gyro is `still_doubted` and so the
    /// robot held still. The wall's tilt, the same on every such tick, is averaged over
    /// [`HELD_TICKS`] (or as many as there were, if the gyro is trusted again sooner) and
    /// gives the gyro's turn past the wall again, without the noise and the lag of the
    /// few ticks it was found out on. Returns how much further clockwise to turn the
    /// heading back (the difference from the first turn back), once.
    pub fn held(&mut self, wall: Option<WallFit>, still_doubted: bool) -> Option<Angle> {
        let mut held = self.held.take()?;
        if still_doubted {
            let Some(wall) = wall.filter(fits_well) else {
                self.held = Some(held);
                return None;
            };
            let tilt = (wall.tilt - held.first_tilt).to_millidegrees();
            if tilt.abs() > SAME_WALL_MDEG || (wall.distance_mm - held.last_mm).abs() > SAME_WALL_MM
            {
                return None;
            }
            held.tilt_sum_mdeg += tilt;
            held.ticks += 1;
            if held.ticks < HELD_TICKS {
                self.held = Some(held);
                return None;
            }
        } else if held.ticks < FEWEST_HELD_TICKS {
            return None;
        }
        let value = held.tilt_sum_mdeg / held.ticks as i32 + held.gyro_mdeg;
        let further = value - held.first_mdeg - held.turned_back_mdeg;
        Some(Angle::from_millidegrees(further.into()))
    }
}

/// Whether a fit is good enough to hold the gyro to: near walls and loose fits tilt by
/// degrees.
fn fits_well(w: &WallFit) -> bool {
    w.distance_mm >= NEAREST_WALL_MM && w.ends >= FEWEST_ENDS && w.stray_mm <= MOST_STRAY_MM
}

#[cfg(test)]
mod tests {
    use super::*;

    fn wall(distance_mm: i32, tilt_mdeg: i64) -> Option<WallFit> {
        Some(WallFit {
            distance_mm,
            cos_q16: 65_536,
            tilt: Angle::from_millidegrees(tilt_mdeg),
            ends: 8,
            stray_mm: 5,
        })
    }

    /// A tick of 100 ms at `mdps`.
    fn turn(mdps: i32) -> Option<i64> {
        Some(gyro_turn_ndeg(mdps, 100_000))
    }

    #[test]
    fn a_turn_the_walls_show_agrees() {
        let mut check = WallTurn::new();
        // Turning clockwise at 10 deg/s: the wall's tilt falls 1 degree a tick.
        for tick in 0..20 {
            assert_eq!(
                check.observe(wall(1000, 10_000 - tick * 1_000), turn(10_000)),
                None
            );
        }
    }

    #[test]
    fn a_turn_the_walls_do_not_show_is_the_gyros() {
        let mut check = WallTurn::new();
        // Driving straight at a wall 10 degrees off square; the gyro reads 3 deg/s.
        let mut found = None;
        let mut ticks = 0;
        while found.is_none() && ticks < 30 {
            found = check.observe(wall(1500 - ticks * 10, 10_000), turn(3_000));
            ticks += 1;
        }
        let excess = found.expect("the bias is found").to_millidegrees();
        // 0.3 degrees a tick from the first fit: the first five ticks' mean is 0.6, and
        // the newest five's passes it by 1.5 degrees ten ticks after the first (1.8) and
        // again on the eleventh and the twelfth, whose newest two ticks' mean is 3.45:
        // 2.85 past the first five's.
        assert_eq!(ticks, 13);
        assert!((2_800..=2_900).contains(&excess), "{excess}");
        // The gyro read anticlockwise: the excess is anticlockwise.
        let mut check = WallTurn::new();
        let found = (0..30).find_map(|_| check.observe(wall(1500, 0), turn(-3_000)));
        assert!(found.is_some_and(|a| a.to_millidegrees() < -1_500));
    }

    #[test]
    fn another_wall_or_a_gyro_unchecked_starts_again() {
        let mut check = WallTurn::new();
        for tick in 0..48 {
            // The gyro reads 2 deg/s where the robot does not turn, but the fan moves to
            // another wall every 4 ticks (a leap of tilt, or of distance), or the gyro
            // cannot be checked (a turn commanded), before the means can part.
            let (w, g) = match tick % 12 {
                0..=3 => (wall(1000, 0), turn(2_000)),
                4..=7 => (wall(1000, 5_000), turn(2_000)),
                8..=10 => (wall(1200, 5_000), turn(2_000)),
                _ => (wall(1200, 5_000), None),
            };
            assert_eq!(check.observe(w, g), None, "tick {tick}");
        }
        // One fit thrown off is not enough.
        let mut check = WallTurn::new();
        for tick in 0..20 {
            let tilt = if tick == 10 { 2_000 } else { 0 };
            assert_eq!(
                check.observe(wall(1000, tilt), turn(0)),
                None,
                "tick {tick}"
            );
        }
    }

    #[test]
    fn ticks_with_no_wall_fitted_still_count_the_gyros_turn() {
        // Every third tick's fit lost (an end dropped, a loose fit, a wall too near):
        // the gyro's 3 deg/s is found all the same, as late as with every tick fitted.
        let mut check = WallTurn::new();
        let mut ticks = 0;
        let found = loop {
            ticks += 1;
            let w = if ticks % 3 == 0 { None } else { wall(1500, 0) };
            if let Some(a) = check.observe(w, turn(3_000)) {
                break a;
            }
            assert!(ticks < 40, "never found");
        };
        assert!(found.to_millidegrees() > 1_500, "{found:?}");
        assert!(ticks <= 18, "{ticks} ticks");
        // Past the most ticks unfitted, the check starts again.
        let mut check = WallTurn::new();
        for tick in 0..60 {
            let w = if tick % 8 < 6 { None } else { wall(1500, 0) };
            assert_eq!(check.observe(w, turn(3_000)), None, "tick {tick}");
        }
    }

    #[test]
    fn a_robot_held_still_pins_what_the_gyro_turned() {
        // Found out 3 deg/s on a wall 10 degrees off square, with the fits noisy (half a
        // degree either way, tick by tick): the first turn back errs with the noise.
        let noise: [i64; HELD_TICKS as usize] = [500, -500, 300, -300, 0, 200, -200, 400, -400, 0];
        let mut check = WallTurn::new();
        let mut gyro = 0;
        let mut tick = 0;
        let first = loop {
            let w = wall(1500, 10_000 + noise[tick % noise.len()]);
            if let Some(a) = check.observe(w, turn(3_000)) {
                break a;
            }
            gyro += 300;
            tick += 1;
            assert!(tick < 40, "never found");
        };
        assert!(check.holding());
        // The gyro's turn since the first fit, less what it turned past the wall within
        // the first five ticks (their mean: 0.6 degrees), which the check measures from.
        let truth = gyro - 600;
        // Held still (the gyro doubted), the same wall's tilt averaged over ten ticks.
        let mut further = None;
        for (held, n) in noise.iter().enumerate() {
            further = check.held(wall(1500, 10_000 + n), true);
            assert_eq!(further.is_some(), held + 1 == HELD_TICKS as usize);
        }
        assert!(!check.holding());
        let total = first.to_millidegrees() + further.expect("pinned").to_millidegrees();
        // The noise's mean over the first five ticks and the ten held is 0: exact but for
        // rounding, where the first turn back missed by the newest two ticks' noise.
        assert!((first.to_millidegrees() - truth).abs() >= 100, "{first:?}");
        assert!((total - truth).abs() <= 5, "{total} against {truth}");
        // Trusted again before three ticks held: nothing more.
        let mut check = WallTurn::new();
        let _ = (0..40).find_map(|_| check.observe(wall(1500, 0), turn(3_000)));
        assert_eq!(check.held(wall(1500, 0), true), None);
        assert_eq!(check.held(wall(1500, 0), false), None);
        assert!(!check.holding());
    }
}
