//! A scan match as a filter update: the matched pose of the sweep's moment, measured only
//! along the directions the match pins, with the covariance its score surface shows.
//!
//! The components are the position across and along the match's wider spread and the
//! heading; those the match pins are measured, the others left out (the marginal of the
//! match's Gaussian). Their joint covariance, correlations included, is factored
//! `L D L^T`, so that each becomes a scalar measurement with its own noise (the later
//! ones less what the earlier explain), and each pair of scalars is one two-row update of
//! the covariance, gated at the tags' chi-square. The match's spread is widened by
//! [`MatchNoise`] before: the map it matched against was built at poses no better than
//! the filter's, and its errors repeat from one match to the next. For the same reason
//! each measurement's noise is raised so that it never leaves the filter surer along its
//! direction than the map can be ([`MatchNoise`]'s floors plus [`MapUncertainty`]); where
//! the filter already is (tags in view), the measurement is left out.

use super::covariance::{GAIN_SHIFT, N};
use super::filter::Estimator;
use super::fixed::{fits_i32, mul_shift_call as mul_shift, square, Reciprocal};
use super::step_limit::steps_further;
use super::units::{self, FINE_SHIFT};
use super::State;
use crate::angle::mdeg_of_bits;
use crate::matcher::{Match, MatchRefusal, Pins};
use crate::pose::Pose;
use crate::wall_rate::FlowScale;

/// What the filter adds to a match's own spread: the map it matched against was built at
/// poses no better than the filter's, which the score surface cannot know.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MatchNoise {
    /// Added to the standard deviation of each position measurement, micrometres.
    pub position_um: u32,
    /// Added to the standard deviation of the heading measurement, millidegrees.
    pub heading_mdeg: u32,
    /// The match's own standard deviations are multiplied by this, per cent.
    pub scale_pct: u32,
    /// The least position standard deviation matches may leave the filter with along the
    /// direction they measure, micrometres: the map places a wall only to within its cell,
    /// and that error is the same in every match against it, so matches repeated a
    /// hundred times know no more than one does. Where the filter is surer than this (tags
    /// in view), a match adds nothing.
    pub floor_position_um: u32,
    /// The same for the heading, millidegrees.
    pub floor_heading_mdeg: u32,
}

/// The furthest one match may move the position at its moment, micrometres: 2 cm, inside
/// the 3 cm a tick that issue 11 allows. A match that would move it further is taken
/// with its noise widened until it does not ([`Estimator::apply_match_within`]): the rest
/// of the way comes over the next matches, so the map is never written across a jump.
/// A constant rather than a field of [`MatchNoise`]: a field moves the core's state in
/// memory, and the step's loads with it (33 M0+ cycles in the worst step).
pub const MATCH_STEP_UM: u32 = 20_000;

/// How far a match may turn the heading from its prediction, in deviations of the
/// filter's own heading ([`Estimator::apply_match`]).
pub const TURN_GATE_SIGMAS: i64 = 4;

impl MatchNoise {
    /// The seed's: a match's spread doubled, plus 3 mm and 0.3 degrees; floors of a
    /// 5 cm cell's quantisation (`50 / sqrt(12)` mm) and 0.3 degrees.
    pub const SEED: MatchNoise = MatchNoise {
        position_um: 3_000,
        heading_mdeg: 300,
        scale_pct: 200,
        floor_position_um: 14_434,
        floor_heading_mdeg: 300,
    };

    /// The floors as a covariance over x, y and heading in the filter's units: the map's
    /// own, with this noise's floors added to the variances.
    fn floors(&self, map: &MapUncertainty) -> Floors {
        let position = units::position_from_um(units::position_from_um(square(i64::from(
            self.floor_position_um,
        ))));
        let heading = units::heading_from_mdeg(units::heading_from_mdeg(square(i64::from(
            self.floor_heading_mdeg,
        ))));
        Floors {
            xx: position.saturating_add(map.xx),
            yy: position.saturating_add(map.yy),
            xy: map.xy,
            heading: heading.saturating_add(map.heading),
        }
    }
}

/// The least covariance matches may leave the filter with ([`MatchNoise::floors`]):
/// position over x and y with their correlation, and the heading, in the filter's units.
#[derive(Clone, Copy)]
struct Floors {
    xx: i64,
    yy: i64,
    xy: i64,
    heading: i64,
}

impl Floors {
    /// The variance along a row `e` over x, y and heading (Q16 entries within 1.0).
    fn along(&self, e: [i32; 3]) -> i64 {
        let [x, y, h] = e.map(i64::from);
        let terms = [
            mul_shift(x * x, self.xx, 32),
            mul_shift(2 * x * y, self.xy, 32),
            mul_shift(y * y, self.yy, 32),
            mul_shift(h * h, self.heading, 32),
        ];
        terms.iter().fold(0i64, |s, &t| s.saturating_add(t)).max(0)
    }
}

/// How far the map itself may be off: the filter's uncertainty at the poses its scans were
/// written at, followed as a running mean over the last scans written (a time constant of
/// `2^MEMORY_SHIFT` scans). A match places the robot against the map, so it can place it
/// in the world no better than the map lies there: a map drawn while dead reckoning in the
/// dark carries that drift, and matching against it must not make the filter sure of it.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MapUncertainty {
    /// Variance along x, the filter's units.
    pub xx: i64,
    /// Variance along y, the filter's units.
    pub yy: i64,
    /// Covariance of x and y, the filter's units: a map drawn while unsure along a
    /// corridor is unsure along it, not across.
    pub xy: i64,
    /// Heading variance, the filter's units.
    pub heading: i64,
}

impl MapUncertainty {
    /// Scans over which the running mean forgets, as a power of two.
    pub const MEMORY_SHIFT: u32 = 6;

    /// A map drawn all at once while the filter is as `estimator` says (a turn drawn again
    /// once it closed, [`crate::slam::first_turn`]).
    pub fn drawn_at(estimator: &Estimator) -> MapUncertainty {
        let p = estimator.covariance();
        MapUncertainty {
            xx: p.get(State::X, State::X),
            yy: p.get(State::Y, State::Y),
            xy: p.get(State::X, State::Y),
            heading: p.get(State::Heading, State::Heading),
        }
    }

    /// Follows one scan written into the map while the filter is as `estimator` says.
    pub fn wrote(&mut self, estimator: &Estimator) {
        let p = estimator.covariance();
        let follow = |m: &mut i64, v: i64| *m += (v - *m) >> Self::MEMORY_SHIFT;
        follow(&mut self.xx, p.get(State::X, State::X));
        follow(&mut self.yy, p.get(State::Y, State::Y));
        follow(&mut self.xy, p.get(State::X, State::Y));
        follow(&mut self.heading, p.get(State::Heading, State::Heading));
    }
}

/// Matches used and refused since start, by cause.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MatchCounters {
    /// Matches applied.
    pub used: u32,
    /// Sweeps with no beam end.
    pub empty: u32,
    /// Sweeps with too few beam ends.
    pub too_few_points: u32,
    /// Sweeps whose ends fell on nothing the map knows.
    pub no_fit: u32,
    /// Matches that pinned nothing.
    pub nothing_pinned: u32,
    /// Matches beyond the gate.
    pub gate: u32,
    /// Sweeps whose moment the history no longer reaches, or a window the footprint
    /// cannot hold.
    pub other: u32,
}

impl MatchCounters {
    /// Counts one outcome.
    pub fn count(&mut self, outcome: Result<(), MatchRefusal>) {
        let c = match outcome {
            Ok(()) => &mut self.used,
            Err(MatchRefusal::EmptySweep) => &mut self.empty,
            Err(MatchRefusal::TooFewPoints) => &mut self.too_few_points,
            Err(MatchRefusal::NoFit) => &mut self.no_fit,
            Err(MatchRefusal::NothingPinned) => &mut self.nothing_pinned,
            Err(MatchRefusal::Gate) => &mut self.gate,
            Err(MatchRefusal::Window | MatchRefusal::TooOld) => &mut self.other,
        };
        *c = c.saturating_add(1);
    }
}

/// One scalar measurement: a row over up to three states (Q16, each entry within 1.0),
/// the innovation and its noise, in covariance units.
#[derive(Clone, Copy)]
struct Scalar {
    h: [(State, i32); 3],
    nu: i64,
    r: i64,
    /// The least variance the filter may be left with along `h` ([`MatchNoise`]'s floor).
    floor: i64,
}

/// A component of the match: across its wider spread, along it, or the heading.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Component {
    Across = 0,
    Along = 1,
    Heading = 2,
}

/// `h a` for a sparse Q16 row `h`.
fn dot(h: &[(State, i32)], a: &[i64; N]) -> i64 {
    h.iter()
        .map(|&(j, v)| mul_shift(a[j as usize], i64::from(v), 16))
        .sum()
}

/// `nu^2 / s` in Q8, saturating.
fn normalised_square_q8(nu: i64, s: &Reciprocal) -> i64 {
    if fits_i32(nu) {
        s.times(nu * nu, 8)
    } else {
        i64::MAX
    }
}

/// `x / d` in Q16 (`d > 0`).
fn ratio_q16(x: i64, d: i64) -> Option<i64> {
    Some(Reciprocal::of(d)?.times(x, 16))
}

/// The match in the filter's units along its components: innovations, their covariance
/// (inflated by `noise`) and each component's row over x, y and heading (Q16).
struct Components {
    nu: [i64; 3],
    c: [[i64; 3]; 3],
    rows: [[i64; 3]; 3],
}

impl Components {
    fn of(matched: &Match, noise: &MatchNoise) -> Components {
        let then = &matched.prediction;
        let m = &matched.covariance;
        let dx = i64::from(matched.pose.x_um) - i64::from(then.x_um);
        let dy = i64::from(matched.pose.y_um) - i64::from(then.y_um);
        let dh = (matched.pose.heading - then.heading).signed_bits();
        // Along the wider spread (sin a, cos a), across it (cos a, -sin a); Q16.
        let (s, co) = (i64::from(matched.wide.sin()), i64::from(matched.wide.cos()));
        let units = [(co, -s), (s, co)];
        // The match's covariance in these components: um^2, um mdeg, mdeg^2.
        let pos = |u: (i64, i64), v: (i64, i64)| {
            mul_shift(m.xx_um2, u.0 * v.0, 32)
                + mul_shift(m.xy_um2, u.0 * v.1 + u.1 * v.0, 32)
                + mul_shift(m.yy_um2, u.1 * v.1, 32)
        };
        let cross =
            |u: (i64, i64)| mul_shift(m.xh_um_mdeg, u.0, 16) + mul_shift(m.yh_um_mdeg, u.1, 16);
        let raw = [
            [
                pos(units[0], units[0]),
                pos(units[0], units[1]),
                cross(units[0]),
            ],
            [
                pos(units[1], units[0]),
                pos(units[1], units[1]),
                cross(units[1]),
            ],
            [cross(units[0]), cross(units[1]), m.hh_mdeg2],
        ];
        // Scaled (the correlations kept), the floors added to the variances, and into the
        // filter's units: position 1/16 mm, heading 2^-16 rad.
        let scale = i64::from(noise.scale_pct);
        let floors = [
            square(i64::from(noise.position_um)),
            square(i64::from(noise.position_um)),
            square(i64::from(noise.heading_mdeg)),
        ];
        let to_filter = |v: i64, i: usize| {
            if i == 2 {
                units::heading_from_mdeg(v)
            } else {
                units::position_from_um(v)
            }
        };
        let mut c = [[0i64; 3]; 3];
        for (i, row) in c.iter_mut().enumerate() {
            for (j, out) in row.iter_mut().enumerate() {
                let mut v = raw[i][j] * scale / 100 * scale / 100;
                if i == j {
                    v += floors[i];
                }
                *out = to_filter(to_filter(v, i), j);
            }
        }
        let along_um = |u: (i64, i64)| mul_shift(dx, u.0, 16) + mul_shift(dy, u.1, 16);
        Components {
            nu: [
                units::position_from_um(along_um(units[0])),
                units::position_from_um(along_um(units[1])),
                units::heading_from_bits(i64::from(dh)),
            ],
            c,
            rows: [[co, -s, 0], [s, co, 0], [0, 0, 1 << 16]],
        }
    }

    /// These components with their covariance shifted left by `bits` (saturating): the
    /// same match, trusted less.
    fn widened(&self, bits: u32) -> Components {
        let bits = bits.min(MOST_WIDENED);
        let widen = |v: i64| {
            if v.unsigned_abs() >> (62 - bits) != 0 {
                if v < 0 {
                    i64::MIN
                } else {
                    i64::MAX
                }
            } else {
                v << bits
            }
        };
        Components {
            nu: self.nu,
            c: self.c.map(|row| row.map(widen)),
            rows: self.rows,
        }
    }

    /// The chosen components as independent scalar measurements (the match's covariance
    /// factored as `L D L^T`, each measurement less what the earlier ones explain), in
    /// `order`. `None` if a variance left is not positive.
    fn whitened(&self, order: &[Component], floors: &Floors) -> Option<([Scalar; 3], usize)> {
        let n = order.len().min(3);
        let idx = |k: usize| order.get(k).map_or(0, |&c| c as usize);
        let c = |i: usize, j: usize| self.c[idx(i)][idx(j)];
        let mut l = [[0i64; 3]; 3];
        let mut d = [0i64; 3];
        for i in 0..n {
            for j in 0..i {
                // L_ij = (C_ij - sum_k<j L_ik L_jk D_k) / D_j
                let mut v = c(i, j);
                for k in 0..j {
                    v -= mul_shift(mul_shift(l[i][k], l[j][k], 16), d[k], 16);
                }
                l[i][j] = ratio_q16(v, d[j])?;
            }
            let mut v = c(i, i);
            for k in 0..i {
                v -= mul_shift(mul_shift(l[i][k], l[i][k], 16), d[k], 16);
            }
            if v <= 0 {
                return None;
            }
            d[i] = v;
        }
        let mut out = [Scalar {
            h: [(State::X, 0), (State::Y, 0), (State::Heading, 0)],
            nu: 0,
            r: 1,
            floor: 0,
        }; 3];
        let mut nus = [0i64; 3];
        let mut rows = [[0i64; 3]; 3];
        for i in 0..n {
            let mut nu = self.nu[idx(i)];
            let mut row = self.rows[idx(i)];
            for k in 0..i {
                nu -= mul_shift(l[i][k], nus[k], 16);
                for (r, e) in row.iter_mut().zip(rows[k]) {
                    *r -= mul_shift(l[i][k], e, 16);
                }
            }
            nus[i] = nu;
            rows[i] = row;
            // Rows within 1.0: a larger one is scaled down with its innovation and noise.
            let big = row.iter().map(|e| e.abs()).max().unwrap_or(0);
            let (row, nu, r) = if big > 1 << 16 {
                let f = Reciprocal::of(big)?;
                let shrink = |v: i64| f.times(v, 16);
                (row.map(shrink), shrink(nu), shrink(shrink(d[i])))
            } else {
                (row, nu, d[i])
            };
            let e = |k: usize| {
                row.get(k)
                    .map_or(0, |&v| v.clamp(-(1 << 16), 1 << 16) as i32)
            };
            // The floor along this row: the map's own uncertainty seen along it. A
            // measurement conditioned on an earlier one mixes position and heading, and
            // must not leave the filter surer of the position in it than the map is.
            let floor = floors.along([e(0), e(1), e(2)]);
            out[i] = Scalar {
                h: [(State::X, e(0)), (State::Y, e(1)), (State::Heading, e(2))],
                nu,
                r: r.max(1),
                floor,
            };
        }
        Some((out, n))
    }
}

/// Bits a widening shifts the match's covariance by: its deviations doubled.
const WIDEN_SHIFT: u32 = 2;

/// The most a match's covariance is widened, in bits: deviations 64 times the surface's.
/// One that still steps too far is refused as beyond the gate.
const MOST_WIDENED: u32 = 12;

/// The noise to give `m` so that the filter's variance along it, `prior` before, is
/// left at least `m.floor` after: `r` with `prior r / (prior + r) >= floor`. `None` when
/// `prior` is already at or below the floor.
fn floored_noise(prior: i64, m: &Scalar) -> Option<i64> {
    if prior <= m.floor {
        return None;
    }
    let least = i128::from(prior) * i128::from(m.floor) / i128::from(prior - m.floor);
    Some(m.r.max(i64::try_from(least).unwrap_or(i64::MAX)))
}

impl Estimator {
    /// Updates the filter from `matched`, the sweep's pose at its newest scan's moment
    /// against `matched.prediction`, the pose believed then, moving the position at most
    /// [`MATCH_STEP_UM`]. Returns the corrected pose of that moment, or why the match was
    /// refused.
    pub fn apply_match(
        &mut self,
        matched: &Match,
        noise: &MatchNoise,
        map: &MapUncertainty,
    ) -> Result<Pose, MatchRefusal> {
        self.apply_match_within(matched, noise, map, MATCH_STEP_UM)
    }

    /// [`Estimator::apply_match`], moving the position at most `step_um`: a match that
    /// would move it further is taken again with its covariance widened (deviations
    /// doubled, up to 64 times) until it does not, and refused as beyond the gate if it
    /// still would.
    pub fn apply_match_within(
        &mut self,
        matched: &Match,
        noise: &MatchNoise,
        map: &MapUncertainty,
        step_um: u32,
    ) -> Result<Pose, MatchRefusal> {
        if self.turned_past_gate(matched, noise) {
            return Err(MatchRefusal::Gate);
        }
        let parts = Components::of(matched, noise);
        let floors = noise.floors(map);
        self.stepped(
            &matched.prediction,
            step_um,
            |trial, widened| match widened {
                0 => trial.matched(matched.pins, &parts, &floors),
                bits => trial.matched(matched.pins, &parts.widened(bits), &floors),
            },
        )
    }

    /// Whether `matched` measures the heading and turns it from its prediction by more
    /// than [`TURN_GATE_SIGMAS`] of the filter's own heading deviations (with `noise`'s
    /// heading floor). The match's spread is its surface's over the search window, widened
    /// for the map's errors before the gate: where a wall is drawn ragged (along a cell's
    /// edge) the surface can lean to a heading the robot cannot have turned to, the lean
    /// passing that gate, and the matches after it repeat it. Such a match is refused at
    /// the gate, as a camera's leap is.
    fn turned_past_gate(&self, matched: &Match, noise: &MatchNoise) -> bool {
        if matches!(matched.pins, Pins::PositionOnly | Pins::AcrossOnly(_)) {
            return false;
        }
        let turned = mdeg_of_bits(matched.pose.heading.diff(matched.prediction.heading));
        // The heading's variance in millidegrees squared; within 2^31 units squared, so
        // the product fits 64 bits.
        let filter = (self.p.get(State::Heading, State::Heading).max(0)
            * units::MDEG2_PER_HEADING2_Q16)
            >> 16;
        let floor = i64::from(noise.floor_heading_mdeg);
        turned * turned > (filter + floor * floor) * (TURN_GATE_SIGMAS * TURN_GATE_SIGMAS)
    }

    /// Updates the filter from a drive's measurement of the flow sensor's scale
    /// ([`crate::wall_rate`]), taken at `then`, the pose now, moving the position at most
    /// [`MATCH_STEP_UM`] as a match does: the scale's error moved the pose along the drive,
    /// and the filter's belief of how much is corrected with it. Returns the corrected
    /// pose, `None` if the filter already knows the scale better than the drive measured
    /// it (tags teach it fast; the drive would add little and move what they placed), or
    /// why the measurement was refused.
    pub fn apply_flow_scale(
        &mut self,
        then: &Pose,
        measured: &FlowScale,
    ) -> Option<Result<Pose, MatchRefusal>> {
        let sd = units::scale_from_ppm(i64::from(measured.sd_ppm)).max(1);
        if self.p.get(State::FlowScale, State::FlowScale) <= sd.saturating_mul(sd) {
            return None;
        }
        let learned = i64::from(self.calibration().flow_scale_ppm);
        let nu = units::scale_from_ppm(i64::from(measured.scale_ppm) - learned);
        Some(self.measured(then, MATCH_STEP_UM, State::FlowScale, nu, sd))
    }

    /// Updates the filter from a measurement of the gyro's scale, `scale_ppm` with
    /// deviation `sd_ppm`, taken at `then`, the pose now (a turn's closure,
    /// [`crate::spin_closure`]). Returns the corrected pose, or why it was refused.
    pub fn apply_gyro_scale(
        &mut self,
        then: &Pose,
        scale_ppm: i32,
        sd_ppm: i32,
    ) -> Result<Pose, MatchRefusal> {
        let sd = units::scale_from_ppm(i64::from(sd_ppm)).max(1);
        let learned = i64::from(self.calibration().gyro_scale_ppm);
        let nu = units::scale_from_ppm(i64::from(scale_ppm) - learned);
        self.measured(then, u32::MAX, State::GyroScale, nu, sd)
    }

    /// Updates the filter from a measurement of the heading, `off_mdeg` from the heading
    /// of `then`, the pose now, with deviation `sd_mdeg` (a turn's closure). Returns the
    /// corrected pose, or why it was refused.
    pub fn apply_heading(
        &mut self,
        then: &Pose,
        off_mdeg: i32,
        sd_mdeg: i32,
    ) -> Result<Pose, MatchRefusal> {
        let sd = units::heading_from_mdeg(i64::from(sd_mdeg)).max(1);
        let nu = units::heading_from_mdeg(i64::from(off_mdeg));
        self.measured(then, u32::MAX, State::Heading, nu, sd)
    }

    /// One state measured directly: innovation `nu` and deviation `sd`, the state's own
    /// units, through [`Estimator::stepped`].
    fn measured(
        &mut self,
        then: &Pose,
        step_um: u32,
        state: State,
        nu: i64,
        sd: i64,
    ) -> Result<Pose, MatchRefusal> {
        self.stepped(then, step_um, |trial, widened| {
            let scalar = Scalar {
                h: [(state, 1 << 16), (State::X, 0), (State::Y, 0)],
                nu,
                r: (sd * sd).saturating_mul(1 << widened),
                floor: 0,
            };
            let mut fine = [0i64; N];
            trial.update_pair(scalar, None, &mut fine)?;
            Ok(fine)
        })
    }

    /// One update, `attempt`, tried on a copy of the filter with its measurement's
    /// covariance widened by `widened` bits (0 first): if it would move the position
    /// further than `step_um` it is tried again widened (deviations doubled, up to 64
    /// times), and refused as beyond the gate if it still would. Each part of an update is
    /// gated given the ones before, and one beyond the gate refuses the whole, so the
    /// parts go into a copy (a 6 x 6 matrix: a few hundred bytes). Returns the pose `then`
    /// corrected.
    fn stepped(
        &mut self,
        then: &Pose,
        step_um: u32,
        attempt: impl Fn(&mut Estimator, u32) -> Result<[i64; N], MatchRefusal>,
    ) -> Result<Pose, MatchRefusal> {
        let mut widened = 0;
        loop {
            let mut trial = self.clone();
            let fine = attempt(&mut trial, widened)?;
            if !steps_further(&fine, step_um) {
                *self = trial;
                return Ok(self.corrected(then, fine));
            }
            widened += WIDEN_SHIFT;
            if widened > MOST_WIDENED {
                return Err(MatchRefusal::Gate);
            }
        }
    }

    /// Updates the filter from the match's components `parts`, measured along what `pins`
    /// says; returns the state correction in fine units.
    fn matched(
        &mut self,
        pins: Pins,
        parts: &Components,
        floors: &Floors,
    ) -> Result<[i64; N], MatchRefusal> {
        use Component::{Across, Along, Heading};
        // The heading second: a match that cannot place the robot along a wall still
        // turns it.
        let order: &[Component] = match pins {
            Pins::All => &[Across, Heading, Along],
            Pins::AllButAlong(_) => &[Across, Heading],
            Pins::AcrossOnly(_) => &[Across],
            Pins::PositionOnly => &[Across, Along],
            Pins::HeadingOnly => &[Heading],
        };
        let (scalars, n) = parts
            .whitened(order, floors)
            .ok_or(MatchRefusal::NothingPinned)?;
        let scalars = scalars.get(..n).unwrap_or(&[]);
        let mut fine = [0i64; N];
        for pair in scalars.chunks(2) {
            self.update_pair(pair[0], pair.get(1).copied(), &mut fine)?;
        }
        Ok(fine)
    }

    /// One or two scalar measurements as one update, the second conditioned on the first
    /// (as a tag's range and bearing), gated on their joint chi-square; adds the state
    /// correction, in fine units, to `fine`.
    fn update_pair(
        &mut self,
        first: Scalar,
        second: Option<Scalar>,
        fine: &mut [i64; N],
    ) -> Result<(), MatchRefusal> {
        // The state corrections of an earlier pair move the innovations of this one.
        let moved = |m: &Scalar| {
            let shift: i64 =
                m.h.iter()
                    .map(|&(j, v)| mul_shift(fine[j as usize], i64::from(v), 16 + FINE_SHIFT))
                    .sum();
            Scalar {
                nu: m.nu - shift,
                ..*m
            }
        };
        let first = moved(&first);
        let a1 = self.p.times_unit_row(&first.h);
        let prior1 = dot(&first.h, &a1);
        let Some(r1) = floored_noise(prior1, &first) else {
            // The filter knows this direction better than the map can: only the second.
            return match second {
                Some(m) => self.update_pair(m, None, fine),
                None => Ok(()),
            };
        };
        let s1 = prior1.saturating_add(r1);
        let inv1 = Reciprocal::of(s1).ok_or(MatchRefusal::Gate)?;
        let mut chi2 = normalised_square_q8(first.nu, &inv1);
        let (a2, inv2, nu2) = match second.map(|m| moved(&m)) {
            Some(m) => {
                let a = self.p.times_unit_row(&m.h);
                let s_cross = dot(&first.h, &a);
                let k = inv1.times(s_cross, 16);
                let nu = m.nu.saturating_sub(mul_shift(k, first.nu, 16));
                // The second's variance given the first, before its own noise.
                let prior2 = dot(&m.h, &a).saturating_sub(mul_shift(k, s_cross, 16));
                match floored_noise(prior2, &m) {
                    Some(r2) => {
                        let mut given = a;
                        for (g, r) in given.iter_mut().zip(a1) {
                            *g = g.saturating_sub(mul_shift(k, r, 16));
                        }
                        let s2 = prior2.saturating_add(r2);
                        let inv = Reciprocal::of(s2).ok_or(MatchRefusal::Gate)?;
                        chi2 = chi2.saturating_add(normalised_square_q8(nu, &inv));
                        (given, inv, nu)
                    }
                    // Nothing to learn along it: the first alone.
                    None => ([0; N], inv1, 0),
                }
            }
            None => ([0; N], inv1, 0),
        };
        if chi2 > i64::from(self.config.gate_chi2_q8) {
            return Err(MatchRefusal::Gate);
        }
        let [k1, k2] = self.p.update([(&a1, &inv1), (&a2, &inv2)]);
        for ((f, g1), g2) in fine.iter_mut().zip(k1).zip(k2) {
            *f = f
                .saturating_add(mul_shift(g1, first.nu, GAIN_SHIFT - FINE_SHIFT))
                .saturating_add(mul_shift(g2, nu2, GAIN_SHIFT - FINE_SHIFT));
        }
        Ok(())
    }
}
