//! The depth sensor against the camera: a tag the camera sees lies on a surface one of the
//! depth sensor's beams points at, so that beam's range and the tag's distance are two
//! measurements of one length.
//!
//! Neither sensor can check itself: a depth sensor that reads every range 15 cm long draws
//! every wall 15 cm too far, and its frames are as varied and plausible as true ones. The
//! camera measures the same lengths independently. When a tag's column falls inside a
//! depth zone, the zone's range must match the tag's distance within
//! [`TagRangeConfig::tolerance_mm`]; when they part, one of the two lies, and the core
//! stops mapping until they agree again ([`crate::plausible`]). That is the cautious
//! choice whichever lies: a lying camera's tags also misplace the pose that the scans are
//! written at. Unless the filter already refuses the camera's pictures and blames the
//! camera for them where the map is matched ([`Witness::Discredited`]): then its tags
//! move the pose no more, the matches hold it, and a tag read a few pixels aside, which
//! falls in the wrong beam, would only stop the map and the matches that vouch for it.
//!
//! The check costs integer compares: each zone's edges are precomputed as picture
//! columns, and the turn between the picture's moment and the scan's shifts the tag's
//! column by the gyro's rate times the time between them.

use crate::frame::{DepthScan, SensorFrame, TagDetection, BEAMS};
use crate::slam::DepthConfig;
use crate::tagfix::CameraConfig;

/// How the check matches a tag to a beam and a distance to a range.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TagRangeConfig {
    /// Most a beam's range, moved to the tag's column along the slope its neighbours
    /// show, and the tag's distance may differ where the wall faces the robot,
    /// millimetres: the sensors' noise and a tag's standing off its wall. A quarter of
    /// the slope is added per tag.
    pub tolerance_mm: u16,
    /// How far inside its zone's edges a tag's column must lie, hundredths of a pixel:
    /// a tag on the edge may belong to either beam, and the turn between the two moments
    /// is only estimated.
    pub margin_centipx: u16,
    /// Tags whose beam's range is less than this many times the range's change over a
    /// zone are not compared: the wall there is seen steeply off facing (with 5.6 degree
    /// zones, 6 is about 60 degrees off).
    pub range_per_slope: u8,
}

impl TagRangeConfig {
    /// BugBot: 80 mm, well under the 150 mm a plausibly wrong sensor is off by, and
    /// above the most the shipped worlds' tags and ranges part by (the seed's tags stand
    /// 5 cm off the wall); half a degree of margin (80 hundredths of a pixel at a 92.4 px
    /// focal length).
    pub const SEED: TagRangeConfig = TagRangeConfig {
        tolerance_mm: 80,
        margin_centipx: 80,
        range_per_slope: 6,
    };
}

/// The depth zones' edges as picture columns, and the turn's shift per unit of time.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub struct ZoneColumns {
    /// Columns, hundredths of a pixel, rising: each zone's left edge (even places), its
    /// beam's centre (odd places), and the last zone's right edge. A zone beyond the
    /// picture's quarter turn is never matched.
    columns_centipx: [i32; 2 * BEAMS + 1],
    /// Each zone's width in columns, as its reciprocal in Q16.
    per_width_q16: [i32; BEAMS],
    /// Columns a turn of one turn unit ([`ZoneColumns::TURN_UNIT_BITS`]) moves a tag
    /// near the picture's centre, as `(scale, bits)`: `scale / 2^bits`, `scale` under 2^10.
    per_turn: (i32, u32),
}

impl ZoneColumns {
    /// The unit of turn [`ZoneColumns::shift`] counts in: 65,536 millidegrees-per-second
    /// microseconds, about 0.066 millidegrees.
    const TURN_UNIT_BITS: u32 = 16;

    /// The zones of `depth`'s fan, seen by `camera` (both looking along the nose).
    ///
    /// Out of line: once, at start.
    #[inline(never)]
    pub fn new(depth: &DepthConfig, camera: &CameraConfig) -> ZoneColumns {
        let bits = |i: usize| i64::from(depth.beam_angles[i].signed_bits());
        let mut columns_centipx = [0; 2 * BEAMS + 1];
        for (j, column) in columns_centipx.iter_mut().enumerate() {
            // A centre; an edge midway between neighbouring centres; the outer edges
            // half a spacing out.
            let twice = match (j / 2, j % 2) {
                (i, 1) => 2 * bits(i),
                (0, _) => 3 * bits(0) - bits(1),
                (BEAMS, _) => 3 * bits(BEAMS - 1) - bits(BEAMS - 2),
                (i, _) => bits(i - 1) + bits(i),
            };
            *column = column_of(twice / 2, camera);
        }
        let width = |i: usize| {
            columns_centipx[2 * i + 2]
                .saturating_sub(columns_centipx[2 * i])
                .max(1)
        };
        ZoneColumns {
            columns_centipx,
            per_width_q16: core::array::from_fn(|i| (1 << 16) / width(i)),
            per_turn: turn_scale(camera.focal_centipx),
        }
    }

    fn edge(&self, zone: usize) -> i32 {
        self.columns_centipx[2 * zone]
    }

    fn centre(&self, beam: usize) -> i32 {
        self.columns_centipx[2 * beam + 1]
    }

    /// The beam whose zone holds `column` at least `margin` inside its edges.
    fn beam_of(&self, column: i32, margin: i32) -> Option<usize> {
        if column < self.edge(0) || column >= self.edge(BEAMS) {
            return None;
        }
        // A binary search of the edges: three compares for eight zones.
        let mut beam = 0;
        let mut step = BEAMS.next_power_of_two() / 2;
        while step > 0 {
            if beam + step < BEAMS && column >= self.edge(beam + step) {
                beam += step;
            }
            step /= 2;
        }
        let inside = column >= self.edge(beam).saturating_add(margin)
            && column <= self.edge(beam + 1).saturating_sub(margin);
        inside.then_some(beam)
    }

    /// How far a turn at `rate_mdps` for `dt_us` (at most [`MOST_APART_US`]) moves a
    /// tag's column, in 32-bit multiplies (the M0+ has no 64-bit one).
    fn shift(&self, rate_mdps: i32, dt_us: i32) -> i32 {
        // Under 2^16 and 2^15 after their shifts: the product fits 31 bits, and in
        // turn units under 2^21, times a scale under 2^10.
        let rate = rate_mdps.clamp(-(1 << 20) + 1, (1 << 20) - 1) >> 4;
        let dt = dt_us.clamp(-MOST_APART_US + 4, MOST_APART_US - 4) >> 2;
        let turned = (rate * dt) >> (Self::TURN_UNIT_BITS - 6);
        let (scale, bits) = self.per_turn;
        -((turned * scale) >> bits)
    }
}

/// A picture further from its scan in time than this, microseconds, is not compared:
/// the robot may have moved too far between them.
pub const MOST_APART_US: i32 = 1 << 17;

/// The picture column a direction `bits` (an [`crate::Angle`]'s signed bits) off the
/// nose is seen at; beyond a quarter turn, the picture's edge at infinity.
fn column_of(bits: i64, camera: &CameraConfig) -> i32 {
    let (sin, cos) = crate::Angle::from_bits(bits as i32 as u32).sin_cos();
    if cos <= 0 {
        return if sin < 0 { i32::MIN } else { i32::MAX };
    }
    let offset = i64::from(camera.focal_centipx) * i64::from(sin) / i64::from(cos);
    (i64::from(camera.centre_centipx) + offset).clamp(i64::from(i32::MIN), i64::from(i32::MAX))
        as i32
}

/// `focal_centipx x pi / 180,000` columns a millidegree, times 2^16 / 10^6 millidegrees
/// a turn unit, as `(scale, bits)` with `scale` under 2^10 and as many bits as that
/// allows (16 for BugBot's 92.4 px). Without floating point: pi as 355 / 113, 3e-7 off.
fn turn_scale(focal_centipx: i32) -> (i32, u32) {
    /// `pi / 180,000 x 2^16 / 10^6` in Q40, worked out when the crate is built.
    const PER_CENTIPX: i64 =
        ((355u128 << (40 + ZoneColumns::TURN_UNIT_BITS)) / (113 * 180_000 * 1_000_000)) as i64;
    // PER_CENTIPX is under 2^26 and a focal length under 2^31.
    let exact = i64::from(focal_centipx.max(0)) * PER_CENTIPX;
    let mut bits = 16;
    while bits > 0 && exact >> (40 - bits) >= 1 << 10 {
        bits -= 1;
    }
    (((exact >> (40 - bits)).min((1 << 10) - 1)) as i32, bits)
}

/// The range a beam would read at `column`, inside `beam`'s zone: the beam's own range,
/// moved along the slope its neighbours show (half the difference across them, so that a
/// bump at the beam itself, a tag standing off its wall, is not taken as a slant; at the
/// fan's edge, the one step there is). Returns the range and the slope's size, both in
/// millimetres; `None`: the beam or every neighbour has no return.
fn range_at(zones: &ZoneColumns, scan: &DepthScan, beam: usize, column: i32) -> Option<(i32, i32)> {
    let range = |i: Option<usize>| scan.ranges_mm.get(i?).copied().flatten().map(i32::from);
    let own = range(Some(beam))?;
    let slope = match (range(beam.checked_sub(1)), range(Some(beam + 1))) {
        (Some(left), Some(right)) => (right - left) / 2,
        (Some(left), None) => own - left,
        (None, Some(right)) => right - own,
        (None, None) => return None,
    };
    // The column's place in the zone, Q16: under 2^16 either way, as the column lies
    // inside the zone; a slope of 2^14 mm a zone is far past any compared.
    let offset = column.saturating_sub(zones.centre(beam));
    let fraction = (offset * zones.per_width_q16[beam]).clamp(-(1 << 16), 1 << 16);
    let slope = slope.clamp(-(1 << 14), 1 << 14);
    Some((own + ((slope * fraction + (1 << 15)) >> 16), slope.abs()))
}

/// What the camera's tags say of a depth scan.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Witness {
    /// No tag fell inside a zone with a return: nothing to compare.
    Silent,
    /// The first tag inside a zone with a return agrees with its beam.
    Agrees,
    /// The first tag inside a zone with a return and its beam differ by more than the
    /// tolerance.
    Disagrees,
    /// The camera is to blame for the pictures the filter refuses
    /// ([`crate::camera_check::CameraCheck::blamed`]): its tags are not compared with the
    /// scan, and a doubt they cast on the depth sensor is lifted as any other, by frames
    /// its own checks pass. A tag read at the wrong column falls in the wrong beam.
    Discredited,
}

/// What the tags of `frame`'s picture say of its depth scan: the first tag that can be
/// compared decides (one comparison a tick: a sensor whose every range is off shows in
/// any tag, and the robot's costliest ticks are those with two tags in view). The
/// picture and the scan have their own ages; the turn between them, at the gyro's rate
/// (none: taken as still), moves the tags' columns first.
///
/// Out of line: once a tick, and it returns at once when no tag is in view.
#[inline(never)]
pub fn witness(zones: &ZoneColumns, frame: &SensorFrame, config: &TagRangeConfig) -> Witness {
    let Some(scan) = &frame.depth else {
        return Witness::Silent;
    };
    // Ages past 2^31 us (35 minutes) are as far apart as any the check refuses.
    let age = |us: u32| us.min(i32::MAX as u32) as i32;
    let picture_before_scan_us = age(frame.tags_age_us) - age(frame.depth_age_us);
    let tags = frame.tags.as_slice();
    if tags.is_empty() || picture_before_scan_us.unsigned_abs() > MOST_APART_US as u32 {
        return Witness::Silent;
    }
    let rate_mdps = frame.gyro.map(|g| g.rate_mdps);
    let shift = rate_mdps.map_or(0, |r| zones.shift(r, picture_before_scan_us));
    tags.iter()
        .find_map(|tag| compare(zones, scan, tag, shift, config))
        .unwrap_or(Witness::Silent)
}

/// One tag against its beam, its column moved by `shift`: `None` when it cannot be
/// compared (outside the fan or on a zone's edge, no return, a wall seen steeply).
///
/// Out of line: a tag or two a tick, and inlined the loop keeps every zone's edge in
/// registers and on the stack whether a tag needs them or not.
#[inline(never)]
fn compare(
    zones: &ZoneColumns,
    scan: &DepthScan,
    tag: &TagDetection,
    shift: i32,
    config: &TagRangeConfig,
) -> Option<Witness> {
    let column = tag.cx_centipx.saturating_add(shift);
    let beam = zones.beam_of(column, i32::from(config.margin_centipx))?;
    let (range, slope) = range_at(zones, scan, beam, column)?;
    // A wall seen far off facing: a tag a few centimetres off its wall is seen where the
    // beam passes it by, and the wall behind lies further by more than any tolerance
    // that still catches a lying sensor. (The slope is at most 2^14 and the factor a
    // byte: one 32-bit multiply.)
    if slope * i32::from(config.range_per_slope) > range {
        return None;
    }
    // A quarter of the slope more: a slanted wall's range grows faster than in
    // proportion to the angle, and a tag stands a little off its wall.
    let tolerance = i32::from(config.tolerance_mm) + slope / 4;
    let distance = tag.distance_mm.min(1 << 20) as i32;
    Some(if range.abs_diff(distance) > tolerance as u32 {
        Witness::Disagrees
    } else {
        Witness::Agrees
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frame::GyroRate;

    fn zones() -> ZoneColumns {
        ZoneColumns::new(&DepthConfig::SEED, &CameraConfig::SEED)
    }

    /// `witness` of a frame with `scan` and `tags`, the picture `before_us` before the
    /// scan, turning at `rate_mdps`.
    fn witness(
        zones: &ZoneColumns,
        scan: &DepthScan,
        tags: &[TagDetection],
        before_us: i32,
        rate_mdps: Option<i32>,
        config: &TagRangeConfig,
    ) -> Witness {
        let mut frame = SensorFrame::empty(100_000);
        frame.depth = Some(*scan);
        (frame.tags_age_us, frame.depth_age_us) = if before_us >= 0 {
            (before_us as u32, 0)
        } else {
            (0, before_us.unsigned_abs())
        };
        for t in tags {
            frame.tags.push(*t).expect("room");
        }
        frame.gyro = rate_mdps.map(|rate_mdps| GyroRate { rate_mdps });
        super::witness(zones, &frame, config)
    }

    fn tag(cx_centipx: i32, distance_mm: u32) -> TagDetection {
        TagDetection {
            id: 11,
            cx_centipx,
            distance_mm,
        }
    }

    fn scan(range: u16) -> DepthScan {
        DepthScan {
            ranges_mm: [Some(range); BEAMS],
        }
    }

    #[test]
    fn the_zones_span_the_fan_in_the_picture() {
        let z = zones();
        // 92.4 px x tan(22.5 deg) = 38.27 px either side of the 160 px centre.
        assert!((z.edge(0) - (16_000 - 3_827)).abs() <= 2);
        assert!((z.edge(BEAMS) - (16_000 + 3_827)).abs() <= 2);
        assert_eq!(z.edge(BEAMS / 2), 16_000);
        assert!(z.columns_centipx.windows(2).all(|w| w[0] < w[1]));
        assert_eq!(z.beam_of(16_000 + 300, 80), Some(4));
        assert_eq!(z.beam_of(16_000 - 300, 80), Some(3));
        assert_eq!(z.beam_of(16_000 + 40, 80), None, "on an edge");
        assert_eq!(z.beam_of(16_000 + 5_000, 80), None, "outside the fan");
    }

    #[test]
    fn a_turn_moves_the_tag_by_its_angle() {
        // 30 deg/s for 50 ms: 1.5 degrees, 92.4 px x 0.02618 rad = 2.42 px, to the left.
        let shift = zones().shift(30_000, 50_000);
        assert!((shift + 242).abs() <= 1, "{shift}");
        assert_eq!(zones().shift(0, 50_000), 0);
        assert!(
            zones().shift(i32::MAX, i32::MAX) < 0,
            "saturates, never wraps"
        );
        assert!(
            zones().shift(i32::MIN, i32::MAX) > 0,
            "saturates, never wraps"
        );
        // A long focal length keeps its scale under 2^10 with fewer bits.
        assert_eq!(turn_scale(CameraConfig::SEED.focal_centipx).1, 16);
        let (scale, bits) = turn_scale(1 << 30);
        assert!(scale < 1 << 10 && bits < 16, "{scale} {bits}");
    }

    #[test]
    fn a_range_is_held_to_the_tags_distance() {
        let z = zones();
        let c = TagRangeConfig::SEED;
        let seen = [tag(16_300, 1_200)];
        assert_eq!(
            witness(&z, &scan(1_250), &seen, 0, None, &c),
            Witness::Agrees
        );
        assert_eq!(
            witness(&z, &scan(1_301), &seen, 0, None, &c),
            Witness::Disagrees
        );
        assert_eq!(
            witness(&z, &scan(1_099), &seen, 0, None, &c),
            Witness::Disagrees
        );
        assert_eq!(witness(&z, &scan(1_250), &[], 0, None, &c), Witness::Silent);
        let no_return = DepthScan {
            ranges_mm: [None; BEAMS],
        };
        assert_eq!(witness(&z, &no_return, &seen, 0, None, &c), Witness::Silent);
        let outside = [tag(30_000, 1_200)];
        assert_eq!(
            witness(&z, &scan(2_000), &outside, 0, None, &c),
            Witness::Silent
        );
    }

    #[test]
    fn the_turn_between_picture_and_scan_picks_the_beam() {
        let z = zones();
        let c = TagRangeConfig::SEED;
        let mut ranges = [Some(1_200); BEAMS];
        ranges[4] = Some(900);
        let scan = DepthScan { ranges_mm: ranges };
        // Seen just right of centre (beam 4); the robot then turned right 2 degrees
        // before the scan, so the tag lies in beam 3's zone when the scan is taken.
        let seen = [tag(16_050, 1_200)];
        assert_eq!(
            witness(&z, &scan, &seen, 0, None, &c),
            Witness::Silent,
            "on the edge"
        );
        let seen = [tag(16_200, 1_200)];
        assert_eq!(witness(&z, &scan, &seen, 0, None, &c), Witness::Disagrees);
        assert_eq!(
            witness(&z, &scan, &seen, 100_000, Some(20_000), &c),
            Witness::Agrees
        );
    }

    #[test]
    fn a_slanted_wall_is_read_at_the_tags_column() {
        let z = zones();
        let c = TagRangeConfig::SEED;
        // A wall whose range grows 150 mm a zone to the right; a tag a third of a zone
        // right of beam 4's centre lies 50 mm further than the beam reads.
        let scan = DepthScan {
            ranges_mm: core::array::from_fn(|i| Some(1_000 + 150 * i as u16)),
        };
        let column = z.centre(4) + (z.edge(5) - z.edge(4)) / 3;
        let at = |d| witness(&z, &scan, &[tag(column, d)], 0, None, &c);
        // 1,650 there; 80 mm and a quarter of the slope (37) either side.
        assert_eq!(at(1_650), Witness::Agrees);
        assert_eq!(at(1_650 + 117), Witness::Agrees);
        assert_eq!(at(1_650 + 118), Witness::Disagrees);
        assert_eq!(at(1_650 - 118), Witness::Disagrees);
        // A wall seen steeply (the range under six zones' change) is not compared.
        let steep = DepthScan {
            ranges_mm: core::array::from_fn(|i| Some(500 + 320 * i as u16)),
        };
        assert_eq!(
            witness(&z, &steep, &[tag(column, 3_000)], 0, None, &c),
            Witness::Silent
        );
    }

    #[test]
    fn wild_columns_and_distances_never_panic() {
        let z = zones();
        let c = TagRangeConfig::SEED;
        for cx in [i32::MIN, -1, 0, 16_000, i32::MAX] {
            for d in [0, u32::MAX] {
                let _ = witness(
                    &z,
                    &scan(u16::MAX),
                    &[tag(cx, d)],
                    i32::MIN,
                    Some(i32::MAX),
                    &c,
                );
            }
        }
    }
}
