//! A progress bar for the emulator's long runs: simulated seconds, ticks and overruns so
//! far, from the firmware's own once-a-second counters line, read from its defmt log as
//! the harness writes it. Drawn on stderr only when stderr is a terminal; a run under CI
//! or with its output piped prints nothing more than before.

use std::fs::File;
use std::io::{IsTerminal, Read};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

use defmt_decoder::{DecodeError, StreamDecoder, Table};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

use super::defmt_log::LoopCounters;

/// How often the log is read again.
const POLL: Duration = Duration::from_millis(250);

/// Follows a defmt log as it grows and keeps the newest loop counters.
pub struct Follower<'t> {
    decoder: Box<dyn StreamDecoder + 't>,
    latest: Option<LoopCounters>,
}

impl<'t> Follower<'t> {
    /// A follower decoding with `table`.
    pub fn new(table: &'t Table) -> Follower<'t> {
        Follower {
            decoder: table.new_stream_decoder(),
            latest: None,
        }
    }

    /// Takes the log's next bytes; `false` once a frame does not decode (the progress then
    /// stops: the run's own check reports the bad log at the end).
    pub fn feed(&mut self, bytes: &[u8]) -> bool {
        self.decoder.received(bytes);
        loop {
            match self.decoder.decode() {
                Ok(frame) => {
                    let message = frame.display_message().to_string();
                    if let Some(c) = LoopCounters::parse(&message) {
                        self.latest = Some(c);
                    }
                }
                Err(DecodeError::UnexpectedEof) => return true,
                Err(DecodeError::Malformed) => return false,
            }
        }
    }

    /// The newest counters line so far.
    pub fn latest(&self) -> Option<LoopCounters> {
        self.latest
    }
}

/// The bar's text for `counters` on a run of `seconds`.
pub fn message(counters: &LoopCounters, seconds: f64) -> String {
    format!(
        "{:.0} / {seconds:.0} s simulated, {} ticks, {} overruns",
        counters.ticks as f64 / 10.0,
        counters.ticks,
        counters.overruns
    )
}

/// The bar, drawn by a thread of its own until [`Progress::finish`].
pub struct Progress {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl Progress {
    /// Starts following `defmt` (written by the harness as the firmware of `elf` runs for
    /// `seconds`), when stderr is a terminal; `None` otherwise.
    pub fn start(elf: &Path, defmt: &Path, seconds: f64) -> Option<Progress> {
        if !std::io::stderr().is_terminal() {
            return None;
        }
        let stop = Arc::new(AtomicBool::new(false));
        let flag = Arc::clone(&stop);
        let (elf, defmt) = (elf.to_path_buf(), defmt.to_path_buf());
        let thread = std::thread::spawn(move || follow(&elf, &defmt, seconds, &flag));
        Some(Progress {
            stop,
            thread: Some(thread),
        })
    }

    /// Stops the bar and clears it.
    pub fn finish(mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Drop for Progress {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
    }
}

fn follow(elf: &PathBuf, defmt: &PathBuf, seconds: f64, stop: &AtomicBool) {
    let Some(table) = std::fs::read(elf)
        .ok()
        .and_then(|bytes| Table::parse(&bytes).ok().flatten())
    else {
        return;
    };
    let bar = ProgressBar::with_draw_target(
        Some((seconds * 10.0).max(1.0) as u64),
        ProgressDrawTarget::stderr(),
    );
    if let Ok(style) = ProgressStyle::with_template("[emulate] [{bar:30}] {msg} ({elapsed})") {
        bar.set_style(style.progress_chars("=> "));
    }
    bar.set_message("booting");
    let mut follower = Follower::new(&table);
    let mut file = None;
    let mut buf = Vec::new();
    while !stop.load(Ordering::Relaxed) {
        std::thread::sleep(POLL);
        // The harness creates the file once the firmware is loaded.
        if file.is_none() {
            file = File::open(defmt).ok();
        }
        let Some(f) = file.as_mut() else { continue };
        buf.clear();
        if f.read_to_end(&mut buf).is_err() || !follower.feed(&buf) {
            break;
        }
        if let Some(c) = follower.latest() {
            bar.set_position(c.ticks);
            bar.set_message(message(&c, seconds));
        }
        bar.tick();
    }
    bar.finish_and_clear();
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::emulate::defmt_log::tests::{counters_frame, firmware_like_elf, frame};

    fn log() -> Vec<u8> {
        let mut log = frame(1, &[5, 0, 0, 0, b'0', b'.', b'1', b'.', b'0']);
        log.extend(counters_frame([10, 0, 12, 3400]));
        log.extend(frame(3, &[7]));
        log.extend(counters_frame([20, 1, 15, 3500]));
        log
    }

    #[test]
    fn the_newest_counters_whatever_the_chunks() {
        let elf = firmware_like_elf();
        let table = Table::parse(&elf).unwrap().unwrap();
        let log = log();
        for chunk in 1..=log.len() {
            let mut f = Follower::new(&table);
            for part in log.chunks(chunk) {
                assert!(f.feed(part));
            }
            let c = f.latest().unwrap();
            assert_eq!((c.ticks, c.overruns), (20, 1), "chunks of {chunk}");
        }
    }

    #[test]
    fn counters_only_once_their_line_is_whole() {
        let elf = firmware_like_elf();
        let table = Table::parse(&elf).unwrap().unwrap();
        let mut f = Follower::new(&table);
        let line = counters_frame([10, 0, 12, 3400]);
        assert!(f.feed(&line[..line.len() - 1]));
        assert_eq!(f.latest(), None);
        assert!(f.feed(&line[line.len() - 1..]));
        assert_eq!(f.latest().map(|c| c.ticks), Some(10));
    }

    #[test]
    fn a_bad_frame_stops_the_following() {
        let elf = firmware_like_elf();
        let table = Table::parse(&elf).unwrap().unwrap();
        let mut f = Follower::new(&table);
        assert!(!f.feed(&frame(99, &[])));
    }

    #[test]
    fn the_message_says_seconds_ticks_and_overruns() {
        let c = LoopCounters {
            ticks: 125,
            overruns: 2,
            max_late_us: 0,
            max_step_us: 0,
        };
        assert_eq!(
            message(&c, 60.0),
            "12 / 60 s simulated, 125 ticks, 2 overruns"
        );
    }
}
