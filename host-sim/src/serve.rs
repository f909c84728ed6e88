//! `host-sim serve`: the simulator as a device for an emulated robot.
//!
//! The emulator harness runs the real firmware and asks this process, over stdin and
//! stdout, to move the world on and to read each sensor, so the emulated robot lives in
//! the same physics as the host demos. One JSON object per line each way; every request
//! gets exactly one reply line.
//!
//! | request | reply |
//! |---|---|
//! | `{"cmd":"advance","t_s":T,"left":L,"right":R}` | `{"t_s","x_mm","y_mm","heading_deg","collisions"}`: the world moved on to the 5 ms sub-step nearest time `T` s (the reply's `t_s`) with wheel duties `L`, `R` in [-1, 1] (positive forward); `collisions` counts the body's contacts with a wall so far |
//! | `{"cmd":"flow"}` | `{"forward_counts","right_counts","squal"}`: counts since the last flow read |
//! | `{"cmd":"gyro"}` | `{"rate_mdps"}`: the newest 200 Hz yaw rate sample, bias and noise included |
//! | `{"cmd":"depth"}` | `{"ranges_mm":[8 x (mm or null)]}`: the 8 beams, left to right |
//! | `{"cmd":"tags"}` | `{"tags":[{"id","cx_px","distance_mm"}]}`: what the camera reads now, from where the robot was `sensors.camera.latency_ms` ago (the link does not say: the firmware knows only when the frame was sent) |
//! | `{"cmd":"truth"}` | as `advance`, without moving |
//!
//! A request that cannot be understood (not UTF-8, not JSON, an unknown command) or that
//! asks for the impossible (time going backwards or below 0, a step longer than
//! [`MAX_ADVANCE_S`]) gets `{"error": "..."}`, and the session goes on.

use crate::robot::{Command, Robot, SUBSTEP_S};
use crate::scenario::Scenario;
use serde::{Deserialize, Serialize};
use std::io::{BufRead, Write};

/// The longest one `advance` may move the world on, seconds. The emulator asks for a few
/// milliseconds at a time; a minute is 12,000 sub-steps, answered at once, where a
/// runaway `t_s` (1e12) would keep the process busy for ever without a reply.
pub const MAX_ADVANCE_S: f64 = 60.0;

/// One request line.
#[derive(Debug, Deserialize, PartialEq)]
#[serde(try_from = "RequestLine")]
pub enum Request {
    /// Move the world on to `t_s` under these wheel duties.
    Advance {
        /// Simulated time to reach, seconds.
        t_s: f64,
        /// Left wheel duty, -1 to 1.
        left: f64,
        /// Right wheel duty, -1 to 1.
        right: f64,
    },
    /// Read the flow sensor.
    Flow,
    /// Read the gyro.
    Gyro,
    /// Read the depth sensor.
    Depth,
    /// Read the camera.
    Tags,
    /// Where the robot really is.
    Truth,
}

/// A request line as written: one flat object. Read as a plain struct, its numbers come
/// straight from the text; an internally tagged enum would buffer them first, and that
/// breaks under serde_json's `arbitrary_precision` (which a workspace build that also
/// builds `xtask`'s defmt-decoder switches on).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RequestLine {
    cmd: CommandName,
    t_s: Option<f64>,
    left: Option<f64>,
    right: Option<f64>,
}

/// The `cmd` of a request line.
#[derive(Deserialize)]
#[serde(rename_all = "snake_case")]
enum CommandName {
    Advance,
    Flow,
    Gyro,
    Depth,
    Tags,
    Truth,
}

impl TryFrom<RequestLine> for Request {
    type Error = String;

    fn try_from(line: RequestLine) -> Result<Request, String> {
        let without_arguments = |request: Request, cmd: &str| {
            if line.t_s.is_none() && line.left.is_none() && line.right.is_none() {
                Ok(request)
            } else {
                Err(format!("`{cmd}` takes no t_s, left or right"))
            }
        };
        match line.cmd {
            CommandName::Advance => match (line.t_s, line.left, line.right) {
                (Some(t_s), Some(left), Some(right)) => Ok(Request::Advance { t_s, left, right }),
                _ => Err("`advance` needs t_s, left and right".into()),
            },
            CommandName::Flow => without_arguments(Request::Flow, "flow"),
            CommandName::Gyro => without_arguments(Request::Gyro, "gyro"),
            CommandName::Depth => without_arguments(Request::Depth, "depth"),
            CommandName::Tags => without_arguments(Request::Tags, "tags"),
            CommandName::Truth => without_arguments(Request::Truth, "truth"),
        }
    }
}

#[derive(Serialize)]
struct TruthReply {
    t_s: f64,
    x_mm: f64,
    y_mm: f64,
    heading_deg: f64,
    collisions: u32,
}

#[derive(Serialize)]
struct TagReply {
    id: u16,
    cx_px: f64,
    distance_mm: u32,
}

/// The motion a pair of wheel duties makes, by the scenario's drive.
pub fn command_from_duty(scenario: &Scenario, left: f64, right: f64) -> Command {
    let max = scenario.robot.max_wheel_speed_mm_s;
    let (vl, vr) = (left.clamp(-1.0, 1.0) * max, right.clamp(-1.0, 1.0) * max);
    Command {
        speed_mm_s: (vl + vr) / 2.0,
        // Left faster than right turns clockwise, which is a positive heading change.
        turn_dps: ((vl - vr) / scenario.robot.wheel_base_mm).to_degrees(),
    }
}

/// Answers one request, moving `robot` on if asked.
pub fn answer(robot: &mut Robot, scenario: &Scenario, line: &str) -> String {
    let request: Request = match serde_json::from_str(line) {
        Ok(r) => r,
        Err(e) => return serde_json::json!({ "error": format!("bad request: {e}") }).to_string(),
    };
    let truth = |robot: &Robot| {
        let t = robot.truth();
        serde_json::to_string(&TruthReply {
            t_s: robot.time_s(),
            x_mm: t.x_mm,
            y_mm: t.y_mm,
            heading_deg: t.heading_deg,
            collisions: robot.collisions(),
        })
    };
    let reply = match request {
        Request::Advance { t_s, left, right } => {
            if let Err(problem) = check_advance(robot.time_s(), t_s, left, right) {
                return serde_json::json!({ "error": problem }).to_string();
            }
            robot.advance_to_nearest(t_s, command_from_duty(scenario, left, right));
            truth(robot)
        }
        Request::Truth => truth(robot),
        Request::Flow => {
            let (f, r, q) = robot.take_flow();
            Ok(
                serde_json::json!({ "forward_counts": f, "right_counts": r, "squal": q })
                    .to_string(),
            )
        }
        Request::Gyro => {
            Ok(serde_json::json!({ "rate_mdps": robot.gyro_sample_mdps() }).to_string())
        }
        Request::Depth => {
            Ok(serde_json::json!({ "ranges_mm": robot.read_depth().ranges_mm }).to_string())
        }
        Request::Tags => {
            let tags: Vec<TagReply> = robot
                .read_tags()
                .as_slice()
                .iter()
                .map(|t| TagReply {
                    id: t.id,
                    cx_px: t.cx_centipx as f64 / 100.0,
                    distance_mm: t.distance_mm,
                })
                .collect();
            Ok(serde_json::json!({ "tags": tags }).to_string())
        }
    };
    reply.unwrap_or_else(|e| serde_json::json!({ "error": e.to_string() }).to_string())
}

/// How far before the world's time an `advance` may ask without being refused, seconds:
/// the world moves to the sub-step nearest the time asked for, up to half a sub-step past
/// it ([`Robot::advance_to_nearest`]), and a millionth of one for rounding.
const BACKWARDS_TOLERANCE_S: f64 = SUBSTEP_S / 2.0 + 1e-6;

/// Why an `advance` from the world's time `now_s` cannot be done, if it cannot.
fn check_advance(now_s: f64, t_s: f64, left: f64, right: f64) -> Result<(), String> {
    if !(t_s.is_finite() && left.is_finite() && right.is_finite()) {
        Err("advance needs finite t_s, left and right".into())
    } else if t_s < 0.0 {
        Err(format!("advance t_s must be 0 or later, got {t_s}"))
    } else if t_s < now_s - BACKWARDS_TOLERANCE_S {
        Err(format!(
            "advance t_s {t_s} is before the world's time {now_s} s: time only goes forward"
        ))
    } else if t_s - now_s > MAX_ADVANCE_S {
        Err(format!(
            "advance may move the world on at most {MAX_ADVANCE_S} s at a time: from {now_s} s to {t_s} s is too far"
        ))
    } else {
        Ok(())
    }
}

/// Serves requests from `input` until it ends. A line that is not UTF-8 is answered with
/// an error like any other bad request; only a failure to read or write ends the session.
pub fn serve(
    scenario: &Scenario,
    seed: u64,
    mut input: impl BufRead,
    mut output: impl Write,
) -> std::io::Result<()> {
    let mut robot = Robot::new(scenario, seed);
    let mut bytes = Vec::new();
    loop {
        bytes.clear();
        if input.read_until(b'\n', &mut bytes)? == 0 {
            return Ok(());
        }
        let reply = match std::str::from_utf8(&bytes) {
            Ok(line) if line.trim().is_empty() => continue,
            Ok(line) => answer(&mut robot, scenario, line.trim_end_matches(['\n', '\r'])),
            Err(e) => {
                serde_json::json!({ "error": format!("bad request: not UTF-8: {e}") }).to_string()
            }
        };
        writeln!(output, "{reply}")?;
        output.flush()?;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn seed() -> Scenario {
        let text = include_str!("../scenarios/seed-mat.toml");
        match Scenario::parse(text) {
            Ok(s) => s,
            Err(e) => panic!("{e}"),
        }
    }

    fn json(s: &str) -> serde_json::Value {
        serde_json::from_str(s).unwrap_or_default()
    }

    #[test]
    fn duty_makes_the_seed_motions() {
        let s = seed();
        let c = command_from_duty(&s, 86.0 / 300.0, 86.0 / 300.0);
        assert!((c.speed_mm_s - 86.0).abs() < 1e-9 && c.turn_dps == 0.0);
        // 31.5 deg/s on the spot: wheels at +-b/2 * omega.
        let w = (31.5f64).to_radians() * 50.0 / 300.0;
        let c = command_from_duty(&s, w, -w);
        assert!((c.turn_dps - 31.5).abs() < 1e-9 && c.speed_mm_s.abs() < 1e-12);
    }

    #[test]
    fn request_lines_parse_or_say_what_is_wrong() {
        let parse = |line: &str| serde_json::from_str::<Request>(line).map_err(|e| e.to_string());
        assert_eq!(
            parse(r#"{"cmd":"advance","t_s":0.25,"left":0.5,"right":-1}"#),
            Ok(Request::Advance {
                t_s: 0.25,
                left: 0.5,
                right: -1.0
            })
        );
        assert_eq!(parse(r#"{"cmd":"gyro"}"#), Ok(Request::Gyro));
        let refused = [
            (r#"{"cmd":"advance","t_s":1}"#, "needs t_s, left and right"),
            (r#"{"cmd":"gyro","t_s":1}"#, "takes no"),
            (r#"{"cmd":"frobnicate"}"#, "frobnicate"),
            (r#"{"cmd":"truth","speed":3}"#, "speed"),
            (r#"{"t_s":1}"#, "cmd"),
        ];
        for (line, says) in refused {
            match parse(line) {
                Ok(r) => panic!("{line} parsed as {r:?}"),
                Err(e) => assert!(e.contains(says), "{line}: {e}"),
            }
        }
    }

    #[test]
    fn a_session_moves_and_reads() {
        let s = seed();
        let input = concat!(
            "{\"cmd\":\"advance\",\"t_s\":1.0,\"left\":0.5,\"right\":0.5}\n",
            "{\"cmd\":\"flow\"}\n",
            "{\"cmd\":\"gyro\"}\n",
            "{\"cmd\":\"depth\"}\n",
            "{\"cmd\":\"tags\"}\n",
            "not json\n",
            "{\"cmd\":\"advance\",\"t_s\":1.0,\"left\":NaN,\"right\":0}\n",
            "{\"cmd\":\"advance\",\"t_s\":2.0,\"left\":0.0916,\"right\":-0.0916}\n",
            "{\"cmd\":\"gyro\"}\n",
        );
        let mut out = Vec::new();
        assert!(serve(&s, 1, input.as_bytes(), &mut out).is_ok());
        let lines: Vec<serde_json::Value> =
            String::from_utf8_lossy(&out).lines().map(json).collect();
        assert_eq!(lines.len(), 9);
        assert!(
            (lines[0]["y_mm"].as_f64().unwrap_or(0.0) - 650.0).abs() < 1.0,
            "{}",
            lines[0]
        );
        assert_eq!(lines[0]["collisions"].as_u64(), Some(0), "{}", lines[0]);
        // 150 mm at 100 um per count, 4 % short.
        let counts = lines[1]["forward_counts"].as_i64().unwrap_or(0);
        assert!((counts - 1440).abs() < 20, "{counts}");
        assert!(lines[2]["rate_mdps"].as_i64().is_some());
        assert_eq!(lines[3]["ranges_mm"].as_array().map(Vec::len), Some(8));
        assert!(lines[4]["tags"].is_array());
        assert!(lines[5]["error"].is_string());
        assert!(lines[6]["error"].is_string());
        // Turning clockwise at about 31.5 deg/s: the gyro reads it, with its 0.75 % scale
        // error, 0.02 deg/s bias and 0.1 deg/s noise.
        let rate = lines[8]["rate_mdps"].as_i64().unwrap_or(0);
        assert!(
            (rate - 31_800).abs() < 600,
            "gyro reads {rate} mdps while turning"
        );
        assert_eq!(
            lines[2]["rate_mdps"].as_i64().map(|r| r.abs() < 600),
            Some(true),
            "{}",
            lines[2]
        );
    }

    /// Serves `input` on the seed scenario and returns the reply lines.
    fn session(input: &[u8]) -> Vec<serde_json::Value> {
        let mut out = Vec::new();
        assert!(serve(&seed(), 1, input, &mut out).is_ok());
        String::from_utf8_lossy(&out).lines().map(json).collect()
    }

    fn error_of(reply: &serde_json::Value) -> &str {
        reply["error"].as_str().unwrap_or_default()
    }

    #[test]
    fn impossible_times_get_an_error_and_the_session_goes_on() {
        let lines = session(
            concat!(
                "{\"cmd\":\"advance\",\"t_s\":1e12,\"left\":0.5,\"right\":0.5}\n",
                "{\"cmd\":\"advance\",\"t_s\":-5,\"left\":0,\"right\":0}\n",
                "{\"cmd\":\"advance\",\"t_s\":2.0,\"left\":0.5,\"right\":0.5}\n",
                "{\"cmd\":\"advance\",\"t_s\":1.0,\"left\":0.5,\"right\":0.5}\n",
                "{\"cmd\":\"advance\",\"t_s\":62.5,\"left\":0,\"right\":0}\n",
                "{\"cmd\":\"advance\",\"t_s\":2.0,\"left\":0,\"right\":0}\n",
                "{\"cmd\":\"truth\"}\n",
            )
            .as_bytes(),
        );
        assert_eq!(lines.len(), 7, "{lines:?}");
        assert!(error_of(&lines[0]).contains("at most 60 s"), "{}", lines[0]);
        assert!(error_of(&lines[1]).contains("0 or later"), "{}", lines[1]);
        assert_eq!(lines[2]["t_s"].as_f64(), Some(2.0), "{}", lines[2]);
        assert!(error_of(&lines[3]).contains("before"), "{}", lines[3]);
        assert!(error_of(&lines[4]).contains("at most 60 s"), "{}", lines[4]);
        // The same time again is no step at all, and fine.
        assert_eq!(lines[5]["t_s"].as_f64(), Some(2.0), "{}", lines[5]);
        assert_eq!(lines[6]["t_s"].as_f64(), Some(2.0), "{}", lines[6]);
    }

    /// A time between two 5 ms sub-steps is served from the nearer, so a sensor read there
    /// sees the world within 2.5 ms of when it asked, not up to 5 ms before; a time up to
    /// half a sub-step before the world's, as the nearer-rounding leaves it, is no error.
    #[test]
    fn a_time_between_sub_steps_is_served_from_the_nearer() {
        let lines = session(
            concat!(
                "{\"cmd\":\"advance\",\"t_s\":1.0124,\"left\":0,\"right\":0}\n",
                "{\"cmd\":\"advance\",\"t_s\":1.0126,\"left\":0,\"right\":0}\n",
                "{\"cmd\":\"advance\",\"t_s\":1.0128,\"left\":0,\"right\":0}\n",
                "{\"cmd\":\"advance\",\"t_s\":1.0174,\"left\":0,\"right\":0}\n",
            )
            .as_bytes(),
        );
        let t = |i: usize| lines[i]["t_s"].as_f64().unwrap_or(f64::NAN);
        assert!((t(0) - 1.010).abs() < 1e-9, "{}", lines[0]);
        assert!((t(1) - 1.015).abs() < 1e-9, "{}", lines[1]);
        assert!((t(2) - 1.015).abs() < 1e-9, "{}", lines[2]);
        assert!((t(3) - 1.015).abs() < 1e-9, "{}", lines[3]);
    }

    #[test]
    fn a_line_that_is_not_utf8_gets_an_error_and_the_session_goes_on() {
        let mut input = b"{\"cmd\":\"gyro\"}\n".to_vec();
        input.extend(b"{\"cmd\":\"\xff\"}\r\n");
        input.extend(b"\n  \n");
        input.extend(b"{\"cmd\":\"advance\",\"t_s\":1.0,\"left\":0.5,\"right\":0.5}\r\n");
        input.extend(b"{\"cmd\":\"truth\"}"); // the last line may lack its newline
        let lines = session(&input);
        assert_eq!(lines.len(), 4, "{lines:?}");
        assert!(lines[0]["rate_mdps"].is_i64(), "{}", lines[0]);
        assert!(error_of(&lines[1]).contains("UTF-8"), "{}", lines[1]);
        assert_eq!(lines[2]["t_s"].as_f64(), Some(1.0), "{}", lines[2]);
        assert_eq!(lines[3]["t_s"].as_f64(), Some(1.0), "{}", lines[3]);
    }
}
