//! The firmware's defmt log, decoded with the format table from its ELF.
//!
//! The harness captures the defmt RTT up-channel as raw bytes; this module turns them into
//! lines with `defmt-decoder` (the crate `defmt-print` is built on, at the version that
//! reads `defmt = "1"`'s wire format), writes them as text the way `probe-rs run` prints
//! them ([`text`], for `host-sim view --log`) and reads the firmware's loop counters from
//! its once-a-second line. A log that cannot be decoded is a [`DefmtError`], never a figure
//! left empty.

use std::fmt;

use defmt_decoder::{DecodeError, Table};

/// Lines kept for `last_logs` in the emulator's figures.
pub const LAST_LOGS: usize = 8;

/// Why the defmt log could not be read.
#[derive(Debug, PartialEq, Eq)]
pub enum DefmtError {
    /// The ELF could not be read as one, or its defmt metadata is inconsistent.
    BadElf(String),
    /// The ELF has no `.defmt` section: the firmware was built without defmt.
    NoTable,
    /// A frame did not decode against the table: the log and the ELF do not match, or the
    /// capture is corrupt. `frame` counts from 0; `decoded` lines came before it.
    BadFrame { frame: usize, decoded: usize },
    /// No line holds the loop counters (`ticks: N, overruns: N, ...`): the firmware logged
    /// for less than a second, or its log no longer says it that way.
    NoCounters { lines: usize },
}

impl fmt::Display for DefmtError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DefmtError::BadElf(why) => write!(f, "cannot read the defmt table from the ELF: {why}"),
            DefmtError::NoTable => f.write_str(
                "the ELF has no .defmt section, so its log cannot be decoded (built without defmt?)",
            ),
            DefmtError::BadFrame { frame, decoded } => write!(
                f,
                "defmt frame {frame} does not decode with the ELF's table (after {decoded} good \
lines): the log was not written by this ELF, or the capture is corrupt"
            ),
            DefmtError::NoCounters { lines } => write!(
                f,
                "none of the firmware's {lines} log lines holds its loop counters \
(`ticks: N, overruns: N, max_late_us: N, max_step_us: N`, logged once a second)"
            ),
        }
    }
}

impl std::error::Error for DefmtError {}

/// One decoded line: its timestamp as the firmware's `defmt::timestamp!` shows it (seconds
/// since boot, `1.234`; empty without one), its level (`INFO`, ..., empty for `println!`)
/// and its message.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LogLine {
    pub time: String,
    pub level: String,
    pub message: String,
}

impl LogLine {
    /// The line as `probe-rs run` prints it for this firmware, `{t} [{L}] {s}` with the
    /// level padded to five characters (`1.234 [INFO ] message`), without the location:
    /// the same shape whether the log came from the emulator or a robot on a probe. A
    /// message spread over lines is joined with spaces, so that an entry is one line.
    pub fn probe_rs_line(&self) -> String {
        let mut line = String::new();
        if !self.time.is_empty() {
            line.push_str(&self.time);
            line.push(' ');
        }
        if !self.level.is_empty() {
            line.push_str(&format!("[{:<5}] ", self.level));
        }
        line.push_str(&self.message.replace(['\r', '\n'], " "));
        line
    }
}

/// The whole log as text, a [`LogLine::probe_rs_line`] per line.
pub fn text(lines: &[LogLine]) -> String {
    lines.iter().map(|l| l.probe_rs_line() + "\n").collect()
}

impl fmt::Display for LogLine {
    /// As `defmt-print --log-format "{L} {s}"` prints it.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.level.is_empty() {
            f.write_str(&self.message)
        } else {
            write!(f, "{} {}", self.level, self.message)
        }
    }
}

/// Decodes a whole capture: every complete frame in `log`, with the table in `elf`.
///
/// Bytes after the last complete frame are not an error: the emulation stops wherever
/// it stops, possibly half-way through the firmware writing a frame.
pub fn decode(elf: &[u8], log: &[u8]) -> Result<Vec<LogLine>, DefmtError> {
    let table = Table::parse(elf)
        .map_err(|e| DefmtError::BadElf(format!("{e:#}")))?
        .ok_or(DefmtError::NoTable)?;
    decode_with(&table, log)
}

fn decode_with(table: &Table, log: &[u8]) -> Result<Vec<LogLine>, DefmtError> {
    let mut decoder = table.new_stream_decoder();
    decoder.received(log);
    let mut lines = Vec::new();
    loop {
        match decoder.decode() {
            Ok(frame) => lines.push(LogLine {
                time: frame
                    .display_timestamp()
                    .map_or_else(String::new, |t| t.to_string()),
                level: frame
                    .level()
                    .map_or_else(String::new, |l| l.as_str().to_uppercase()),
                message: frame.display_message().to_string(),
            }),
            Err(DecodeError::UnexpectedEof) => return Ok(lines),
            Err(DecodeError::Malformed) => {
                return Err(DefmtError::BadFrame {
                    frame: lines.len(),
                    decoded: lines.len(),
                })
            }
        }
    }
}

/// The firmware's own loop counters, from its last once-a-second line.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LoopCounters {
    pub ticks: u64,
    pub overruns: u64,
    pub max_late_us: u64,
    pub max_step_us: u64,
}

impl LoopCounters {
    /// The counters in one message, if it is the counters line.
    pub fn parse(message: &str) -> Option<LoopCounters> {
        message
            .match_indices("ticks: ")
            .find_map(|(start, _)| Self::parse_at(&message[start..]))
    }

    /// The counters at the start of `text`.
    fn parse_at(text: &str) -> Option<LoopCounters> {
        let mut values = [0u64; 4];
        let mut rest = text;
        for (value, key) in values.iter_mut().zip([
            "ticks: ",
            ", overruns: ",
            ", max_late_us: ",
            ", max_step_us: ",
        ]) {
            rest = rest.strip_prefix(key)?;
            let digits = rest
                .find(|c: char| !c.is_ascii_digit())
                .unwrap_or(rest.len());
            *value = rest[..digits].parse().ok()?;
            rest = &rest[digits..];
        }
        let [ticks, overruns, max_late_us, max_step_us] = values;
        Some(LoopCounters {
            ticks,
            overruns,
            max_late_us,
            max_step_us,
        })
    }

    /// The last counters line in `lines`.
    pub fn last_in(lines: &[LogLine]) -> Result<LoopCounters, DefmtError> {
        lines
            .iter()
            .rev()
            .find_map(|l| LoopCounters::parse(&l.message))
            .ok_or(DefmtError::NoCounters { lines: lines.len() })
    }
}

/// Adds the log's figures to the harness's JSON object: the firmware's counters
/// (`fw_ticks`, `overruns`, `fw_max_late_us`, `fw_max_step_us`), `defmt_lines` and the
/// last [`LAST_LOGS`] lines as `last_logs`. A `defmt_decoder` key from a harness that
/// still tried `defmt-print` itself is dropped: the log is decoded here.
pub fn add_figures(
    figures: &mut serde_json::Map<String, serde_json::Value>,
    lines: &[LogLine],
    counters: LoopCounters,
) {
    use serde_json::Value;
    figures.remove("defmt_decoder");
    figures.insert("fw_ticks".into(), counters.ticks.into());
    figures.insert("overruns".into(), counters.overruns.into());
    figures.insert("fw_max_step_us".into(), counters.max_step_us.into());
    figures.insert("fw_max_late_us".into(), counters.max_late_us.into());
    figures.insert("defmt_lines".into(), lines.len().into());
    let last = lines[lines.len().saturating_sub(LAST_LOGS)..]
        .iter()
        .map(|l| Value::String(l.to_string()))
        .collect();
    figures.insert("last_logs".into(), Value::Array(last));
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use object::write::{Object, Symbol, SymbolSection};
    use object::{
        Architecture, BinaryFormat, Endianness, SectionKind, SymbolFlags, SymbolKind, SymbolScope,
    };

    /// An ELF with a defmt table as `defmt` 1 lays it out: one symbol per format string in
    /// `.defmt`, its address the string's index and its name the JSON defmt's macros write,
    /// plus the version and encoding symbols. Raw encoding keeps the frames readable.
    pub(crate) fn fixture_elf(formats: &[(&str, &str)]) -> Vec<u8> {
        let mut obj = Object::new(BinaryFormat::Elf, Architecture::Arm, Endianness::Little);
        let defmt = obj.add_section(Vec::new(), b".defmt".to_vec(), SectionKind::Other);
        obj.append_section_data(defmt, &vec![0u8; formats.len() + 1], 1);
        for (i, (tag, data)) in formats.iter().enumerate() {
            let name = serde_json::json!({
                "package": "fixture",
                "tag": tag,
                "data": data,
                "disambiguator": i.to_string(),
                "crate_name": "fixture",
            })
            .to_string();
            obj.add_symbol(symbol(&name, SymbolSection::Section(defmt), i as u64 + 1));
        }
        for name in ["_defmt_version_ = 4", "_defmt_encoding_ = raw"] {
            obj.add_symbol(symbol(name, SymbolSection::Absolute, 1));
        }
        obj.write().expect("the fixture ELF writes")
    }

    fn symbol(name: &str, section: SymbolSection, value: u64) -> Symbol {
        Symbol {
            name: name.as_bytes().to_vec(),
            value,
            size: 1,
            kind: SymbolKind::Data,
            scope: SymbolScope::Dynamic,
            weak: false,
            section,
            flags: SymbolFlags::None,
        }
    }

    const COUNTERS: &str =
        "ticks: {=u32}, overruns: {=u32}, max_late_us: {=u32}, max_step_us: {=u32}";

    pub(crate) fn firmware_like_elf() -> Vec<u8> {
        fixture_elf(&[
            ("defmt_info", "BugBot firmware {=str}"),
            ("defmt_info", COUNTERS),
            ("defmt_warn", "depth: {=u8} read errors"),
        ])
    }

    /// A raw-encoded frame: the string's index, then its arguments.
    pub(crate) fn frame(index: u16, args: &[u8]) -> Vec<u8> {
        let mut f = index.to_le_bytes().to_vec();
        f.extend_from_slice(args);
        f
    }

    pub(crate) fn counters_frame(values: [u32; 4]) -> Vec<u8> {
        frame(
            2,
            &values
                .iter()
                .flat_map(|v| v.to_le_bytes())
                .collect::<Vec<_>>(),
        )
    }

    #[test]
    fn decodes_frames_with_the_elf_table() {
        let mut log = frame(1, &[5, 0, 0, 0, b'0', b'.', b'1', b'.', b'0']);
        log.extend(counters_frame([10, 0, 12, 3400]));
        log.extend(frame(3, &[7]));
        log.extend(counters_frame([20, 1, 15, 3500]));
        let lines = decode(&firmware_like_elf(), &log).unwrap();
        let text: Vec<String> = lines.iter().map(ToString::to_string).collect();
        assert_eq!(
            text,
            [
                "INFO BugBot firmware 0.1.0",
                "INFO ticks: 10, overruns: 0, max_late_us: 12, max_step_us: 3400",
                "WARN depth: 7 read errors",
                "INFO ticks: 20, overruns: 1, max_late_us: 15, max_step_us: 3500",
            ]
        );
        let counters = LoopCounters::last_in(&lines).unwrap();
        assert_eq!(
            counters,
            LoopCounters {
                ticks: 20,
                overruns: 1,
                max_late_us: 15,
                max_step_us: 3500
            }
        );
    }

    #[test]
    fn the_text_log_is_one_probe_rs_line_per_entry_with_its_time() {
        let elf = fixture_elf(&[
            ("defmt_timestamp", "{=u64:ms}"),
            ("defmt_info", "BugBot firmware {=str}"),
            ("defmt_warn", "depth: {=u8} read errors"),
            ("defmt_println", "two{=str}lines"),
        ]);
        // Raw encoding: the index, the timestamp's u64, then the arguments.
        let at = |ms: u64, args: &[u8]| [&ms.to_le_bytes()[..], args].concat();
        let mut log = frame(2, &at(5, &[5, 0, 0, 0, b'0', b'.', b'1', b'.', b'0']));
        log.extend(frame(3, &at(1234, &[7])));
        log.extend(frame(4, &at(1000, &[1, 0, 0, 0, b'\n'])));
        let lines = decode(&elf, &log).unwrap();
        assert_eq!(
            text(&lines),
            "0.005 [INFO ] BugBot firmware 0.1.0\n\
             1.234 [WARN ] depth: 7 read errors\n\
             1.000 two lines\n"
        );
        // `last_logs` keeps its shape: level and message.
        assert_eq!(lines[1].to_string(), "WARN depth: 7 read errors");
    }

    #[test]
    fn a_frame_cut_off_at_the_end_is_not_an_error() {
        let mut log = counters_frame([10, 0, 12, 3400]);
        log.extend(&counters_frame([20, 0, 12, 3400])[..7]);
        assert_eq!(decode(&firmware_like_elf(), &log).unwrap().len(), 1);
    }

    #[test]
    fn a_frame_with_an_unknown_index_is_an_error() {
        let mut log = counters_frame([10, 0, 12, 3400]);
        log.extend(frame(99, &[]));
        assert_eq!(
            decode(&firmware_like_elf(), &log),
            Err(DefmtError::BadFrame {
                frame: 1,
                decoded: 1
            })
        );
    }

    #[test]
    fn an_elf_without_defmt_or_no_elf_at_all_is_an_error() {
        // This very test binary is an ELF without a .defmt section.
        let me = std::fs::read(std::env::current_exe().unwrap()).unwrap();
        assert_eq!(decode(&me, &[]), Err(DefmtError::NoTable));
        let err = decode(b"not an elf", &[]).unwrap_err();
        assert!(matches!(err, DefmtError::BadElf(_)), "{err:?}");
        assert!(err.to_string().contains("cannot read the defmt table"));
    }

    #[test]
    fn counters_are_read_from_their_line_only() {
        let line = |m: &str| LogLine {
            time: String::new(),
            level: "INFO".into(),
            message: m.into(),
        };
        assert_eq!(
            LoopCounters::parse(
                "pose x=1mm | ticks: none | LoopCounters { ticks: 7, overruns: 2, \
max_late_us: 30, max_step_us: 9000, max_telemetry_us: 80 } | beams=3"
            ),
            Some(LoopCounters {
                ticks: 7,
                overruns: 2,
                max_late_us: 30,
                max_step_us: 9000
            })
        );
        assert_eq!(LoopCounters::parse("ticks: 7, overruns: x"), None);
        assert_eq!(LoopCounters::parse("ticks: 7"), None);
        assert_eq!(LoopCounters::parse("BugBot firmware 0.1.0"), None);
        let err = LoopCounters::last_in(&[line("BugBot firmware 0.1.0")]).unwrap_err();
        assert_eq!(err, DefmtError::NoCounters { lines: 1 });
        assert!(err.to_string().contains("loop counters"), "{err}");
    }

    #[test]
    fn figures_hold_the_counters_and_the_last_lines() {
        let lines: Vec<LogLine> = (0..10)
            .map(|i| LogLine {
                time: format!("{i}.000"),
                level: "INFO".into(),
                message: format!("line {i}"),
            })
            .collect();
        let counters = LoopCounters {
            ticks: 519,
            overruns: 0,
            max_late_us: 40,
            max_step_us: 3000,
        };
        let mut figures = serde_json::Map::new();
        figures.insert("defmt_bytes".into(), 1234.into());
        figures.insert("defmt_decoder".into(), "none: install defmt-print".into());
        figures.insert("overruns".into(), serde_json::Value::Null);
        add_figures(&mut figures, &lines, counters);
        assert_eq!(figures["fw_ticks"], 519);
        assert_eq!(figures["overruns"], 0);
        assert_eq!(figures["fw_max_late_us"], 40);
        assert_eq!(figures["fw_max_step_us"], 3000);
        assert_eq!(figures["defmt_lines"], 10);
        assert_eq!(figures["defmt_bytes"], 1234);
        assert!(!figures.contains_key("defmt_decoder"));
        let last = figures["last_logs"].as_array().unwrap();
        assert_eq!(last.len(), LAST_LOGS);
        assert_eq!(last[0], "INFO line 2");
        assert_eq!(last[7], "INFO line 9");
    }
}
