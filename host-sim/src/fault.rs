//! Sensor faults, injected into what the core reads: every sensor, every way it fails.
//!
//! A fault turns one sensor bad for a stretch of simulated time, then the sensor recovers
//! (or never does, without a duration). It acts on the [`SensorFrame`] the core steps, so
//! the core sees exactly what a driver would hand it from a sensor failing that way:
//!
//! | kind | depth | flow | gyro | camera |
//! |---|---|---|---|---|
//! | `off` | no frame | no reading | no reading | no pictures |
//! | `stuck` | the last frame again, bit for bit | the last delta again | the last rate again | the last sightings again |
//! | `garbage` | random ranges | random counts | random rates | random ids, pixels and distances |
//! | `wrong` | every range [`WRONG_RANGE_MM`] long | counts scaled by [`WRONG_FLOW_SCALE`] | rate off by [`WRONG_GYRO_BIAS_MDPS`] | centres off by [`WRONG_TAG_CENTIPX`] |
//! | `slow` | readings [`SLOW_TICKS`] ticks late | the same | the same | the same |
//! | `intermittent` | each tick's reading lost half the time | the same | the same | the same |
//!
//! A fault is written `SENSOR-KIND@START[/DURATION]` on the command line (`gyro-stuck@5/3`:
//! the gyro stuck from 5 s for 3 s; `T+5` for `5` as the emulator writes it) or as a
//! scenario's `[[faults]]` table.

use std::fmt;
use std::str::FromStr;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Deserialize;
use slam_core::{DepthScan, FlowDelta, GyroRate, SensorFrame, TagDetection, TagDetections};

/// How far a `wrong` depth sensor reads every range, millimetres: a plausible offset.
pub const WRONG_RANGE_MM: i32 = 150;
/// How a `wrong` flow sensor scales its counts: a surface change it cannot tell.
pub const WRONG_FLOW_SCALE: f64 = 1.3;
/// How far a `wrong` gyro's rate is off, millidegrees a second: a bias jump.
pub const WRONG_GYRO_BIAS_MDPS: i32 = 3_000;
/// How far a `wrong` camera puts each tag's centre, hundredths of a pixel.
pub const WRONG_TAG_CENTIPX: i32 = 4_000;
/// How many ticks late a `slow` sensor's readings come.
pub const SLOW_TICKS: usize = 3;

/// The sensors a fault can strike.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Sensor {
    /// The VL53L5CX depth sensor.
    Depth,
    /// The PMW3901 optical-flow sensor.
    Flow,
    /// The gyro.
    Gyro,
    /// The camera co-processor's tag sightings.
    Camera,
}

impl Sensor {
    /// Every sensor, in the matrix's order.
    pub const ALL: [Sensor; 4] = [Sensor::Depth, Sensor::Flow, Sensor::Gyro, Sensor::Camera];

    /// The name the command line and scenario files use.
    pub fn name(self) -> &'static str {
        match self {
            Sensor::Depth => "depth",
            Sensor::Flow => "flow",
            Sensor::Gyro => "gyro",
            Sensor::Camera => "camera",
        }
    }
}

/// The ways a sensor fails.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Kind {
    /// No answer.
    Off,
    /// The same reading forever.
    Stuck,
    /// Random values.
    Garbage,
    /// A plausible but false reading.
    Wrong,
    /// Readings late by more than a tick.
    Slow,
    /// Dropping in and out.
    Intermittent,
}

impl Kind {
    /// Every kind, in the matrix's order.
    pub const ALL: [Kind; 6] = [
        Kind::Off,
        Kind::Stuck,
        Kind::Garbage,
        Kind::Wrong,
        Kind::Slow,
        Kind::Intermittent,
    ];

    /// The name the command line and scenario files use.
    pub fn name(self) -> &'static str {
        match self {
            Kind::Off => "off",
            Kind::Stuck => "stuck",
            Kind::Garbage => "garbage",
            Kind::Wrong => "wrong",
            Kind::Slow => "slow",
            Kind::Intermittent => "intermittent",
        }
    }
}

/// One sensor failing one way from `start_s`, for `duration_s` (for good without one).
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Fault {
    /// Which sensor.
    pub sensor: Sensor,
    /// How it fails.
    pub kind: Kind,
    /// Simulated seconds from the start of the run.
    pub start_s: f64,
    /// How long it lasts, seconds; absent: to the end of the run.
    #[serde(default)]
    pub duration_s: Option<f64>,
}

/// What is wrong with a fault as written.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum FaultError {
    /// Not `SENSOR-KIND@START[/DURATION]`.
    Form(String),
    /// A sensor with no such name.
    Sensor(String),
    /// A kind with no such name.
    Kind(String),
    /// A start or duration that is not a finite number of seconds >= 0 (a duration > 0).
    Time(String),
}

impl fmt::Display for FaultError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let sensors = Sensor::ALL.map(Sensor::name).join(", ");
        let kinds = Kind::ALL.map(Kind::name).join(", ");
        match self {
            FaultError::Form(s) => write!(
                f,
                "bad fault `{s}`: want SENSOR-KIND@START[/DURATION] in seconds, e.g. gyro-stuck@5/3"
            ),
            FaultError::Sensor(s) => write!(f, "unknown sensor `{s}`: want one of {sensors}"),
            FaultError::Kind(s) => write!(f, "unknown fault kind `{s}`: want one of {kinds}"),
            FaultError::Time(s) => write!(
                f,
                "bad fault time `{s}`: want seconds, a start >= 0 and a duration > 0, at most an hour"
            ),
        }
    }
}

impl std::error::Error for FaultError {}

/// The longest start or duration a fault may name, seconds: the longest run.
const MAX_FAULT_S: f64 = 3600.0;

impl Fault {
    /// Checks the times: finite, a start from 0, a duration above 0, each within an hour.
    pub fn validate(&self) -> Result<(), FaultError> {
        let start_ok = (0.0..=MAX_FAULT_S).contains(&self.start_s);
        let duration_ok = self.duration_s.is_none_or(|d| d > 0.0 && d <= MAX_FAULT_S);
        if start_ok && duration_ok {
            Ok(())
        } else {
            Err(FaultError::Time(format!(
                "start {} s, duration {:?} s",
                self.start_s, self.duration_s
            )))
        }
    }

    /// Whether the fault is in force at `t_s`.
    pub fn active(&self, t_s: f64) -> bool {
        t_s >= self.start_s && self.duration_s.is_none_or(|d| t_s < self.start_s + d)
    }

    /// When the sensor comes back, seconds; `None` if it never does.
    pub fn end_s(&self) -> Option<f64> {
        self.duration_s.map(|d| self.start_s + d)
    }
}

impl fmt::Display for Fault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}-{}@{}",
            self.sensor.name(),
            self.kind.name(),
            self.start_s
        )?;
        match self.duration_s {
            Some(d) => write!(f, "/{d}"),
            None => Ok(()),
        }
    }
}

impl FromStr for Fault {
    type Err = FaultError;

    fn from_str(s: &str) -> Result<Fault, FaultError> {
        let form = || FaultError::Form(s.to_string());
        let (what, when) = s.split_once('@').ok_or_else(form)?;
        let (sensor, kind) = what.split_once('-').ok_or_else(form)?;
        let sensor = Sensor::ALL
            .into_iter()
            .find(|x| x.name() == sensor)
            .ok_or_else(|| FaultError::Sensor(sensor.to_string()))?;
        let kind = Kind::ALL
            .into_iter()
            .find(|x| x.name() == kind)
            .ok_or_else(|| FaultError::Kind(kind.to_string()))?;
        let when = when.strip_prefix("T+").unwrap_or(when);
        let (start, duration) = match when.split_once('/') {
            Some((a, d)) => (a, Some(d)),
            None => (when, None),
        };
        let seconds = |x: &str| {
            let x = x.strip_suffix('s').unwrap_or(x);
            x.parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| FaultError::Time(x.to_string()))
        };
        let fault = Fault {
            sensor,
            kind,
            start_s: seconds(start)?,
            duration_s: duration.map(seconds).transpose()?,
        };
        fault.validate()?;
        Ok(fault)
    }
}

/// One sensor's reading as the frame carries it.
#[derive(Clone, Debug, PartialEq)]
enum Reading {
    Depth(Option<DepthScan>),
    Flow(Option<FlowDelta>),
    Gyro(Option<GyroRate>),
    Camera(TagDetections),
}

/// Applies a run's faults to each tick's frame.
pub struct Injector {
    faults: Vec<Fault>,
    rng: ChaCha8Rng,
    /// Per sensor (in [`Sensor::ALL`]'s order): the last reading it gave before a fault,
    /// and the healthy readings of the last ticks, newest last, for `slow`.
    last: [Option<Reading>; 4],
    history: [Vec<Reading>; 4],
    /// Frames a fault changed, per sensor.
    touched: [u32; 4],
}

impl Injector {
    /// An injector for `faults`, its random values seeded from `seed`.
    pub fn new(faults: &[Fault], seed: u64) -> Injector {
        Injector {
            faults: faults.to_vec(),
            // Its own stream: a run's noise is the same with and without faults.
            rng: ChaCha8Rng::seed_from_u64(seed ^ 0xfa17_fa17_fa17_fa17),
            last: Default::default(),
            history: Default::default(),
            touched: [0; 4],
        }
    }

    /// Whether any fault is in force at `t_s`.
    pub fn any_active(&self, t_s: f64) -> bool {
        self.faults.iter().any(|f| f.active(t_s))
    }

    /// Ticks on which a fault changed a sensor's reading, per sensor in [`Sensor::ALL`]'s
    /// order.
    pub fn touched(&self) -> [u32; 4] {
        self.touched
    }

    /// Turns `frame`, the healthy readings at `t_s`, into what the failing sensors give.
    pub fn apply(&mut self, t_s: f64, frame: &mut SensorFrame) {
        for (i, sensor) in Sensor::ALL.into_iter().enumerate() {
            let healthy = read(frame, sensor);
            let history = &mut self.history[i];
            history.push(healthy.clone());
            if history.len() > SLOW_TICKS + 1 {
                history.remove(0);
            }
            let kind = self
                .faults
                .iter()
                .find(|f| f.sensor == sensor && f.active(t_s))
                .map(|f| f.kind);
            let Some(kind) = kind else {
                self.last[i] = Some(healthy);
                continue;
            };
            let faulty = match kind {
                Kind::Off => off(sensor),
                Kind::Stuck => self.last[i].clone().unwrap_or_else(|| healthy.clone()),
                Kind::Garbage => garbage(sensor, &mut self.rng),
                Kind::Wrong => wrong(healthy.clone()),
                Kind::Slow => history[0].clone(),
                Kind::Intermittent => {
                    if self.rng.gen_bool(0.5) {
                        off(sensor)
                    } else {
                        healthy.clone()
                    }
                }
            };
            if faulty != healthy {
                self.touched[i] += 1;
            }
            write(frame, faulty);
        }
    }
}

fn read(frame: &SensorFrame, sensor: Sensor) -> Reading {
    match sensor {
        Sensor::Depth => Reading::Depth(frame.depth),
        Sensor::Flow => Reading::Flow(frame.flow),
        Sensor::Gyro => Reading::Gyro(frame.gyro),
        Sensor::Camera => Reading::Camera(frame.tags.clone()),
    }
}

fn write(frame: &mut SensorFrame, reading: Reading) {
    match reading {
        Reading::Depth(d) => frame.depth = d,
        Reading::Flow(f) => frame.flow = f,
        Reading::Gyro(g) => frame.gyro = g,
        Reading::Camera(t) => frame.tags = t,
    }
}

fn off(sensor: Sensor) -> Reading {
    match sensor {
        Sensor::Depth => Reading::Depth(None),
        Sensor::Flow => Reading::Flow(None),
        Sensor::Gyro => Reading::Gyro(None),
        Sensor::Camera => Reading::Camera(TagDetections::new()),
    }
}

/// Random values over the whole of each field's type, as a corrupted bus would give.
fn garbage(sensor: Sensor, rng: &mut ChaCha8Rng) -> Reading {
    match sensor {
        Sensor::Depth => {
            let mut scan = DepthScan {
                ranges_mm: [None; slam_core::BEAMS],
            };
            for r in &mut scan.ranges_mm {
                *r = rng.gen_bool(0.9).then(|| rng.gen());
            }
            Reading::Depth(Some(scan))
        }
        Sensor::Flow => Reading::Flow(Some(FlowDelta {
            forward_counts: rng.gen_range(-32_768..32_768),
            right_counts: rng.gen_range(-32_768..32_768),
        })),
        Sensor::Gyro => Reading::Gyro(Some(GyroRate {
            rate_mdps: rng.gen_range(-2_000_000..2_000_000),
        })),
        Sensor::Camera => {
            let mut tags = TagDetections::new();
            for _ in 0..rng.gen_range(1..=slam_core::MAX_TAGS) {
                let tag = TagDetection {
                    id: rng.gen(),
                    cx_centipx: rng.gen_range(-100_000..100_000),
                    distance_mm: rng.gen_range(0..100_000),
                };
                // Full: the loop stops at the capacity.
                let _ = tags.push(tag);
            }
            Reading::Camera(tags)
        }
    }
}

/// The healthy reading, falsified plausibly.
fn wrong(healthy: Reading) -> Reading {
    match healthy {
        Reading::Depth(d) => Reading::Depth(d.map(|mut scan| {
            for r in scan.ranges_mm.iter_mut().flatten() {
                *r = (i32::from(*r) + WRONG_RANGE_MM).clamp(0, i32::from(u16::MAX)) as u16;
            }
            scan
        })),
        Reading::Flow(f) => Reading::Flow(f.map(|f| {
            let scale = |c: i32| (f64::from(c) * WRONG_FLOW_SCALE).round() as i32;
            FlowDelta {
                forward_counts: scale(f.forward_counts),
                right_counts: scale(f.right_counts),
            }
        })),
        Reading::Gyro(g) => Reading::Gyro(g.map(|g| GyroRate {
            rate_mdps: g.rate_mdps.saturating_add(WRONG_GYRO_BIAS_MDPS),
        })),
        Reading::Camera(mut tags) => {
            for t in &mut tags {
                t.cx_centipx = t.cx_centipx.saturating_add(WRONG_TAG_CENTIPX);
            }
            Reading::Camera(tags)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn faults_parse_as_the_emulator_writes_them() {
        let f: Fault = "gyro-stuck@T+5/3".parse().expect("fault");
        assert_eq!(
            f,
            Fault {
                sensor: Sensor::Gyro,
                kind: Kind::Stuck,
                start_s: 5.0,
                duration_s: Some(3.0),
            }
        );
        assert_eq!(f.to_string().parse::<Fault>(), Ok(f));
        let forever: Fault = "depth-off@2.5s".parse().expect("fault");
        assert_eq!(forever.duration_s, None);
        assert!(forever.active(1e6) && !forever.active(2.4));
        assert!(f.active(5.0) && f.active(7.99) && !f.active(8.0));
    }

    #[test]
    fn bad_faults_name_what_is_wrong() {
        for (text, want) in [
            ("gyro", "SENSOR-KIND@START"),
            ("lidar-off@1", "unknown sensor `lidar`"),
            ("gyro-broken@1", "unknown fault kind `broken`"),
            ("gyro-off@-1", "bad fault time"),
            ("gyro-off@1/0", "bad fault time"),
            ("gyro-off@NaN", "bad fault time"),
            ("gyro-off@1/1e99", "bad fault time"),
        ] {
            let e = text.parse::<Fault>().expect_err(text).to_string();
            assert!(e.contains(want), "{text}: {e}");
        }
    }

    fn frame(k: i32) -> SensorFrame {
        let mut f = SensorFrame::empty(100_000);
        f.flow = Some(FlowDelta {
            forward_counts: 10 * k,
            right_counts: -k,
        });
        f.gyro = Some(GyroRate {
            rate_mdps: 1000 * k,
        });
        f.depth = Some(DepthScan {
            ranges_mm: [Some(500 + k as u16); slam_core::BEAMS],
        });
        let _ = f.tags.push(TagDetection {
            id: 11,
            cx_centipx: 100 * k,
            distance_mm: 1000,
        });
        f
    }

    /// Runs ticks 0..n at 10 Hz with `fault`, returning the frames the core would see.
    fn inject(fault: &str, n: i32) -> Vec<SensorFrame> {
        let mut inj = Injector::new(&[fault.parse().expect("fault")], 1);
        (0..n)
            .map(|k| {
                let mut f = frame(k);
                inj.apply(f64::from(k) * 0.1, &mut f);
                f
            })
            .collect()
    }

    #[test]
    fn each_kind_does_what_it_says_and_only_while_in_force() {
        let healthy: Vec<_> = (0..20).map(frame).collect();
        let during =
            |frames: &[SensorFrame]| (10..15).map(|k| frames[k].clone()).collect::<Vec<_>>();
        // From tick 10 for 0.5 s: ticks 10 to 14.
        let off = inject("gyro-off@1/0.5", 20);
        assert!(during(&off)
            .iter()
            .all(|f| f.gyro.is_none() && f.flow.is_some()));
        assert_eq!(off[15], healthy[15]);
        assert_eq!(off[9], healthy[9]);

        let stuck = inject("depth-stuck@1/0.5", 20);
        assert!(during(&stuck).iter().all(|f| f.depth == healthy[9].depth));

        let wrong = inject("flow-wrong@1/0.5", 20);
        assert_eq!(wrong[12].flow.map(|f| f.forward_counts), Some(156));

        let slow = inject("camera-slow@1/0.5", 20);
        assert_eq!(slow[12].tags, healthy[12 - SLOW_TICKS].tags);

        let garbage = inject("gyro-garbage@1/0.5", 20);
        assert!(during(&garbage)
            .iter()
            .zip(&healthy[10..15])
            .all(|(g, h)| g.gyro != h.gyro));

        let flaky = inject("camera-intermittent@0", 200);
        let lost = flaky.iter().filter(|f| f.tags.is_empty()).count();
        assert!((60..140).contains(&lost), "{lost} of 200 lost");
    }
}
