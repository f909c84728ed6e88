//! How far a full turn on the spot truly turned, from the turn's own depth scans.
//!
//! Turning on the spot, the robot sees once round what it saw at the start. Its heading,
//! integrated from the gyro, says where "once round" is; the ranges say where it really
//! is. Laying the ranges of the turn's last scans over those of its first, bearing
//! against bearing, and sliding them until they agree measures how far the integrated
//! turn ran past the true one: the gyro's scale error over a whole turn, with no map and
//! no tags. A map cannot do this while the turn is being mapped (the turn is what lays
//! it), and the raw ranges reach the far walls the mapper stops short of.
//!
//! Each reading of the last scans is compared with the first scans' profile at the same
//! bearing (interpolated between its two neighbours there), its disagreement measured in
//! the depth sensor's noise at that range and capped at 3 sigma, so that the edges a zone
//! mixes and readings that just miss a box count only so much. The slide goes in tenths
//! of a degree over [`MAX_EXCESS_MDEG`] each way; the best is refined between its
//! neighbours by a parabola. How sure it is comes from the whole surface, as a
//! correlative matcher's covariance does (Olson 2009): each slide weighted by the
//! likelihood its disagreement gives, the spread of those weights about their mean. A
//! turn facing plain walls at its ends, whose ranges hardly change with bearing, agrees
//! almost as well over a wide slide and says so.

use crate::angle::Angle;
use crate::frame::BEAMS;

/// One tick of the turn: its heading as integrated, and the depth scan read there.
///
/// The ranges are kept in two bytes each, [`SpinScan::NO_RANGE`] for none, rather than as
/// `Option<u16>` (four): the first turn keeps 150 of these beside a room's map, in RAM
/// that starts zeroed.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub struct SpinScan {
    /// The heading, as the odometry gave it.
    pub heading: Angle,
    /// Range along each beam, millimetres, or [`SpinScan::NO_RANGE`].
    ranges_mm: [u16; BEAMS],
}

impl Default for SpinScan {
    fn default() -> Self {
        SpinScan::BLIND
    }
}

impl SpinScan {
    /// A beam with no reading. Zero, so that an empty store is all zero bits; a depth
    /// sensor reads no surface at its own window, so a reading of 0 mm is taken as none.
    pub const NO_RANGE: u16 = 0;

    /// No heading and no reading.
    pub const BLIND: SpinScan = SpinScan {
        heading: Angle::ZERO,
        ranges_mm: [Self::NO_RANGE; BEAMS],
    };

    /// The scan `ranges_mm` read at `heading`.
    pub fn new(heading: Angle, ranges_mm: &[Option<u16>; BEAMS]) -> SpinScan {
        SpinScan {
            heading,
            ranges_mm: ranges_mm.map(|r| r.unwrap_or(Self::NO_RANGE)),
        }
    }

    /// Range along each beam, millimetres.
    pub fn ranges_mm(&self) -> [Option<u16>; BEAMS] {
        self.ranges_mm.map(|r| (r != Self::NO_RANGE).then_some(r))
    }
}

/// The turn's measured excess: how far its integrated heading ran past the true one over
/// the turn, positive when the heading turned further than the robot.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Closure {
    /// The excess, millidegrees.
    pub excess_mdeg: i32,
    /// The integrated turn it was measured over, millidegrees (a full turn and the
    /// excess, give or take the fan).
    pub turn_mdeg: i32,
    /// Readings compared at the best slide.
    pub compared: u32,
    /// The excess's standard deviation, millidegrees: the spread of the slides, each
    /// weighted by how well it agrees.
    pub sd_mdeg: i32,
}

impl Closure {
    /// The correction to the gyro's scale the excess says, parts per million: the true
    /// rate is the integrated one times `1 + scale_ppm / 1e6`.
    pub fn scale_ppm(&self) -> i32 {
        let turn = i64::from(self.turn_mdeg.unsigned_abs().max(1));
        let ppm = -i64::from(self.excess_mdeg) * 1_000_000 / turn;
        ppm.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32
    }
}

/// What the filter believed of a turn's excess before its closure was measured.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Prior {
    /// The excess its heading implies, millidegrees, over the turn the closure measures.
    pub excess_mdeg: i32,
    /// Its deviation, millidegrees.
    pub sd_mdeg: i32,
}

impl Prior {
    /// The deviation's square, millidegrees squared, the deviation taken within 1 and a
    /// whole turn: a belief wider than that says nothing, and the products it enters stay
    /// within 64 bits.
    fn variance(&self) -> i64 {
        i64::from(self.sd_mdeg.clamp(1, 360_000)).pow(2)
    }
}

/// Why a turn's closure was not measured.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ClosureRefusal {
    /// The scans do not turn a full turn, one way, less the fan: their ends do not look
    /// the same way.
    NotAFullTurn,
    /// Too few readings at the turn's ends see the same walls to compare.
    TooFewReadings,
    /// The ranges agree best at the edge of the slide: the excess is beyond what is
    /// searched, or the ends do not agree at all.
    NoClosure,
}

/// The largest excess searched each way, millidegrees: twice the 2.7 degrees a turn of
/// the seed's 0.75 % gyro scale error.
pub const MAX_EXCESS_MDEG: i32 = 6_000;

/// The slide's step, millidegrees.
const SLIDE_MDEG: i32 = 100;

/// The first scans, those this far into the turn, millidegrees, make the profile the
/// last are laid over: enough for the fan's width and the slide.
const PROFILE_MDEG: i32 = 60_000;

/// The most readings the first scans' profile holds: 24 ticks of 8 beams, the first
/// 60 degrees of a turn at the seed's 31.5 degrees a second and more.
const PROFILE_READINGS: usize = 256;

/// Neighbours in the profile further apart than this in bearing are not interpolated
/// between: the wall between them was not seen.
const MAX_GAP_MDEG: i32 = 3_000;

/// The fewest readings a slide is judged on.
const MIN_COMPARED: u32 = 20;

/// The depth sensor's noise: 10 mm and 1 % of the range, a little above the seed's.
const NOISE_MM: i32 = 10;
const NOISE_PER_100: i32 = 1;

/// The cap on a reading's squared disagreement, in its noise: 3 sigma.
const CAP_Q8: i64 = 9 << 16;

/// A reading of the turn: its bearing from the turn's start, along the turn, and range.
#[derive(Clone, Copy, Debug, Default)]
struct Reading {
    bearing_mdeg: i32,
    range_mm: i32,
}

/// The slides searched: every [`SLIDE_MDEG`] over [`MAX_EXCESS_MDEG`] each way.
const STEPS: usize = (2 * MAX_EXCESS_MDEG / SLIDE_MDEG) as usize + 1;

/// Measures the excess of the turn `scans` made, each scan's beams at `beam_angles`
/// from its heading. The scans are consecutive ticks of one turn on the spot, in order.
/// All at once: [`Search`] does it in pieces.
pub fn measure(
    scans: &[SpinScan],
    beam_angles: &[Angle; BEAMS],
) -> Result<Closure, ClosureRefusal> {
    let mut search = Search::new();
    search.start(scans, beam_angles)?;
    while !search.search(scans, usize::MAX) {}
    search.finish()
}

/// A closure measured in pieces ([`Search::search`], a few scans at a time), so that a
/// caller can let other work run in between; the same result as [`measure`], bit for bit.
/// Built in place ([`Search::new`], then [`Search::start`]): it holds the first scans'
/// profile and the slides' costs, a few kilobytes.
#[derive(Clone, Debug)]
pub struct Search {
    /// The turn from the first scan to the last, millidegrees, and its sign.
    total: i32,
    sign: i32,
    /// Each beam's bearing from the heading, along the turn.
    beams: [i32; BEAMS],
    /// How far along the turn a reading is laid over the profile.
    reach: i32,
    /// The first scans' readings, by bearing along the turn.
    profile: [Reading; PROFILE_READINGS],
    held: usize,
    /// Each slide's capped squared disagreements and their count. Words: each at most
    /// 9 in Q16, so 3,600 readings fit, and a turn has fewer (a closure compares its last
    /// scans alone); past that a sum saturates.
    sums: [i32; STEPS],
    counts: [u32; STEPS],
    /// The next scan to lay over the profile and its next beam, whether its turn is
    /// counted yet, and the turn so far (binary units, unwrapped) at the last heading
    /// counted.
    next: usize,
    beam: usize,
    entered: bool,
    bits: i64,
    last: Angle,
}

impl Default for Search {
    fn default() -> Self {
        Self::new()
    }
}

impl Search {
    /// Nothing searched: all zero bits (a `static` holding one lies in zeroed RAM).
    pub const fn new() -> Search {
        Search {
            total: 0,
            sign: 0,
            beams: [0; BEAMS],
            reach: 0,
            profile: [Reading {
                bearing_mdeg: 0,
                range_mm: 0,
            }; PROFILE_READINGS],
            held: 0,
            sums: [0; STEPS],
            counts: [0; STEPS],
            next: 0,
            beam: 0,
            entered: false,
            bits: 0,
            last: Angle::ZERO,
        }
    }

    /// Starts measuring the turn `scans` made, as [`measure`] does: refused at once if
    /// they do not turn a full turn; otherwise the first scans' profile, sorted.
    pub fn start(
        &mut self,
        scans: &[SpinScan],
        beam_angles: &[Angle; BEAMS],
    ) -> Result<(), ClosureRefusal> {
        let mut total = 0;
        each_turn(scans, |turn, _| total = turn);
        let sign = if total < 0 { -1 } else { 1 };
        let fan = fan_mdeg(beam_angles);
        // The ends must look at least half the fan's width the same way.
        if total.saturating_mul(sign) < 360_000 - fan / 2 {
            return Err(ClosureRefusal::NotAFullTurn);
        }
        let beams = beam_angles.map(|a| a.to_millidegrees() * sign);
        let (profile, mut held) = (&mut self.profile, 0);
        each_reading(scans, &beams, sign, |turn, r| {
            if turn < PROFILE_MDEG && held < PROFILE_READINGS {
                profile[held] = r;
                held += 1;
            }
        });
        sort_by_bearing(&mut profile[..held]);
        self.total = total;
        self.sign = sign;
        self.beams = beams;
        self.reach = 360_000 - fan - MAX_EXCESS_MDEG;
        self.held = held;
        self.sums = [0; STEPS];
        self.counts = [0; STEPS];
        self.next = 0;
        self.beam = 0;
        self.entered = false;
        self.bits = 0;
        self.last = scans.first().map_or(Angle::ZERO, |s| s.heading);
        Ok(())
    }

    /// Lays up to `pieces` more readings of `scans` (the same as given to
    /// [`Search::start`]) over the profile, each at every slide; `true` once every scan
    /// has been. A reading is the piece: a scan's eight at once outlast a sensor task's
    /// read on the M0+.
    pub fn search(&mut self, scans: &[SpinScan], pieces: usize) -> bool {
        let profile = self.profile.get(..self.held).unwrap_or(&[]);
        let mut left = pieces;
        while let Some(s) = scans.get(self.next) {
            if !self.entered {
                self.bits += i64::from(s.heading.diff(self.last));
                self.last = s.heading;
                self.entered = true;
            }
            let turn = turn_mdeg(self.bits).saturating_mul(self.sign);
            let readings = s.ranges_mm.iter().zip(&self.beams).skip(self.beam);
            for (&range, beam) in readings.take_while(|_| turn >= self.reach) {
                if left == 0 {
                    return false;
                }
                self.beam += 1;
                if range == SpinScan::NO_RANGE {
                    continue;
                }
                left -= 1;
                let (bearing, range) = (turn + beam, i32::from(range));
                for (k, (sum, count)) in self.sums.iter_mut().zip(&mut self.counts).enumerate() {
                    let slide = k as i32 * SLIDE_MDEG - MAX_EXCESS_MDEG;
                    if let Some(seen) = interpolate(profile, bearing - 360_000 - slide) {
                        *sum = sum.saturating_add(disagreement_q8(range, seen));
                        *count += 1;
                    }
                }
            }
            self.next += 1;
            self.beam = 0;
            self.entered = false;
        }
        true
    }

    /// The turn from the first scan to the last, millidegrees, as the gyro integrated it:
    /// what the closure's excess is measured over (0 before [`Search::start`]).
    pub fn turn_mdeg(&self) -> i32 {
        self.total
    }

    /// The closure the slides found: the best, refined between its neighbours, and how
    /// sure it is.
    pub fn finish(&self) -> Result<Closure, ClosureRefusal> {
        let judged = |k: usize| self.judged(k);
        // The best slide: the least mean cost (compared as cross products, no division).
        let mut best: Option<usize> = None;
        for k in 0..STEPS {
            let Some((s, n)) = judged(k) else { continue };
            let better = best.and_then(judged).is_none_or(|(bs, bn)| {
                i128::from(s) * i128::from(bn) < i128::from(bs) * i128::from(n)
            });
            if better {
                best = Some(k);
            }
        }
        let k = best.ok_or(ClosureRefusal::TooFewReadings)?;
        if k == 0 || k == STEPS - 1 {
            return Err(ClosureRefusal::NoClosure);
        }
        let mean = |k: usize| self.mean(k);
        let slide = k as i32 * SLIDE_MDEG - MAX_EXCESS_MDEG;
        // The parabola through the best and its neighbours, where both are judged: its
        // vertex refines the slide.
        let refined = match (mean(k - 1), mean(k), mean(k + 1)) {
            (Some(before), Some(at), Some(after)) if before - 2 * at + after > 0 => {
                let curve = before - 2 * at + after;
                let offset = i64::from(SLIDE_MDEG) * (before - after) / (2 * curve);
                slide + offset.clamp(-i64::from(SLIDE_MDEG), i64::from(SLIDE_MDEG)) as i32
            }
            _ => slide,
        };
        let compared = self.counts.get(k).copied().unwrap_or(0);
        let (_, var) = self.weighed(compared, None);
        Ok(Closure {
            excess_mdeg: refined,
            turn_mdeg: self.total,
            compared,
            sd_mdeg: root(var.max(LEAST_VAR)),
        })
    }

    /// What the slides add to the filter's `prior` belief of the excess, for the
    /// `closure` [`Search::finish`] found: the slides weighed by both, and the
    /// measurement that, taken with the prior, gives their weighed mean and spread.
    /// `None` where they add next to nothing (the weighed variance within a twentieth of
    /// the prior's). A turn whose ends agree almost as well over a wide slide so leaves
    /// the belief nearly as it was, where its best slide taken as a Gaussian would move it
    /// to wherever the readings' noise put the least cost.
    pub fn given(&self, closure: &Closure, prior: Prior) -> Option<Closure> {
        let weighed = self.weighed(closure.compared, Some(prior));
        let (excess_mdeg, sd_mdeg) = measured(weighed, prior)?;
        Some(Closure {
            excess_mdeg,
            sd_mdeg,
            ..*closure
        })
    }

    /// The slides' mean and variance (millidegrees, and squared), each slide weighted by
    /// the likelihood of its disagreement over `n` readings, the cost a reading's mean
    /// squared disagreement in the sensor's noise (`mean`, Q24), and by the `prior`'s
    /// Gaussian if given. A disagreement is the difference of two readings, each with that
    /// noise, so its variance is twice one's: the likelihood is `exp(-n (cost - best) /
    /// (2 x 2 max(best, 1)))`. Where the readings disagree more than the sensor's noise
    /// says at the best slide (its cost above one), the costs are taken in that larger
    /// noise. No slide judged: no mean, and the whole slide's width as the spread. Out of
    /// line: [`Search::finish`] and [`Search::given`] share it.
    #[inline(never)]
    fn weighed(&self, n: u32, prior: Option<Prior>) -> (i64, i64) {
        // Each slide's cost, then its exponent; `NOT_JUDGED` where too few readings compared.
        const NOT_JUDGED: i64 = i64::MAX;
        let mut x = [NOT_JUDGED; STEPS];
        for (k, slot) in x.iter_mut().enumerate() {
            *slot = self.mean(k).unwrap_or(NOT_JUDGED);
        }
        let best = x.iter().copied().min().unwrap_or(NOT_JUDGED);
        if best == NOT_JUDGED {
            return (0, i64::from(MAX_EXCESS_MDEG).pow(2));
        }
        let scale = best.max(1 << 24);
        let slide = |k: usize| i64::from(k as i32 * SLIDE_MDEG - MAX_EXCESS_MDEG);
        let (centre, var) = prior.map_or((0, 0), |p| {
            (
                i64::from(p.excess_mdeg.clamp(-PRIOR_REACH, PRIOR_REACH)),
                p.variance(),
            )
        });
        // Each slide's exponent in Q16: n (cost - best) / (4 scale), n at most a few thousand
        // and the costs at most 9 in Q24, so the product fits 64 bits; and the prior's
        // (slide - mean)^2 / (2 var), its mean within a few slide widths and its variance at
        // least one.
        for (k, slot) in x.iter_mut().enumerate() {
            if *slot != NOT_JUDGED {
                let off = slide(k) - centre;
                let believed = if var > 0 {
                    off * off * (1 << 15) / var
                } else {
                    0
                };
                *slot = i64::from(n) * (*slot - best) * (1 << 14) / scale + believed;
            }
        }
        let floor = x.iter().copied().min().unwrap_or(0);
        let (mut w_sum, mut wd_sum, mut wdd_sum) = (0i64, 0i64, 0i64);
        for (k, &e) in x.iter().enumerate() {
            if e == NOT_JUDGED {
                continue;
            }
            let (w, d) = (exp_neg_q16(e - floor), slide(k));
            w_sum += w;
            wd_sum += w * d;
            wdd_sum += w * d * d;
        }
        // The least exponent's weight is one (2^16), so the sum is never zero.
        let mu = wd_sum / w_sum.max(1);
        (mu, (wdd_sum / w_sum.max(1) - mu * mu).max(0))
    }

    /// Slide `k`'s summed cost and readings, if enough were compared to judge it.
    fn judged(&self, k: usize) -> Option<(i64, u32)> {
        let (&sum, &count) = (self.sums.get(k)?, self.counts.get(k)?);
        (count >= MIN_COMPARED).then_some((i64::from(sum), count))
    }

    /// Slide `k`'s mean cost, Q24, if judged.
    fn mean(&self, k: usize) -> Option<i64> {
        self.judged(k).map(|(s, n)| s * 256 / i64::from(n))
    }
}

/// The least variance a closure is given, millidegrees squared: a uniform step's own,
/// the slide's step squared over 12.
const LEAST_VAR: i64 = (SLIDE_MDEG as i64 * SLIDE_MDEG as i64) / 12;

/// Sorts `readings` by bearing: an insertion sort, as the turn lays them nearly in order
/// already (one scan's beams across the fan, then the next scan's a little further on),
/// in a few hundred bytes of code where the library's sort takes kilobytes.
fn sort_by_bearing(readings: &mut [Reading]) {
    for i in 1..readings.len() {
        let mut j = i;
        while j > 0 && readings[j - 1].bearing_mdeg > readings[j].bearing_mdeg {
            readings.swap(j - 1, j);
            j -= 1;
        }
    }
}

/// How far the prior's excess is taken to lie from no excess at most, millidegrees: a
/// filter whose belief is beyond the slides' reach is clamped to a few widths past it.
const PRIOR_REACH: i32 = 4 * MAX_EXCESS_MDEG;

/// The measurement that, taken with the `prior`, gives the weighed `(mean, variance)`
/// (the variance at least [`LEAST_VAR`]): its excess and deviation, millidegrees. The
/// slides add information `1 / var - 1 / prior_var`; `None` where that is next to none.
fn measured((mu, var): (i64, i64), prior: Prior) -> Option<(i32, i32)> {
    let a = prior.variance();
    let b = var.max(LEAST_VAR);
    let gained = a - b;
    if 20 * gained <= a {
        return None;
    }
    let excess = (mu * a - i64::from(prior.excess_mdeg) * b) / gained;
    let sd = root(a.saturating_mul(b) / gained);
    Some((
        excess.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32,
        sd,
    ))
}

/// The square root of a variance in millidegrees squared, as a deviation.
fn root(var: i64) -> i32 {
    (var.max(0) as u64).isqrt().min(i32::MAX as u64) as i32
}

/// `exp(-x)` for `x >= 0` in Q16, to about 2 %: `2^(-x log2 e)`, its whole part a shift
/// and its fraction a cubic. Zero beyond `x = 16`.
fn exp_neg_q16(x_q16: i64) -> i64 {
    if x_q16 >= 16 << 16 {
        return 0;
    }
    // log2(e) in Q16.
    let y = (x_q16.max(0) * 94_548) >> 16;
    let (whole, f) = (y >> 16, y & 0xFFFF);
    // 2^-f = 1 - 0.693147 f + 0.240227 f^2 - 0.0555041 f^3, each term Q16.
    let f2 = (f * f) >> 16;
    let f3 = (f2 * f) >> 16;
    let frac = 65_536 - ((45_426 * f) >> 16) + ((15_743 * f2) >> 16) - ((3_637 * f3) >> 16);
    frac >> whole
}

/// How wide the fan is, millidegrees.
fn fan_mdeg(beam_angles: &[Angle; BEAMS]) -> i32 {
    let mdeg = beam_angles.map(|a| a.to_millidegrees());
    let widest = mdeg.iter().max().copied().unwrap_or(0);
    let narrowest = mdeg.iter().min().copied().unwrap_or(0);
    widest - narrowest
}

/// Calls `f` with each scan's turn from the first, millidegrees (unwrapped tick by tick,
/// each tick's turn less than half a turn), and the scan.
fn each_turn(scans: &[SpinScan], mut f: impl FnMut(i32, &SpinScan)) {
    let Some(first) = scans.first() else { return };
    let mut bits = 0i64;
    let mut last = first.heading;
    for s in scans {
        bits += i64::from(s.heading.diff(last));
        last = s.heading;
        f(turn_mdeg(bits), s);
    }
}

/// An unwrapped turn of `bits` binary units in millidegrees: 2^32 bits a turn, within
/// i32 for any turn under 5,965 turns.
fn turn_mdeg(bits: i64) -> i32 {
    ((bits * 360_000) >> 32).clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32
}

/// Calls `f` with each valid reading of `scans` and its scan's turn from the first,
/// millidegrees along the turn; the reading's bearing is the turn and its beam's angle.
fn each_reading(
    scans: &[SpinScan],
    beams: &[i32; BEAMS],
    sign: i32,
    mut f: impl FnMut(i32, Reading),
) {
    each_turn(scans, |turn, s| {
        let turn = turn.saturating_mul(sign);
        for (range, beam) in s.ranges_mm().iter().zip(beams) {
            if let Some(r) = range {
                let bearing_mdeg = turn + beam;
                f(
                    turn,
                    Reading {
                        bearing_mdeg,
                        range_mm: i32::from(*r),
                    },
                );
            }
        }
    });
}

/// The profile's range at `bearing`, between the two readings either side of it, if
/// they are close enough in bearing.
fn interpolate(profile: &[Reading], bearing: i32) -> Option<i32> {
    let after = profile.partition_point(|r| r.bearing_mdeg < bearing);
    let (a, b) = (profile.get(after.checked_sub(1)?)?, profile.get(after)?);
    let gap = b.bearing_mdeg - a.bearing_mdeg;
    if gap > MAX_GAP_MDEG {
        return None;
    }
    if gap == 0 {
        return Some((a.range_mm + b.range_mm) / 2);
    }
    let w = bearing - a.bearing_mdeg;
    Some(a.range_mm + (b.range_mm - a.range_mm) * w / gap)
}

/// A reading's squared disagreement with the profile, in the sensor's noise at its range,
/// Q16, capped at [`CAP_Q8`]'s 3 sigma.
fn disagreement_q8(range_mm: i32, seen_mm: i32) -> i32 {
    let noise = i64::from(NOISE_MM + range_mm * NOISE_PER_100 / 100).max(1);
    let e = i64::from(range_mm - seen_mm) * 256 / noise;
    (e * e).min(CAP_Q8) as i32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_scan_keeps_its_ranges_and_a_zero_reading_is_none() {
        let ranges = [
            Some(1),
            None,
            Some(4_000),
            Some(u16::MAX),
            None,
            Some(0),
            Some(7),
            None,
        ];
        let scan = SpinScan::new(Angle::from_millidegrees(12_345), &ranges);
        let mut want = ranges;
        want[5] = None;
        assert_eq!(scan.ranges_mm(), want);
        assert_eq!(scan.heading, Angle::from_millidegrees(12_345));
        assert_eq!(SpinScan::default().ranges_mm(), [None; BEAMS]);
    }

    #[test]
    fn exp_neg_is_within_two_percent_of_a_unit() {
        for i in 0..=1600 {
            let x = f64::from(i) / 100.0;
            let got = exp_neg_q16((x * 65_536.0) as i64) as f64 / 65_536.0;
            let want = (-x).exp();
            assert!(
                (got - want).abs() <= 0.02 * want + 2.0 / 65_536.0,
                "{x}: {got} against {want}"
            );
        }
        assert_eq!(exp_neg_q16(16 << 16), 0);
        assert_eq!(exp_neg_q16(0), 65_536);
    }
}
