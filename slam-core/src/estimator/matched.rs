//! A scan match as a filter update: the matched pose of the sweep's moment, measured only
//! along the directions the match pins, with the covariance its score surface shows.
//!
//! The position is measured along the two principal directions of the match's position
//! covariance (where its cross term vanishes) and the heading on its own; the match's
//! correlation between heading and position is left out, which a scalar update cannot
//! carry. Each pair of measurements is one two-row update of the covariance, gated at the
//! tags' chi-square; an unpinned direction is simply not measured.

use super::covariance::{GAIN_SHIFT, N};
use super::filter::Estimator;
use super::fixed::{fits_i32, mul_shift, square, Reciprocal};
use super::units::{self, FINE_SHIFT};
use super::State;
use crate::angle::Angle;
use crate::matcher::{Match, MatchRefusal, Pins};
use crate::pose::{isqrt, Pose};

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
}

impl MatchNoise {
    /// The seed's: a match's spread doubled, plus 3 mm and 0.3 degrees.
    pub const SEED: MatchNoise = MatchNoise {
        position_um: 3_000,
        heading_mdeg: 300,
        scale_pct: 200,
    };
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

/// One scalar measurement: a unit row (Q16), the innovation and its noise, in covariance
/// units.
#[derive(Clone, Copy)]
struct Scalar {
    h: [(State, i32); 2],
    nu: i64,
    r: i64,
}

/// `h a` for a sparse Q16 row `h`.
fn dot(h: &[(State, i32); 2], a: &[i64; N]) -> i64 {
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

impl Estimator {
    /// Updates the filter from `matched`, the sweep's pose at its newest scan's moment
    /// against `matched.prediction`, the pose believed then. Returns the corrected pose
    /// of that moment, or [`MatchRefusal::Gate`].
    pub fn apply_match(
        &mut self,
        matched: &Match,
        noise: &MatchNoise,
    ) -> Result<Pose, MatchRefusal> {
        let then = matched.prediction;
        let c = &matched.covariance;
        let dx = i64::from(matched.pose.x_um) - i64::from(then.x_um);
        let dy = i64::from(matched.pose.y_um) - i64::from(then.y_um);
        // Along the wider spread (sin a, cos a) and across it (cos a, -sin a).
        let along_angle = matched.wide;
        let (s, co) = (i64::from(along_angle.sin()), i64::from(along_angle.cos()));
        let directional = |ux: i64, uy: i64| {
            // u^T C u in um^2, the unit vector in Q16.
            let var = (mul_shift(c.xx_um2, ux * ux, 32)
                + 2 * mul_shift(c.xy_um2, ux * uy, 32)
                + mul_shift(c.yy_um2, uy * uy, 32))
            .max(0);
            let nu_um = mul_shift(dx, ux, 16) + mul_shift(dy, uy, 16);
            let sigma_um = i64::from(isqrt(var as u64) as u32) * i64::from(noise.scale_pct) / 100
                + i64::from(noise.position_um);
            Scalar {
                h: [(State::X, ux as i32), (State::Y, uy as i32)],
                nu: units::position_from_um(nu_um),
                r: square(units::position_from_um(sigma_um)).max(1),
            }
        };
        let along = directional(s, co);
        let across = directional(co, -s);
        let heading = {
            let dh = (matched.pose.heading - then.heading).signed_bits();
            let sigma_mdeg = i64::from(isqrt(c.hh_mdeg2.max(0) as u64) as u32)
                * i64::from(noise.scale_pct)
                / 100
                + i64::from(noise.heading_mdeg);
            Scalar {
                h: [(State::Heading, 1 << 16), (State::X, 0)],
                nu: units::heading_from_bits(i64::from(dh)),
                r: square(units::heading_from_mdeg(sigma_mdeg)).max(1),
            }
        };
        let mut fine = [0i64; N];
        match matched.pins {
            Pins::All => {
                self.update_pair(across, Some(heading), &mut fine)?;
                // The along direction after: a refusal of it alone keeps the first pair.
                let _ = self.update_pair(along, None, &mut fine);
            }
            Pins::AllButAlong(_) => self.update_pair(across, Some(heading), &mut fine)?,
            Pins::AcrossOnly(_) => self.update_pair(across, None, &mut fine)?,
            Pins::PositionOnly => self.update_pair(across, Some(along), &mut fine)?,
            Pins::HeadingOnly => self.update_pair(heading, None, &mut fine)?,
        }
        self.bound_variances();
        let [fx, fy, fh, gs, gb, fs] = fine;
        self.correct_calibration([gs, gb, fs]);
        let shift = |um: i32, fine: i64| {
            (i64::from(um) + units::um_from_fine_position(fine))
                .clamp(i32::MIN as i64, i32::MAX as i64) as i32
        };
        Ok(Pose {
            x_um: shift(then.x_um, fx),
            y_um: shift(then.y_um, fy),
            heading: then.heading + Angle::from_bits(units::bits_from_fine_heading(fh) as u32),
        })
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
        let s1 = dot(&first.h, &a1).saturating_add(first.r);
        let inv1 = Reciprocal::of(s1).ok_or(MatchRefusal::Gate)?;
        let mut chi2 = normalised_square_q8(first.nu, &inv1);
        let (a2, inv2, nu2) = match second.map(|m| moved(&m)) {
            Some(m) => {
                let a = self.p.times_unit_row(&m.h);
                let s_cross = dot(&first.h, &a);
                let s2 = dot(&m.h, &a).saturating_add(m.r);
                let k = inv1.times(s_cross, 16);
                let nu = m.nu.saturating_sub(mul_shift(k, first.nu, 16));
                let s2 = s2.saturating_sub(mul_shift(k, s_cross, 16));
                let mut given = a;
                for (g, r) in given.iter_mut().zip(a1) {
                    *g = g.saturating_sub(mul_shift(k, r, 16));
                }
                let inv = Reciprocal::of(s2).ok_or(MatchRefusal::Gate)?;
                chi2 = chi2.saturating_add(normalised_square_q8(nu, &inv));
                (given, inv, nu)
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
