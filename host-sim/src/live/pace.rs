//! Playing a recorded stream at the pace its ticks were recorded.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// The slowest and fastest `--speed`: a tenth of real time, and a thousand times it (a
/// ten-minute run in under a second, for tests).
pub const SPEED_RANGE: (f64, f64) = (0.1, 1000.0);

/// A gap between two ticks longer than this, in stream time, is taken as a restart or a
/// corrupt time rather than waited out: playing resumes from the new tick at once.
pub const MAX_GAP_MS: u32 = 10_000;

/// How long one sleep lasts at most, so that Ctrl-C and `--seconds` are heard.
const SLICE: Duration = Duration::from_millis(50);

/// When each tick of a recorded stream is due, at `speed` times the recorded pace.
#[derive(Clone, Copy, Debug)]
pub struct Pace {
    speed: f64,
    /// The wall time and stream time the schedule counts from.
    anchor: Option<(Instant, u32)>,
    last_ms: u32,
}

impl Pace {
    /// A schedule at `speed` times real time (clamped to [`SPEED_RANGE`]).
    pub fn new(speed: f64) -> Pace {
        let speed = if speed.is_finite() {
            speed.clamp(SPEED_RANGE.0, SPEED_RANGE.1)
        } else {
            1.0
        };
        Pace {
            speed,
            anchor: None,
            last_ms: 0,
        }
    }

    /// Waits until the tick recorded at `time_ms` is due; `false` if `stop` was set or
    /// `deadline` passed first. The first tick is due at once, and so is one that goes
    /// back in time or jumps ahead by more than [`MAX_GAP_MS`] (the schedule restarts there).
    pub fn wait_for(&mut self, time_ms: u32, stop: &AtomicBool, deadline: Option<Instant>) -> bool {
        let jump = time_ms < self.last_ms || time_ms - self.last_ms > MAX_GAP_MS;
        self.last_ms = time_ms;
        let (start, start_ms) = match self.anchor {
            Some(anchor) if !jump => anchor,
            _ => {
                self.anchor = Some((Instant::now(), time_ms));
                return !stop.load(Ordering::Relaxed);
            }
        };
        let due =
            start + Duration::from_secs_f64(f64::from(time_ms - start_ms) / 1000.0 / self.speed);
        loop {
            if stop.load(Ordering::Relaxed) || deadline.is_some_and(|d| Instant::now() >= d) {
                return false;
            }
            let now = Instant::now();
            if now >= due {
                return true;
            }
            std::thread::sleep((due - now).min(SLICE));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_come_at_their_time_and_jumps_do_not_wait() {
        let stop = AtomicBool::new(false);
        let mut pace = Pace::new(100.0);
        let started = Instant::now();
        assert!(pace.wait_for(1_000, &stop, None));
        // 2 s of stream at 100 times: 20 ms.
        assert!(pace.wait_for(3_000, &stop, None));
        let waited = started.elapsed();
        assert!(waited >= Duration::from_millis(20), "{waited:?}");
        // Back in time, and a day ahead: at once.
        let before = Instant::now();
        assert!(pace.wait_for(500, &stop, None));
        assert!(pace.wait_for(86_400_000, &stop, None));
        assert!(before.elapsed() < Duration::from_millis(20));
    }

    #[test]
    fn stop_ends_the_wait() {
        let stop = AtomicBool::new(false);
        let mut pace = Pace::new(0.1);
        assert!(pace.wait_for(0, &stop, None));
        stop.store(true, Ordering::Relaxed);
        assert!(!pace.wait_for(1_000, &stop, None));
    }
}
