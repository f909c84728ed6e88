//! A simulated robot on the seed mat for the filter's tests: a true pose driven by commands,
//! and the frames its sensors would report, with the sensors' own errors (flow and gyro
//! scale, gyro bias, reading noise) and the camera's pictures from a moment before the tick.
//!
//! In `f64` and independent of the core: it only builds `SensorFrame`s.
#![allow(dead_code)]

use crate::reference::filter::FPose;
use crate::reference::{column_of, heading_of, nose, wrap, Lcg};
use slam_core::{FlowDelta, GyroRate, SensorFrame, TagDetection, TagDetections, MAX_TAGS};

/// The sensors' errors, as the truth has them.
#[derive(Clone, Copy, Debug)]
pub struct Sensors {
    /// The flow's scale error: a reading is the true displacement over `100 um (1 + this)`.
    pub flow_scale: f64,
    /// The gyro's scale error: a reading is the true rate over `1 + this`, plus the bias.
    pub gyro_scale: f64,
    /// The gyro's bias, millidegrees per second.
    pub gyro_bias_mdps: f64,
    /// Half-width of the gyro's uniform noise, millidegrees per second.
    pub gyro_noise_mdps: f64,
    /// Half-width of the camera's uniform range noise, millimetres.
    pub range_noise_mm: f64,
    /// Half-width of the camera's uniform noise on a tag's column, pixels (so a bearing off
    /// the picture's centre is read closer, as a real camera reads it).
    pub column_noise_px: f64,
    /// Farthest the camera reads a tag, mm, and widest off the nose, radians.
    pub max_range_mm: f64,
    pub half_view: f64,
}

impl Sensors {
    /// The seed's errors: the flow reads 4 % short, the gyro 0.75 % high (its true rate is
    /// the reading times 1.0075), with 20 mdps of bias; the camera within 2 mm and 0.16 px
    /// (0.1 deg at the picture's centre).
    pub const SEED: Sensors = Sensors {
        flow_scale: -0.04,
        gyro_scale: 0.0075,
        gyro_bias_mdps: 20.0,
        gyro_noise_mdps: 100.0,
        range_noise_mm: 2.0,
        column_noise_px: 0.16,
        max_range_mm: 1450.0,
        half_view: 55.0 * std::f64::consts::PI / 180.0,
    };
}

/// The robot, its world and its sensors.
pub struct Robot {
    pub truth: FPose,
    previous: FPose,
    pub sensors: Sensors,
    /// Tags where they really are: id, x mm, y mm.
    pub tags: Vec<(u16, f64, f64)>,
    rng: Lcg,
    /// Flow not yet counted, in counts (the sensor keeps the fraction).
    flow_rest: (f64, f64),
    /// The current command: speed mm/s (sign: forward or back) and the wobble on the heading.
    forward: bool,
    wobble: f64,
    ticks: u32,
    /// The last tick's distance, mm, and turn, rad.
    last_step: (f64, f64),
}

impl Robot {
    pub fn new(start: FPose, sensors: Sensors, tags: Vec<(u16, f64, f64)>, seed: u64) -> Robot {
        Robot {
            truth: start,
            previous: start,
            sensors,
            tags,
            rng: Lcg(seed),
            flow_rest: (0.0, 0.0),
            forward: true,
            wobble: 0.0,
            ticks: 0,
            last_step: (0.0, 0.0),
        }
    }

    /// Uniform in `[-1, 1)`.
    pub fn uniform(&mut self) -> f64 {
        (self.rng.next_u64() >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }

    /// A command that keeps the robot on the mat facing the far wall: up and down between
    /// y = 400 and 1400 mm, weaving within about 40 degrees of +y, pulled to the middle.
    pub fn wander(&mut self) -> (f64, f64) {
        if self.ticks.is_multiple_of(15) {
            self.wobble = 0.5 * self.uniform();
        }
        if self.truth.y > 1400.0 {
            self.forward = false;
        } else if self.truth.y < 400.0 {
            self.forward = true;
        }
        let sign = if self.forward { 1.0 } else { -1.0 };
        let pull = (-(self.truth.x - 1100.0) / 1000.0 * sign).clamp(-0.3, 0.3);
        let want = self.wobble + pull;
        let rate = (2.0 * (want - wrap(self.truth.heading))).clamp(-0.6, 0.6);
        (sign * (60.0 + 40.0 * self.uniform()), rate)
    }

    /// One tick of `dt_us` at `speed` mm/s and `rate` rad/s (clockwise), with the picture
    /// taken `age_us` before the tick's end: the frame the sensors report.
    pub fn tick(&mut self, speed: f64, rate: f64, dt_us: u32, age_us: u32) -> SensorFrame {
        self.ticks += 1;
        let dt = dt_us as f64 / 1e6;
        let turn = rate * dt;
        let mid = self.truth.heading + turn / 2.0;
        let d = speed * dt;
        self.previous = self.truth;
        self.last_step = (d, turn);
        let (nx, ny) = nose(mid);
        self.truth = FPose {
            x: self.truth.x + d * nx,
            y: self.truth.y + d * ny,
            heading: self.truth.heading + turn,
        };
        let s = self.sensors;
        // Counts of 100 um, read short or long by the flow's scale; the fraction kept.
        let counts = d * 1000.0 / (100.0 * (1.0 + s.flow_scale)) + self.flow_rest.0;
        let forward = counts.round();
        self.flow_rest = (counts - forward, 0.0);
        let rate_mdps = rate.to_degrees() * 1000.0 / (1.0 + s.gyro_scale)
            + s.gyro_bias_mdps
            + s.gyro_noise_mdps * self.uniform();
        let mut frame = SensorFrame::empty(dt_us);
        frame.flow = Some(FlowDelta {
            forward_counts: forward as i32,
            right_counts: 0,
        });
        frame.gyro = Some(GyroRate {
            rate_mdps: rate_mdps.round() as i32,
        });
        frame.tags = self.picture(age_us.min(dt_us), dt_us);
        frame.tags_age_us = age_us;
        frame
    }

    /// The true pose `age_us` before the tick's end, along this tick's arc.
    pub fn truth_at(&self, age_us: u32, dt_us: u32) -> FPose {
        let f = 1.0 - age_us as f64 / dt_us.max(1) as f64;
        let (d, turn) = self.last_step;
        let a = self.previous;
        let (nx, ny) = nose(a.heading + f * turn / 2.0);
        FPose {
            x: a.x + f * d * nx,
            y: a.y + f * d * ny,
            heading: a.heading + f * turn,
        }
    }

    /// What the camera reads of every tag in view from the truth `age_us` back.
    fn picture(&mut self, age_us: u32, dt_us: u32) -> TagDetections {
        let from = self.truth_at(age_us, dt_us);
        let s = self.sensors;
        let mut out = TagDetections::new();
        for (id, tx, ty) in self.tags.clone() {
            let (dx, dy) = (tx - from.x, ty - from.y);
            let range = dx.hypot(dy);
            let bearing = wrap(heading_of(dx, dy) - from.heading);
            // Drawn whether or not the tag is in view, so that two worlds that differ in
            // one tag's place see the same noise on the others.
            let noise = (self.uniform(), self.uniform());
            if range > s.max_range_mm || bearing.abs() > s.half_view || out.len() >= MAX_TAGS {
                continue;
            }
            let range = range + s.range_noise_mm * noise.0;
            let column = column_of(bearing) + s.column_noise_px * noise.1;
            let _ = out.push(TagDetection {
                id,
                cx_centipx: (column * 100.0).round() as i32,
                distance_mm: range.round() as u32,
            });
        }
        out
    }
}
