//! The telemetry's USB copy held to the UART's: both streams decoded by the `wire` crate's
//! [`StreamDecoder`] (the one `host-sim view` uses), then compared message for message.
//!
//! The firmware offers every frame to USB as it writes it to the UART, and drops (and
//! counts, as `usb no host`) the frames offered before a host configured the device. The
//! emulator's host reads every packet as it comes, so the USB stream must be the UART
//! stream from the first frame after enumeration on, with nothing missing, reordered or
//! changed: every `Hello`, `Inputs`, `Tick` (its tick number, time, pose, fix and counters),
//! `Filter`, map chunk and `Health`. Where the streams join is found by tick number, and
//! the frames the USB stream lacks before it must be exactly the firmware's `usb no host`
//! count; `usb dropped` must be 0. At the end the run stops wherever the two links are, so
//! one stream may hold up to [`MAX_TAIL`] messages (one tick's frames) past the other's
//! last. The final map is rebuilt from each stream's chunks over the compared messages.

use std::path::Path;

use wire::telemetry::{Message, StreamDecoder};

use super::defmt_log::LogLine;

/// The most frames one tick sends (`Hello`, `Inputs`, `Tick`, `Filter`, two map chunks,
/// `Health`): what one link may still have had in flight when the run stopped.
pub const MAX_TAIL: usize = 7;

/// A stream's messages, and its frames that did not decode.
#[derive(Debug)]
pub struct Decoded {
    pub messages: Vec<Message>,
    pub bad_frames: u32,
}

/// Decodes a whole recorded stream; a frame cut off at the end is not counted.
pub fn decode(bytes: &[u8]) -> Decoded {
    let mut decoder = StreamDecoder::new();
    let mut messages = Vec::new();
    let mut bad_frames = 0;
    for result in decoder.feed(bytes) {
        match result {
            Ok(m) => messages.push(m),
            Err(_) => bad_frames += 1,
        }
    }
    Decoded {
        messages,
        bad_frames,
    }
}

/// The firmware's USB counters from its last health line (`usb sent=N no host=N
/// dropped=N`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct UsbCounters {
    pub sent: u64,
    pub no_host: u64,
    pub dropped: u64,
}

impl UsbCounters {
    /// The counters in the last health line of `lines`, if any.
    pub fn last_in(lines: &[LogLine]) -> Option<UsbCounters> {
        lines.iter().rev().find_map(|l| Self::parse(&l.message))
    }

    fn parse(message: &str) -> Option<UsbCounters> {
        let rest = &message[message.find("usb sent=")?..];
        let number = |key: &str| -> Option<u64> {
            let at = rest.find(key)? + key.len();
            let digits = rest[at..]
                .find(|c: char| !c.is_ascii_digit())
                .map_or(&rest[at..], |end| &rest[at..at + end]);
            digits.parse().ok()
        };
        Some(UsbCounters {
            sent: number("usb sent=")?,
            no_host: number("no host=")?,
            dropped: number("dropped=")?,
        })
    }
}

/// The tick a message carries, and its kind, for joining the streams.
fn ticked(m: &Message) -> Option<(&'static str, u32)> {
    match m {
        Message::Tick(t) => Some(("Tick", t.tick)),
        Message::Filter(f) => Some(("Filter", f.tick)),
        Message::Inputs(i) => Some(("Inputs", i.tick)),
        _ => None,
    }
}

/// A message in a few words, for naming a difference.
fn describe(m: &Message) -> String {
    match m {
        Message::Hello(h) => format!("Hello ({} x {} grid)", h.width, h.height),
        Message::Tick(t) => format!(
            "Tick {} at {} ms, pose ({}, {}) um heading {:#010x}",
            t.tick, t.time_ms, t.x_um, t.y_um, t.heading_bits
        ),
        Message::Filter(f) => format!("Filter of tick {}", f.tick),
        Message::Inputs(i) => format!("Inputs of tick {}", i.tick),
        Message::MapRows(r) => format!(
            "map chunk at row {} column {} ({} cells)",
            r.first_row,
            r.first_column,
            r.cells.len()
        ),
        Message::Health(_) => "Health".to_string(),
    }
}

/// The map a run of messages leaves: the last `Hello`'s grid with every chunk slotted in.
fn final_map(messages: &[Message]) -> Option<Vec<i8>> {
    let mut grid: Option<(Vec<i8>, usize)> = None;
    for m in messages {
        match m {
            Message::Hello(h) => {
                let (w, h) = (usize::from(h.width), usize::from(h.height));
                if grid
                    .as_ref()
                    .is_none_or(|(g, gw)| g.len() != w * h || *gw != w)
                {
                    grid = Some((vec![0; w * h], w));
                }
            }
            Message::MapRows(rows) => {
                if let Some((g, w)) = grid.as_mut() {
                    if let Some(slot) = rows.slot_in(g, *w) {
                        slot.copy_from_slice(&rows.cells);
                    }
                }
            }
            _ => {}
        }
    }
    grid.map(|(g, _)| g)
}

/// How the USB stream compares with the UART's.
#[derive(Debug, PartialEq)]
pub struct Comparison {
    pub uart_messages: usize,
    pub usb_messages: usize,
    pub usb_bad_frames: u32,
    /// Index of the UART message the USB stream starts with.
    pub joined_at: Option<usize>,
    /// Messages compared, equal up to `first_difference`.
    pub compared: usize,
    /// Ticks among them, and the first and last tick number.
    pub ticks: usize,
    pub tick_range: Option<(u32, u32)>,
    /// Messages past the other stream's end, at the cut: (UART's, USB's).
    pub tail: (usize, usize),
    /// Cells of the final map, and whether both streams' final maps are equal.
    pub map_cells: usize,
    pub maps_equal: bool,
    pub counters: Option<UsbCounters>,
    pub first_difference: Option<String>,
}

impl Comparison {
    /// Whether the USB stream is the UART's run: every compared message equal, joined
    /// where the firmware's no-host count says, nothing dropped, a short tail at most.
    pub fn same_run(&self) -> bool {
        self.first_difference.is_none()
    }
}

/// Compares the decoded streams; `counters` are the firmware's, if its log had them.
pub fn compare(uart: &Decoded, usb: &Decoded, counters: Option<UsbCounters>) -> Comparison {
    let mut c = Comparison {
        uart_messages: uart.messages.len(),
        usb_messages: usb.messages.len(),
        usb_bad_frames: usb.bad_frames,
        joined_at: None,
        compared: 0,
        ticks: 0,
        tick_range: None,
        tail: (0, 0),
        map_cells: 0,
        maps_equal: false,
        counters,
        first_difference: None,
    };
    let differ = |c: &mut Comparison, why: String| {
        if c.first_difference.is_none() {
            c.first_difference = Some(why);
        }
    };
    // Join at the USB's first message that names its tick.
    let Some((i, kind, tick)) = usb
        .messages
        .iter()
        .enumerate()
        .find_map(|(i, m)| ticked(m).map(|(k, t)| (i, k, t)))
    else {
        differ(
            &mut c,
            "the USB stream holds no Tick, Filter or Inputs".into(),
        );
        return c;
    };
    let Some(j) = uart
        .messages
        .iter()
        .position(|m| ticked(m) == Some((kind, tick)))
    else {
        differ(
            &mut c,
            format!("the USB stream's {kind} of tick {tick} is not in the UART stream"),
        );
        return c;
    };
    let Some(k) = j.checked_sub(i) else {
        differ(
            &mut c,
            format!(
                "the USB stream holds {i} messages before its {kind} of tick {tick}, the UART only {j}"
            ),
        );
        return c;
    };
    c.joined_at = Some(k);
    let (uart_rest, usb_all) = (&uart.messages[k..], &usb.messages[..]);
    for (n, (a, b)) in uart_rest.iter().zip(usb_all).enumerate() {
        if a != b {
            differ(
                &mut c,
                format!(
                    "message {} of the USB stream (UART message {}): UART has {}, USB has {}",
                    n,
                    k + n,
                    describe(a),
                    describe(b)
                ),
            );
            break;
        }
        c.compared += 1;
        if let Message::Tick(t) = b {
            c.ticks += 1;
            c.tick_range = Some(c.tick_range.map_or((t.tick, t.tick), |(f, _)| (f, t.tick)));
        }
    }
    let common = uart_rest.len().min(usb_all.len());
    c.tail = (uart_rest.len() - common, usb_all.len() - common);
    let (a, b) = (
        final_map(&uart_rest[..c.compared]),
        final_map(&usb_all[..c.compared]),
    );
    c.map_cells = b.as_ref().map_or(0, Vec::len);
    c.maps_equal = a.is_some() && a == b;
    if usb.bad_frames > 0 {
        differ(
            &mut c,
            format!("{} USB frames did not decode", usb.bad_frames),
        );
    }
    match counters {
        None => differ(&mut c, "no health line with the firmware's USB counters".into()),
        Some(f) if f.dropped > 0 => differ(
            &mut c,
            format!("the firmware dropped {} frames meant for USB", f.dropped),
        ),
        Some(f) if f.no_host != k as u64 => differ(
            &mut c,
            format!(
                "the USB stream starts at UART message {k}, but the firmware offered {} frames before a host was there",
                f.no_host
            ),
        ),
        Some(_) => {}
    }
    let (uart_tail, usb_tail) = c.tail;
    if uart_tail.max(usb_tail) > MAX_TAIL {
        differ(
            &mut c,
            format!(
                "at the end the UART holds {uart_tail} messages more and the USB {usb_tail} more (at most {MAX_TAIL}, one tick's frames, may be in flight)"
            ),
        );
    }
    if !c.maps_equal {
        differ(&mut c, "the final maps differ".into());
    }
    c
}

/// Reads the two recordings and compares them, with the firmware's counters from `lines`
/// (its defmt log); the comparison as JSON ([`Comparison::to_json`]).
pub fn check(uart: &Path, usb: &Path, lines: &[LogLine]) -> Result<serde_json::Value, String> {
    let read = |p: &Path| std::fs::read(p).map_err(|e| format!("cannot read {}: {e}", p.display()));
    let c = compare(
        &decode(&read(uart)?),
        &decode(&read(usb)?),
        UsbCounters::last_in(lines),
    );
    Ok(c.to_json())
}

/// Fails, naming why, when the harness's host did not open the port (`host`: the
/// harness's `usb` report) or the stream is not the UART's run (`usb`: [`check`]'s JSON).
pub fn verdict(host: &serde_json::Value, usb: &serde_json::Value) -> Result<(), String> {
    if let Some(e) = host["error"].as_str() {
        return Err(format!("USB: {e}"));
    }
    match usb["first_difference"].as_str() {
        Some(d) => Err(format!("USB stream: {d}")),
        None => Ok(()),
    }
}

impl Comparison {
    /// The comparison as JSON, for `cargo xtask emulate --json` and the checks.
    pub fn to_json(&self) -> serde_json::Value {
        serde_json::json!({
            "same_run": self.same_run(),
            "uart_messages": self.uart_messages,
            "usb_messages": self.usb_messages,
            "usb_bad_frames": self.usb_bad_frames,
            "joined_at_message": self.joined_at,
            "compared_messages": self.compared,
            "ticks": self.ticks,
            "first_tick": self.tick_range.map(|r| r.0),
            "last_tick": self.tick_range.map(|r| r.1),
            "tail_uart_only": self.tail.0,
            "tail_usb_only": self.tail.1,
            "map_cells": self.map_cells,
            "maps_equal": self.maps_equal,
            "firmware": self.counters.map(|f| serde_json::json!({
                "sent": f.sent, "no_host": f.no_host, "dropped": f.dropped,
            })),
            "first_difference": self.first_difference,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use wire::telemetry::{MapRows, Tick};

    fn tick(n: u32, x_um: i32) -> Message {
        Message::Tick(Tick {
            tick: n,
            time_ms: n * 100,
            x_um,
            y_um: 0,
            heading_bits: 0,
            fix: slam_core::FixOutcome::NotAttempted,
            stale: 0,
            cells_written: 0,
            doubts: 0,
            counters: slam_core::Counters::default(),
        })
    }

    fn hello() -> Message {
        Message::Hello(wire::telemetry::Hello {
            width: 2,
            height: 2,
            cell_mm: 50,
            origin_x_mm: 0,
            origin_y_mm: 0,
            free_below: 1,
            occupied_above: 1,
            firmware: Default::default(),
            localiser: slam_core::Localiser::Filter,
            matching: false,
            boot: Default::default(),
        })
    }

    fn rows(cell: i8) -> Message {
        let mut cells = wire::telemetry::CellChunk::new();
        let _ = cells.extend_from_slice(&[cell; 4]);
        Message::MapRows(MapRows {
            first_row: 0,
            first_column: 0,
            cells,
        })
    }

    fn run(n: u32) -> Vec<Message> {
        let mut m = vec![hello()];
        for t in 1..=n {
            m.push(tick(t, t as i32));
            m.push(rows(t as i8));
        }
        m
    }

    fn decoded(messages: Vec<Message>) -> Decoded {
        Decoded {
            messages,
            bad_frames: 0,
        }
    }

    fn counters(no_host: u64) -> Option<UsbCounters> {
        Some(UsbCounters {
            sent: 0,
            no_host,
            dropped: 0,
        })
    }

    #[test]
    fn a_suffix_joined_where_the_firmware_says_is_the_same_run() {
        let uart = run(10);
        let usb: Vec<Message> = [vec![hello()], uart[5..].to_vec()].concat();
        // The USB copy starts with a Hello the UART sent at the same place in its stream.
        let mut uart_with_hello = uart[..5].to_vec();
        uart_with_hello.extend(usb.iter().cloned());
        let c = compare(&decoded(uart_with_hello), &decoded(usb), counters(5));
        assert!(c.same_run(), "{c:?}");
        assert_eq!(
            (c.joined_at, c.ticks, c.tick_range),
            (Some(5), 8, Some((3, 10)))
        );
        assert!(c.maps_equal && c.map_cells == 4);
    }

    #[test]
    fn a_changed_pose_is_named() {
        let uart = run(10);
        let mut usb = uart.clone();
        usb[7] = tick(4, 999);
        let c = compare(&decoded(uart), &decoded(usb), counters(0));
        let d = c.first_difference.unwrap_or_default();
        assert!(
            d.contains("message 7") && d.contains("pose (4, 0)") && d.contains("pose (999, 0)"),
            "{d}"
        );
    }

    #[test]
    fn a_dropped_frame_a_late_join_and_a_long_tail_fail() {
        let uart = run(10);
        let mut usb = uart.clone();
        usb.remove(4);
        assert!(!compare(&decoded(uart.clone()), &decoded(usb), counters(0)).same_run());
        // Joined at message 3 while the firmware says it dropped 1 frame for want of a host.
        let c = compare(
            &decoded(uart.clone()),
            &decoded(uart[3..].to_vec()),
            counters(1),
        );
        assert!(c
            .first_difference
            .unwrap_or_default()
            .contains("offered 1 frames"));
        // A tail of one tick is the cut; of eight messages, frames went missing.
        let c = compare(
            &decoded(uart.clone()),
            &decoded(uart[..19].to_vec()),
            counters(0),
        );
        assert!(c.same_run() && c.tail == (2, 0), "{c:?}");
        let c = compare(
            &decoded(uart.clone()),
            &decoded(uart[..13].to_vec()),
            counters(0),
        );
        assert!(!c.same_run());
    }

    #[test]
    fn bytes_decode_with_the_wire_crate() {
        let mut bytes = vec![0];
        for m in run(3) {
            let mut frame = [0u8; wire::telemetry::MAX_FRAME_LEN];
            let n = wire::telemetry::encode(&m, &mut frame).unwrap();
            bytes.extend_from_slice(&frame[..n]);
        }
        let d = decode(&bytes);
        assert_eq!((d.messages, d.bad_frames), (run(3), 0));
        assert_eq!(decode(&[1, 2, 3, 0]).bad_frames, 1);
    }

    #[test]
    fn usb_counters_come_from_the_last_health_line() {
        let line = |m: &str| LogLine {
            time: String::new(),
            level: "INFO".into(),
            message: m.into(),
        };
        let lines = [
            line("health: telemetry dropped=0 err=0 | usb sent=1 no host=5 dropped=0 | motion halts=0"),
            line("health: telemetry dropped=0 err=0 | usb sent=90 no host=6 dropped=2 | motion halts=0"),
            line("ticks: 10, overruns: 0"),
        ];
        assert_eq!(
            UsbCounters::last_in(&lines),
            Some(UsbCounters {
                sent: 90,
                no_host: 6,
                dropped: 2
            })
        );
    }
}
