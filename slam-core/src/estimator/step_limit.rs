//! How far one update may move the position. A correction larger than that is taken in
//! part, and the rest of the way comes over the next measurements, so that the map is
//! never written across a jump.

use super::covariance::N;
use super::units;
use super::State;
use crate::frame::MAX_TAGS;
use crate::pose::isqrt;

/// The furthest one picture's tag sightings together may move the position at its
/// moment where the map is matched, micrometres: 2 cm, as a match
/// ([`super::MATCH_STEP_UM`]), inside the 3 cm a tick that issue 11 allows. A robot back
/// in sight of a tag after a long while without one is brought back over a few pictures
/// rather than in one leap.
pub const TAG_STEP_UM: u32 = 20_000;

/// One sighting's part of a picture's [`TAG_STEP_UM`], for a picture of `n` tags: each
/// may move the position `TAG_STEP_UM / n`.
#[derive(Debug, PartialEq, Eq)]
pub struct TagShare {
    /// How far the sighting may move the position, micrometres.
    pub(super) step_um: u32,
    /// The square of that in position units, Q8, less a sixteenth for rounding: a
    /// sighting whose correction is surely shorter is taken whole without being
    /// measured ([`Estimator::sight`](super::Estimator::sight)). Under 2^25.
    pub(super) surely_within_q8: u32,
}

/// [`TagShare`] for pictures of 0 to [`MAX_TAGS`] tags, worked out at compile time.
static TAG_SHARES: [TagShare; MAX_TAGS + 1] = {
    const NONE: TagShare = TagShare {
        step_um: 0,
        surely_within_q8: 0,
    };
    let mut shares = [NONE; MAX_TAGS + 1];
    let mut n = 0;
    while n <= MAX_TAGS {
        let step_um = TAG_STEP_UM / if n == 0 { 1 } else { n as u32 };
        let step = step_um as u64 * units::POSITION_PER_MM as u64 / 1000;
        shares[n] = TagShare {
            step_um,
            surely_within_q8: (step * step * 256 * 15 / 16) as u32,
        };
        n += 1;
    }
    shares
};

impl TagShare {
    /// Each sighting's share of a picture of `sightings` tags.
    pub fn of(sightings: usize) -> &'static TagShare {
        TAG_SHARES.get(sightings).unwrap_or(&TAG_SHARES[MAX_TAGS])
    }
}

/// Whether the correction `fine` moves the position further than `step_um`.
pub(super) fn steps_further(fine: &[i64; N], step_um: u32) -> bool {
    let dx = units::um_from_fine_position(fine[State::X as usize]);
    let dy = units::um_from_fine_position(fine[State::Y as usize]);
    further((dx, dy), step_um).is_some()
}

/// The square of a move by `(dx, dy)` micrometres, if it is longer than `step_um`.
fn further((dx, dy): (i64, i64), step_um: u32) -> Option<u64> {
    // Each held within 2^31 um (2 km) before squaring: the sum fits 64 bits unsigned.
    let square = |d: i64| d.unsigned_abs().min(1 << 31).pow(2);
    let squared = square(dx) + square(dy);
    let most = u64::from(step_um);
    (squared > most * most).then_some(squared)
}

/// The share of a move of the position by `(dx, dy)` micrometres that moves it
/// `step_um`, Q16 (below 1.0), or `None` if the whole moves it no further.
pub(super) fn share_of_move(moved: (i64, i64), step_um: u32) -> Option<i64> {
    let squared = further(moved, step_um)?;
    let most = u64::from(step_um);
    let length = isqrt(squared).max(1);
    Some(((most << 16) / length).min((1 << 16) - 1) as i64)
}
