//! From the score surface to a pose, a covariance and the directions it cannot pin.
//!
//! Olson (2009): read the surface as a likelihood, `exp` of the score, and take its mean
//! and second moment about the mean. In integers the weight of a candidate is a table of
//! `2^(-d / halving)` for its score `d` below the best: 8 entries a halving, zero past 12
//! halvings. The mean rather than the best candidate: the map's cells are five times the
//! search step, so the best is a plateau and its middle is the estimate.
//!
//! A direction along which the weighted spread is near the spread of the whole window
//! (`(R^2 + R) / 3` steps squared for `2R + 1` steps) is one the surface does not pin:
//! along a flat wall, along a corridor, every heading when the ends fall on nothing known.

use super::divide::Divider;
use super::search::{Surface, PRUNED};
use crate::angle::Angle;
use crate::pose::isqrt;

/// `round(4096 * 2^(-i / 8))`: the weight of a candidate `i / 8` halvings below the best.
const WEIGHT: [u16; 96] = [
    4096, 3756, 3444, 3158, 2896, 2656, 2435, 2233, 2048, 1878, 1722, 1579, 1448, 1328, 1218, 1117,
    1024, 939, 861, 790, 724, 664, 609, 558, 512, 470, 431, 395, 362, 332, 304, 279, 256, 235, 215,
    197, 181, 166, 152, 140, 128, 117, 108, 99, 91, 83, 76, 70, 64, 59, 54, 49, 45, 41, 38, 35, 32,
    29, 27, 25, 23, 21, 19, 17, 16, 15, 13, 12, 11, 10, 10, 9, 8, 7, 7, 6, 6, 5, 5, 4, 4, 4, 3, 3,
    3, 3, 2, 2, 2, 2, 2, 2, 1, 1, 1, 1,
];

/// Table entries per halving.
const PER_HALVING: i32 = 8;

/// The variance of rounding to a step, a twelfth of a step squared, in 1/65536 step
/// squared.
const QUANTISATION_Q16: i64 = 65536 / 12;

/// The score drop, for a given `halving`, past which a candidate weighs nothing.
pub(super) const fn cutoff(halving: i32) -> i32 {
    (WEIGHT.len() as i32 * halving + PER_HALVING - 1) / PER_HALVING
}

/// The surface's best score, weighted mean and second moment, in search steps.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub(super) struct Moments {
    /// The best score on the surface.
    pub best: i32,
    /// The lowest score computed (pruned headings aside).
    pub worst: i32,
    /// The offset from the prediction of the best candidate nearest it, `[x, y,
    /// heading]`, in steps.
    pub peak: [i64; 3],
    /// Mean offset from the prediction, `[x, y, heading]`, in 1/256 of a step.
    pub mean_q8: [i32; 3],
    /// Covariance about the mean, in 1/65536 of a step squared, `[x, y, heading]`.
    pub covariance_q16: [[i64; 3]; 3],
}

/// The moments of `surface`'s weights; `None` if nothing was scored.
///
/// Plain index loops and 32-bit products where they fit: this runs over every candidate
/// of every match, and on the M0+ nested iterators copy their rows and a 64-bit multiply
/// is a library call.
pub(super) fn moments<const SIDE: usize, const TURNS: usize>(
    surface: &Surface<SIDE, TURNS>,
    halving: i32,
) -> Option<Moments> {
    let (mut best, mut worst) = (PRUNED, i32::MAX);
    for plane in surface.iter() {
        for row in plane.iter() {
            for &s in row.iter().filter(|&&s| s != PRUNED) {
                best = best.max(s);
                worst = worst.min(s);
            }
        }
    }
    if best == PRUNED {
        return None;
    }
    let halving = halving.max(1);
    let divider = Divider::new(halving)?;
    // A drop this far below the best, times `PER_HALVING`, is past the table: weight 0.
    let past_table = (WEIGHT.len() as i32).saturating_mul(halving);
    let weight = |s: i32| -> i32 {
        if s == PRUNED {
            return 0;
        }
        let drop = (best - s).saturating_mul(PER_HALVING);
        if drop >= past_table {
            return 0;
        }
        let (index, _) = divider.div_rem(drop);
        usize::try_from(index)
            .ok()
            .and_then(|i| WEIGHT.get(i))
            .map_or(0, |&w| i32::from(w))
    };
    let (half_side, half_turns) = ((SIDE / 2) as i32, (TURNS / 2) as i32);
    // One pass: the weights' sum, first moments and second moments about the middle, each
    // candidate's offsets from the middle in steps, `[x, y, heading]`. Within a heading
    // plane the heading's offset is the same for every candidate, so the sums over a plane
    // are kept in 32 bits (a weight below 2^13 times two position offsets below 2^2, over
    // `SIDE^2` candidates) and the heading's terms come from them once a plane.
    const {
        let (side, most) = (SIDE as u64, WEIGHT[0] as u64);
        assert!(side * side * (side / 2) * (side / 2) * most <= i32::MAX as u64);
    }
    let (mut total, mut sum) = (0i64, [0i64; 3]);
    let mut about_middle = [[0i64; 3]; 3];
    let mut peak = [0i32; 3];
    let mut peak_distance = i32::MAX;
    for (k, plane) in surface.iter().enumerate() {
        let h = k as i32 - half_turns;
        let (mut w_sum, mut x_sum, mut y_sum, mut xx, mut xy, mut yy) = (0i32, 0, 0, 0, 0, 0);
        for (j, row) in plane.iter().enumerate() {
            let y = j as i32 - half_side;
            for (i, &s) in row.iter().enumerate() {
                let x = i as i32 - half_side;
                if s == best {
                    let distance = x * x + y * y + h * h;
                    if distance < peak_distance {
                        (peak, peak_distance) = ([x, y, h], distance);
                    }
                }
                let w = weight(s);
                if w == 0 {
                    continue;
                }
                let (wx, wy) = (w * x, w * y);
                w_sum += w;
                x_sum += wx;
                y_sum += wy;
                xx += wx * x;
                xy += wx * y;
                yy += wy * y;
            }
        }
        let (w_sum, x_sum, y_sum, h) = (
            i64::from(w_sum),
            i64::from(x_sum),
            i64::from(y_sum),
            i64::from(h),
        );
        total += w_sum;
        sum[0] += x_sum;
        sum[1] += y_sum;
        sum[2] += w_sum * h;
        about_middle[0][0] += i64::from(xx);
        about_middle[0][1] += i64::from(xy);
        about_middle[1][1] += i64::from(yy);
        about_middle[0][2] += x_sum * h;
        about_middle[1][2] += y_sum * h;
        about_middle[2][2] += w_sum * h * h;
    }
    about_middle[1][0] = about_middle[0][1];
    about_middle[2][0] = about_middle[0][2];
    about_middle[2][1] = about_middle[1][2];
    if total == 0 {
        return None;
    }
    let mean_q8 = sum.map(|s| round_div(s << 8, total) as i32);
    // About the mean, in 1/256 steps: sum w (256 o_a - m_a)(256 o_b - m_b), expanded, in
    // integers and so exactly.
    let second: [[i64; 3]; 3] = core::array::from_fn(|a| {
        core::array::from_fn(|b| {
            let (ma, mb) = (i64::from(mean_q8[a]), i64::from(mean_q8[b]));
            (about_middle[a][b] << 16) - ((mb * sum[a] + ma * sum[b]) << 8) + ma * mb * total
        })
    });
    let mut covariance_q16 = second.map(|row| row.map(|v| round_div(v, total)));
    // A surface sampled a step apart cannot say more than a step: each axis keeps at least
    // the variance of rounding to it, a twelfth of a step squared.
    for (a, row) in covariance_q16.iter_mut().enumerate() {
        if let Some(v) = row.get_mut(a) {
            *v += QUANTISATION_Q16;
        }
    }
    Some(Moments {
        best,
        worst,
        peak: peak.map(i64::from),
        mean_q8,
        covariance_q16,
    })
}

/// What the surface pins, from its covariance in steps.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub(super) struct Spread {
    /// The position's larger variance, in 1/65536 step squared, and the direction along
    /// which it lies (a line: within a quarter turn of +y).
    pub wide: (i64, Angle),
    /// The position's smaller variance.
    pub narrow: i64,
}

/// The principal axes of the position block of `c` (Q16 steps squared).
pub(super) fn spread(c: &[[i64; 3]; 3]) -> Spread {
    let (a, b, d) = (c[0][0], c[0][1], c[1][1]);
    let middle = (a + d) / 2;
    let half_gap = (a - d) / 2;
    let root = isqrt((half_gap * half_gap + b * b).unsigned_abs()) as i64;
    let (wide, narrow) = (middle + root, (middle - root).max(0));
    // The eigenvector of `wide`: (wide - d, b) or (b, wide - a), whichever is longer.
    let (u, v) = ((wide - d, b), (b, wide - a));
    let (x, y) = if u.0.abs() + u.1.abs() >= v.0.abs() + v.1.abs() {
        u
    } else {
        v
    };
    Spread {
        wide: (wide, line_of(x, y)),
        narrow,
    }
}

/// The line through the vector `(x, y)`, as the angle of its direction within a quarter
/// turn of +y.
pub(super) fn line_of(x: i64, y: i64) -> Angle {
    let mut along = Angle::of_vector(x, y);
    let quarter = Angle::QUARTER_TURN.signed_bits();
    if along.signed_bits() >= quarter || along.signed_bits() < -quarter {
        along += Angle::HALF_TURN;
    }
    along
}

/// Where the surface still rises at the window's edge: its best candidate nearest the
/// prediction lies on a face of the window, so the best fit is outside what was
/// searched, or nowhere. A sweep's newest ends run past the walls the map holds so far
/// (the map lags the sweep), and pulling them back onto those walls scores: along a wall
/// driven beside, round a turn on the spot. The surface's moments say nothing true along
/// a rising direction.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub(super) struct Rising {
    /// The position line along which it rises, if it does.
    pub position: Option<Angle>,
    /// Whether it rises at a heading face.
    pub heading: bool,
}

/// Where a `SIDE` x `SIDE` x `TURNS` surface whose best candidate nearest the prediction
/// is `peak` (in steps) still rises. The position's line is the surface's slope, not the
/// peak's offset: a ramp along a wall with a peak across it puts the peak in a corner of
/// the window, off the wall's line.
pub(super) fn rising<const SIDE: usize, const TURNS: usize>(
    surface: &Surface<SIDE, TURNS>,
    peak: &[i64; 3],
) -> Rising {
    let (half, half_turns) = ((SIDE / 2) as i64, (TURNS / 2) as i64);
    let [px, py, ph] = *peak;
    let on_face = px.abs() >= half || py.abs() >= half;
    Rising {
        position: on_face.then(|| match slope(surface) {
            [0, 0] => line_of(px, py),
            [sx, sy] => line_of(sx, sy),
        }),
        heading: ph.abs() >= half_turns,
    }
}

/// The least-squares slope over the translations of each one's best score over the
/// headings, `[x, y]` (unnormalised): which way the position's fit improves.
fn slope<const SIDE: usize, const TURNS: usize>(surface: &Surface<SIDE, TURNS>) -> [i64; 2] {
    let mut top = [[PRUNED; SIDE]; SIDE];
    for plane in surface.iter() {
        for (top_row, row) in top.iter_mut().zip(plane.iter()) {
            for (t, &s) in top_row.iter_mut().zip(row.iter()) {
                *t = (*t).max(s);
            }
        }
    }
    let half = (SIDE / 2) as i64;
    let mut slope = [0i64; 2];
    for (j, row) in top.iter().enumerate() {
        for (i, &t) in row.iter().enumerate().filter(|&(_, &t)| t != PRUNED) {
            slope[0] += (i as i64 - half) * i64::from(t);
            slope[1] += (j as i64 - half) * i64::from(t);
        }
    }
    slope
}

/// The variance, in 1/65536 step squared, of a uniform spread over `2 half + 1` steps.
pub(super) const fn uniform_q16(half: i64) -> i64 {
    (half * half + half) * 65536 / 3
}

/// `a / b` rounded half away from zero, `b > 0`.
fn round_div(a: i64, b: i64) -> i64 {
    if a >= 0 {
        (a + b / 2) / b
    } else {
        (a - b / 2) / b
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn degrees(a: Angle) -> f64 {
        f64::from(a.signed_bits()) * 360.0 / 4_294_967_296.0
    }

    /// Where a 7 x 7 x 17 surface rises with its best at `peak` and its scores sloping
    /// `slope` (per step along x and y), the same at every heading.
    fn peaked(peak: [i64; 3], slope: [i64; 2]) -> Rising {
        let mut surface = [[[0i32; 7]; 7]; 17];
        for plane in surface.iter_mut() {
            for (j, row) in plane.iter_mut().enumerate() {
                for (i, s) in row.iter_mut().enumerate() {
                    *s = ((i as i64 - 3) * slope[0] + (j as i64 - 3) * slope[1]) as i32;
                }
            }
        }
        rising::<7, 17>(&surface, &peak)
    }

    #[test]
    fn a_peak_inside_the_window_rises_nowhere() {
        let r = peaked([2, -2, 7], [100, 5]);
        assert_eq!(r.position, None);
        assert!(!r.heading);
    }

    #[test]
    fn a_peak_on_a_face_rises_along_the_slope_not_the_peak() {
        // On the -x face and off the middle in y: the slope, nearly along x, is the line.
        let line = peaked([-3, 2, 0], [-300, 10]).position.expect("on a face");
        assert!(
            (degrees(line).abs() - 90.0).abs() < 3.0,
            "{}",
            degrees(line)
        );
        // No slope at all: the peak's own offset.
        let line = peaked([3, 3, 0], [0, 0]).position.expect("in a corner");
        assert!((degrees(line) - 45.0).abs() < 1.0, "{}", degrees(line));
    }

    #[test]
    fn a_peak_on_a_heading_face_rises_in_heading() {
        assert!(peaked([0, 0, -8], [0, 0]).heading);
        assert!(peaked([0, 0, 8], [0, 0]).heading);
        assert!(!peaked([0, 0, 7], [0, 0]).heading);
    }
}
