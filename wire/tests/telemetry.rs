//! The telemetry stream's frames: byte fixtures, round trips, worst cases, damaged input,
//! the sender's schedule and map sweep.

use proptest::prelude::*;
use slam_core::{
    Angle, Calibration, Counters, DepthScan, Doubt, DriveCommand, Evidence, FixOutcome,
    FixRejection, FlowDelta, GridGeometry, GridMap, GyroRate, Localiser, Pose, PoseCovariance,
    SensorFrame, Staleness, StepReport, TagCounters, TagDetection, TagDetections, Trust, BEAMS,
    MAX_TAGS,
};
use wire::framing::{cobs_encode, crc16};
use wire::telemetry::*;

/// `raw` as it goes on the wire, built by hand: its CRC appended, COBS-stuffed, and
/// the zero delimiter.
fn sealed(raw: &[u8]) -> Vec<u8> {
    let mut raw = raw.to_vec();
    let crc = crc16(&raw);
    raw.extend_from_slice(&crc.to_le_bytes());
    let mut stuffed = std::vec![0u8; 256];
    let n = cobs_encode(&raw, &mut stuffed).expect("room");
    stuffed.truncate(n);
    stuffed.push(0);
    stuffed
}

const FW: FirmwareVersion = FirmwareVersion {
    major: 0,
    minor: 3,
    patch: 1,
};

fn hello() -> Message {
    Message::Hello(Hello {
        width: 46,
        height: 46,
        cell_mm: 50,
        origin_x_mm: -150,
        origin_y_mm: -150,
        free_below: 16,
        occupied_above: 16,
        firmware: FW,
        localiser: Localiser::Filter,
        matching: false,
        boot: Boot::default(),
    })
}

/// A belief as the filter might hold it mid-route: a few millimetres and a degree or so
/// of doubt, with the seed's gyro and flow scale errors half learned.
fn filter_state() -> Message {
    Message::Filter(FilterState {
        tick: 137,
        covariance: PoseCovariance {
            xx: 4_600,
            xy: -1_200,
            yy: 3_900,
            xh: 15_000,
            yh: -9_000,
            hh: 1_300_000,
        },
        calibration: Calibration {
            gyro_scale_ppm: -3_700,
            gyro_bias_mdps: 120,
            flow_scale_ppm: 21_000,
        },
        tags: TagCounters {
            used: 250,
            unknown_id: 0,
            behind: 3,
            too_far: 17,
            too_old: 1,
            gate: 4,
        },
    })
}

fn tick() -> Message {
    Message::Tick(Tick {
        tick: 137,
        time_ms: 13_600,
        x_um: 812_345,
        y_um: -1_234,
        heading_bits: 0xC000_0001,
        fix: FixOutcome::Rejected(FixRejection::Gate),
        stale: STALE_FLOW | STALE_DEPTH,
        cells_written: 77,
        doubts: Trust {
            gyro: Some(Doubt::Stuck),
            ..Trust::default()
        }
        .packed(),
        counters: Counters {
            ticks: 137,
            fixes_taken: 12,
            fixes_rejected_geometry: 1,
            fixes_rejected_gate: 2,
            fixes_rejected_too_old: 3,
            relocalisations: 0,
            pictures_repeated: 4,
            pictures_leapt: 5,
            pictures_late: 6,
            beams_mapped: 1000,
            beams_invalid: 96,
            flow_stale: 3,
            gyro_stale: 0,
            depth_stale: 1,
            gyro_doubted: 6,
            flow_doubted: 0,
            depth_doubted: 2,
            scans_withheld: 8,
        },
    })
}

fn map_rows() -> Message {
    let cells: Vec<i8> = (0..92).map(|i| (i * 3 - 128) as i8).collect();
    Message::MapRows(MapRows {
        first_row: 44,
        first_column: 0,
        cells: CellChunk::from_slice(&cells).unwrap_or_default(),
    })
}

fn health() -> Message {
    Message::Health(SensorHealth {
        depth_timeouts: 1,
        depth_bus_errors: 2,
        flow_no_surface: 3,
        flow_outliers: 4,
        flow_bus_errors: 5,
        gyro_bus_errors: 6,
        camera_bad_frames: 7,
        tick_overruns: 8,
        watchdog_feeds: u32::MAX,
        depth_start_failures: 9,
        flow_start_failures: 10,
        gyro_start_failures: 11,
    })
}

/// A frame with every input present.
fn sensor_frame() -> SensorFrame {
    let mut tags = TagDetections::new();
    for (id, cx) in [(11u16, 16_000i32), (12, -2_500)] {
        let _ = tags.push(TagDetection {
            id,
            cx_centipx: cx,
            distance_mm: 900 + u32::from(id),
        });
    }
    let mut ranges_mm = [Some(700u16); BEAMS];
    ranges_mm[3] = None;
    SensorFrame {
        dt_us: 100_012,
        flow: Some(FlowDelta {
            forward_counts: 41,
            right_counts: -3,
        }),
        gyro: Some(GyroRate { rate_mdps: -1_234 }),
        depth: Some(DepthScan { ranges_mm }),
        depth_age_us: 33_000,
        depth_doubt: Some(Doubt::Jump),
        tags,
        tags_age_us: 61_000,
        external_pose: Some(Pose::from_mm_mdeg(700, 500, 90_000)),
        commanded: Some(DriveCommand {
            speed_mm_s: 86,
            turn_mdps: -31_500,
        }),
    }
}

fn inputs() -> Message {
    Message::Inputs(Inputs {
        tick: 42,
        time_ms: 4_200,
        frame: sensor_frame(),
    })
}

/// An `Inputs` whose every field takes the most bytes.
fn worst_inputs() -> Message {
    let mut tags = TagDetections::new();
    for _ in 0..MAX_TAGS {
        let _ = tags.push(TagDetection {
            id: u16::MAX,
            cx_centipx: i32::MIN,
            distance_mm: u32::MAX,
        });
    }
    Message::Inputs(Inputs {
        tick: u32::MAX,
        time_ms: u32::MAX,
        frame: SensorFrame {
            dt_us: u32::MAX,
            flow: Some(FlowDelta {
                forward_counts: i32::MIN,
                right_counts: i32::MIN,
            }),
            gyro: Some(GyroRate {
                rate_mdps: i32::MIN,
            }),
            depth: Some(DepthScan {
                ranges_mm: [Some(u16::MAX); BEAMS],
            }),
            depth_age_us: u32::MAX,
            depth_doubt: Some(Doubt::Late),
            tags,
            tags_age_us: u32::MAX,
            external_pose: Some(Pose {
                x_um: i32::MIN,
                y_um: i32::MIN,
                heading: Angle::from_bits(u32::MAX),
            }),
            commanded: Some(DriveCommand {
                speed_mm_s: i32::MIN,
                turn_mdps: i32::MIN,
            }),
        },
    })
}

fn frame(m: &Message) -> Vec<u8> {
    let mut buf = [0u8; MAX_FRAME_LEN];
    let n = encode(m, &mut buf).expect("encodes");
    buf[..n].to_vec()
}

fn decode_all(bytes: &[u8]) -> (Vec<Result<Message, FrameError>>, DecoderStats) {
    let mut d = StreamDecoder::new();
    let out = d.feed(bytes).collect();
    (out, *d.stats())
}

#[test]
fn health_frame_fixture() {
    // The layout written out by hand: version, variant 3, twelve varints, CRC, stuffed.
    let h = Message::Health(SensorHealth {
        depth_timeouts: 0,
        depth_bus_errors: 1,
        flow_no_surface: 300,
        gyro_start_failures: 2,
        ..SensorHealth::default()
    });
    let stuffed = sealed(&[0xBA, 3, 0, 1, 0xAC, 0x02, 0, 0, 0, 0, 0, 0, 0, 0, 2]);
    assert_eq!(frame(&h), stuffed);
    // No zero before the delimiter.
    assert!(!stuffed[..stuffed.len() - 1].contains(&0));
    assert_eq!(stuffed[0], 3, "first COBS code: b5 03 then a zero");
}

#[test]
fn filter_frame_fixture() {
    // Version, variant 4, tick 2, xx 300 (zigzag 600: 0xD8 0x04), xy -1 (1), yy 0, xh 0,
    // yh 0, hh 65536 (zigzag 131072: 0x80 0x80 0x08), gyro scale -2 (3), bias 0, flow
    // scale 64 (128: 0x80 0x01), used 5 and the five refusals 0, 0, 1, 0, 2.
    let m = Message::Filter(FilterState {
        tick: 2,
        covariance: PoseCovariance {
            xx: 300,
            xy: -1,
            hh: 65_536,
            ..PoseCovariance::default()
        },
        calibration: Calibration {
            gyro_scale_ppm: -2,
            gyro_bias_mdps: 0,
            flow_scale_ppm: 64,
        },
        tags: TagCounters {
            used: 5,
            too_far: 1,
            gate: 2,
            ..TagCounters::default()
        },
    });
    let raw = [
        0xBA, 4, 2, 0xD8, 0x04, 1, 0, 0, 0, 0x80, 0x80, 0x08, 3, 0, 0x80, 0x01, 5, 0, 0, 1, 0, 2,
    ];
    assert_eq!(frame(&m), sealed(&raw));
    assert_eq!(decode_all(&sealed(&raw)).0, std::vec![Ok(m)]);
}

/// A `Hello`'s postcard body.
fn hello_body(m: &Message) -> std::vec::Vec<u8> {
    postcard::to_slice(m, &mut [0u8; 64])
        .map(|b| b.to_vec())
        .unwrap_or_default()
}

#[test]
fn hello_carries_the_boot() {
    // The last three bytes: the reset cause (0 power-on, 1 watchdog, 2 other), resumed or
    // not, and the resumes as a varint.
    for (cause, byte) in [
        (ResetCause::PowerOn, 0),
        (ResetCause::Watchdog, 1),
        (ResetCause::Other, 2),
    ] {
        let mut m = hello();
        if let Message::Hello(h) = &mut m {
            h.boot = Boot {
                cause,
                resumed: cause == ResetCause::Watchdog,
                resumes: 3,
            };
        }
        let body = hello_body(&m);
        let resumed = u8::from(cause == ResetCause::Watchdog);
        assert_eq!(body.get(body.len() - 3..), Some(&[byte, resumed, 3][..]));
        assert_eq!(decode_all(&frame(&m)).0, std::vec![Ok(m)]);
    }
    // No fourth cause, and a flag is 0 or 1.
    refuses_hello_with(&[(3, 3), (2, 2)]);
}

/// A `Hello` with byte `from_end` from its body's end set to `bad` is refused, for each
/// `(from_end, bad)`.
fn refuses_hello_with(changes: &[(usize, u8)]) {
    for &(from_end, bad) in changes {
        let mut body = hello_body(&hello());
        let at = body.len() - from_end;
        body[at] = bad;
        let mut raw = std::vec![0xBA];
        raw.extend(body);
        assert_eq!(
            decode_all(&sealed(&raw)).0,
            std::vec![Err(FrameError::Body)],
            "byte {bad} {from_end} from the end"
        );
    }
}

#[test]
fn hello_carries_the_localiser_and_matching() {
    // Before the boot's three bytes: the localiser (0 dead reckoning, 1 two-tag fix,
    // 2 filter), then whether the filter matches scans (0 or 1).
    for (localiser, byte) in [
        (Localiser::DeadReckoning, 0),
        (Localiser::TwoTagFix, 1),
        (Localiser::Filter, 2),
    ] {
        for matching in [false, true] {
            let mut m = hello();
            if let Message::Hello(h) = &mut m {
                h.localiser = localiser;
                h.matching = matching;
            }
            let body = hello_body(&m);
            assert_eq!(body.get(body.len() - 5), Some(&byte), "{localiser:?}");
            assert_eq!(body.get(body.len() - 4), Some(&u8::from(matching)));
            assert_eq!(decode_all(&frame(&m)).0, std::vec![Ok(m)]);
        }
    }
    // No fourth localiser, and matching is a bool.
    refuses_hello_with(&[(5, 3), (4, 2)]);
}

#[test]
fn inputs_frame_fixture() {
    // Tick 1 at 2 ms, dt 3 us, every input stale: each option a 0 byte, no tags.
    let m = Message::Inputs(Inputs {
        tick: 1,
        time_ms: 2,
        frame: SensorFrame::empty(3),
    });
    let raw = [0xBA, 5, 1, 2, 3, 0, 0, 0, 0, 0, 0, 0, 0, 0];
    assert_eq!(frame(&m), sealed(&raw));
    assert_eq!(decode_all(&sealed(&raw)).0, std::vec![Ok(m)]);
    // The depth task found the scan late: doubt code 8 after the depth's age; a code no
    // doubt has is refused.
    let m = Message::Inputs(Inputs {
        tick: 1,
        time_ms: 2,
        frame: SensorFrame {
            depth_doubt: Some(Doubt::Late),
            ..SensorFrame::empty(3)
        },
    });
    let raw = [0xBA, 5, 1, 2, 3, 0, 0, 0, 0, 8, 0, 0, 0, 0];
    assert_eq!(frame(&m), sealed(&raw));
    assert_eq!(decode_all(&sealed(&raw)).0, std::vec![Ok(m)]);
    assert_eq!(Doubt::ALL.len(), 10);
    let raw = [0xBA, 5, 1, 2, 3, 0, 0, 0, 0, 11, 0, 0, 0, 0];
    assert_eq!(
        decode_all(&sealed(&raw)).0,
        std::vec![Err(FrameError::Body)]
    );
    // One tag (id 11, cx -1 zigzagged to 1, 300 mm) and a gyro reading of 5 mdps.
    let mut tags = TagDetections::new();
    let _ = tags.push(TagDetection {
        id: 11,
        cx_centipx: -1,
        distance_mm: 300,
    });
    let m = Message::Inputs(Inputs {
        tick: 1,
        time_ms: 2,
        frame: SensorFrame {
            gyro: Some(GyroRate { rate_mdps: 5 }),
            tags,
            ..SensorFrame::empty(3)
        },
    });
    let raw = [
        0xBA, 5, 1, 2, 3, 0, 1, 10, 0, 0, 0, 1, 11, 1, 0xAC, 0x02, 0, 0, 0,
    ];
    assert_eq!(frame(&m), sealed(&raw));
    // Commanded 86 mm/s (zigzag 172) and -31.5 deg/s (zigzag 62,999).
    let m = Message::Inputs(Inputs {
        tick: 1,
        time_ms: 2,
        frame: SensorFrame {
            commanded: Some(DriveCommand {
                speed_mm_s: 86,
                turn_mdps: -31_500,
            }),
            ..SensorFrame::empty(3)
        },
    });
    let raw = [
        0xBA, 5, 1, 2, 3, 0, 0, 0, 0, 0, 0, 0, 0, 1, 0xAC, 0x01, 0x97, 0xEC, 0x03,
    ];
    assert_eq!(frame(&m), sealed(&raw));
    assert_eq!(decode_all(&sealed(&raw)).0, std::vec![Ok(m)]);
}

#[test]
fn inputs_with_more_tags_than_the_core_holds_are_refused() {
    let mut raw = std::vec![0xBA, 5, 1, 2, 3, 0, 0, 0, 0, 0];
    raw.push(u8::try_from(MAX_TAGS + 1).unwrap_or(u8::MAX));
    for _ in 0..=MAX_TAGS {
        raw.extend([1, 0, 0]);
    }
    raw.extend([0, 0, 0]);
    assert_eq!(
        decode_all(&sealed(&raw)).0,
        std::vec![Err(FrameError::Body)]
    );
    // The same with the most it holds decodes.
    let mut raw = std::vec![0xBA, 5, 1, 2, 3, 0, 0, 0, 0, 0];
    raw.push(u8::try_from(MAX_TAGS).unwrap_or(u8::MAX));
    for _ in 0..MAX_TAGS {
        raw.extend([1, 0, 0]);
    }
    raw.extend([0, 0, 0]);
    let (out, _) = decode_all(&sealed(&raw));
    assert!(
        matches!(&out[..], [Ok(Message::Inputs(i))] if i.frame.tags.len() == MAX_TAGS),
        "{out:?}"
    );
}

#[test]
fn round_trip_each_message() {
    for m in [
        hello(),
        tick(),
        filter_state(),
        map_rows(),
        health(),
        inputs(),
        Message::Inputs(Inputs {
            tick: 0,
            time_ms: 0,
            frame: SensorFrame::empty(0),
        }),
    ] {
        let bytes = frame(&m);
        assert_eq!(bytes.last(), Some(&0));
        assert!(bytes.len() <= MAX_FRAME_LEN);
        let (out, stats) = decode_all(&bytes);
        assert_eq!(out, std::vec![Ok(m)]);
        assert_eq!(stats.frames_ok, 1);
        assert_eq!(stats.bad_frames.total(), 0);
    }
}

#[test]
fn worst_case_messages_fit() {
    let full = CellChunk::from_slice(&[-1i8; MAX_CHUNK_CELLS]).unwrap_or_default();
    let big = Message::MapRows(MapRows {
        first_row: u16::MAX,
        first_column: u16::MAX,
        cells: full,
    });
    let body = postcard::to_slice(&big, &mut [0u8; 512])
        .map(|b| b.len())
        .unwrap_or(0);
    assert!(body < MAX_MESSAGE_LEN, "a full MapRows is not the longest");
    let body = postcard::to_slice(&worst_inputs(), &mut [0u8; 512])
        .map(|b| b.len())
        .unwrap_or(0);
    assert_eq!(body, MAX_MESSAGE_LEN, "a full Inputs is");
    let mut worst_tick = tick();
    if let Message::Tick(t) = &mut worst_tick {
        t.tick = u32::MAX;
        t.time_ms = u32::MAX;
        t.x_um = i32::MIN;
        t.y_um = i32::MIN;
        t.heading_bits = u32::MAX;
        t.cells_written = u32::MAX;
        t.fix = FixOutcome::Rejected(FixRejection::TooOld);
        t.counters = Counters {
            ticks: u32::MAX,
            fixes_taken: u32::MAX,
            fixes_rejected_geometry: u32::MAX,
            fixes_rejected_gate: u32::MAX,
            fixes_rejected_too_old: u32::MAX,
            relocalisations: u32::MAX,
            pictures_repeated: u32::MAX,
            pictures_leapt: u32::MAX,
            pictures_late: u32::MAX,
            beams_mapped: u32::MAX,
            beams_invalid: u32::MAX,
            flow_stale: u32::MAX,
            gyro_stale: u32::MAX,
            depth_stale: u32::MAX,
            gyro_doubted: u32::MAX,
            flow_doubted: u32::MAX,
            depth_doubted: u32::MAX,
            scans_withheld: u32::MAX,
        };
        t.doubts = u16::MAX;
    }
    let all_max = SensorHealth {
        depth_timeouts: u32::MAX,
        depth_bus_errors: u32::MAX,
        flow_no_surface: u32::MAX,
        flow_outliers: u32::MAX,
        flow_bus_errors: u32::MAX,
        gyro_bus_errors: u32::MAX,
        camera_bad_frames: u32::MAX,
        tick_overruns: u32::MAX,
        watchdog_feeds: u32::MAX,
        depth_start_failures: u32::MAX,
        flow_start_failures: u32::MAX,
        gyro_start_failures: u32::MAX,
    };
    let worst_filter = Message::Filter(FilterState {
        tick: u32::MAX,
        covariance: PoseCovariance {
            xx: i64::MIN,
            xy: i64::MIN,
            yy: i64::MIN,
            xh: i64::MIN,
            yh: i64::MIN,
            hh: i64::MIN,
        },
        calibration: Calibration {
            gyro_scale_ppm: i32::MIN,
            gyro_bias_mdps: i32::MIN,
            flow_scale_ppm: i32::MIN,
        },
        tags: TagCounters {
            used: u32::MAX,
            unknown_id: u32::MAX,
            behind: u32::MAX,
            too_far: u32::MAX,
            too_old: u32::MAX,
            gate: u32::MAX,
        },
    });
    let mut worst_hello = hello();
    if let Message::Hello(h) = &mut worst_hello {
        h.width = u16::MAX;
        h.height = u16::MAX;
        h.cell_mm = i32::MIN;
        h.origin_x_mm = i32::MIN;
        h.origin_y_mm = i32::MIN;
        h.boot = Boot {
            cause: ResetCause::Other,
            resumed: true,
            resumes: u16::MAX,
        };
    }
    for (m, limit) in [
        (big, 142),
        (worst_inputs(), MAX_FRAME_LEN),
        (worst_tick, 132),
        (worst_filter, 116),
        (Message::Health(all_max), 66),
        (worst_hello, 39),
    ] {
        let bytes = frame(&m);
        assert!(bytes.len() <= limit, "{} > {limit}", bytes.len());
        assert_eq!(decode_all(&bytes).0, std::vec![Ok(m)]);
    }
}

#[test]
fn buffer_too_small_is_an_error() {
    let needed = frame(&map_rows()).len();
    let mut small = [0u8; 40];
    assert_eq!(
        encode(&map_rows(), &mut small),
        Err(EncodeError::BufferTooSmall { needed })
    );
    let mut exact = std::vec![0u8; needed];
    assert_eq!(encode(&map_rows(), &mut exact), Ok(needed));
}

#[test]
fn garbage_between_frames_resynchronises() {
    let mut bytes = std::vec![0x55, 0x13, 0xFF];
    bytes.extend(frame(&hello()));
    bytes.extend([1, 2, 3, 4, 5, 0]);
    bytes.extend(frame(&tick()));
    bytes.extend([0, 0, 0]); // empty frames: ignored
    bytes.extend([0xBA, 0x07, 0]); // stuffing that runs past the end
    bytes.extend(frame(&health()));
    let (out, stats) = decode_all(&bytes);
    let good: Vec<Message> = out.iter().filter_map(|r| r.clone().ok()).collect();
    assert_eq!(good, std::vec![tick(), health()]);
    assert_eq!(stats.frames_ok, 2);
    // The leading garbage swallowed the hello: the frame boundary was lost.
    assert_eq!(stats.bad_frames.total(), 3, "{stats:?}");
    assert_eq!(
        stats.bad_frames.bad_cobs, 3,
        "each piece of garbage fails its stuffing"
    );
}

#[test]
fn truncated_frame_is_counted_and_the_next_one_decodes() {
    let whole = frame(&tick());
    let mut bytes = whole[..whole.len() / 2].to_vec();
    bytes.push(0);
    bytes.extend(frame(&hello()));
    let (out, stats) = decode_all(&bytes);
    assert_eq!(out.len(), 2);
    assert!(out[0].is_err());
    assert_eq!(out[1], Ok(hello()));
    assert_eq!(stats.bad_frames.total(), 1);
    // Too short to hold anything.
    let (out, stats) = decode_all(&[0x02, 0xB3, 0]);
    assert_eq!(out, std::vec![Err(FrameError::TooShort)]);
    assert_eq!(stats.bad_frames.too_short, 1);
}

#[test]
fn every_flipped_bit_is_caught() {
    let good = frame(&tick());
    let mut codes = Vec::new();
    let mut at = 0;
    while at < good.len() - 1 {
        codes.push(at);
        at += good[at] as usize;
    }
    for i in 0..good.len() - 1 {
        for bit in 0..8 {
            let mut bad = good.clone();
            bad[i] ^= 1 << bit;
            let (out, stats) = decode_all(&bad);
            assert_eq!(stats.frames_ok, 0, "byte {i} bit {bit}: {out:?}");
            assert!(stats.bad_frames.total() >= 1);
            if bad[i] != 0 && !codes.contains(&i) {
                // A data byte changed and the stuffing still adds up: the CRC tells.
                assert_eq!(stats.bad_frames.bad_crc, 1, "byte {i} bit {bit}: {stats:?}");
                assert_eq!(stats.bad_frames.total(), 1);
            }
        }
    }
}

#[test]
fn wrong_version_and_bad_body_are_told_apart() {
    // Layouts 1 to 5's health frames: older firmwares'.
    for old in [
        std::vec![0xB1, 3, 0, 0, 0, 0, 0, 0, 0, 0, 0],
        std::vec![0xB2, 3, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0],
        std::vec![0xB3, 3, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0],
        std::vec![0xB4, 3, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0],
        std::vec![0xB5, 3, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0],
    ] {
        assert_eq!(
            decode_all(&sealed(&old)).0,
            std::vec![Err(FrameError::Version)]
        );
    }

    for raw in [
        std::vec![0xBA, 9],                                        // no such variant
        std::vec![0xBA, 3, 0, 0, 0, 0, 0, 0, 0, 0, 0],             // health cut short
        std::vec![0xBA, 3, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 7], // a byte left over
        std::vec![0xBA, 2, 0, 0, 0x81, 0x01],                      // 129 cells announced
        std::vec![0xBA, 4, 1, 0, 0, 0, 0, 0],                      // filter cut short
        std::vec![0xBA, 5, 1, 2, 3, 0, 0, 0],                      // inputs cut short
        std::vec![0xBA, 5, 1, 2, 3, 2],                            // flow option byte 2
    ] {
        assert_eq!(
            decode_all(&sealed(&raw)).0,
            std::vec![Err(FrameError::Body)]
        );
    }
}

#[test]
fn overlong_frame_is_dropped_and_the_next_decodes() {
    let mut bytes = std::vec![0x42; MAX_FRAME_LEN * 3];
    bytes.push(0);
    bytes.extend(frame(&health()));
    let (out, stats) = decode_all(&bytes);
    assert_eq!(out, std::vec![Err(FrameError::Overlong), Ok(health())]);
    assert_eq!(stats.bad_frames.overlong, 1);
    // Exactly the longest legal frame still fits.
    let m = worst_inputs();
    let bytes = frame(&m);
    assert_eq!(bytes.len(), MAX_FRAME_LEN);
    assert_eq!(decode_all(&bytes).0, std::vec![Ok(m)]);
}

fn seed_map() -> GridMap<46, 46> {
    let mut map = GridMap::new(world::shipped::seed_robot().config.geometry, Evidence::SEED);
    for i in 0..46 {
        map.add(i, i, 19);
        map.add(45 - i, i, -19);
        map.add(i, 0, 125);
    }
    map
}

#[test]
fn a_sweep_covers_the_map_in_whole_rows() {
    let map = seed_map();
    let mut s = Streamer::new(Schedule::DEFAULT, FW, Localiser::Filter);
    let mut rebuilt = [[0i8; 46]; 46];
    let scale = CellScale::new(map.evidence());
    for i in 0..23 {
        let rows = s.next_map_rows(&map).expect("a chunk");
        assert_eq!((rows.first_row, rows.first_column), (2 * i, 0));
        assert_eq!(rows.cells.len(), 92);
        for (k, &c) in rows.cells.as_slice().iter().enumerate() {
            rebuilt[rows.first_row as usize + k / 46][k % 46] = c;
        }
    }
    assert_eq!(s.next_map_rows(&map).map(|r| r.first_row), Some(0));
    for (r, row) in rebuilt.iter().enumerate() {
        for (c, &q) in row.iter().enumerate() {
            assert_eq!(scale.belief(q), map.occupancy(c as i32, r as i32));
        }
    }
}

#[test]
fn wide_grids_go_in_row_pieces() {
    let geometry = GridGeometry {
        cell_mm: 50,
        origin_x_mm: 0,
        origin_y_mm: 0,
    };
    let map: GridMap<206, 3> = GridMap::new(geometry, Evidence::SEED);
    let mut s = Streamer::new(Schedule::DEFAULT, FW, Localiser::Filter);
    let mut seen = Vec::new();
    s.send_whole_map(&map, |m| {
        if let Message::MapRows(r) = m {
            seen.push((r.first_row, r.first_column, r.cells.len()));
        }
    });
    assert_eq!(
        seen,
        std::vec![
            (0, 0, 128),
            (0, 128, 78),
            (1, 0, 128),
            (1, 128, 78),
            (2, 0, 128),
            (2, 128, 78)
        ]
    );
    // Every frame of a sweep fits the longest frame.
    s.send_whole_map(&map, |m| assert!(frame(m).len() <= MAX_FRAME_LEN));
}

#[test]
fn the_schedule() {
    let map = seed_map();
    let mut s = Streamer::new(Schedule::DEFAULT, FW, Localiser::Filter);
    let report = StepReport {
        pose: Pose::from_mm_mdeg(1, 2, 3),
        fix: FixOutcome::Taken,
        stale: Staleness::default(),
        trust: Trust::default(),
        cells_written: 3,
        counters: Counters::default(),
        estimate: None,
    };
    let mut kinds = Vec::new();
    for t in 0..51u32 {
        s.tick(
            t * 100,
            &SensorFrame::empty(100_000),
            &report,
            TagCounters::default(),
            &map,
            &SensorHealth::default(),
            |m| kinds.push((t, core::mem::discriminant(m))),
        );
    }
    let count = |m: &Message| {
        kinds
            .iter()
            .filter(|(_, d)| *d == core::mem::discriminant(m))
            .count()
    };
    assert_eq!(count(&hello()), 2); // ticks 0 and 50
    assert_eq!(count(&tick()), 51);
    assert_eq!(
        count(&inputs()),
        51,
        "the default schedule records the inputs"
    );
    assert_eq!(count(&filter_state()), 0, "no estimate, no Filter");
    assert_eq!(count(&map_rows()), 51);
    assert_eq!(count(&health()), 6); // ticks 0, 10, ..., 50
    assert_eq!(kinds[0].1, core::mem::discriminant(&hello()));
}

#[test]
fn a_filter_follows_each_tick_with_an_estimate() {
    let map = seed_map();
    let mut s = Streamer::new(Schedule::DEFAULT, FW, Localiser::Filter);
    let Message::Filter(expected) = filter_state() else {
        unreachable!()
    };
    let report = StepReport {
        pose: Pose::from_mm_mdeg(1, 2, 3),
        fix: FixOutcome::NotAttempted,
        stale: Staleness::default(),
        trust: Trust::default(),
        cells_written: 3,
        counters: Counters {
            ticks: expected.tick,
            ..Counters::default()
        },
        estimate: Some(expected.estimate()),
    };
    let mut sent = Vec::new();
    s.tick(
        0,
        &SensorFrame::empty(100_000),
        &report,
        expected.tags,
        &map,
        &SensorHealth::default(),
        |m| sent.push(m.clone()),
    );
    let kinds: Vec<_> = sent.iter().map(core::mem::discriminant).collect();
    let d = core::mem::discriminant;
    assert_eq!(
        kinds,
        std::vec![
            d(&hello()),
            d(&inputs()),
            d(&tick()),
            d(&filter_state()),
            d(&map_rows()),
            d(&health())
        ]
    );
    assert_eq!(sent[3], Message::Filter(expected));
    assert_eq!(
        FilterState::new(&report, expected.tags).map(|f| f.estimate()),
        report.estimate
    );
    let Message::Hello(h) = &sent[0] else {
        unreachable!()
    };
    assert_eq!(h.localiser, Localiser::Filter);
    assert_eq!(h.boot, Boot::default());
}

#[test]
fn every_hello_carries_the_boot_it_was_given() {
    let boot = Boot {
        cause: ResetCause::Watchdog,
        resumed: true,
        resumes: 2,
    };
    let schedule = Schedule {
        hello_every_ticks: 2,
        ..Schedule::DEFAULT
    };
    let mut s = Streamer::new(schedule, FW, Localiser::Filter).with_boot(boot);
    let map = seed_map();
    let report = StepReport {
        pose: Pose::default(),
        fix: FixOutcome::NotAttempted,
        stale: Staleness::default(),
        cells_written: 0,
        counters: Counters::default(),
        estimate: None,
        trust: Trust::default(),
    };
    let mut hellos = std::vec::Vec::new();
    for _ in 0..4 {
        s.tick(
            0,
            &SensorFrame::empty(100_000),
            &report,
            TagCounters::default(),
            &map,
            &SensorHealth::default(),
            |m| {
                if let Message::Hello(h) = m {
                    hellos.push(h.boot);
                }
            },
        );
    }
    assert_eq!(hellos, std::vec![boot, boot]);
}

#[test]
fn tick_carries_the_report() {
    let report = StepReport {
        pose: Pose {
            x_um: -5,
            y_um: 7,
            heading: Angle::from_bits(0x8000_0000),
        },
        fix: FixOutcome::Rejected(FixRejection::Geometry),
        stale: Staleness {
            flow: true,
            gyro: false,
            depth: true,
        },
        trust: Trust {
            flow: Some(Doubt::Impossible),
            ..Trust::default()
        },
        cells_written: 9,
        counters: Counters {
            ticks: 4,
            ..Counters::default()
        },
        estimate: None,
    };
    let t = Tick::new(300, &report);
    assert_eq!(t.pose(), report.pose);
    assert_eq!(t.staleness(), report.stale);
    assert_eq!(t.trust(), report.trust);
    assert_eq!(t.tick, 4);
    let (out, _) = decode_all(&frame(&Message::Tick(t)));
    assert_eq!(out, std::vec![Ok(Message::Tick(t))]);
}

proptest! {
    #[test]
    fn arbitrary_filter_states_round_trip(
        cov in proptest::array::uniform6(any::<i64>()),
        cal in proptest::array::uniform3(any::<i32>()),
        tags in proptest::array::uniform7(any::<u32>()),
    ) {
        let f = FilterState {
            tick: tags[6],
            covariance: PoseCovariance {
                xx: cov[0], xy: cov[1], yy: cov[2], xh: cov[3], yh: cov[4], hh: cov[5],
            },
            calibration: Calibration {
                gyro_scale_ppm: cal[0], gyro_bias_mdps: cal[1], flow_scale_ppm: cal[2],
            },
            tags: TagCounters {
                used: tags[0], unknown_id: tags[1], behind: tags[2], too_far: tags[3],
                too_old: tags[4], gate: tags[5],
            },
        };
        let bytes = frame(&Message::Filter(f));
        prop_assert!(bytes.len() <= 116);
        prop_assert_eq!(decode_all(&bytes).0, std::vec![Ok(Message::Filter(f))]);
    }

    #[test]
    fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..2000)) {
        let mut d = StreamDecoder::new();
        let results: Vec<_> = d.feed(&bytes).collect();
        let stats = *d.stats();
        prop_assert_eq!(results.len() as u32, stats.frames_ok + stats.bad_frames.total());
    }

    #[test]
    fn arbitrary_ticks_round_trip(
        v in proptest::array::uniform17(any::<u32>()),
        w in proptest::array::uniform7(any::<u32>()),
        fix in 0u8..5,
        stale in any::<u8>(),
        doubts in any::<u16>(),
        noise in proptest::collection::vec(any::<u8>(), 0..300),
    ) {
        let t = Tick {
            tick: v[0], time_ms: v[1], x_um: v[2] as i32, y_um: v[3] as i32,
            heading_bits: v[4],
            fix: match fix {
                0 => FixOutcome::NotAttempted,
                1 => FixOutcome::Taken,
                2 => FixOutcome::Rejected(FixRejection::Geometry),
                3 => FixOutcome::Rejected(FixRejection::Gate),
                _ => FixOutcome::Rejected(FixRejection::TooOld),
            },
            stale,
            cells_written: v[5],
            doubts,
            counters: Counters {
                ticks: v[6], fixes_taken: v[7], fixes_rejected_geometry: v[8],
                fixes_rejected_gate: v[9], fixes_rejected_too_old: v[16], relocalisations: v[10], beams_mapped: v[11],
                beams_invalid: v[12], flow_stale: v[13], gyro_stale: v[14], depth_stale: v[15],
                gyro_doubted: w[0], flow_doubted: w[1], depth_doubted: w[2], scans_withheld: w[3],
                pictures_repeated: w[4], pictures_leapt: w[5], pictures_late: w[6],
            },
        };
        // Noise, a delimiter, then the frame: the frame always comes through.
        let mut bytes = noise;
        bytes.push(0);
        bytes.extend(frame(&Message::Tick(t)));
        let (out, _) = decode_all(&bytes);
        prop_assert_eq!(out.last().cloned(), Some(Ok(Message::Tick(t))));
    }

    #[test]
    fn arbitrary_inputs_round_trip(
        v in proptest::array::uniform13(any::<u32>()),
        present in proptest::array::uniform5(any::<bool>()),
        ranges in proptest::array::uniform8(proptest::option::of(any::<u16>())),
        tags in proptest::collection::vec((any::<u16>(), any::<i32>(), any::<u32>()), 0..=MAX_TAGS),
    ) {
        let mut detections = TagDetections::new();
        for (id, cx_centipx, distance_mm) in tags {
            let pushed = detections.push(TagDetection { id, cx_centipx, distance_mm });
            prop_assert!(pushed.is_ok(), "at most MAX_TAGS");
        }
        let m = Message::Inputs(Inputs {
            tick: v[0],
            time_ms: v[1],
            frame: SensorFrame {
                dt_us: v[2],
                flow: present[0].then_some(FlowDelta {
                    forward_counts: v[3] as i32,
                    right_counts: v[4] as i32,
                }),
                gyro: present[1].then_some(GyroRate { rate_mdps: v[5] as i32 }),
                depth: present[2].then_some(DepthScan { ranges_mm: ranges }),
                depth_age_us: v[6],
                depth_doubt: Doubt::from_code((v[6] % (Doubt::ALL.len() as u32 + 1)) as u8),
                tags: detections,
                tags_age_us: v[7],
                external_pose: present[3].then_some(Pose {
                    x_um: v[8] as i32,
                    y_um: v[9] as i32,
                    heading: Angle::from_bits(v[10]),
                }),
                commanded: present[4].then_some(DriveCommand {
                    speed_mm_s: v[11] as i32,
                    turn_mdps: v[12] as i32,
                }),
            },
        });
        let bytes = frame(&m);
        prop_assert!(bytes.len() <= MAX_FRAME_LEN);
        prop_assert_eq!(decode_all(&bytes).0, std::vec![Ok(m)]);
    }
}
