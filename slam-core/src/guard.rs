//! The guard: may the robot drive the next tick, by what it believes?
//!
//! One pure function, [`decide`], of the estimate, the map, the latest depth scan, the
//! core's trust in its inputs and the command about to be driven. The firmware and the
//! simulator both call it every tick.
//!
//! # Policy
//!
//! A motion whose input is doubted ([`crate::plausible`]) holds: a turn needs the gyro,
//! a drive the gyro and the flow. The robot stands and the route step waits (it is not
//! skipped), so the pose, which the core then takes as still, stays true, and the route
//! goes on where it stopped once the input is trusted again.
//!
//! The map holds only what the fan has seen, so a forward drive also holds while the
//! depth sensor is blind: no frame this tick, or none that shows what is ahead as it is
//! ([`SensorFrame::sight`]: the frame before again, a range the sensor cannot read,
//! every range stepped off). It goes on with the first frame that does. Any other frame
//! is looked at, even one the core does not map for a doubt (a late frame, ranges a
//! tag's distance disagreed with): a return in the path stops the drive, which is the
//! safe way to be wrong, and those doubts may be lifted only by what a robot standing
//! still never sees (a turn, a tag in the beam).
//!
//! The body is a circle about the turning axis, so a turn on the spot sweeps nothing new:
//! turns always go. A drive sweeps a stadium: every point within the body's radius `r` of
//! the segment from the centre to `reach` ahead along the direction of travel, where
//!
//! `reach = v * (latency + tick) + margin`
//!
//! is how far the body may move between the moment the scan was measured and the end of
//! the tick the decision drives (one tick of sensor latency, since a frame arrives every
//! tick and is read a tick late, and the tick itself), plus a margin for range noise. The
//! safe distance straight ahead is then `D = r + reach`. With [`GuardConfig::SEED`]:
//! `r` = 60 mm, latency = tick = 100 ms, margin = 25 mm (5 sigma of the depth sensor's
//! 5 mm noise), so `D = 60 + 86 mm/s * 0.2 s + 25 = 103` mm at the seed route's speed
//! and `60 + 150 * 0.2 + 25 = 115` mm at 150 mm/s.
//!
//! The drive stops ([`Decision::Stop`]) when anything lies in the stadium ahead of the
//! centre: a beam's return (forward drives only: the sensor looks ahead), or an occupied
//! cell of the map, taken as its centre with the radius grown by half a cell (the wall may
//! lie anywhere in the cell). The map covers what the fan does not: close in, the 45
//! degree fan is narrower than the body, so a box's corner that clips the body's edge
//! was last seen by the beams from further back, and only the map still holds it; and a
//! drive backwards has only the map. Points beside or behind the swept path are ignored.
//! A beam with no return says nothing (the map stands in). The caller then skips the
//! rest of the route step: the robot stands for that tick and goes on with the next step.
//!
//! A drive is taken as straight (a turn rate while driving is not swept), and the pose as
//! exact: the map was built at the estimated poses, so near the robot the map and the
//! estimate agree even when both are off the truth.

use crate::angle::{Angle, TRIG_ONE};
#[cfg(doc)]
use crate::frame::SensorFrame;
use crate::frame::{DepthScan, DriveCommand, BEAMS};
use crate::grid::{GridMap, Occupancy};
use crate::plausible::{Input, Trust};
use crate::pose::Pose;
use crate::slam::fan;

/// The body and the sensor timing the guard's safe distance is built from.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct GuardConfig {
    /// The body's radius about the turning axis, millimetres.
    pub radius_mm: u16,
    /// Added to the reach for the depth sensor's range noise, millimetres.
    pub margin_mm: u16,
    /// How old a scan may be when the guard reads it, microseconds.
    pub latency_us: u32,
    /// How long the decision is driven for: one control tick, microseconds.
    pub tick_us: u32,
    /// Direction of each beam relative to the nose, left to right (the core's fan).
    pub beam_angles: [Angle; BEAMS],
}

impl GuardConfig {
    /// The seed robot: a 60 mm radius, the 45 degree fan, 100 ms ticks with scans a tick
    /// late, 25 mm for range noise.
    pub const SEED: GuardConfig = GuardConfig {
        radius_mm: 60,
        margin_mm: 25,
        latency_us: 100_000,
        tick_us: 100_000,
        beam_angles: fan(45_000),
    };

    /// How far ahead of the centre the body's front may get before the scan after next,
    /// at `speed_mm_s`: `speed * (latency + tick) + margin`, millimetres, rounded up.
    pub fn reach_mm(&self, speed_mm_s: u32) -> u32 {
        let window_us = u64::from(self.latency_us) + u64::from(self.tick_us);
        let travel = (u64::from(speed_mm_s) * window_us).div_ceil(1_000_000);
        u32::try_from(travel)
            .unwrap_or(u32::MAX)
            .saturating_add(u32::from(self.margin_mm))
    }

    /// The safe distance straight ahead at `speed_mm_s`: radius plus reach, millimetres.
    pub fn safe_distance_mm(&self, speed_mm_s: u32) -> u32 {
        self.reach_mm(speed_mm_s)
            .saturating_add(u32::from(self.radius_mm))
    }
}

impl Default for GuardConfig {
    fn default() -> Self {
        GuardConfig::SEED
    }
}

/// What stands in the way.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Obstacle {
    /// A beam's return, by beam index (0 is the leftmost).
    Beam(u8),
    /// An occupied map cell.
    Cell {
        /// Its column.
        column: i32,
        /// Its row.
        row: i32,
    },
}

/// The guard's answer.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Decision {
    /// Drive the command.
    Go,
    /// Stand still this tick and skip the rest of the route step.
    Stop(Obstacle),
    /// Stand still this tick and keep the route step for later: the input the motion
    /// needs is doubted.
    Hold(Input),
}

impl Decision {
    /// Whether the command may be driven.
    pub fn is_go(&self) -> bool {
        *self == Decision::Go
    }
}

/// Whether `command` may be driven for the next tick from `pose`, given the map, what
/// the depth sensor saw this tick ([`SensorFrame::sight`]; `None`: nothing new, so a
/// forward drive holds) and the core's trust in its inputs. See the module docs.
///
/// Out of line, as is its map walk: the firmware builds the core for speed, and this
/// once-a-tick check need not be unrolled into its caller.
#[inline(never)]
pub fn decide<const W: usize, const H: usize>(
    config: &GuardConfig,
    pose: &Pose,
    map: &GridMap<W, H>,
    scan: Option<&DepthScan>,
    trust: &Trust,
    command: DriveCommand,
) -> Decision {
    if let Some(input) = trust.lacking(command.turn_mdps != 0, command.speed_mm_s != 0) {
        return Decision::Hold(input);
    }
    if command.speed_mm_s == 0 {
        return Decision::Go;
    }
    let forward = command.speed_mm_s > 0;
    let reach = i64::from(config.reach_mm(command.speed_mm_s.unsigned_abs()));
    let radius = i64::from(config.radius_mm);
    if forward {
        // Blind, the sensor that looks ahead sees nothing the map does not hold.
        let Some(scan) = scan else {
            return Decision::Hold(Input::Depth);
        };
        for (i, (range, angle)) in scan.ranges_mm.iter().zip(config.beam_angles).enumerate() {
            let Some(range) = range else { continue };
            let range = i64::from(*range);
            let ahead = range * i64::from(angle.cos()) / i64::from(TRIG_ONE);
            let across = range * i64::from(angle.sin()) / i64::from(TRIG_ONE);
            if in_stadium(ahead, across, reach, radius) {
                return Decision::Stop(Obstacle::Beam(i as u8));
            }
        }
    }
    let heading = if forward {
        pose.heading
    } else {
        pose.heading + Angle::HALF_TURN
    };
    match occupied_in_stadium(map, pose, heading, reach, radius) {
        Some((column, row)) => Decision::Stop(Obstacle::Cell { column, row }),
        None => Decision::Go,
    }
}

/// Whether the point `ahead` mm along the travel and `across` mm to its side lies ahead
/// of the centre and within `radius` of the segment from the centre to `reach` ahead.
fn in_stadium(ahead: i64, across: i64, reach: i64, radius: i64) -> bool {
    if ahead <= 0 {
        return false;
    }
    let beyond = ahead - ahead.min(reach);
    beyond * beyond + across * across < radius * radius
}

/// The first occupied cell whose centre lies in the stadium (radius grown by half a cell)
/// travelling along `heading` from `pose`.
#[inline(never)]
fn occupied_in_stadium<const W: usize, const H: usize>(
    map: &GridMap<W, H>,
    pose: &Pose,
    heading: Angle,
    reach: i64,
    radius: i64,
) -> Option<(i32, i32)> {
    let geometry = map.geometry();
    let radius = radius + i64::from(geometry.cell_mm / 2);
    let (sin, cos) = (i64::from(heading.sin()), i64::from(heading.cos()));
    let one = i64::from(TRIG_ONE);
    let (x, y) = (i64::from(pose.x_mm()), i64::from(pose.y_mm()));
    let (end_x, end_y) = (x + reach * sin / one, y + reach * cos / one);
    let near = |v: i64| i32::try_from(v).unwrap_or(if v < 0 { i32::MIN } else { i32::MAX });
    let pad = radius + i64::from(geometry.cell_mm);
    let (c0, r0) = geometry.cell_of(near(x.min(end_x) - pad), near(y.min(end_y) - pad));
    let (c1, r1) = geometry.cell_of(near(x.max(end_x) + pad), near(y.max(end_y) + pad));
    // Only the grid's own cells can be occupied.
    let (c0, r0) = (c0.max(0), r0.max(0));
    let (c1, r1) = (c1.min(W as i32 - 1), r1.min(H as i32 - 1));
    for row in r0..=r1 {
        for column in c0..=c1 {
            if map.occupancy(column, row) != Occupancy::Occupied {
                continue;
            }
            let (cx, cy) = geometry.centre_of(column, row);
            let (dx, dy) = (i64::from(cx) - x, i64::from(cy) - y);
            let ahead = (dx * sin + dy * cos) / one;
            let across = (dx * cos - dy * sin) / one;
            if in_stadium(ahead, across, reach, radius) {
                return Some((column, row));
            }
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::{Evidence, GridGeometry, LOG_ODDS_ONE};
    use crate::plausible::Doubt;

    const GEOMETRY: GridGeometry = GridGeometry {
        cell_mm: 50,
        origin_x_mm: -150,
        origin_y_mm: -150,
    };
    type Map = GridMap<46, 46>;

    const CONFIG: GuardConfig = GuardConfig::SEED;
    const TRUSTED: Trust = Trust {
        gyro: None,
        flow: None,
        depth: None,
    };
    const AHEAD: DriveCommand = DriveCommand {
        speed_mm_s: 86,
        turn_mdps: 0,
    };

    /// A frame with no return on any beam: nothing within the sensor's reach.
    const NOTHING_AHEAD: DepthScan = DepthScan {
        ranges_mm: [None; BEAMS],
    };

    fn empty_map() -> Map {
        Map::new(GEOMETRY, Evidence::SEED)
    }

    /// A map with the cell holding `(x_mm, y_mm)` occupied.
    fn map_with(points: &[(i32, i32)]) -> Map {
        let mut map = empty_map();
        for &(x, y) in points {
            let (c, r) = GEOMETRY.cell_of(x, y);
            assert!(map.add(c, r, 4 * LOG_ODDS_ONE));
            assert_eq!(map.occupancy(c, r), Occupancy::Occupied);
        }
        map
    }

    /// What the fan sees of a straight wall across the path `distance_mm` ahead.
    fn wall_ahead(distance_mm: i64) -> DepthScan {
        let mut scan = DepthScan::default();
        for (range, angle) in scan.ranges_mm.iter_mut().zip(CONFIG.beam_angles) {
            *range = Some((distance_mm * i64::from(TRIG_ONE) / i64::from(angle.cos())) as u16);
        }
        scan
    }

    /// Facing +y from the middle of the mat.
    const POSE: Pose = Pose::from_mm_mdeg(1000, 1000, 0);

    #[test]
    fn the_safe_distance_is_radius_plus_speed_times_latency_and_tick_plus_margin() {
        assert_eq!(CONFIG.reach_mm(86), 18 + 25);
        assert_eq!(CONFIG.safe_distance_mm(86), 103);
        assert_eq!(CONFIG.safe_distance_mm(150), 115);
        assert_eq!(CONFIG.safe_distance_mm(0), 85);
        let slow = GuardConfig {
            latency_us: 300_000,
            ..CONFIG
        };
        assert_eq!(slow.safe_distance_mm(100), 60 + 40 + 25);
    }

    #[test]
    fn a_wall_ahead_stops_within_the_safe_distance_and_not_beyond() {
        let map = empty_map();
        let safe = i64::from(CONFIG.safe_distance_mm(86));
        let ahead_at = |distance: i64, command: DriveCommand| {
            decide(
                &CONFIG,
                &POSE,
                &map,
                Some(&wall_ahead(distance)),
                &TRUSTED,
                command,
            )
        };
        for distance in [20, 60, 90, safe - 1] {
            assert!(
                matches!(ahead_at(distance, AHEAD), Decision::Stop(Obstacle::Beam(_))),
                "{distance}"
            );
        }
        for distance in [safe + 1, 150, 400, 2000] {
            assert_eq!(ahead_at(distance, AHEAD), Decision::Go, "{distance}");
        }
        // Faster, a wall beyond the safe distance at 86 mm/s is inside it (145 mm at 300).
        assert!(ahead_at(140, AHEAD).is_go());
        let fast = DriveCommand {
            speed_mm_s: 300,
            ..AHEAD
        };
        assert!(!ahead_at(140, fast).is_go());
    }

    #[test]
    fn turns_and_standing_still_always_go() {
        let map = map_with(&[(1000, 1060)]);
        let scan = wall_ahead(70);
        for command in [
            DriveCommand::default(),
            DriveCommand {
                speed_mm_s: 0,
                turn_mdps: 31_500,
            },
        ] {
            assert_eq!(
                decide(&CONFIG, &POSE, &map, Some(&scan), &TRUSTED, command),
                Decision::Go
            );
        }
    }

    #[test]
    fn a_motion_whose_input_is_doubted_holds() {
        let map = empty_map();
        let turn = DriveCommand {
            speed_mm_s: 0,
            turn_mdps: 31_500,
        };
        let no_gyro = Trust {
            gyro: Some(Doubt::Stuck),
            ..TRUSTED
        };
        let no_flow = Trust {
            flow: Some(Doubt::Impossible),
            ..TRUSTED
        };
        let hold = Decision::Hold(Input::Gyro);
        assert_eq!(decide(&CONFIG, &POSE, &map, None, &no_gyro, turn), hold);
        assert_eq!(decide(&CONFIG, &POSE, &map, None, &no_gyro, AHEAD), hold);
        assert!(!hold.is_go());
        // A turn on the spot needs no flow; a drive does.
        assert!(decide(&CONFIG, &POSE, &map, None, &no_flow, turn).is_go());
        assert_eq!(
            decide(&CONFIG, &POSE, &map, None, &no_flow, AHEAD),
            Decision::Hold(Input::Flow)
        );
        // Standing still needs nothing.
        let still = DriveCommand::default();
        assert!(decide(&CONFIG, &POSE, &map, None, &no_gyro, still).is_go());
    }

    #[test]
    fn a_scan_the_core_doubts_still_stops_a_drive() {
        let disagreed = Trust {
            depth: Some(Doubt::DisagreesWithTag),
            ..TRUSTED
        };
        let wall = wall_ahead(60);
        for trust in [TRUSTED, disagreed] {
            let decision = decide(&CONFIG, &POSE, &empty_map(), Some(&wall), &trust, AHEAD);
            assert!(
                matches!(decision, Decision::Stop(Obstacle::Beam(_))),
                "{trust:?}"
            );
        }
    }

    #[test]
    fn a_forward_drive_holds_while_the_depth_sensor_is_blind() {
        let map = empty_map();
        let hold = Decision::Hold(Input::Depth);
        let back = DriveCommand {
            speed_mm_s: -86,
            turn_mdps: 0,
        };
        let turn = DriveCommand {
            speed_mm_s: 0,
            turn_mdps: 31_500,
        };
        // Nothing seen as it is this tick: no frame, the frame before again, a range
        // beyond the sensor's, or every range stepped.
        let mut frame = crate::SensorFrame::empty(100_000);
        frame.depth = Some(NOTHING_AHEAD);
        for doubt in [
            None,
            Some(Doubt::Stuck),
            Some(Doubt::Impossible),
            Some(Doubt::Jump),
        ] {
            frame.depth_doubt = doubt;
            let sight = (doubt.is_none()).then_some(&NOTHING_AHEAD);
            assert_eq!(frame.sight(), sight, "{doubt:?}");
        }
        frame.depth = None;
        assert_eq!(frame.sight(), None);
        assert_eq!(decide(&CONFIG, &POSE, &map, None, &TRUSTED, AHEAD), hold);
        // Backwards the sensor never looked; turns on the spot sweep nothing new.
        assert!(decide(&CONFIG, &POSE, &map, None, &TRUSTED, back).is_go());
        assert!(decide(&CONFIG, &POSE, &map, None, &TRUSTED, turn).is_go());
        // A late frame still shows what was ahead.
        frame.depth = Some(NOTHING_AHEAD);
        frame.depth_doubt = Some(Doubt::Late);
        assert_eq!(frame.sight(), Some(&NOTHING_AHEAD));
        // The core's doubt of the depth sensor alone does not hold a drive that sees.
        for doubt in [Doubt::Jump, Doubt::Late, Doubt::DisagreesWithTag] {
            let doubted = Trust {
                depth: Some(doubt),
                ..TRUSTED
            };
            let scan = Some(&NOTHING_AHEAD);
            assert!(decide(&CONFIG, &POSE, &map, scan, &doubted, AHEAD).is_go());
        }
        // A frame with nothing in reach is a frame: the drive goes.
        assert!(decide(&CONFIG, &POSE, &map, Some(&NOTHING_AHEAD), &TRUSTED, AHEAD).is_go());
    }

    #[test]
    fn a_wall_beside_the_swept_path_does_not_stop() {
        // Only the outermost beam on each side returns, from a wall 75 mm to the side
        // (15 mm clear of the body): its hit lies beside the path.
        let mut scan = DepthScan::default();
        for i in [0, BEAMS - 1] {
            let sin = i64::from(CONFIG.beam_angles[i].sin()).abs();
            scan.ranges_mm[i] = Some((75 * i64::from(TRIG_ONE) / sin) as u16);
        }
        assert_eq!(
            decide(&CONFIG, &POSE, &empty_map(), Some(&scan), &TRUSTED, AHEAD),
            Decision::Go
        );
        // The same return a beam nearer the nose is in the path.
        let mut near_nose = DepthScan::default();
        near_nose.ranges_mm[3] = Some(90);
        assert_eq!(
            decide(
                &CONFIG,
                &POSE,
                &empty_map(),
                Some(&near_nose),
                &TRUSTED,
                AHEAD
            ),
            Decision::Stop(Obstacle::Beam(3))
        );
        // A mapped wall parallel to the path, its cells' centres 125 mm to the side.
        let wall: [(i32, i32); 6] = core::array::from_fn(|i| (1125, 900 + 50 * i as i32));
        assert_eq!(
            decide(
                &CONFIG,
                &POSE,
                &map_with(&wall),
                Some(&NOTHING_AHEAD),
                &TRUSTED,
                AHEAD
            ),
            Decision::Go
        );
    }

    #[test]
    fn dropouts_say_nothing() {
        let map = empty_map();
        assert_eq!(
            decide(&CONFIG, &POSE, &map, Some(&NOTHING_AHEAD), &TRUSTED, AHEAD),
            Decision::Go
        );
        let blank = DepthScan::default();
        assert_eq!(
            decide(&CONFIG, &POSE, &map, Some(&blank), &TRUSTED, AHEAD),
            Decision::Go
        );
        // One beam left of a close wall still stops.
        let mut one = DepthScan::default();
        one.ranges_mm[5] = wall_ahead(50).ranges_mm[5];
        assert_eq!(
            decide(&CONFIG, &POSE, &map, Some(&one), &TRUSTED, AHEAD),
            Decision::Stop(Obstacle::Beam(5))
        );
    }

    #[test]
    fn a_box_seen_only_in_the_map_stops() {
        // A box corner 95 mm ahead and 55 mm right: under the body's edge, outside the fan.
        let map = map_with(&[(1055, 1095)]);
        let (c, r) = GEOMETRY.cell_of(1055, 1095);
        let blind = DepthScan::default();
        assert_eq!(
            decide(&CONFIG, &POSE, &map, Some(&blind), &TRUSTED, AHEAD),
            Decision::Stop(Obstacle::Cell { column: c, row: r })
        );
        // Facing away from it, or driving past it further off, the robot goes.
        let away = Pose::from_mm_mdeg(1000, 1000, 180_000);
        assert_eq!(
            decide(&CONFIG, &away, &map, Some(&blind), &TRUSTED, AHEAD),
            Decision::Go
        );
        let further = map_with(&[(1000, 1300)]);
        assert_eq!(
            decide(
                &CONFIG,
                &POSE,
                &further,
                Some(&NOTHING_AHEAD),
                &TRUSTED,
                AHEAD
            ),
            Decision::Go
        );
        // Backing into it: only the map can tell.
        let reverse = DriveCommand {
            speed_mm_s: -86,
            turn_mdps: 0,
        };
        assert!(!decide(&CONFIG, &away, &map, Some(&blind), &TRUSTED, reverse).is_go());
        assert_eq!(
            decide(&CONFIG, &POSE, &map, Some(&blind), &TRUSTED, reverse),
            Decision::Go
        );
    }

    #[test]
    fn the_map_is_read_in_the_heading_of_the_pose() {
        // A cell 75 mm east and 25 mm south: stops facing east (90 degrees) or north-east,
        // not facing north (it is then behind the centre).
        let map = map_with(&[(1075, 975)]);
        let east = Pose::from_mm_mdeg(1000, 1000, 90_000);
        assert!(!decide(&CONFIG, &east, &map, Some(&NOTHING_AHEAD), &TRUSTED, AHEAD).is_go());
        let north_east = Pose::from_mm_mdeg(1000, 1000, 45_000);
        assert!(!decide(
            &CONFIG,
            &north_east,
            &map,
            Some(&NOTHING_AHEAD),
            &TRUSTED,
            AHEAD
        )
        .is_go());
        assert_eq!(
            decide(&CONFIG, &POSE, &map, Some(&NOTHING_AHEAD), &TRUSTED, AHEAD),
            Decision::Go
        );
        // Near the grid's edge nothing is read outside it.
        let corner = Pose::from_mm_mdeg(-140, -140, 225_000);
        assert_eq!(
            decide(
                &CONFIG,
                &corner,
                &empty_map(),
                Some(&NOTHING_AHEAD),
                &TRUSTED,
                AHEAD
            ),
            Decision::Go
        );
    }
}
