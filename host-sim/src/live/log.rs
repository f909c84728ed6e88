//! The firmware's defmt log as text (`view --log FILE`), put in time order with the ticks.
//!
//! The text is what `probe-rs run` prints for this firmware, or what `cargo xtask emulate`
//! writes to `out/emulator/defmt.log` in the same shape: a line per entry, `TIME [LEVEL]
//! message`, the time in seconds since boot (`1.234`, or `00:00:01.234`). The level may
//! also come bare (`TIME INFO message`, `defmt-print`'s `{t} {L} {s}`) or not at all
//! (`println!`). Colour codes are ignored, and so are `└─` location lines.
//!
//! The firmware stamps its lines with embassy-time's uptime, the clock a `Tick`'s
//! `time_ms` counts: both start at the robot's boot, so a line and the ticks need no
//! offset. [`FirmwareLog::due`] hands out the lines at or before a tick's time, so each
//! goes out just before the first tick at or after it, and a paced stream paces its log.
//!
//! The file is read as it grows (what was appended since the last tick, on every tick),
//! so a log that `probe-rs run` is still writing is followed; at most
//! [`MAX_LOG_BYTES`] are read, and a line longer than [`MAX_LINE_BYTES`] or one that does
//! not parse is counted in [`FirmwareLog::skipped`] and left out.

use crate::bounded::MAX_RECORDING_BYTES;
use std::collections::VecDeque;
use std::fmt;
use std::io::{self, Read};
use std::path::Path;

/// Most bytes read from a log, as for a recorded stream.
pub const MAX_LOG_BYTES: u64 = MAX_RECORDING_BYTES;

/// Longest line kept, bytes: the firmware's longest message is a few hundred.
pub const MAX_LINE_BYTES: usize = 4096;

/// A defmt level; `None` in a [`LogLine`] for `println!`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LogLevel {
    /// `trace!`.
    Trace,
    /// `debug!`.
    Debug,
    /// `info!`.
    Info,
    /// `warn!`.
    Warn,
    /// `error!`.
    Error,
}

impl LogLevel {
    /// The level named `word` (`INFO`, `info`, ...).
    fn named(word: &str) -> Option<LogLevel> {
        match word.to_ascii_uppercase().as_str() {
            "TRACE" => Some(LogLevel::Trace),
            "DEBUG" => Some(LogLevel::Debug),
            "INFO" => Some(LogLevel::Info),
            "WARN" | "WARNING" => Some(LogLevel::Warn),
            "ERROR" => Some(LogLevel::Error),
            _ => None,
        }
    }
}

/// One entry of the firmware's log.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LogLine {
    /// Milliseconds since the robot's boot.
    pub time_ms: u64,
    /// `None` for `println!`, or a line that names no level.
    pub level: Option<LogLevel>,
    /// The text after the level, a location in brackets included when printed.
    pub message: String,
}

/// Why a line is not a log entry.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LineError {
    /// Longer than [`MAX_LINE_BYTES`].
    TooLong,
    /// It does not start with a time in seconds.
    NoTime,
    /// A `[...]` that holds no level.
    BadLevel,
}

impl fmt::Display for LineError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            LineError::TooLong => "the line is too long",
            LineError::NoTime => "the line does not start with a time in seconds",
            LineError::BadLevel => "the line's [LEVEL] is not a defmt level",
        })
    }
}

/// A line without its colour codes (`ESC [ ... letter`).
fn without_colour(line: &str) -> String {
    let mut out = String::with_capacity(line.len());
    let mut chars = line.chars();
    while let Some(c) = chars.next() {
        if c == '\u{1b}' {
            // The sequence ends at its first letter.
            for c in chars.by_ref() {
                if c.is_ascii_alphabetic() {
                    break;
                }
            }
        } else {
            out.push(c);
        }
    }
    out
}

/// Seconds as the firmware's timestamp shows them (`12`, `1.234`, `00:01:02.345`), in ms.
fn parse_time(text: &str) -> Option<u64> {
    let mut parts = text.rsplit(':');
    let seconds = parts.next()?;
    let (whole, fraction) = seconds.split_once('.').unwrap_or((seconds, ""));
    let digits = |s: &str| !s.is_empty() && s.len() <= 12 && s.bytes().all(|b| b.is_ascii_digit());
    if !digits(whole) || !(fraction.is_empty() || digits(fraction)) {
        return None;
    }
    let mut ms: u64 = whole.parse::<u64>().ok()?.checked_mul(1000)?;
    let mut scale = 100;
    for b in fraction.bytes().take(3) {
        ms += u64::from(b - b'0') * scale;
        scale /= 10;
    }
    // Minutes, then hours, for `tms`-style times.
    for (part, unit) in parts.zip([60_000u64, 3_600_000]) {
        if !digits(part) {
            return None;
        }
        ms = ms.checked_add(part.parse::<u64>().ok()?.checked_mul(unit)?)?;
    }
    Some(ms)
}

/// One line of the text log: `Ok(None)` for a line that holds no entry and is no error
/// (blank, or a `└─` location line).
pub fn parse_line(line: &str) -> Result<Option<LogLine>, LineError> {
    if line.len() > MAX_LINE_BYTES {
        return Err(LineError::TooLong);
    }
    let line = without_colour(line);
    let line = line.trim();
    if line.is_empty() || line.starts_with('└') {
        return Ok(None);
    }
    let (time, rest) = line.split_once(char::is_whitespace).unwrap_or((line, ""));
    let time_ms = parse_time(time).ok_or(LineError::NoTime)?;
    let rest = rest.trim_start();
    let (level, message) = if let Some(after) = rest.strip_prefix('[') {
        let (inside, message) = after.split_once(']').ok_or(LineError::BadLevel)?;
        let level = LogLevel::named(inside.trim()).ok_or(LineError::BadLevel)?;
        (Some(level), message.trim_start())
    } else {
        let (word, message) = rest.split_once(char::is_whitespace).unwrap_or((rest, ""));
        match LogLevel::named(word) {
            Some(level) => (Some(level), message.trim_start()),
            None => (None, rest),
        }
    };
    Ok(Some(LogLine {
        time_ms,
        level,
        message: message.to_string(),
    }))
}

/// A text log being read, as its lines fall due: see [the module](self).
pub struct FirmwareLog {
    source: Box<dyn Read + Send>,
    /// Bytes of the line being read, not yet ended by a newline.
    partial: Vec<u8>,
    /// The current line has passed [`MAX_LINE_BYTES`]: the rest of it is dropped.
    overlong: bool,
    read_bytes: u64,
    /// The source ended for good (an error, or the bound reached).
    closed: bool,
    pending: VecDeque<LogLine>,
    published: u64,
    skipped: u64,
}

impl FirmwareLog {
    /// The log in the file at `path`.
    pub fn open(path: &Path) -> io::Result<FirmwareLog> {
        Ok(FirmwareLog::from_reader(Box::new(std::fs::File::open(
            path,
        )?)))
    }

    /// The log read from `source`, a file or anything that gives 0 at its current end.
    pub fn from_reader(source: Box<dyn Read + Send>) -> FirmwareLog {
        FirmwareLog {
            source,
            partial: Vec::new(),
            overlong: false,
            read_bytes: 0,
            closed: false,
            pending: VecDeque::new(),
            published: 0,
            skipped: 0,
        }
    }

    /// Lines handed out so far.
    pub fn published(&self) -> u64 {
        self.published
    }

    /// Lines that did not parse or were too long.
    pub fn skipped(&self) -> u64 {
        self.skipped
    }

    /// Whether reading stopped at [`MAX_LOG_BYTES`].
    pub fn truncated(&self) -> bool {
        self.read_bytes >= MAX_LOG_BYTES
    }

    /// Reads what the source holds now, up to the bound.
    fn fill(&mut self) {
        let mut buf = [0u8; 8192];
        while !self.closed {
            let room = MAX_LOG_BYTES.saturating_sub(self.read_bytes);
            if room == 0 {
                self.closed = true;
                break;
            }
            let want = buf.len().min(usize::try_from(room).unwrap_or(usize::MAX));
            match self.source.read(buf.get_mut(..want).unwrap_or(&mut [])) {
                Ok(0) => break,
                Ok(n) => {
                    self.read_bytes += n as u64;
                    self.take(buf.get(..n).unwrap_or(&[]));
                }
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(_) => self.closed = true,
            }
        }
    }

    /// Splits `bytes` into lines, parsing each complete one.
    fn take(&mut self, bytes: &[u8]) {
        let mut rest = bytes;
        while let Some(end) = rest.iter().position(|&b| b == b'\n') {
            let (head, tail) = rest.split_at(end);
            self.extend_partial(head);
            self.end_line();
            rest = tail.get(1..).unwrap_or(&[]);
        }
        self.extend_partial(rest);
    }

    fn extend_partial(&mut self, bytes: &[u8]) {
        if self.overlong {
            return;
        }
        if self.partial.len() + bytes.len() > MAX_LINE_BYTES {
            self.overlong = true;
            self.partial.clear();
        } else {
            self.partial.extend_from_slice(bytes);
        }
    }

    /// The current line is complete.
    fn end_line(&mut self) {
        if std::mem::take(&mut self.overlong) {
            self.skipped += 1;
            return;
        }
        let bytes = std::mem::take(&mut self.partial);
        match parse_line(&String::from_utf8_lossy(&bytes)) {
            Ok(Some(line)) => self.pending.push_back(line),
            Ok(None) => {}
            Err(_) => self.skipped += 1,
        }
    }

    /// The lines at or before `time_ms`, in the log's order, after reading what the file
    /// gained since the last call. A line later than `time_ms` holds back the ones after
    /// it, so the log keeps its own order.
    pub fn due(&mut self, time_ms: u32) -> Vec<LogLine> {
        self.fill();
        let mut due = Vec::new();
        while self
            .pending
            .front()
            .is_some_and(|l| l.time_ms <= u64::from(time_ms))
        {
            due.extend(self.pending.pop_front());
        }
        self.published += due.len() as u64;
        due
    }

    /// Every line left, the stream having ended (a last line without its newline too).
    pub fn rest(&mut self) -> Vec<LogLine> {
        self.fill();
        if !self.partial.is_empty() || self.overlong {
            self.end_line();
        }
        let rest: Vec<LogLine> = self.pending.drain(..).collect();
        self.published += rest.len() as u64;
        rest
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line(time_ms: u64, level: Option<LogLevel>, message: &str) -> LogLine {
        LogLine {
            time_ms,
            level,
            message: message.to_string(),
        }
    }

    #[test]
    fn good_lines_in_each_shape_parse() {
        let cases = [
            (
                "1.234 [INFO ] BugBot firmware 0.1.0",
                line(1234, Some(LogLevel::Info), "BugBot firmware 0.1.0"),
            ),
            (
                "0.005 [WARN ] depth: 7 read errors (bugbot_firmware src/sensors/depth.rs:40)",
                line(
                    5,
                    Some(LogLevel::Warn),
                    "depth: 7 read errors (bugbot_firmware src/sensors/depth.rs:40)",
                ),
            ),
            (
                "12.3 ERROR motor: stalled",
                line(12_300, Some(LogLevel::Error), "motor: stalled"),
            ),
            (
                "00:01:02.345 [DEBUG] x",
                line(62_345, Some(LogLevel::Debug), "x"),
            ),
            ("7 [TRACE] ", line(7000, Some(LogLevel::Trace), "")),
            ("1.500000 hello there", line(1500, None, "hello there")),
            (
                "\u{1b}[2m3.000\u{1b}[0m \u{1b}[1m[INFO ]\u{1b}[0m coloured",
                line(3000, Some(LogLevel::Info), "coloured"),
            ),
        ];
        for (text, want) in cases {
            assert_eq!(parse_line(text), Ok(Some(want)), "{text}");
        }
        assert_eq!(parse_line(""), Ok(None));
        assert_eq!(parse_line("   "), Ok(None));
        assert_eq!(
            parse_line("└─ bugbot_firmware::____embassy_main_task @ src/main.rs:47"),
            Ok(None)
        );
    }

    #[test]
    fn bad_lines_are_errors() {
        for text in [
            "garbage",
            "INFO 1.234 swapped",
            "1.2.3 [INFO ] two points",
            "-1.000 [INFO ] negative",
            "1.0x [INFO ] junk after",
            "99999999999999999999.0 [INFO ] too far",
            "a:b:1.0 [INFO ] bad clock",
            ":1.0 [INFO ] empty minutes",
            "\u{0}\u{1}\u{2}",
        ] {
            assert_eq!(parse_line(text), Err(LineError::NoTime), "{text}");
        }
        for text in ["1.000 [LOUD ] nope", "1.000 [INFO unclosed"] {
            assert_eq!(parse_line(text), Err(LineError::BadLevel), "{text}");
        }
    }

    #[test]
    fn a_huge_line_is_refused_and_the_log_reads_on() {
        let huge = format!("1.000 [INFO ] {}", "x".repeat(MAX_LINE_BYTES));
        assert_eq!(parse_line(&huge), Err(LineError::TooLong));
        let text = format!("0.100 [INFO ] before\n{huge}\n{huge}{huge}\n0.200 [INFO ] after\n");
        let mut log = FirmwareLog::from_reader(Box::new(io::Cursor::new(text.into_bytes())));
        let lines = log.rest();
        assert_eq!(
            lines,
            [
                line(100, Some(LogLevel::Info), "before"),
                line(200, Some(LogLevel::Info), "after")
            ]
        );
        assert_eq!(log.skipped(), 2);
    }

    #[test]
    fn lines_fall_due_with_the_ticks_and_the_rest_at_the_end() {
        let text = "0.000 [INFO ] boot\nnot a line\n0.100 [INFO ] a\n0.150 [WARN ] b\n\
                    0.300 [ERROR] c\n0.250 [INFO ] d\n0.400 [INFO ] no newline";
        let mut log = FirmwareLog::from_reader(Box::new(io::Cursor::new(text.as_bytes())));
        let messages =
            |lines: Vec<LogLine>| -> Vec<String> { lines.into_iter().map(|l| l.message).collect() };
        assert_eq!(messages(log.due(0)), ["boot"]);
        assert_eq!(messages(log.due(99)), Vec::<String>::new());
        assert_eq!(messages(log.due(200)), ["a", "b"]);
        // `d` is earlier than `c` but comes after it in the log.
        assert_eq!(messages(log.due(299)), Vec::<String>::new());
        assert_eq!(messages(log.due(300)), ["c", "d"]);
        assert_eq!(messages(log.rest()), ["no newline"]);
        assert_eq!((log.published(), log.skipped()), (6, 1));
    }

    /// A reader that gives its chunks one per call and 0 in between, as a file that
    /// another program is still writing does.
    struct Growing(VecDeque<Option<&'static [u8]>>);

    impl Read for Growing {
        fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
            match self.0.pop_front().flatten() {
                Some(chunk) => {
                    buf[..chunk.len()].copy_from_slice(chunk);
                    Ok(chunk.len())
                }
                None => Ok(0),
            }
        }
    }

    #[test]
    fn a_growing_log_is_followed() {
        let chunks = [
            Some(&b"0.100 [INFO ] fir"[..]),
            None,
            Some(&b"st\n0.200 [INFO ] second\n"[..]),
            None,
        ];
        let mut log = FirmwareLog::from_reader(Box::new(Growing(chunks.into_iter().collect())));
        assert!(log.due(1000).is_empty());
        let lines = log.due(1000);
        assert_eq!(lines.len(), 2);
        assert_eq!(lines[0].message, "first");
    }
}
