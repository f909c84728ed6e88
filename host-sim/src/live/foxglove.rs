//! The run as Foxglove channels: what the app's 3D, plot, raw-message and log panels read.
//!
//! One [`FoxgloveSink`] turns the stream into the channels below, once; the Foxglove SDK
//! hands every logged message to each of its outputs: the WebSocket server
//! ([`super::websocket`], for `--live`) and the MCAP file ([`super::mcap`], for `--mcap`).
//!
//! | topic | schema | when |
//! |---|---|---|
//! | `/map` | `foxglove.Grid`, field `probability` (`f32`, the logistic of the cell's log odds) | on the first tick, every 10th tick, and at the end |
//! | `/tf` | `foxglove.FrameTransforms`, `map` to `base_link` | every tick |
//! | `/pose` | `foxglove.PoseInFrame` | every tick |
//! | `/pose/covariance` | `foxglove.Odometry`, its `pose_covariance` (m², rad²; x, y and yaw) | every `Filter` |
//! | `/pose/ellipse` | `foxglove.SceneUpdate`, the 3-sigma position ellipse | every `Filter` |
//! | `/path/estimated`, `/path/true` | `foxglove.PosesInFrame`, decimated ([`super::path`]) | with the map; the truth's only in simulation or with `--truth` |
//! | `/tags` | `foxglove.SceneUpdate`, the listed tags | with the map |
//! | `/tags/sightings` | `foxglove.SceneUpdate`, the tags in the tick's picture | every tick with inputs |
//! | `/health` | JSON: the sensors' fault counters and the core's counters | every `Health` |
//! | `/filter` | JSON: the covariance, the learned calibration and the tags used and refused | every `Filter` |
//! | `/log` | `foxglove.Log`: what the viewer noticed in the stream (a `Hello`, a restart, the end), name `host-sim`; and with `view --log` the firmware's defmt lines, name `firmware`, at their own times | as it happens; a firmware line just before the first tick at or after it |
//!
//! Times are the wall clock when the session started plus the stream's own time, so a
//! recorded run plays in the app as it was recorded; a restart of the robot carries on
//! from where its time stood.

use super::grid::LatestMap;
use super::log::{LogLevel, LogLine};
use super::mcap::McapFile;
use super::path::{new_path, Path, PathPoint};
use super::scene::{self, Stage, MAP_FRAME, ROBOT_FRAME};
use super::websocket::FoxgloveServer;
use super::{LiveError, LiveSink};
use crate::record::Belief;
use crate::truth::TruthSample;
use ::foxglove::messages::{
    log::Level, FrameTransform, FrameTransforms, Grid, Log, Odometry, PoseInFrame, PosesInFrame,
    SceneUpdate, Timestamp, Vector3,
};
use ::foxglove::{Channel, Context, PartialMetadata, RawChannel, Schema};
use serde::Serialize;
use slam_core::{Counters, TagDetection};
use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, SystemTime, UNIX_EPOCH};
use wire::telemetry::{serialize_counters, FilterState, Hello, Message, SensorHealth, Tick};

/// The map, the paths and the tags go out on the first tick and then every this many.
pub const SLOW_EVERY_TICKS: u64 = 10;

/// How long the server stays up after the last message, so that it reaches the clients.
const LINGER: Duration = Duration::from_millis(300);

/// Where the channels go: a WebSocket server, an MCAP file, or both.
#[derive(Clone, Debug, Default)]
pub struct Outputs {
    /// Serve on 127.0.0.1 at this port (0: any free one).
    pub websocket_port: Option<u16>,
    /// Record into this file (replaced if it exists).
    pub mcap: Option<PathBuf>,
}

/// The typed and JSON channels, all in one context.
struct Channels {
    map: Channel<Grid>,
    tf: Channel<FrameTransforms>,
    pose: Channel<PoseInFrame>,
    covariance: Channel<Odometry>,
    ellipse: Channel<SceneUpdate>,
    path_estimated: Channel<PosesInFrame>,
    path_true: Channel<PosesInFrame>,
    tags: Channel<SceneUpdate>,
    sightings: Channel<SceneUpdate>,
    health: Arc<RawChannel>,
    filter: Arc<RawChannel>,
    log: Channel<Log>,
}

/// A JSON channel: its messages are objects whose JSON Schema is `schema`.
fn json_channel(
    ctx: &Arc<Context>,
    topic: &str,
    name: &str,
    schema: &'static str,
) -> Result<Arc<RawChannel>, LiveError> {
    ctx.channel_builder(topic)
        .message_encoding("json")
        .schema(Schema::new(name, "jsonschema", schema.as_bytes()))
        .build_raw()
        .map_err(|e| LiveError::Server {
            what: "Foxglove channels",
            port: 0,
            reason: e.to_string(),
        })
}

impl Channels {
    fn new(ctx: &Arc<Context>) -> Result<Channels, LiveError> {
        Ok(Channels {
            map: ctx.channel_builder("/map").build(),
            tf: ctx.channel_builder("/tf").build(),
            pose: ctx.channel_builder("/pose").build(),
            covariance: ctx.channel_builder("/pose/covariance").build(),
            ellipse: ctx.channel_builder("/pose/ellipse").build(),
            path_estimated: ctx.channel_builder("/path/estimated").build(),
            path_true: ctx.channel_builder("/path/true").build(),
            tags: ctx.channel_builder("/tags").build(),
            sightings: ctx.channel_builder("/tags/sightings").build(),
            health: json_channel(ctx, "/health", "bugbot.Health", HEALTH_SCHEMA)?,
            filter: json_channel(ctx, "/filter", "bugbot.Filter", FILTER_SCHEMA)?,
            log: ctx.channel_builder("/log").build(),
        })
    }
}

/// The JSON Schema of `/health` messages ([`HealthJson`]).
const HEALTH_SCHEMA: &str = r#"{"title":"bugbot.Health","type":"object","properties":{"time_s":{"type":"number"},"tick":{"type":"integer"},"sensors":{"type":"object"},"counters":{"type":["object","null"]},"stale":{"type":"object"}}}"#;

/// The JSON Schema of `/filter` messages ([`FilterJson`]).
const FILTER_SCHEMA: &str = r#"{"title":"bugbot.Filter","type":"object","properties":{"time_s":{"type":"number"},"tick":{"type":"integer"},"belief":{"type":"object"},"bound_3sigma_cm":{"type":"number"},"bound_3sigma_heading_deg":{"type":"number"}}}"#;

/// A `/health` message.
#[derive(Serialize)]
struct HealthJson<'a> {
    time_s: f64,
    tick: u32,
    sensors: &'a SensorHealth,
    #[serde(serialize_with = "serialize_counters")]
    counters: Option<Counters>,
    stale: StaleJson,
}

/// The inputs missing on the latest tick.
#[derive(Serialize)]
struct StaleJson {
    flow: bool,
    gyro: bool,
    depth: bool,
}

/// A `/filter` message.
#[derive(Serialize)]
struct FilterJson<'a> {
    time_s: f64,
    tick: u32,
    belief: &'a Belief,
    bound_3sigma_cm: f64,
    bound_3sigma_heading_deg: f64,
}

/// Stream time to the app's time: the session's start plus the stream's milliseconds,
/// carried on across restarts so that it never goes back.
#[derive(Clone, Copy, Debug)]
struct Clock {
    start_ns: u64,
    /// Stream milliseconds before the latest restart.
    offset_ms: u64,
    last_ms: u32,
}

impl Clock {
    fn new() -> Clock {
        let start_ns = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .map_or(0, |d| u64::try_from(d.as_nanos()).unwrap_or(0));
        Clock {
            start_ns,
            offset_ms: 0,
            last_ms: 0,
        }
    }

    /// Moves to a tick at `time_ms`.
    fn tick(&mut self, time_ms: u32) {
        if time_ms < self.last_ms {
            // One tick's worth after the last time before the restart.
            self.offset_ms += u64::from(self.last_ms) + 100;
        }
        self.last_ms = time_ms;
    }

    fn now_ns(&self) -> u64 {
        self.start_ns
            .saturating_add((self.offset_ms + u64::from(self.last_ms)).saturating_mul(1_000_000))
    }

    /// The app's time of a firmware log line at `time_ms` since boot: the robot's clock
    /// is the stream's, so it is placed as a tick at that time would be.
    fn at_ns(&self, time_ms: u64) -> u64 {
        self.start_ns
            .saturating_add((self.offset_ms.saturating_add(time_ms)).saturating_mul(1_000_000))
    }

    fn timestamp(&self) -> Timestamp {
        timestamp_of(self.now_ns())
    }
}

/// Nanoseconds since the Unix epoch as a message's timestamp.
fn timestamp_of(ns: u64) -> Timestamp {
    let sec = u32::try_from(ns / 1_000_000_000).unwrap_or(u32::MAX);
    Timestamp::new(sec, (ns % 1_000_000_000) as u32)
}

/// The Foxglove end of a live session: see [the module](self).
pub struct FoxgloveSink {
    /// The channels' context, which the outputs are attached to.
    _ctx: Arc<Context>,
    channels: Channels,
    server: Option<FoxgloveServer>,
    mcap: Option<McapFile>,
    stage: Stage,
    clock: Clock,
    map: LatestMap,
    estimated: Path,
    truth: Path,
    last_tick: Option<Tick>,
    ticks: u64,
    /// The tags in the picture of the tick whose `Inputs` came last, for its `Tick`.
    seen: Option<Vec<TagDetection>>,
    last_hello: Option<Hello>,
    finished: bool,
}

impl FoxgloveSink {
    /// The channels, served and recorded as `outputs` say, with `stage` for the tags.
    pub fn new(stage: Stage, outputs: &Outputs) -> Result<FoxgloveSink, LiveError> {
        let ctx = Context::new();
        let channels = Channels::new(&ctx)?;
        let mcap = match &outputs.mcap {
            Some(path) => Some(McapFile::create(&ctx, path)?),
            None => None,
        };
        let server = match outputs.websocket_port {
            Some(port) => Some(FoxgloveServer::start(&ctx, port)?),
            None => None,
        };
        Ok(FoxgloveSink {
            _ctx: ctx,
            channels,
            server,
            mcap,
            stage,
            clock: Clock::new(),
            map: LatestMap::new(),
            estimated: new_path(),
            truth: new_path(),
            last_tick: None,
            ticks: 0,
            seen: None,
            last_hello: None,
            finished: false,
        })
    }

    /// The port the WebSocket server listens on, when it serves.
    pub fn websocket_port(&self) -> Option<u16> {
        self.server.as_ref().map(FoxgloveServer::port)
    }

    fn log(&self, level: Level, message: String) {
        let log = Log {
            timestamp: Some(self.clock.timestamp()),
            level: level as i32,
            message,
            name: "host-sim".to_string(),
            ..Log::default()
        };
        self.channels.log.log_with_time(&log, self.clock.now_ns());
    }

    fn firmware_log(&self, line: &LogLine) {
        let level = match line.level {
            Some(LogLevel::Trace | LogLevel::Debug) => Level::Debug,
            Some(LogLevel::Info) => Level::Info,
            Some(LogLevel::Warn) => Level::Warning,
            Some(LogLevel::Error) => Level::Error,
            None => Level::Unknown,
        };
        let ns = self.clock.at_ns(line.time_ms);
        let log = Log {
            timestamp: Some(timestamp_of(ns)),
            level: level as i32,
            message: line.message.clone(),
            name: "firmware".to_string(),
            ..Log::default()
        };
        self.channels.log.log_with_time(&log, ns);
    }

    fn json<T: Serialize>(&self, channel: &RawChannel, value: &T) {
        if let Ok(bytes) = serde_json::to_vec(value) {
            channel.log_with_meta(&bytes, PartialMetadata::with_log_time(self.clock.now_ns()));
        }
    }

    fn take_hello(&mut self, h: &Hello) {
        self.map.hello(h);
        let same = self.last_hello.is_some_and(|old| {
            (old.width, old.height, old.firmware, old.localiser)
                == (h.width, h.height, h.firmware, h.localiser)
        });
        if !same {
            let f = h.firmware;
            self.log(
                Level::Info,
                format!(
                    "Hello: firmware {}.{}.{}, localiser {:?}, {} x {} grid of {} mm cells",
                    f.major, f.minor, f.patch, h.localiser, h.width, h.height, h.cell_mm
                ),
            );
        }
        self.last_hello = Some(*h);
    }

    fn take_tick(&mut self, t: &Tick) {
        if self.last_tick.is_some_and(|last| t.tick <= last.tick) {
            self.log(
                Level::Warning,
                format!(
                    "the robot restarted: tick {} after tick {}",
                    t.tick,
                    self.last_tick.map_or(0, |l| l.tick)
                ),
            );
        }
        self.clock.tick(t.time_ms);
        self.last_tick = Some(*t);
        self.ticks += 1;
        let ts = self.clock.timestamp();
        let ns = self.clock.now_ns();
        let p = t.pose();
        let (x_mm, y_mm) = (f64::from(p.x_um) / 1000.0, f64::from(p.y_um) / 1000.0);
        let heading_deg = f64::from(p.heading.to_microdegrees()) / 1e6;
        let pose = scene::pose_m(x_mm, y_mm, heading_deg);
        self.channels.tf.log_with_time(
            &FrameTransforms {
                transforms: vec![FrameTransform {
                    timestamp: Some(ts),
                    parent_frame_id: MAP_FRAME.to_string(),
                    child_frame_id: ROBOT_FRAME.to_string(),
                    translation: pose.position,
                    rotation: pose.orientation,
                }],
            },
            ns,
        );
        self.channels.pose.log_with_time(
            &PoseInFrame {
                timestamp: Some(ts),
                frame_id: MAP_FRAME.to_string(),
                pose: Some(pose),
            },
            ns,
        );
        self.estimated.push(PathPoint {
            x_mm,
            y_mm,
            heading_deg,
        });
        if let Some(seen) = self.seen.take() {
            let update = scene::sightings(&self.stage, (x_mm, y_mm, heading_deg), &seen, ts);
            self.channels.sightings.log_with_time(&update, ns);
        }
        if (self.ticks - 1).is_multiple_of(SLOW_EVERY_TICKS) {
            self.publish_slow();
        }
    }

    /// The map, the paths and the tags: large, and they change slowly.
    fn publish_slow(&mut self) {
        let ts = self.clock.timestamp();
        let ns = self.clock.now_ns();
        if let Some(grid) = self.map.grid(MAP_FRAME, ts) {
            self.channels.map.log_with_time(&grid, ns);
        }
        for (path, channel) in [
            (&self.estimated, &self.channels.path_estimated),
            (&self.truth, &self.channels.path_true),
        ] {
            if path.is_empty() {
                continue;
            }
            let poses = path
                .points()
                .map(|p| scene::pose_m(p.x_mm, p.y_mm, p.heading_deg))
                .collect();
            channel.log_with_time(
                &PosesInFrame {
                    timestamp: Some(ts),
                    frame_id: MAP_FRAME.to_string(),
                    poses,
                },
                ns,
            );
        }
        if !self.stage.tags.is_empty() {
            self.channels
                .tags
                .log_with_time(&scene::tags(&self.stage, ts), ns);
        }
    }

    fn take_filter(&mut self, f: &FilterState) {
        let Some(t) = self.last_tick.filter(|t| t.tick == f.tick) else {
            return;
        };
        let ts = self.clock.timestamp();
        let ns = self.clock.now_ns();
        let belief = Belief::new(&f.estimate(), f.tags);
        let p = t.pose();
        let (x_mm, y_mm) = (f64::from(p.x_um) / 1000.0, f64::from(p.y_um) / 1000.0);
        let heading_deg = f64::from(p.heading.to_microdegrees()) / 1e6;
        // x, y in m², the heading (a yaw, the same variance) in rad²; no cross terms with
        // the heading are sent.
        let mut covariance = vec![0.0; 36];
        let m2 = 1e-6;
        covariance[0] = belief.xx_mm2 * m2;
        covariance[1] = belief.xy_mm2 * m2;
        covariance[6] = belief.xy_mm2 * m2;
        covariance[7] = belief.yy_mm2 * m2;
        covariance[35] = belief.hh_deg2 * (std::f64::consts::PI / 180.0).powi(2);
        self.channels.covariance.log_with_time(
            &Odometry {
                timestamp: Some(ts),
                frame_id: MAP_FRAME.to_string(),
                body_frame_id: ROBOT_FRAME.to_string(),
                pose: Some(scene::pose_m(x_mm, y_mm, heading_deg)),
                linear_velocity: Some(Vector3::default()),
                angular_velocity: Some(Vector3::default()),
                pose_covariance: covariance,
                velocity_covariance: vec![0.0; 36],
                ..Odometry::default()
            },
            ns,
        );
        self.channels
            .ellipse
            .log_with_time(&scene::ellipse(&belief, (x_mm, y_mm), ts), ns);
        self.json(
            &self.channels.filter,
            &FilterJson {
                time_s: f64::from(t.time_ms) / 1000.0,
                tick: t.tick,
                belief: &belief,
                bound_3sigma_cm: belief.bound_3sigma_cm(),
                bound_3sigma_heading_deg: belief.bound_3sigma_heading_deg(),
            },
        );
    }

    fn take_health(&mut self, h: &SensorHealth) {
        let stale = self.last_tick.map(|t| t.staleness()).unwrap_or_default();
        self.json(
            &self.channels.health,
            &HealthJson {
                time_s: self
                    .last_tick
                    .map_or(0.0, |t| f64::from(t.time_ms) / 1000.0),
                tick: self.last_tick.map_or(0, |t| t.tick),
                sensors: h,
                counters: self.last_tick.map(|t| t.counters),
                stale: StaleJson {
                    flow: stale.flow,
                    gyro: stale.gyro,
                    depth: stale.depth,
                },
            },
        );
    }
}

impl LiveSink for FoxgloveSink {
    fn message(&mut self, message: &Message) {
        match message {
            Message::Hello(h) => self.take_hello(h),
            Message::Tick(t) => self.take_tick(t),
            Message::MapRows(r) => self.map.rows(r),
            Message::Health(h) => self.take_health(h),
            Message::Filter(f) => self.take_filter(f),
            Message::Inputs(i) => self.seen = Some(i.frame.tags.iter().copied().collect()),
        }
    }

    fn log_line(&mut self, line: &LogLine) {
        self.firmware_log(line);
    }

    fn truth(&mut self, s: &TruthSample) {
        self.truth.push(PathPoint {
            x_mm: s.x_mm,
            y_mm: s.y_mm,
            heading_deg: s.heading_deg,
        });
    }

    /// The final map, paths and tags; then the MCAP file is closed and the server stopped.
    fn finish(&mut self) -> Result<(), LiveError> {
        if self.finished {
            return Ok(());
        }
        self.finished = true;
        self.publish_slow();
        self.log(
            Level::Info,
            format!("the stream ended after {} ticks", self.ticks),
        );
        let closed = self.mcap.take().map_or(Ok(()), McapFile::close);
        if let Some(server) = self.server.take() {
            std::thread::sleep(LINGER);
            server.stop();
        }
        closed
    }
}
