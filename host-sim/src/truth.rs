//! The world's truth beside a robot's telemetry, for `host-sim view --truth FILE`.
//!
//! The emulator's harness (`tests/emulator/harness.mjs --truth FILE`) writes one JSON line
//! per SLAM step, sampled as the step starts:
//! `{"t_s":0.1,"x_mm":700,"y_mm":500,"heading_deg":0}` (seconds since reset, the world's
//! millimetres, degrees clockwise from +y, unwrapped). [`parse_truth`] reads them and
//! [`truth_at`] finds the one that belongs to a telemetry `Tick`.

use crate::run::TICK_S;
use serde::Deserialize;
use std::fmt;

/// The true pose at one instant.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
pub struct TruthSample {
    /// Seconds since the robot's reset.
    pub t_s: f64,
    /// Millimetres.
    pub x_mm: f64,
    /// Millimetres.
    pub y_mm: f64,
    /// Degrees clockwise from +y; may run past 360.
    pub heading_deg: f64,
}

/// Why a truth file was refused. Lines count from 1.
#[derive(Clone, Debug, PartialEq)]
pub enum TruthError {
    /// Not a JSON object with the numbers `t_s`, `x_mm`, `y_mm` and `heading_deg`.
    Malformed {
        /// The line.
        line: usize,
        /// What is wrong with it.
        reason: String,
    },
    /// A sample earlier than the line above: the samples must come in time order.
    OutOfOrder {
        /// The line.
        line: usize,
        /// Its time, seconds.
        t_s: f64,
        /// The line above's time, seconds.
        previous_t_s: f64,
    },
}

impl fmt::Display for TruthError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            TruthError::Malformed { line, reason } => write!(
                f,
                "line {line}: {reason} (expected {{\"t_s\":..,\"x_mm\":..,\"y_mm\":..,\"heading_deg\":..}})"
            ),
            TruthError::OutOfOrder {
                line,
                t_s,
                previous_t_s,
            } => write!(
                f,
                "line {line}: t_s {t_s} comes before the line above's {previous_t_s}: samples must be in time order"
            ),
        }
    }
}

impl std::error::Error for TruthError {}

/// Reads a truth file's text: one sample per line, blank lines skipped, fields other
/// than the four ignored (so the harness may add some).
pub fn parse_truth(text: &str) -> Result<Vec<TruthSample>, TruthError> {
    let mut samples: Vec<TruthSample> = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        if raw.trim().is_empty() {
            continue;
        }
        let malformed = |reason: String| TruthError::Malformed { line, reason };
        let s: TruthSample = serde_json::from_str(raw).map_err(|e| {
            // serde_json counts lines within this one line: keep only the column.
            let text = e.to_string();
            let what = text.split(" at line ").next().unwrap_or(&text);
            malformed(format!("{what} at column {}", e.column()))
        })?;
        let fields = [
            ("t_s", s.t_s),
            ("x_mm", s.x_mm),
            ("y_mm", s.y_mm),
            ("heading_deg", s.heading_deg),
        ];
        if let Some((name, _)) = fields.iter().find(|(_, v)| !v.is_finite()) {
            return Err(malformed(format!("{name} is not a finite number")));
        }
        if s.t_s < 0.0 {
            return Err(malformed(format!("t_s is negative ({})", s.t_s)));
        }
        if let Some(previous) = samples.last().filter(|p| s.t_s < p.t_s) {
            return Err(TruthError::OutOfOrder {
                line,
                t_s: s.t_s,
                previous_t_s: previous.t_s,
            });
        }
        samples.push(s);
    }
    Ok(samples)
}

/// How far a truth sample may be from a tick's time and still be its truth: half a tick,
/// milliseconds.
///
/// The firmware stamps a `Tick` with the millisecond its pose is of (its newest gyro
/// sample's, a few milliseconds before the step starts), rounded down, and the harness
/// samples the truth as each step starts, so a tick's own sample is a few milliseconds
/// away. Its neighbours' are a whole tick away (a pose up to 15 mm and 3 degrees off on
/// the seed route), so half a tick never takes a neighbour's for it: a tick whose own
/// sample is missing gets none, and is counted rather than scored.
pub const PAIRING_TOLERANCE_MS: f64 = TICK_S * 1000.0 / 2.0;

/// The true pose at `time_ms`: linear between the two samples around it when they are
/// consecutive steps' (at most a tick and a half apart), else the nearest sample; `None`
/// unless a sample lies within [`PAIRING_TOLERANCE_MS`]. `samples` in time order, as
/// [`parse_truth`] gives them. In a turn at 31.5 degrees a second the pose's 4 ms before
/// its step's sample is 0.13 degrees, more than a filter sure of its heading allows.
pub fn truth_at(samples: &[TruthSample], time_ms: u32) -> Option<TruthSample> {
    let t_ms = f64::from(time_ms);
    let later = samples.partition_point(|s| s.t_s * 1000.0 < t_ms);
    let (before, after) = (
        later.checked_sub(1).and_then(|i| samples.get(i)),
        samples.get(later),
    );
    let gap = |s: &TruthSample| (s.t_s * 1000.0 - t_ms).abs();
    let nearest = [before, after]
        .into_iter()
        .flatten()
        .filter(|s| gap(s) < PAIRING_TOLERANCE_MS)
        .min_by(|a, b| gap(a).total_cmp(&gap(b)))?;
    match (before, after) {
        (Some(a), Some(b)) if (b.t_s - a.t_s) * 1000.0 <= 1.5 * TICK_S * 1000.0 => {
            let span = (b.t_s - a.t_s) * 1000.0;
            let f = if span > 0.0 {
                (t_ms - a.t_s * 1000.0) / span
            } else {
                0.0
            };
            let between = |x: f64, y: f64| x + (y - x) * f;
            Some(TruthSample {
                t_s: t_ms / 1000.0,
                x_mm: between(a.x_mm, b.x_mm),
                y_mm: between(a.y_mm, b.y_mm),
                heading_deg: between(a.heading_deg, b.heading_deg),
            })
        }
        _ => Some(*nearest),
    }
}

/// The time of the last sample before the robot first moved, seconds; `None` if it never
/// did.
///
/// `host-sim run` counts time from the route's start, but a robot's clock starts at reset
/// and the firmware first stands still to calibrate its gyro. A time minus this one is a
/// time into the route, as `run` counts it (for `run` itself this is 0).
pub fn route_start_s(samples: &[TruthSample]) -> Option<f64> {
    let first = samples.first()?;
    let moved = |s: &TruthSample| {
        (s.x_mm - first.x_mm).hypot(s.y_mm - first.y_mm) > 0.1
            || (s.heading_deg - first.heading_deg).abs() > 0.01
    };
    let i = samples.iter().position(moved)?;
    samples.get(i.checked_sub(1)?).map(|s| s.t_s)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(t_s: f64, heading_deg: f64) -> TruthSample {
        TruthSample {
            t_s,
            x_mm: 700.0,
            y_mm: 500.0,
            heading_deg,
        }
    }

    #[test]
    fn parses_the_harness_lines() {
        let text = "{\"t_s\":0.1,\"x_mm\":700,\"y_mm\":500,\"heading_deg\":0}\n\n\
            {\"t_s\":0.7000000000000001,\"x_mm\":670.5,\"y_mm\":1102.1,\"heading_deg\":374.6,\"extra\":1}\n";
        let s = parse_truth(text).expect("good lines");
        assert_eq!(s.len(), 2);
        assert_eq!(s[0], sample(0.1, 0.0));
        assert_eq!(s[1].heading_deg, 374.6);
        assert_eq!(parse_truth("").map(|s| s.len()), Ok(0));
    }

    #[test]
    fn bad_lines_are_named() {
        let good = "{\"t_s\":0.1,\"x_mm\":1,\"y_mm\":2,\"heading_deg\":3}\n";
        for (bad, line, words) in [
            ("garbage", 2, "expected value"),
            ("{\"t_s\":0.2,\"x_mm\":1,\"y_mm\":2}", 2, "heading_deg"),
            (
                "{\"t_s\":0.2,\"x_mm\":\"a\",\"y_mm\":2,\"heading_deg\":3}",
                2,
                "invalid type",
            ),
            (
                "{\"t_s\":0.2,\"x_mm\":1e999,\"y_mm\":2,\"heading_deg\":3}",
                2,
                "line 2",
            ),
            (
                "{\"t_s\":-1,\"x_mm\":1,\"y_mm\":2,\"heading_deg\":3}",
                2,
                "negative",
            ),
            ("[1,2,3,4,5]", 2, "line 2"),
        ] {
            let err = parse_truth(&format!("{good}{bad}\n{good}")).expect_err(bad);
            let text = err.to_string();
            assert!(text.starts_with(&format!("line {line}:")), "{bad}: {text}");
            assert!(text.contains(words), "{bad}: {text}");
        }
        let backwards = "{\"t_s\":0.2,\"x_mm\":1,\"y_mm\":2,\"heading_deg\":3}";
        let err = parse_truth(&format!("{good}{backwards}\n{good}")).expect_err("order");
        assert!(
            matches!(err, TruthError::OutOfOrder { line: 3, .. }),
            "{err}"
        );
    }

    #[test]
    fn a_tick_pairs_with_its_own_sample_despite_jitter() {
        // Harness times carry float noise and sit a fraction of a millisecond after the
        // tick's (rounded-down) stamp.
        let samples = [
            sample(0.1, 1.0),
            sample(0.2004, 2.0),
            sample(0.30000000000000004, 3.0),
        ];
        let heading = |t: u32| truth_at(&samples, t).map(|s| s.heading_deg);
        let near = |h: Option<f64>, want: f64| h.is_some_and(|h| (h - want).abs() < 0.01);
        assert!(near(heading(100), 1.0), "{:?}", heading(100));
        assert!(near(heading(200), 2.0), "{:?}", heading(200));
        assert!(near(heading(300), 3.0), "{:?}", heading(300));
        // Between two steps' samples, the truth moves linearly from one to the other.
        assert!(near(heading(196), 1.96), "{:?}", heading(196));
        assert!(near(heading(250), 2.5), "{:?}", heading(250));
        assert_eq!(truth_at(&samples, 0), None);
        assert_eq!(truth_at(&samples, 400), None);
        assert_eq!(truth_at(&[], 100), None);
    }

    #[test]
    fn a_missing_sample_leaves_its_tick_unpaired() {
        // The sample for 200 ms is lost: its neighbours are a tick away, too far.
        let samples = [sample(0.1, 1.0), sample(0.3, 3.0)];
        assert_eq!(truth_at(&samples, 200), None);
        assert_eq!(truth_at(&samples, 240).map(|s| s.heading_deg), None);
        assert_eq!(truth_at(&samples, 251).map(|s| s.heading_deg), Some(3.0));
    }

    #[test]
    fn the_route_starts_when_the_truth_first_moves() {
        let mut samples: Vec<TruthSample> =
            (1..=12).map(|i| sample(i as f64 / 10.0, 0.0)).collect();
        assert_eq!(route_start_s(&samples), None);
        samples[10].heading_deg = 1.58;
        samples[11].heading_deg = 4.7;
        assert_eq!(route_start_s(&samples), Some(1.0));
        samples[0].x_mm += 5.0;
        assert_eq!(route_start_s(&samples), Some(0.1));
    }
}
