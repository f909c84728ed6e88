//! The two-tag fix: a pose from the range and bearing to two tags whose places are known.
//!
//! The line from one tag to the other is fixed on the mat, and the robot also sees it in
//! its own frame; the angle between the two is the heading. With the heading known, each
//! tag's range and bearing gives the position; we average the two.

use crate::angle::Angle;
use crate::frame::TagDetection;
use crate::pose::{hypot, mul_q16, Pose, UM_PER_MM};

/// Most known tags a map can hold.
pub const MAX_KNOWN_TAGS: usize = 8;

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
}

/// When a fix is believed.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FixConfig {
    /// Whether tag fixes are taken at all (off: dead reckoning only).
    pub enabled: bool,
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
    /// 0 never overrides the gate.
    pub relocalise_after: u8,
}

impl FixConfig {
    /// Gates sized for the seed mat: a fix may move the pose 30 cm and 20 degrees at most.
    pub const SEED: FixConfig = FixConfig {
        enabled: true,
        baseline_tolerance_permille: 200,
        min_baseline_mm: 100,
        min_range_mm: 50,
        gate_position_mm: 300,
        gate_heading_mdeg: 20_000,
        relocalise_after: 5,
    };
}

/// Why a fix was not taken.
#[derive(Clone, Copy, PartialEq, Eq, Debug, serde::Serialize, serde::Deserialize)]
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
#[derive(Clone, Copy, PartialEq, Eq, Debug, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FixOutcome {
    /// Fewer than two known tags were in view (or fixes are off).
    NotAttempted,
    /// The pose was reset to the fix.
    Taken,
    /// The fix was computed and thrown away.
    Rejected(FixRejection),
}

/// A tag's place in the robot frame: `(right, forward)` millimetres.
fn robot_frame(d: &TagDetection, camera: &CameraConfig) -> (i64, i64, Angle) {
    let bearing = camera.bearing(d.cx_centipx);
    let r = d.distance_mm as i64;
    (
        mul_q16(r, bearing.sin()),
        mul_q16(r, bearing.cos()),
        bearing,
    )
}

/// The pose two detected known tags imply, or why they cannot give one.
pub fn two_tag_pose(
    (a, ta): Sighting<'_>,
    (b, tb): Sighting<'_>,
    camera: &CameraConfig,
    config: &FixConfig,
) -> Result<Pose, FixRejection> {
    // A tag read closer than this is a misread: no card fits in front of the lens.
    if a.distance_mm < config.min_range_mm || b.distance_mm < config.min_range_mm {
        return Err(FixRejection::Geometry);
    }
    let (ax, ay, bearing_a) = robot_frame(a, camera);
    let (bx, by, bearing_b) = robot_frame(b, camera);
    let (seen_x, seen_y) = (bx - ax, by - ay);
    let (true_x, true_y) = ((tb.x_mm - ta.x_mm) as i64, (tb.y_mm - ta.y_mm) as i64);
    let seen_len = hypot(seen_x, seen_y) as i128;
    let true_len = hypot(true_x, true_y) as i128;
    if true_len < config.min_baseline_mm as i128 {
        return Err(FixRejection::Geometry);
    }
    if (seen_len - true_len).abs() * 1000 > true_len * config.baseline_tolerance_permille as i128 {
        return Err(FixRejection::Geometry);
    }
    let heading = Angle::of_vector(true_x, true_y) - Angle::of_vector(seen_x, seen_y);
    // Each tag: robot = tag - range * (sin, cos)(heading + bearing).
    let from = |d: &TagDetection, t: &KnownTag, bearing: Angle| {
        let dir = heading + bearing;
        let r_um = d.distance_mm as i64 * UM_PER_MM as i64;
        (
            t.x_mm as i64 * UM_PER_MM as i64 - mul_q16(r_um, dir.sin()),
            t.y_mm as i64 * UM_PER_MM as i64 - mul_q16(r_um, dir.cos()),
        )
    };
    let (x1, y1) = from(a, ta, bearing_a);
    let (x2, y2) = from(b, tb, bearing_b);
    let clamp = |v: i64| v.clamp(i32::MIN as i64, i32::MAX as i64) as i32;
    Ok(Pose {
        x_um: clamp((x1 + x2) / 2),
        y_um: clamp((y1 + y2) / 2),
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
    let mut best_len = 0i64;
    for (i, a) in seen.iter().enumerate() {
        let Some(ta) = known.get(a.id) else { continue };
        for b in seen.iter().skip(i + 1) {
            let Some(tb) = known.get(b.id) else { continue };
            if a.id == b.id {
                continue;
            }
            let (dx, dy) = ((tb.x_mm - ta.x_mm) as i64, (tb.y_mm - ta.y_mm) as i64);
            let len = dx * dx + dy * dy;
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
    // Squared distances: no square root on the M0+ for a yes/no answer.
    let (dx, dy) = (
        fix.x_um as i64 - predicted.x_um as i64,
        fix.y_um as i64 - predicted.y_um as i64,
    );
    let gate_um = config.gate_position_mm as u64 * UM_PER_MM as u64;
    let far = (dx.unsigned_abs() as u128).pow(2) + (dy.unsigned_abs() as u128).pow(2)
        > (gate_um as u128).pow(2);
    let turned = fix.heading.diff(predicted.heading).unsigned_abs()
        > Angle::from_millidegrees(config.gate_heading_mdeg as i64).bits();
    !far && !turned
}

#[cfg(test)]
mod tests {
    use super::*;

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
