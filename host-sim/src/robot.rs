//! The true robot: kinematics, and the sensors as they read the true world.
//!
//! This is the one physics of the project: the demos, the tests and (later) the emulated
//! firmware all read their sensors from here.

use crate::scenario::Scenario;
use crate::slip::WheelSlip;
use crate::world::{Vec2, World};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use slam_core::{DepthScan, FlowDelta, GyroRate, TagDetection, TagDetections, BEAMS};
use std::collections::VecDeque;

/// What the motors are asked to do.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Command {
    /// Forward speed, millimetres per second.
    pub speed_mm_s: f64,
    /// Turn rate, degrees per second, positive clockwise.
    pub turn_dps: f64,
}

/// The robot's true pose.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TruePose {
    /// Millimetres.
    pub x_mm: f64,
    /// Millimetres.
    pub y_mm: f64,
    /// Degrees clockwise from +y, unwrapped (it keeps counting past 360).
    pub heading_deg: f64,
}

/// Physics sub-step: the gyro's 200 Hz sample period, in seconds.
pub const SUBSTEP_S: f64 = 0.005;
/// The sub-step in microseconds, for whole-number arithmetic on latencies.
const SUBSTEP_US: u64 = 5_000;
/// The flow sensor is read every other sub-step (100 Hz).
const FLOW_EVERY: u32 = 2;

/// Independent random streams, so that what one sensor draws never shifts another's noise
/// (the tag run's odometry noise is then the dead-reckoning run's, draw for draw).
struct Streams {
    tof: ChaCha8Rng,
    flow: ChaCha8Rng,
    gyro: ChaCha8Rng,
    camera: ChaCha8Rng,
    /// The wheels' slip.
    slip: ChaCha8Rng,
    /// The gyro bias's random walk.
    gyro_bias: ChaCha8Rng,
}

impl Streams {
    fn new(seed: u64) -> Streams {
        let stream = |n: u64| {
            ChaCha8Rng::seed_from_u64(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15).wrapping_add(n))
        };
        Streams {
            tof: stream(1),
            flow: stream(2),
            gyro: stream(3),
            camera: stream(4),
            slip: stream(5),
            gyro_bias: stream(6),
        }
    }
}

/// A standard normal draw scaled by `sigma` (0 draws nothing).
/// How far apart in range, millimetres, two surfaces under one depth zone must be for the
/// zone to see two targets.
const MIXED_EDGE_GAP_MM: f64 = 100.0;

/// Lines cast across a depth zone to find a step in depth under it.
const MIXED_EDGE_LINES: usize = 5;

fn noise(rng: &mut ChaCha8Rng, sigma: f64) -> f64 {
    if sigma > 0.0 {
        Normal::new(0.0, sigma).map_or(0.0, |n| n.sample(rng))
    } else {
        0.0
    }
}

/// The simulated robot on its mat.
pub struct Robot {
    world: World,
    scenario: Scenario,
    truth: TruePose,
    time_s: f64,
    substeps: u32,
    rng: Streams,
    flow_carry: (f64, f64),
    flow_sum: (i64, i64),
    flow_pending_mm: (f64, f64),
    gyro_sum_mdps: i64,
    gyro_samples: i64,
    last_gyro_mdps: i32,
    /// How far the gyro's bias has wandered from `sensors.gyro.bias_dps`, degrees per second.
    bias_walk_dps: f64,
    /// The wheels, which may slip.
    wheels: WheelSlip,
    /// The camera's latency in microseconds (the scenario's, rounded).
    camera_latency_us: u64,
    /// The depth sensor's frame period and the moment of its first frame, microseconds
    /// (period 0: a frame ranged at every tick).
    depth_period_us: u64,
    depth_phase_us: u64,
    /// True poses at the last sub-steps, newest last (the newest is `truth`), enough to
    /// look `camera_latency_us` and a depth frame's period back; before the start the
    /// robot stood at its start.
    past: VecDeque<TruePose>,
    /// Whether the body is touching a wall: set when a wall stops a move, cleared once
    /// the body is more than [`CONTACT_MM`] further off than its radius.
    in_contact: bool,
    /// Contacts since the start: each time a move was stopped by a wall the body was not
    /// already touching.
    collisions: u32,
}

/// How close to its radius the body's clearance must be to count as touching a wall,
/// millimetres: a contact ends once the body has moved further off than this.
const CONTACT_MM: f64 = 1.0;

/// Halvings when finding how far a blocked move gets before the body touches the wall:
/// 2^-20 of a sub-step's move, well below a micrometre.
const CONTACT_HALVINGS: u32 = 20;

impl Robot {
    /// A robot at the scenario's start, noise seeded by `seed`.
    pub fn new(scenario: &Scenario, seed: u64) -> Robot {
        let start = TruePose {
            x_mm: scenario.start.x_mm,
            y_mm: scenario.start.y_mm,
            heading_deg: scenario.start.heading_deg,
        };
        let depth_period_us = depth_period_us(scenario);
        Robot {
            world: World::new(scenario),
            scenario: scenario.clone(),
            truth: start,
            time_s: 0.0,
            substeps: 0,
            rng: Streams::new(seed),
            flow_carry: (0.0, 0.0),
            flow_sum: (0, 0),
            flow_pending_mm: (0.0, 0.0),
            gyro_sum_mdps: 0,
            gyro_samples: 0,
            last_gyro_mdps: 0,
            bias_walk_dps: 0.0,
            wheels: WheelSlip::new(scenario.robot.slip.clone()),
            camera_latency_us: camera_latency_us(scenario),
            depth_period_us,
            depth_phase_us: depth_phase_us(depth_period_us, seed),
            past: VecDeque::from([start]),
            in_contact: false,
            collisions: 0,
        }
    }

    /// Contacts with walls since the start, one per episode of touching (a move stopped
    /// by a wall the body was not already touching), not one per blocked sub-step.
    pub fn collisions(&self) -> u32 {
        self.collisions
    }

    /// The share (0 to 1) of the move by `(dx, dy)` the body can make before it touches a
    /// wall; 1 when the whole move is clear. A body already closer than its radius (never
    /// at a checked start) may still move away.
    fn clear_share(&self, dx: f64, dy: f64) -> f64 {
        let radius = self.scenario.robot.radius_mm;
        let (x, y) = (self.truth.x_mm, self.truth.y_mm);
        let clear = |t: f64| self.world.clearance(Vec2::new(x + dx * t, y + dy * t)) >= radius;
        if clear(1.0) {
            return 1.0;
        }
        let (mut lo, mut hi) = (0.0, 1.0);
        for _ in 0..CONTACT_HALVINGS {
            let mid = (lo + hi) / 2.0;
            if clear(mid) {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        lo
    }

    /// The world it drives in.
    pub fn world(&self) -> &World {
        &self.world
    }

    /// Where it really is.
    pub fn truth(&self) -> TruePose {
        self.truth
    }

    /// Simulated time, seconds.
    pub fn time_s(&self) -> f64 {
        self.time_s
    }

    /// Moves the robot for `dt_s` seconds under `command`, sampling the gyro at 200 Hz and
    /// the flow sensor at 100 Hz on the way.
    pub fn advance(&mut self, dt_s: f64, command: Command) {
        self.advance_to(self.time_s + dt_s, command);
    }

    /// Moves the robot under `command` to the sub-step nearest simulated time `t_s`, so
    /// that what is read next is the world within half a sub-step of `t_s`, either way: a
    /// reader at its own phase to the sub-steps (the emulated firmware's 200 Hz gyro) then
    /// sees the world of its own moment, not one that is always behind it.
    pub fn advance_to_nearest(&mut self, t_s: f64, command: Command) {
        self.advance_to(t_s + SUBSTEP_S / 2.0, command);
    }

    /// Moves the robot under `command` until simulated time `t_s`, in whole 5 ms sub-steps
    /// (a time between two sub-steps runs up to the earlier one; later calls catch up).
    /// The wheels may slip, so the true motion may differ from the command; the gyro and
    /// the flow sensor read the true motion.
    pub fn advance_to(&mut self, t_s: f64, command: Command) {
        let target = (t_s / SUBSTEP_S + 1e-6).floor().max(0.0) as u64;
        while (self.substeps as u64) < target {
            let motion = self.wheels.step(command, SUBSTEP_S, &mut self.rng.slip);
            let turn = motion.turn_dps * SUBSTEP_S;
            let mut dist = motion.speed_mm_s * SUBSTEP_S;
            let mid = Vec2::heading(self.truth.heading_deg + turn / 2.0);
            let mut slide = motion.slide_mm;
            // A wall stops the body where it touches; the wheels spin on (the gyro still
            // sees the turn, the flow sensor only the motion that happened).
            let share = self.clear_share(mid.x * dist + slide.x, mid.y * dist + slide.y);
            if share < 1.0 {
                dist *= share;
                slide = Vec2::new(slide.x * share, slide.y * share);
                if !self.in_contact {
                    self.collisions += 1;
                    self.in_contact = true;
                }
            }
            self.truth.x_mm += mid.x * dist;
            self.truth.y_mm += mid.y * dist;
            self.truth.heading_deg += turn;
            self.flow_pending_mm.0 += dist;
            if slide != Vec2::new(0.0, 0.0) {
                self.truth.x_mm += slide.x;
                self.truth.y_mm += slide.y;
                // The slide in the robot's frame (right is the heading plus 90 degrees).
                self.flow_pending_mm.0 += slide.x * mid.x + slide.y * mid.y;
                self.flow_pending_mm.1 += slide.x * mid.y - slide.y * mid.x;
            }
            let [ahead_mm, right_mm] = self.scenario.sensors.flow.offset_mm;
            if ahead_mm != 0.0 || right_mm != 0.0 {
                let (ahead, right) = flow_offset_motion(ahead_mm, right_mm, turn);
                self.flow_pending_mm.0 += ahead;
                self.flow_pending_mm.1 += right;
            }
            if self.in_contact && share == 1.0 {
                let here = Vec2::new(self.truth.x_mm, self.truth.y_mm);
                self.in_contact =
                    self.world.clearance(here) < self.scenario.robot.radius_mm + CONTACT_MM;
            }
            self.substeps += 1;
            self.time_s = self.substeps as f64 * SUBSTEP_S;
            self.remember_truth();

            let g = &self.scenario.sensors.gyro;
            self.bias_walk_dps += noise(
                &mut self.rng.gyro_bias,
                g.bias_walk_dps_per_sqrt_s * SUBSTEP_S.sqrt(),
            );
            let rate = motion.turn_dps * (1.0 + g.scale_error)
                + g.bias_dps
                + self.bias_walk_dps
                + noise(&mut self.rng.gyro, g.noise_dps);
            self.last_gyro_mdps = (rate * 1000.0).round() as i32;
            self.gyro_sum_mdps += self.last_gyro_mdps as i64;
            self.gyro_samples += 1;

            if self.substeps.is_multiple_of(FLOW_EVERY) {
                self.read_flow();
            }
        }
    }

    /// Keeps the newest true pose, and as many before it as the camera's latency or a depth
    /// frame's period reaches.
    fn remember_truth(&mut self) {
        let keep = (self.camera_latency_us.max(self.depth_period_us) / SUBSTEP_US) as usize + 2;
        self.past.push_back(self.truth);
        while self.past.len() > keep {
            self.past.pop_front();
        }
    }

    /// The true pose `age_us` ago, linear between the two sub-steps around that moment;
    /// before the start, the start.
    pub fn truth_ago(&self, age_us: u64) -> TruePose {
        if age_us == 0 {
            return self.truth;
        }
        let steps = (age_us / SUBSTEP_US) as usize;
        let frac = (age_us % SUBSTEP_US) as f64 / SUBSTEP_US as f64;
        // `past` ends with the newest pose; `back(k)` is the pose k sub-steps ago.
        let back = |k: usize| {
            let newest = self.past.len().saturating_sub(1);
            self.past
                .get(newest.saturating_sub(k))
                .copied()
                .unwrap_or(self.truth)
        };
        let (later, earlier) = (back(steps), back(steps + 1));
        let mix = |a: f64, b: f64| a + (b - a) * frac;
        TruePose {
            x_mm: mix(later.x_mm, earlier.x_mm),
            y_mm: mix(later.y_mm, earlier.y_mm),
            heading_deg: mix(later.heading_deg, earlier.heading_deg),
        }
    }

    /// How old the camera's pictures are when read, microseconds (the scenario's latency).
    pub fn camera_latency_us(&self) -> u64 {
        self.camera_latency_us
    }

    /// One 100 Hz flow reading: the floor moved since the last one, in counts, with the
    /// sensor's scale error and noise; the fraction of a count stays in the sensor.
    fn read_flow(&mut self) {
        let f = &self.scenario.sensors.flow;
        let per_mm = 1000.0 / f.um_per_count * (1.0 + f.scale_error);
        let (fwd, right) = self.flow_pending_mm;
        self.flow_pending_mm = (0.0, 0.0);
        let fx = fwd * per_mm + self.flow_carry.0 + noise(&mut self.rng.flow, f.noise_counts);
        let rx = right * per_mm + self.flow_carry.1 + noise(&mut self.rng.flow, f.noise_counts);
        let (cf, cr) = (fx.round(), rx.round());
        self.flow_carry = (fx - cf, rx - cr);
        self.flow_sum.0 += cf as i64;
        self.flow_sum.1 += cr as i64;
    }

    /// Flow counts since the last call, as the sensor's motion registers hold them
    /// (`forward`, `right`), and its surface quality.
    pub fn take_flow(&mut self) -> (i64, i64, u8) {
        let (f, r) = self.flow_sum;
        self.flow_sum = (0, 0);
        (f, r, self.scenario.sensors.flow.quality)
    }

    /// How far the gyro's bias has wandered from the scenario's `bias_dps`, degrees per
    /// second.
    pub fn gyro_bias_walk_dps(&self) -> f64 {
        self.bias_walk_dps
    }

    /// The gyro's newest 200 Hz sample, millidegrees per second.
    pub fn gyro_sample_mdps(&self) -> i32 {
        self.last_gyro_mdps
    }

    /// Flow and mean gyro rate since the last call, as the firmware's sensor tasks hand
    /// them to the SLAM tick. Flow is `None` when its surface quality is below `min_quality`.
    pub fn take_odometry(&mut self, min_quality: u8) -> (Option<FlowDelta>, Option<GyroRate>) {
        let flow = (self.scenario.sensors.flow.quality >= min_quality).then(|| FlowDelta {
            forward_counts: self.flow_sum.0.clamp(i32::MIN as i64, i32::MAX as i64) as i32,
            right_counts: self.flow_sum.1.clamp(i32::MIN as i64, i32::MAX as i64) as i32,
        });
        let gyro = (self.gyro_samples > 0).then(|| GyroRate {
            rate_mdps: (self.gyro_sum_mdps / self.gyro_samples)
                .clamp(i32::MIN as i64, i32::MAX as i64) as i32,
        });
        self.flow_sum = (0, 0);
        self.gyro_sum_mdps = 0;
        self.gyro_samples = 0;
        (flow, gyro)
    }

    /// The depth sensor's newest frame and how old it is now, microseconds: ranged from
    /// the true pose of its own moment, on the sensor's clock (`sensors.tof.rate_hz`).
    pub fn read_depth_frame(&mut self) -> (DepthScan, u32) {
        let age_us = self.depth_frame_age_us();
        let scan = self.depth_from(self.truth_ago(age_us));
        (scan, u32::try_from(age_us).unwrap_or(u32::MAX))
    }

    /// How long ago the sensor ranged its newest frame, microseconds: its frames come at
    /// its phase and every period after (before the start, the robot stood at its start).
    fn depth_frame_age_us(&self) -> u64 {
        if self.depth_period_us == 0 {
            return 0;
        }
        let now_us = (self.time_s * 1e6).round() as i64;
        (now_us - self.depth_phase_us as i64).rem_euclid(self.depth_period_us as i64) as u64
    }

    /// The depth sensor's 8 beams from the true pose now, in millimetres.
    pub fn read_depth(&mut self) -> DepthScan {
        self.depth_from(self.truth)
    }

    /// The depth sensor's 8 beams as ranged from `pose`, in millimetres.
    fn depth_from(&mut self, pose: TruePose) -> DepthScan {
        let t = self.scenario.sensors.tof.clone();
        let origin = Vec2::new(pose.x_mm, pose.y_mm);
        let mut scan = DepthScan::default();
        for (i, slot) in scan.ranges_mm.iter_mut().enumerate() {
            let zone = t.fov_deg / BEAMS as f64;
            let angle = -t.fov_deg / 2.0 + zone * (i as f64 + 0.5);
            let dir = Vec2::heading(pose.heading_deg + angle);
            let mut hit = self.world.ray(origin, dir);
            if t.mixed_edge > 0.0 {
                hit = self.mixed_edge(origin, pose.heading_deg + angle, zone, hit);
            }
            let sigma = t.noise_mm + t.noise_per_m_mm * hit.unwrap_or(0.0) / 1000.0;
            let noise = noise(&mut self.rng.tof, sigma);
            let dropped = rand::Rng::gen_bool(&mut self.rng.tof, t.dropout);
            *slot = match hit {
                Some(d) if d <= t.max_range_mm && !dropped => {
                    Some((d + noise).round().clamp(0.0, u16::MAX as f64) as u16)
                }
                _ => None,
            };
        }
        scan
    }

    /// A zone `zone_deg` wide centred on `centre_deg` that spans a step in depth (two
    /// neighbouring lines across it land on different surfaces more than
    /// [`MIXED_EDGE_GAP_MM`] apart in range: a box's edge before a wall) reports, with the
    /// scenario's chance, a range drawn between the nearest and furthest surface; otherwise
    /// `centre`. A single slanted wall or a room's inside corner is no step.
    fn mixed_edge(
        &mut self,
        origin: Vec2,
        centre_deg: f64,
        zone_deg: f64,
        centre: Option<f64>,
    ) -> Option<f64> {
        let mut hits = [None; MIXED_EDGE_LINES];
        for (k, hit) in hits.iter_mut().enumerate() {
            let across = k as f64 / (MIXED_EDGE_LINES - 1) as f64 - 0.5;
            *hit = self
                .world
                .ray_hit(origin, Vec2::heading(centre_deg + across * zone_deg));
        }
        let step = hits.windows(2).any(|pair| match (pair[0], pair[1]) {
            (Some((a, i)), Some((b, j))) => i != j && (a - b).abs() > MIXED_EDGE_GAP_MM,
            _ => false,
        });
        let ranges = hits.iter().flatten().map(|&(d, _)| d);
        let near = ranges.clone().fold(f64::INFINITY, f64::min);
        let far = ranges.fold(0.0, f64::max);
        let chance = self.scenario.sensors.tof.mixed_edge;
        if step && near < far && rand::Rng::gen_bool(&mut self.rng.tof, chance) {
            Some(rand::Rng::gen_range(&mut self.rng.tof, near..far))
        } else {
            centre
        }
    }

    /// The tags the camera reads from the true pose of the scenario's latency ago.
    pub fn read_tags(&mut self) -> TagDetections {
        let c = self.scenario.sensors.camera.clone();
        let pose = self.truth_ago(self.camera_latency_us);
        let origin = Vec2::new(pose.x_mm, pose.y_mm);
        let mut out = TagDetections::default();
        for tag in self.world.tags().to_vec() {
            let (dx, dy) = (tag.centre.x - origin.x, tag.centre.y - origin.y);
            let dist = dx.hypot(dy);
            let bearing = wrap_deg(dx.atan2(dy).to_degrees() - pose.heading_deg);
            // Angle between the tag's face normal and the direction back to the camera.
            let incidence = ((-dx * tag.normal.x - dy * tag.normal.y) / dist.max(1e-9))
                .clamp(-1.0, 1.0)
                .acos()
                .to_degrees();
            let visible = dist <= c.max_range_mm
                && bearing.abs() <= c.fov_deg / 2.0
                && incidence <= c.max_incidence_deg
                && self.world.line_of_sight(origin, tag.centre, tag.id);
            if !visible {
                continue;
            }
            let cx = c.width_px / 2.0
                + c.focal_px * bearing.to_radians().tan()
                + noise(&mut self.rng.camera, c.pixel_noise_px);
            let d = dist + noise(&mut self.rng.camera, c.distance_noise_mm);
            if !(0.0..=c.width_px).contains(&cx) || d <= 0.0 {
                continue;
            }
            let detection = TagDetection {
                id: tag.id,
                cx_centipx: (cx * 100.0).round() as i32,
                distance_mm: d.round() as u32,
            };
            if out.push(detection).is_err() {
                break;
            }
        }
        out
    }
}

/// How a flow sensor `ahead_mm` ahead of the turning axis and `right_mm` to its right
/// moves when the robot turns by `turn_deg` (clockwise) about that axis, in millimetres
/// along the robot's (`forward`, `right`) at the middle of the turn.
///
/// The sensor swings along a chord of length `2 r sin(turn / 2)`, across the middle of
/// the turn: with clockwise-positive headings, a sensor ahead moves right and one to the
/// right moves back (velocity at the sensor = omega x r).
pub fn flow_offset_motion(ahead_mm: f64, right_mm: f64, turn_deg: f64) -> (f64, f64) {
    let chord = 2.0 * (turn_deg.to_radians() / 2.0).sin();
    (-chord * right_mm, chord * ahead_mm)
}

/// A scenario's depth frame period in whole microseconds, 0 for a frame at every tick
/// (`sensors.tof.rate_hz` validated to 0 or `1..=60`).
fn depth_period_us(scenario: &Scenario) -> u64 {
    match scenario.sensors.tof.rate_hz {
        hz if hz > 0.0 => (1e6 / hz).round() as u64,
        _ => 0,
    }
}

/// When the depth sensor ranges its first frame, microseconds into its first `period`: set
/// by the noise seed (a robot's sensor starts when it starts, not on a tick), without a
/// draw from the noise streams.
fn depth_phase_us(period: u64, seed: u64) -> u64 {
    if period == 0 {
        return 0;
    }
    // SplitMix64's finaliser: seeds 1, 2, 3 spread over the period.
    let mut z = seed.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    (z ^ (z >> 31)) % period
}

/// A scenario's camera latency in whole microseconds (validated to `0..=1000` ms).
fn camera_latency_us(scenario: &Scenario) -> u64 {
    (scenario.sensors.camera.latency_ms * 1000.0)
        .round()
        .clamp(0.0, u32::MAX as f64) as u64
}

/// An angle in degrees wrapped into [-180, 180).
pub fn wrap_deg(deg: f64) -> f64 {
    (deg + 180.0).rem_euclid(360.0) - 180.0
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scenario(latency_ms: f64) -> Scenario {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/scenarios/seed-mat.toml");
        let mut s = match Scenario::load(std::path::Path::new(path)) {
            Ok(s) => s,
            Err(e) => panic!("the shipped scenario must load: {e}"),
        };
        s.sensors.camera.latency_ms = latency_ms;
        s
    }

    const TURN_AND_DRIVE: Command = Command {
        speed_mm_s: 86.0,
        turn_dps: 31.5,
    };

    /// A digest of everything the odometry sensors report over the first turn and drive
    /// of the seed route (seed 1), with the truth they came from.
    fn odometry_digest(scenario: &Scenario) -> u64 {
        let mut robot = Robot::new(scenario, 1);
        let mut digest: u64 = 0xcbf2_9ce4_8422_2325;
        let mut mix = |v: u64| {
            digest ^= v;
            digest = digest.wrapping_mul(0x0000_0100_0000_01b3);
        };
        for tick in 0..200 {
            let command = if tick < 115 {
                Command {
                    speed_mm_s: 0.0,
                    turn_dps: 31.5,
                }
            } else {
                Command {
                    speed_mm_s: 86.0,
                    turn_dps: 0.0,
                }
            };
            robot.advance(0.1, command);
            let (flow, gyro) = robot.take_odometry(0);
            let flow = flow.unwrap_or_default();
            mix(flow.forward_counts as u64);
            mix(flow.right_counts as u64);
            mix(gyro.map_or(0, |g| g.rate_mdps) as u64);
            let t = robot.truth();
            mix(t.x_mm.to_bits());
            mix(t.y_mm.to_bits());
            mix(t.heading_deg.to_bits());
        }
        digest
    }

    /// [`odometry_digest`] of the seed scenario as the robot read it before it had the
    /// failings (flow off the axis, slip, a wandering bias).
    const SEED_ODOMETRY_DIGEST: u64 = 0x3e08_efb9_c006_ecad;

    #[test]
    fn without_the_failings_the_sensors_read_as_they_always_have() {
        let plain = scenario(0.0);
        assert_eq!(plain.robot.slip, None);
        assert_eq!(plain.sensors.flow.offset_mm, [0.0, 0.0]);
        assert_eq!(plain.sensors.gyro.bias_walk_dps_per_sqrt_s, 0.0);
        assert_eq!(odometry_digest(&plain), SEED_ODOMETRY_DIGEST);
        // Each failing given at 0 is no failing.
        let mut zero = plain.clone();
        zero.robot.slip = Some(crate::scenario::Slip {
            spells_per_min: 0.0,
            spell_s: 1.0,
            speed_loss: 0.5,
            skid_mm_per_turn: 0.0,
        });
        assert_eq!(odometry_digest(&zero), SEED_ODOMETRY_DIGEST);
        // And each one at a level changes what the sensors read.
        let mut offset = plain.clone();
        offset.sensors.flow.offset_mm = [20.0, 0.0];
        let mut walk = plain.clone();
        walk.sensors.gyro.bias_walk_dps_per_sqrt_s = 0.01;
        let mut skid = zero.clone();
        if let Some(s) = skid.robot.slip.as_mut() {
            s.skid_mm_per_turn = 5.0;
        }
        for changed in [offset, walk, skid] {
            assert_ne!(odometry_digest(&changed), SEED_ODOMETRY_DIGEST);
        }
    }

    /// The seed scenario with exact sensors: no scale errors, no noise, no bias.
    fn exact() -> Scenario {
        let mut s = scenario(0.0);
        s.sensors.flow.scale_error = 0.0;
        s.sensors.flow.noise_counts = 0.0;
        s.sensors.gyro.scale_error = 0.0;
        s.sensors.gyro.noise_dps = 0.0;
        s.sensors.gyro.bias_dps = 0.0;
        s
    }

    /// Flow in millimetres (`forward`, `right`) and the gyro's mean rate over `seconds`
    /// under `command`.
    fn odometry_over(robot: &mut Robot, seconds: f64, command: Command) -> (f64, f64, f64) {
        let ticks = (seconds / 0.1).round() as usize;
        let (mut fwd, mut right, mut rate) = (0.0, 0.0, 0.0);
        for _ in 0..ticks {
            robot.advance(0.1, command);
            let (flow, gyro) = robot.take_odometry(0);
            let flow = flow.unwrap_or_default();
            fwd += f64::from(flow.forward_counts) * 0.1;
            right += f64::from(flow.right_counts) * 0.1;
            rate += gyro.map_or(0.0, |g| f64::from(g.rate_mdps) / 1000.0) / ticks as f64;
        }
        (fwd, right, rate)
    }

    const SPIN: Command = Command {
        speed_mm_s: 0.0,
        turn_dps: 31.5,
    };

    #[test]
    fn a_flow_sensor_off_the_axis_sees_a_spin_as_flow() {
        // On the axis, a spin moves no floor under the sensor.
        let (f, r, _) = odometry_over(&mut Robot::new(&exact(), 1), 1.0, SPIN);
        assert_eq!((f, r), (0.0, 0.0));
        // 20 mm ahead, spinning clockwise at 31.5 deg/s: the sensor swings right at
        // 2 pi 20 31.5 / 360 mm/s.
        let sideways_mm_s = 2.0 * std::f64::consts::PI * 20.0 * 31.5 / 360.0;
        let mut ahead = exact();
        ahead.sensors.flow.offset_mm = [20.0, 0.0];
        let (f, r, _) = odometry_over(&mut Robot::new(&ahead, 1), 1.0, SPIN);
        assert!(f.abs() < 0.1, "{f}");
        assert!(
            (r - sideways_mm_s).abs() < 0.1,
            "{r} against {sideways_mm_s}"
        );
        let anticlockwise = Command {
            turn_dps: -31.5,
            ..SPIN
        };
        let (_, r, _) = odometry_over(&mut Robot::new(&ahead, 1), 1.0, anticlockwise);
        assert!((r + sideways_mm_s).abs() < 0.1, "{r}");
        // 20 mm to the right, spinning clockwise: the sensor swings backwards.
        let mut right = exact();
        right.sensors.flow.offset_mm = [0.0, 20.0];
        let (f, r, _) = odometry_over(&mut Robot::new(&right, 1), 1.0, SPIN);
        assert!((f + sideways_mm_s).abs() < 0.1, "{f}");
        assert!(r.abs() < 0.1, "{r}");
        // A whole turn brings the sensor back where it started.
        let (f, r, _) = odometry_over(&mut Robot::new(&ahead, 1), 360.0 / 31.5, SPIN);
        assert!(f.abs() < 0.2 && r.abs() > 100.0, "{f} {r}");
        // Driving straight, the offset adds nothing.
        let drive = Command {
            speed_mm_s: 86.0,
            turn_dps: 0.0,
        };
        let (f, r, _) = odometry_over(&mut Robot::new(&ahead, 1), 1.0, drive);
        assert!((f - 86.0).abs() < 0.1 && r == 0.0, "{f} {r}");
    }

    #[test]
    fn flow_offset_motion_is_omega_cross_r() {
        // A small turn: the chord is the arc, omega x r.
        let turn_deg: f64 = 0.01;
        let w = turn_deg.to_radians();
        let (f, r) = flow_offset_motion(30.0, -10.0, turn_deg);
        assert!((f - w * 10.0).abs() < 1e-9 && (r - w * 30.0).abs() < 1e-9);
        assert_eq!(flow_offset_motion(0.0, 0.0, 5.0), (-0.0, 0.0));
        // Half a turn: the sensor ends on the far side of the axis.
        let (f, r) = flow_offset_motion(20.0, 0.0, 180.0);
        assert!(f.abs() < 1e-12 && (r - 40.0).abs() < 1e-12);
    }

    #[test]
    fn the_gyro_bias_wanders_as_a_random_walk() {
        let mut still = exact();
        still.sensors.gyro.bias_dps = 0.05;
        let standing = Command::default();
        // Without a walk the bias stays put, and the gyro reads it exactly.
        let mut robot = Robot::new(&still, 1);
        let (_, _, rate) = odometry_over(&mut robot, 10.0, standing);
        assert_eq!(robot.gyro_bias_walk_dps(), 0.0);
        assert!((rate - 0.05).abs() < 1e-9, "{rate}");
        // With one, the spread after 100 s is the walk's figure times 10.
        still.sensors.gyro.bias_walk_dps_per_sqrt_s = 0.004;
        let walks: Vec<f64> = (1..=40)
            .map(|seed| {
                let mut robot = Robot::new(&still, seed);
                robot.advance(100.0, standing);
                let read = f64::from(robot.gyro_sample_mdps()) / 1000.0;
                let walk = robot.gyro_bias_walk_dps();
                assert!((read - 0.05 - walk).abs() <= 0.0005, "{read} {walk}");
                walk
            })
            .collect();
        let spread = (walks.iter().map(|w| w * w).sum::<f64>() / walks.len() as f64).sqrt();
        assert!((0.028..0.052).contains(&spread), "{spread}");
        // The walk draws from its own stream: the gyro's noise is the same draw for draw.
        let (mut noisy, mut noisy_walk) = (scenario(0.0), scenario(0.0));
        noisy_walk.sensors.gyro.bias_walk_dps_per_sqrt_s = 0.004;
        noisy.sensors.gyro.bias_dps = 0.0;
        noisy_walk.sensors.gyro.bias_dps = 0.0;
        let (mut a, mut b) = (Robot::new(&noisy, 3), Robot::new(&noisy_walk, 3));
        for _ in 0..50 {
            a.advance(0.005, standing);
            b.advance(0.005, standing);
            let expected = f64::from(a.gyro_sample_mdps()) + b.gyro_bias_walk_dps() * 1000.0;
            assert!((f64::from(b.gyro_sample_mdps()) - expected).abs() <= 1.0);
        }
    }

    #[test]
    fn slip_moves_the_truth_and_the_sensors_read_the_truth() {
        let mut slippy = exact();
        slippy.robot.slip = Some(crate::scenario::Slip {
            spells_per_min: 20.0,
            spell_s: 1.0,
            speed_loss: 0.5,
            skid_mm_per_turn: 20.0,
        });
        let mut robot = Robot::new(&slippy, 2);
        let start = robot.truth();
        let seconds = 20.0;
        // The flow turned into the world by the true heading at each tick's middle.
        let (mut seen_x, mut seen_y, mut gyro_deg) = (0.0, 0.0, 0.0);
        for _ in 0..(seconds / 0.1) as usize {
            let before = robot.truth().heading_deg;
            let (f, r, rate) = odometry_over(&mut robot, 0.1, SPIN);
            let h = ((before + robot.truth().heading_deg) / 2.0).to_radians();
            seen_x += f * h.sin() + r * h.cos();
            seen_y += f * h.cos() - r * h.sin();
            gyro_deg += rate * 0.1;
        }
        let end = robot.truth();
        let turned = end.heading_deg - start.heading_deg;
        // Spells slowed the turn, and the gyro read the true rate.
        assert!(turned < 31.5 * seconds - 1.0, "{turned}");
        assert!((gyro_deg - turned).abs() < 0.01, "{gyro_deg} {turned}");
        // The centre slid, and the sensor (on the axis) saw the floor move as it did.
        let (dx, dy) = (end.x_mm - start.x_mm, end.y_mm - start.y_mm);
        assert!(dx.hypot(dy) > 1.0, "{dx} {dy}");
        assert!(
            (seen_x - dx).hypot(seen_y - dy) < 0.5,
            "{seen_x} {seen_y} {dx} {dy}"
        );
    }

    /// A sensor ranging on its own clock: each tick's frame is the newest, younger than a
    /// period, and the frames' moments lie whole periods apart; ranged from the pose of its
    /// moment. At rate 0 a frame is ranged at every tick, at its moment.
    #[test]
    fn a_depth_frame_is_the_newest_on_the_sensors_clock() {
        let mut s = scenario(0.0);
        s.sensors.tof.rate_hz = 15.0;
        s.sensors.tof.noise_mm = 0.0;
        s.sensors.tof.noise_per_m_mm = 0.0;
        s.sensors.tof.dropout = 0.0;
        let period_us = 66_667_i64;
        let mut robot = Robot::new(&s, 3);
        let mut moments = Vec::new();
        let mut ages = Vec::new();
        for tick in 1..=20_i64 {
            robot.advance(0.1, TURN_AND_DRIVE);
            let then = robot.truth_ago(robot.depth_frame_age_us());
            let (scan, age) = robot.read_depth_frame();
            assert!(i64::from(age) < period_us, "tick {tick}: {age} us");
            // Ranged from the truth of its moment: the same beams as a sensor standing there.
            assert_eq!(scan, robot.depth_from(then), "tick {tick}");
            moments.push(tick * 100_000 - i64::from(age));
            ages.push(age);
        }
        for pair in moments.windows(2) {
            let gap = pair[1] - pair[0];
            let periods = (gap as f64 / period_us as f64).round() as i64;
            assert!(
                periods >= 1 && (gap - periods * period_us).abs() <= 1,
                "{moments:?}"
            );
        }
        // A 15 Hz sensor beats against 10 Hz ticks: two ages, a third of a tick apart (the
        // period rounded to a microsecond).
        let age = |k: usize| i64::from(ages[k]);
        assert!((age(0) - age(2)).abs() <= 1, "{ages:?}");
        assert!(((age(0) - age(1)).abs() - 33_333).abs() <= 1, "{ages:?}");

        let mut at_tick = Robot::new(&scenario(0.0), 3);
        let mut plain = Robot::new(&scenario(0.0), 3);
        at_tick.advance(0.7, TURN_AND_DRIVE);
        plain.advance(0.7, TURN_AND_DRIVE);
        assert_eq!(at_tick.read_depth_frame(), (plain.read_depth(), 0));
    }

    #[test]
    fn truth_ago_is_the_truth_back_then() {
        let mut late = Robot::new(&scenario(100.0), 1);
        let mut early = Robot::new(&scenario(100.0), 1);
        // Before the start the robot stood at its start.
        assert_eq!(late.truth_ago(100_000), late.truth());
        late.advance(0.05, TURN_AND_DRIVE);
        assert_eq!(late.truth_ago(100_000), early.truth());
        late.advance(0.45, TURN_AND_DRIVE);
        early.advance(0.4, TURN_AND_DRIVE);
        assert_eq!(late.truth_ago(100_000), early.truth());
        assert_eq!(late.truth_ago(0), late.truth());
        // Between sub-steps: half way between the poses 5 ms apart.
        let (a, b) = (late.truth_ago(100_000), late.truth_ago(105_000));
        let mid = late.truth_ago(102_500);
        assert!((mid.x_mm - (a.x_mm + b.x_mm) / 2.0).abs() < 1e-9);
        assert!((mid.heading_deg - (a.heading_deg + b.heading_deg) / 2.0).abs() < 1e-9);
        assert!(b.heading_deg < a.heading_deg, "older is less turned");
    }

    #[test]
    fn the_camera_sees_from_the_pose_of_its_latency_ago() {
        let mut slow = Robot::new(&scenario(100.0), 1);
        let mut now = Robot::new(&scenario(0.0), 1);
        slow.advance(1.5, TURN_AND_DRIVE);
        now.advance(1.4, TURN_AND_DRIVE);
        // The same noise streams, so the same detections when the poses agree.
        let seen = slow.read_tags();
        assert!(!seen.is_empty(), "tag 11 is in view");
        assert_eq!(seen, now.read_tags());
        now.advance(0.1, TURN_AND_DRIVE);
        assert_ne!(slow.read_tags(), now.read_tags());
    }

    /// The seed's start facing the far wall 1.5 m away, with the depth sensor's noise and
    /// dropouts off and every step in depth read as mixed.
    fn mixing(walls: &[[[f64; 2]; 2]]) -> Robot {
        let mut s = scenario(0.0);
        s.world.walls.extend_from_slice(walls);
        s.world.tags.clear();
        s.sensors.tof.noise_mm = 0.0;
        s.sensors.tof.dropout = 0.0;
        s.sensors.tof.mixed_edge = 1.0;
        Robot::new(&s, 1)
    }

    #[test]
    fn a_zone_across_a_step_in_depth_reads_between_the_two_surfaces() {
        // A card 50 cm ahead whose right end is 2.3 degrees right of the nose: zone 4
        // (0 to 5.6 degrees right) sees the card on its left edge and the far wall on
        // its right; zone 3 (5.6 to 0 degrees left) sees only the card.
        let mut robot = mixing(&[[[500.0, 1000.0], [720.0, 1000.0]]]);
        let scan = robot.read_depth();
        let r = |i: usize| scan.ranges_mm[i].map_or(0, u32::from);
        assert!(
            r(4) > 501 && r(4) < 1501,
            "zone 4 between card and wall: {scan:?}"
        );
        assert!((499..=502).contains(&r(3)), "zone 3 on the card: {scan:?}");
    }

    #[test]
    fn a_slanted_wall_or_an_inside_corner_is_no_step() {
        let mut plain = mixing(&[]);
        plain.scenario.sensors.tof.mixed_edge = 0.0;
        let mut mixed = mixing(&[]);
        for turn in [0.0, 30.0, 60.0, 45.0] {
            // Looking at the far wall, then slanted at it, then into the far-right corner.
            plain.truth.heading_deg = turn;
            mixed.truth.heading_deg = turn;
            assert_eq!(plain.read_depth(), mixed.read_depth(), "heading {turn}");
        }
    }
}
