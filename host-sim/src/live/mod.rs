//! Watching a run as it happens (`--live`) and keeping it for later (`--mcap`).
//!
//! A live session is a stream of decoded telemetry [`Message`]s, from a serial port, a
//! recorded file or a simulated run, pushed one by one into [`LiveSink`]s: the Foxglove
//! channels ([`foxglove::FoxgloveSink`], served on a WebSocket and/or written to an MCAP
//! file) and the zero-install page. [`play`] is that loop: it decodes, keeps the usual
//! [`Recording`] (so the summary and the pictures are what `view` gives), paces a recorded
//! stream at the speed its ticks were recorded ([`pace::Pace`]) and hands each message,
//! and the true pose when known, to every sink, with the firmware's log lines
//! ([`log::FirmwareLog`], `view --log`) each just before the first tick at or after its time.
//!
//! A simulated run is simulated first (a few seconds at most: the simulator runs
//! thousands of times faster than the robot) and its stream then played like a file, so
//! `run --live` and `view FILE --live` are one code path and show the same thing.

pub mod foxglove;
pub mod grid;
pub mod log;
pub mod mcap;
pub mod pace;
pub mod path;
pub mod scene;
pub mod websocket;

use crate::telemetry::Recording;
use crate::truth::{truth_at, TruthSample};
use pace::Pace;
use std::fmt;
use std::io::{self, Read};
use std::sync::atomic::AtomicBool;
use std::time::Instant;
use wire::telemetry::Message;

/// Where a live session's messages go.
///
/// The loop calls [`LiveSink::message`] for every decoded message in stream order (a
/// `Tick` when its time has come, for a paced stream), [`LiveSink::truth`] right before
/// a `Tick` whose true pose is known, and [`LiveSink::finish`] once when the stream ends.
pub trait LiveSink {
    /// One decoded message.
    fn message(&mut self, message: &Message);
    /// The true pose at the `Tick` given next (in simulation, or with `--truth`).
    fn truth(&mut self, _sample: &TruthSample) {}
    /// A line of the firmware's log, given before the first `Tick` at or after its time.
    fn log_line(&mut self, _line: &log::LogLine) {}
    /// The stream has ended: publish what is pending and close.
    fn finish(&mut self) -> Result<(), LiveError> {
        Ok(())
    }
}

/// Why a live session or its recording could not start or be written.
#[derive(Debug)]
pub enum LiveError {
    /// Another program listens on the port already.
    PortInUse {
        /// What the port serves (`Foxglove WebSocket`, `page`).
        what: &'static str,
        /// The port.
        port: u16,
    },
    /// The server could not be started for another reason.
    Server {
        /// What the port serves.
        what: &'static str,
        /// The port asked for.
        port: u16,
        /// Why.
        reason: String,
    },
    /// The MCAP file could not be created or written.
    Mcap {
        /// The file.
        path: String,
        /// Why.
        reason: String,
    },
}

impl fmt::Display for LiveError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LiveError::PortInUse { what, port } => write!(
                f,
                "cannot serve the {what} on 127.0.0.1:{port}: the port is in use (choose another, or 0 for any free port)"
            ),
            LiveError::Server { what, port, reason } => {
                write!(f, "cannot serve the {what} on 127.0.0.1:{port}: {reason}")
            }
            LiveError::Mcap { path, reason } => write!(f, "cannot write MCAP file {path}: {reason}"),
        }
    }
}

impl std::error::Error for LiveError {}

/// What [`play`] feeds: the sinks, the pace and the truth.
pub struct Feed<'a> {
    /// Every message goes to each of these, in order.
    pub sinks: Vec<&'a mut dyn LiveSink>,
    /// `None`: as fast as the source gives bytes (a serial port, or `--mcap` alone).
    pub pace: Option<Pace>,
    /// The true poses in time order, paired with each `Tick` by [`truth_at`].
    pub truth: Option<&'a [TruthSample]>,
    /// The firmware's log, handed out as its lines fall due.
    pub log: Option<&'a mut log::FirmwareLog>,
}

impl Feed<'_> {
    /// Hands `message` to every sink, after waiting for its time if it is a paced `Tick`;
    /// `false` when `stop` was set or `deadline` passed while waiting.
    fn push(&mut self, message: &Message, stop: &AtomicBool, deadline: Option<Instant>) -> bool {
        if let (Message::Tick(t), Some(pace)) = (message, self.pace.as_mut()) {
            if !pace.wait_for(t.time_ms, stop, deadline) {
                return false;
            }
        }
        if let (Message::Tick(t), Some(log)) = (message, self.log.as_deref_mut()) {
            for line in log.due(t.time_ms) {
                for sink in self.sinks.iter_mut() {
                    sink.log_line(&line);
                }
            }
        }
        if let (Message::Tick(t), Some(truth)) = (message, self.truth) {
            if let Some(sample) = truth_at(truth, t.time_ms) {
                for sink in self.sinks.iter_mut() {
                    sink.truth(&sample);
                }
            }
        }
        for sink in self.sinks.iter_mut() {
            sink.message(message);
        }
        true
    }

    /// Hands out the log's remaining lines and ends every sink; the first error is
    /// returned after all were ended.
    pub fn finish(&mut self) -> Result<(), LiveError> {
        if let Some(log) = self.log.as_deref_mut() {
            for line in log.rest() {
                for sink in self.sinks.iter_mut() {
                    sink.log_line(&line);
                }
            }
        }
        let mut result = Ok(());
        for sink in self.sinks.iter_mut() {
            let r = sink.finish();
            if result.is_ok() {
                result = r;
            }
        }
        result
    }
}

/// Reads `source` into `recording` and `feed` until end of file, `stop` is set, or
/// `deadline` passes, as [`Recording::read_from`] does, handing every good message to the
/// feed as it is decoded. The sinks are not finished here ([`Feed::finish`]).
///
/// Timeouts and interrupted reads are waited out; any other error ends the reading and
/// is returned after everything before it was fed.
pub fn play(
    recording: &mut Recording,
    source: &mut dyn Read,
    stop: &AtomicBool,
    deadline: Option<Instant>,
    feed: &mut Feed<'_>,
) -> io::Result<()> {
    recording.read_each(source, stop, deadline, |message| {
        feed.push(message, stop, deadline)
    })
}
