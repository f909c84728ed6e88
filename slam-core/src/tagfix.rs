//! The two-tag fix: a pose from the range and bearing to two tags whose places are known.
//!
//! The line from one tag to the other is fixed on the mat, and the robot also sees it in
//! its own frame; the angle between the two is the heading. With the heading known, each
//! tag's range and bearing gives the position; we average the two.

use crate::angle::{sin_cos_of_vector, Angle, Direction};
use crate::camera_check::LeapLimit;
use crate::frame::TagDetection;
use crate::pose::{hypot, mul_q16_32, Pose, UM_PER_MM};

/// Most known tags a map can hold.
pub const MAX_KNOWN_TAGS: usize = 8;

/// Farthest a tag may be read, in millimetres: the camera link carries ranges in 16 bits,
/// so a farther one is a misread. The fix's 32-bit arithmetic is sized to hold up to here.
pub const MAX_RANGE_MM: u32 = u16::MAX as u32;

/// A tag whose place on the map somebody measured.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct KnownTag {
    /// The tag's id.
    pub id: u16,
    /// Map x of the tag's centre, in millimetres.
    pub x_mm: i32,
    /// Map y of the tag's centre, in millimetres.
    pub y_mm: i32,
}

/// The tags the robot knows, without an allocator.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TagMap {
    tags: [KnownTag; MAX_KNOWN_TAGS],
    len: u8,
}

impl TagMap {
    /// A map of the given tags; `None` if there are too many or an id repeats.
    pub fn new(tags: &[KnownTag]) -> Option<TagMap> {
        let mut map = TagMap::default();
        for t in tags {
            if map.get(t.id).is_some() {
                return None;
            }
            *map.tags.get_mut(map.len as usize)? = *t;
            map.len += 1;
        }
        Some(map)
    }

    /// The known tag with this id.
    pub fn get(&self, id: u16) -> Option<&KnownTag> {
        self.as_slice().iter().find(|t| t.id == id)
    }

    /// All known tags.
    pub fn as_slice(&self) -> &[KnownTag] {
        self.tags.get(..self.len as usize).unwrap_or(&[])
    }
}

/// The camera's intrinsics, as the bearing formula needs them.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CameraConfig {
    /// Focal length in hundredths of a pixel (the seed's 92.4 px is 9240).
    pub focal_centipx: i32,
    /// Optical centre column in hundredths of a pixel (160 px of a 320 px picture is 16000).
    pub centre_centipx: i32,
}

impl CameraConfig {
    /// The seed's camera: 320 px wide, 120 degree view, focal length 92.4 px.
    pub const SEED: CameraConfig = CameraConfig {
        focal_centipx: 9240,
        centre_centipx: 16000,
    };

    /// The bearing of a picture column from the nose: `atan((cx - centre) / focal)`, positive right.
    pub fn bearing(&self, cx_centipx: i32) -> Angle {
        Angle::of_vector(
            cx_centipx as i64 - self.centre_centipx as i64,
            self.focal_centipx as i64,
        )
    }

    /// `(sin, cos)` in Q16 of [`CameraConfig::bearing`], without the angle: the ray's
    /// direction straight from the column, with no CORDIC (see [`sin_cos_of_vector`]).
    pub fn ray(&self, cx_centipx: i32) -> (i32, i32) {
        // Saturated: a column 2^31 centipixels off centre is as good as a right angle.
        let offset = (cx_centipx as i64 - self.centre_centipx as i64)
            .clamp(i32::MIN as i64, i32::MAX as i64) as i32;
        sin_cos_of_vector(offset, self.focal_centipx)
    }
}

/// When a fix is believed.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FixConfig {
    /// The seen distance between the two tags may differ from the true one by this
    /// many per-mille before the geometry is called inconsistent.
    pub baseline_tolerance_permille: u32,
    /// Tags closer together than this, in millimetres, give too short a baseline for a heading.
    pub min_baseline_mm: u32,
    /// A tag read nearer than this, in millimetres, is a misread.
    pub min_range_mm: u32,
    /// A fix further than this from the predicted position, in millimetres, is rejected.
    pub gate_position_mm: u32,
    /// A fix whose heading differs from the prediction by more than this, in millidegrees,
    /// is rejected.
    pub gate_heading_mdeg: u32,
    /// After this many gate rejections in a row the fix is taken anyway: the prediction,
    /// not the tags, is then the likelier liar (a stalled flow sensor, a kidnapped robot).
    /// 0 never overrides the gate. The filter counts pictures whose every sighting the
    /// gate refused, and past this many in a row may forget its heading instead
    /// ([`crate::Estimator::forget_heading`]).
    pub relocalise_after: u8,
    /// How far the first sighting refused after one taken may be off before the refusals
    /// are the camera's leap and never make the filter forget its heading
    /// ([`crate::camera_check`]).
    pub leap: LeapLimit,
}

impl FixConfig {
    /// Gates sized for the seed mat: a fix may move the pose 30 cm and 20 degrees at most.
    pub const SEED: FixConfig = FixConfig {
        baseline_tolerance_permille: 200,
        min_baseline_mm: 100,
        min_range_mm: 50,
        gate_position_mm: 300,
        gate_heading_mdeg: 20_000,
        relocalise_after: 5,
        leap: LeapLimit::SEED,
    };
}

/// Why a fix was not taken.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FixRejection {
    /// The tags' baseline is too short, or the seen distance between them disagrees with
    /// the map's by more than the tolerance: a misread, or a tag moved.
    Geometry,
    /// The fix disagrees with the prediction by more than the gate.
    Gate,
    /// The picture is older than the pose history reaches, so there is no believed pose
    /// of that moment to gate it against or carry it forward from.
    TooOld,
}

/// What the fix step did this tick.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FixOutcome {
    /// Fewer than two known tags were in view (or fixes are off).
    NotAttempted,
    /// The pose was reset to the fix.
    Taken,
    /// The fix was computed and thrown away.
    Rejected(FixRejection),
}

/// A tag's place in the robot frame: `(right, forward)` in sixteenths of a millimetre,
/// each below `2^20` in magnitude for a range up to [`MAX_RANGE_MM`].
fn robot_frame(d: &TagDetection, camera: &CameraConfig) -> (i32, i32) {
    let (sin, cos) = camera.ray(d.cx_centipx);
    let along = |unit: i32| {
        // A 16-bit range times a Q16 unit of at most 1.0 fits 32 bits unsigned.
        let sixteenths = ((d.distance_mm * unit.unsigned_abs() + (1 << 11)) >> 12) as i32;
        if unit < 0 {
            -sixteenths
        } else {
            sixteenths
        }
    };
    (along(sin), along(cos))
}

/// A vector scaled (up exactly, or down rounded) so that its larger component has 15 bits:
/// two such vectors' dot and cross products fit an `i32`. Direction error below 4.4e-5 rad.
fn to_15_bits(x: i64, y: i64) -> (i32, i32) {
    // Only a baseline over 2,147 km (from a nonsense tag map) needs the halving.
    let (x, y) = match (i32::try_from(x), i32::try_from(y)) {
        (Ok(x), Ok(y)) => (x, y),
        _ => ((x >> 1) as i32, (y >> 1) as i32),
    };
    let big = x.unsigned_abs().max(y.unsigned_abs());
    let width = 32 - big.leading_zeros();
    if width <= 15 {
        return (x << (15 - width), y << (15 - width));
    }
    let cut = width - 15;
    let round = |v: i32| {
        let m = (((v.unsigned_abs() >> (cut - 1)) + 1) >> 1).min((1 << 15) - 1) as i32;
        if v < 0 {
            -m
        } else {
            m
        }
    };
    (round(x), round(y))
}

/// The turn from direction `from` to direction `to`, `of_vector(to) - of_vector(from)`, as
/// the direction of `to` times `from`'s conjugate (as complex numbers `y + i x`).
fn turn_between(to: (i64, i64), from: (i64, i64)) -> Direction {
    // A zero vector's direction is zero, as `of_vector` has it.
    if from == (0, 0) || to == (0, 0) {
        let angle = Angle::of_vector(to.0, to.1) - Angle::of_vector(from.0, from.1);
        return Direction {
            angle,
            sin: angle.sin(),
            cos: angle.cos(),
        };
    }
    let (tx, ty) = to_15_bits(to.0, to.1);
    let (fx, fy) = to_15_bits(from.0, from.1);
    // Each product is below 2^30 and each sum below |to| |from| < 2^31.
    Direction::of_vector(tx * fy - ty * fx, tx * fx + ty * fy)
}

/// Whether the seen baseline's length is within `permille` of the true one's.
fn baseline_consistent(seen_mm: u64, true_mm: u64, permille: u32) -> bool {
    if seen_mm < 1 << 20 && true_mm < 1 << 20 && permille < 1 << 12 {
        // Every product below 2^32: no 64-bit multiply on the M0+.
        let (seen, truth) = (seen_mm as u32, true_mm as u32);
        seen.abs_diff(truth) * 1000 <= truth * permille
    } else {
        seen_mm.abs_diff(true_mm) as u128 * 1000 <= true_mm as u128 * permille as u128
    }
}

/// The midpoint of two map coordinates given in millimetres, in micrometres:
/// `(a + b) * 500`, by a 32-bit multiply for every coordinate within 2 km.
fn midpoint_um(a: i32, b: i32) -> i64 {
    let sum = a as i64 + b as i64;
    if sum.unsigned_abs() <= (i32::MAX / 500) as u64 {
        (sum as i32 * 500) as i64
    } else {
        wide_midpoint_um(sum)
    }
}

/// [`midpoint_um`] beyond 2 km, in 64 bits. Out of line so that the compiler does not fold
/// the 32-bit case into this one (the same product, as far as it can tell).
#[cold]
#[inline(never)]
fn wide_midpoint_um(sum_mm: i64) -> i64 {
    sum_mm * 500
}

/// The pose two detected known tags imply, or why they cannot give one.
///
/// Both tags' places in the robot frame come straight from the picture columns and ranges
/// (no bearing angle); the heading is the turn from the seen baseline to the map's; the
/// position is the tags' midpoint less the robot-frame midpoint turned into the map frame.
/// 32-bit arithmetic throughout, for the M0+.
pub fn two_tag_pose(
    (a, ta): Sighting<'_>,
    (b, tb): Sighting<'_>,
    camera: &CameraConfig,
    config: &FixConfig,
) -> Result<Pose, FixRejection> {
    // A tag read closer than this is a misread: no card fits in front of the lens.
    let plausible =
        |d: &TagDetection| (config.min_range_mm..=MAX_RANGE_MM).contains(&d.distance_mm);
    if !plausible(a) || !plausible(b) {
        return Err(FixRejection::Geometry);
    }
    let (ax, ay) = robot_frame(a, camera);
    let (bx, by) = robot_frame(b, camera);
    // In sixteenths of a millimetre, each below 2^21.
    let (seen_x, seen_y) = (bx - ax, by - ay);
    let (true_x, true_y) = (
        tb.x_mm as i64 - ta.x_mm as i64,
        tb.y_mm as i64 - ta.y_mm as i64,
    );
    let true_len = hypot(true_x, true_y);
    if true_len < config.min_baseline_mm as u64 {
        return Err(FixRejection::Geometry);
    }
    let mm = |sixteenths: i32| ((sixteenths + 8) >> 4) as i64;
    let seen_len = hypot(mm(seen_x), mm(seen_y));
    if !baseline_consistent(seen_len, true_len, config.baseline_tolerance_permille) {
        return Err(FixRejection::Geometry);
    }
    let Direction {
        angle: heading,
        sin,
        cos,
    } = turn_between((true_x, true_y), (seen_x as i64, seen_y as i64));
    // The robot sits at each tag less that tag's robot-frame place turned by the heading:
    // right-hand side along (cos, -sin), nose along (sin, cos). Averaged over both tags.
    let (right, forward) = (ax + bx, ay + by);
    let map_x = mul_q16_32(right, cos) + mul_q16_32(forward, sin);
    let map_y = mul_q16_32(forward, cos) - mul_q16_32(right, sin);
    // Half of each, from sixteenths of a millimetre (below 2^21.5) to micrometres: x 125 / 4.
    let half_um = |sixteenths: i32| ((sixteenths * 125 + 2) >> 2) as i64;
    let x = midpoint_um(ta.x_mm, tb.x_mm) - half_um(map_x);
    let y = midpoint_um(ta.y_mm, tb.y_mm) - half_um(map_y);
    let clamp = |v: i64| v.clamp(i32::MIN as i64, i32::MAX as i64) as i32;
    Ok(Pose {
        x_um: clamp(x),
        y_um: clamp(y),
        heading,
    })
}

/// A detection paired with the known tag it is of.
pub type Sighting<'a> = (&'a TagDetection, &'a KnownTag);

/// The two known tags in view with the longest baseline on the map, if two are in view.
pub fn best_pair<'a>(
    seen: &'a [TagDetection],
    known: &'a TagMap,
) -> Option<(Sighting<'a>, Sighting<'a>)> {
    let mut best = None;
    let mut best_len = 0u64;
    for (i, a) in seen.iter().enumerate() {
        let Some(ta) = known.get(a.id) else { continue };
        for b in seen.iter().skip(i + 1) {
            let Some(tb) = known.get(b.id) else { continue };
            if a.id == b.id {
                continue;
            }
            let (dx, dy) = (
                (tb.x_mm as i64 - ta.x_mm as i64).unsigned_abs(),
                (tb.y_mm as i64 - ta.y_mm as i64).unsigned_abs(),
            );
            // Squared lengths: in 32 bits for tags under 32 m apart, as on any real map.
            let len = if dx < 1 << 15 && dy < 1 << 15 {
                u64::from(dx as u32 * dx as u32 + dy as u32 * dy as u32)
            } else {
                (dx * dx).saturating_add(dy * dy)
            };
            if len > best_len {
                best_len = len;
                best = Some(((a, ta), (b, tb)));
            }
        }
    }
    best
}

/// Whether a fix is close enough to the prediction to believe.
pub fn within_gate(fix: &Pose, predicted: &Pose, config: &FixConfig) -> bool {
    let (dx, dy) = (
        (fix.x_um as i64 - predicted.x_um as i64).unsigned_abs(),
        (fix.y_um as i64 - predicted.y_um as i64).unsigned_abs(),
    );
    let gate_mm = config.gate_position_mm;
    let gate_um = if gate_mm <= u32::MAX / UM_PER_MM as u32 {
        u64::from(gate_mm * UM_PER_MM as u32)
    } else {
        wide_um(gate_mm)
    };
    // Squared distances (no square root on the M0+ for a yes/no answer), and only where
    // the box round the gate's circle and the diamond inside it do not settle it.
    let far = if dx > gate_um || dy > gate_um {
        true
    } else if dx + dy <= gate_um {
        false
    } else if gate_um < 1 << 31 {
        dx * dx + dy * dy > gate_um * gate_um
    } else {
        (dx as u128).pow(2) + (dy as u128).pow(2) > (gate_um as u128).pow(2)
    };
    !far && !turned_beyond(
        fix.heading.diff(predicted.heading),
        config.gate_heading_mdeg,
    )
}

/// Whether a turn of `diff` binary units is larger than `limit_mdeg` millidegrees as
/// [`Angle::from_millidegrees`] rounds them, `|diff| > bits(limit)`, without its 64-bit
/// divisions: with `bits = floor(n / 360000)`, that is `|diff| * 360000 > n`.
fn turned_beyond(diff: i32, limit_mdeg: u32) -> bool {
    const MDEG_PER_TURN: u32 = 360_000;
    let turns = if limit_mdeg < MDEG_PER_TURN {
        limit_mdeg
    } else {
        whole_turns_off(limit_mdeg)
    };
    let n = ((turns as u64) << 32) + (MDEG_PER_TURN / 2) as u64;
    diff.unsigned_abs() as u64 * MDEG_PER_TURN as u64 > n
}

/// `mdeg` less its whole turns. Out of line, so that the division (a library call on the
/// M0+) is not done ahead of the test that almost always makes it needless.
#[cold]
#[inline(never)]
fn whole_turns_off(mdeg: u32) -> u32 {
    mdeg % 360_000
}

/// `mm` (over 4,294 km) in micrometres, for [`within_gate`]; out of line like
/// [`wide_midpoint_um`].
#[cold]
#[inline(never)]
fn wide_um(mm: u32) -> u64 {
    mm as u64 * UM_PER_MM as u64
}

#[cfg(test)]
mod tests {
    use super::*;

    // Two tags 80 cm apart on a far wall, facing the tests' robot.
    const T11: KnownTag = KnownTag {
        id: 11,
        x_mm: 700,
        y_mm: 1950,
    };
    const T12: KnownTag = KnownTag {
        id: 12,
        x_mm: 1500,
        y_mm: 1950,
    };

    /// What a perfect camera at `pose` reports for `tag`.
    fn seen_from(pose: &Pose, tag: &KnownTag) -> TagDetection {
        let (dx, dy) = (
            tag.x_mm as i64 - pose.x_mm() as i64,
            tag.y_mm as i64 - pose.y_mm() as i64,
        );
        let bearing = Angle::of_vector(dx, dy) - pose.heading;
        // cx = centre + focal * tan(bearing) = centre + focal * sin / cos
        let cx = 16000 + 9240 * bearing.sin() as i64 / bearing.cos() as i64;
        TagDetection {
            id: tag.id,
            cx_centipx: cx as i32,
            distance_mm: hypot(dx, dy) as u32,
        }
    }

    #[test]
    fn fix_recovers_the_pose() {
        let truth = Pose::from_mm_mdeg(1100, 1200, 25_000);
        let (a, b) = (seen_from(&truth, &T11), seen_from(&truth, &T12));
        let fix = two_tag_pose(
            (&a, &T11),
            (&b, &T12),
            &CameraConfig::SEED,
            &FixConfig::SEED,
        )
        .unwrap();
        assert!(fix.distance_um(&truth) < 3_000, "{fix:?}");
        assert!(
            fix.heading.diff(truth.heading).unsigned_abs() < Angle::from_millidegrees(300).bits()
        );
    }

    #[test]
    fn inconsistent_baseline_is_rejected() {
        let truth = Pose::from_mm_mdeg(1100, 1200, 0);
        let (a, mut b) = (seen_from(&truth, &T11), seen_from(&truth, &T12));
        b.distance_mm *= 2;
        assert_eq!(
            two_tag_pose(
                (&a, &T11),
                (&b, &T12),
                &CameraConfig::SEED,
                &FixConfig::SEED
            ),
            Err(FixRejection::Geometry)
        );
    }

    #[test]
    fn ranges_beyond_the_link_are_refused() {
        let truth = Pose::from_mm_mdeg(1100, 1200, 0);
        let (a, b) = (seen_from(&truth, &T11), seen_from(&truth, &T12));
        let far = TagDetection {
            distance_mm: MAX_RANGE_MM + 1,
            ..a
        };
        let fix = |a: &TagDetection| {
            two_tag_pose((a, &T11), (&b, &T12), &CameraConfig::SEED, &FixConfig::SEED)
        };
        assert_eq!(fix(&far), Err(FixRejection::Geometry));
        assert_eq!(
            fix(&TagDetection {
                distance_mm: u32::MAX,
                ..a
            }),
            Err(FixRejection::Geometry)
        );
        assert!(fix(&a).is_ok());
    }

    #[test]
    fn turns_between_baselines_match_the_angles_difference() {
        let mut rng = crate::lcg::Lcg::new(0x9E37_79B9_7F4A_7C15u64);
        let mut next = move || rng.next_u64();
        // Every width, up to the 33 bits between two i32 tags; the bound is
        // `Direction::of_vector`'s for any components (6e-3 degrees) and two 15-bit
        // roundings (4.4e-5 rad each, 5e-3 degrees).
        let bound = Angle::from_millidegrees(12).bits() as i32;
        for _ in 0..100_000 {
            let (r, s) = (next(), next());
            let v = |r: u64| r as i64 >> 31 >> (r % 33);
            let (to, from) = ((v(r), v(r >> 7)), (v(s), v(s >> 7)));
            let want = Angle::of_vector(to.0, to.1) - Angle::of_vector(from.0, from.1);
            let got = turn_between(to, from);
            assert!(got.angle.diff(want).abs() <= bound, "{to:?} {from:?}");
        }
        let zero = turn_between((0, 0), (3, 4));
        assert_eq!(zero.angle, -Angle::of_vector(3, 4));
        assert_eq!((zero.sin, zero.cos), (zero.angle.sin(), zero.angle.cos()));
    }

    #[test]
    fn pairs_of_far_tags() {
        let far = |id, x_mm| KnownTag {
            id,
            x_mm,
            y_mm: -x_mm,
        };
        let map = TagMap::new(&[far(1, i32::MAX), far(2, -i32::MAX), far(3, 0)]).unwrap();
        let d = |id| TagDetection {
            id,
            cx_centipx: 16000,
            distance_mm: 1000,
        };
        let seen = [d(3), d(1), d(2)];
        let ((a, _), (b, _)) = best_pair(&seen, &map).unwrap();
        assert_eq!((a.id, b.id), (1, 2));
    }

    #[test]
    fn pair_needs_two_distinct_known_tags() {
        let map = TagMap::new(&[T11, T12]).unwrap();
        let d = |id| TagDetection {
            id,
            cx_centipx: 16000,
            distance_mm: 1000,
        };
        assert!(best_pair(&[d(11), d(11)], &map).is_none());
        assert!(best_pair(&[d(11), d(99)], &map).is_none());
        assert!(best_pair(&[d(99), d(12), d(11)], &map).is_some());
        assert!(TagMap::new(&[T11, T11]).is_none());
    }

    #[test]
    fn gate() {
        let p = Pose::from_mm_mdeg(1000, 1000, 0);
        assert!(within_gate(
            &Pose::from_mm_mdeg(1200, 1000, 19_000),
            &p,
            &FixConfig::SEED
        ));
        assert!(!within_gate(
            &Pose::from_mm_mdeg(1400, 1000, 0),
            &p,
            &FixConfig::SEED
        ));
        assert!(!within_gate(
            &Pose::from_mm_mdeg(1000, 1000, -21_000),
            &p,
            &FixConfig::SEED
        ));
    }
}
