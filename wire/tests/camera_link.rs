//! Camera frame byte fixtures: parse, emit, round trip, bad input.

use wire::camera_link::{
    encode_frame, FrameDecoder, FrameRepr, Packet, TagDetection, WireError, MAX_ENCODED_LEN,
};
use wire::framing::{cobs_encode, cobs_max_len, crc16};

/// Version 1, counter 0x0102, two detections:
/// tag 5 at (16000, 12000) cp, 1500 mm; tag 256 at (0, 24000) cp, 0 mm.
/// CRC computed independently (Python) = 0x1B95, sent little-endian.
const FRAME: [u8; 22] = [
    0x01, 0x02, 0x01, 0x02, 0x05, 0x00, 0x80, 0x3E, 0xE0, 0x2E, 0xDC, 0x05, 0x00, 0x01, 0x00, 0x00,
    0xC0, 0x5D, 0x00, 0x00, 0x95, 0x1B,
];

/// [`FRAME`] COBS-encoded (independently, Python), without delimiter.
const FRAME_COBS: [u8; 23] = [
    0x06, 0x01, 0x02, 0x01, 0x02, 0x05, 0x07, 0x80, 0x3E, 0xE0, 0x2E, 0xDC, 0x05, 0x02, 0x01, 0x01,
    0x03, 0xC0, 0x5D, 0x01, 0x03, 0x95, 0x1B,
];

fn fixture_repr() -> FrameRepr {
    let mut repr = FrameRepr::new(0x0102);
    repr.push(TagDetection::new(5, 16_000, 12_000, 1500).unwrap())
        .unwrap();
    repr.push(TagDetection::new(256, 0, 24_000, 0).unwrap())
        .unwrap();
    repr
}

/// Encoded frame with delimiter, from raw (possibly invalid) frame bytes.
fn stuffed(raw: &[u8]) -> Vec<u8> {
    let mut out = vec![0u8; cobs_max_len(raw.len())];
    let n = cobs_encode(raw, &mut out).unwrap();
    out.truncate(n);
    out.push(0);
    out
}

/// A raw frame with a correct CRC over `body`.
fn with_crc(body: &[u8]) -> Vec<u8> {
    let mut v = body.to_vec();
    v.extend(crc16(body).to_le_bytes());
    v
}

#[test]
fn parse_fixture() {
    let packet = Packet::new_checked(&FRAME[..]).unwrap();
    assert_eq!(packet.version(), 1);
    assert_eq!(packet.frame_counter(), 0x0102);
    assert_eq!(packet.detection_count(), 2);
    assert_eq!(packet.crc(), 0x1B95);
    let repr = FrameRepr::parse(&packet).unwrap();
    assert_eq!(repr, fixture_repr());
    let d = repr.detections()[0];
    assert_eq!(
        (d.tag_id(), d.cx_centipx(), d.cy_centipx(), d.distance_mm()),
        (5, 16_000, 12_000, 1500)
    );
}

#[test]
fn emit_fixture() {
    let repr = fixture_repr();
    assert_eq!(repr.buffer_len(), FRAME.len());
    let mut buf = [0xAAu8; 22];
    repr.emit(&mut Packet::new_unchecked(&mut buf[..]));
    assert_eq!(buf, FRAME);
}

#[test]
fn encode_fixture_and_round_trip() {
    let mut out = [0u8; MAX_ENCODED_LEN + 1];
    let n = encode_frame(&fixture_repr(), &mut out).unwrap();
    assert_eq!(&out[..n - 1], &FRAME_COBS[..]);
    assert_eq!(out[n - 1], 0);
    let mut decoder = FrameDecoder::new();
    let frames: Vec<_> = decoder.feed(&out[..n]).collect();
    assert_eq!(frames, vec![fixture_repr()]);
    assert_eq!(decoder.stats().frames_ok, 1);
    assert_eq!(decoder.stats().bad_frames.total(), 0);
}

#[test]
fn empty_and_full_frames_round_trip() {
    let mut full = FrameRepr::new(65535);
    for i in 0..8 {
        full.push(TagDetection::new(i, 32_000, 24_000, u16::MAX).unwrap())
            .unwrap();
    }
    assert_eq!(
        full.push(TagDetection::default()),
        Err(WireError::TooManyDetections)
    );
    for repr in [FrameRepr::new(0), full] {
        let mut out = [0u8; MAX_ENCODED_LEN + 1];
        let n = encode_frame(&repr, &mut out).unwrap();
        let mut decoder = FrameDecoder::new();
        assert_eq!(decoder.feed(&out[..n]).collect::<Vec<_>>(), vec![repr]);
    }
}

/// A frame's length on the line is what the encoder writes, for every count of tags and
/// for fields with zero bytes (COBS stuffs them) and without.
#[test]
fn a_frames_wire_length_is_what_is_encoded() {
    for fill in [0u16, 0x0101, u16::MAX] {
        let mut repr = FrameRepr::new(fill);
        for i in 0..=8u16 {
            let mut out = [0u8; MAX_ENCODED_LEN + 1];
            let n = encode_frame(&repr, &mut out).unwrap();
            assert_eq!(repr.wire_len(), n, "{i} tags, fields {fill:#06x}");
            if i < 8 {
                let (cx, cy) = (fill.min(32_000), fill.min(24_000));
                repr.push(TagDetection::new(fill, cx, cy, fill).unwrap())
                    .unwrap();
            }
        }
    }
}

#[test]
fn encode_into_short_buffer_is_error() {
    let mut out = [0u8; 10];
    assert_eq!(
        encode_frame(&fixture_repr(), &mut out),
        Err(WireError::BadLength)
    );
    // Room for the COBS bytes but not the delimiter.
    let mut out = [0u8; 23];
    assert_eq!(
        encode_frame(&fixture_repr(), &mut out),
        Err(WireError::BadLength)
    );
}

#[test]
fn impossible_lengths() {
    // Shorter than header + CRC.
    for len in 0..6 {
        assert_eq!(
            Packet::new_checked(&FRAME[..len]).unwrap_err(),
            WireError::Truncated
        );
    }
    // Count says two detections, bytes for one.
    assert_eq!(
        Packet::new_checked(&FRAME[..14]).unwrap_err(),
        WireError::Truncated
    );
    assert_eq!(
        Packet::new_checked(&FRAME[..21]).unwrap_err(),
        WireError::Truncated
    );
    // One trailing byte.
    let mut long = FRAME.to_vec();
    long.push(0);
    assert_eq!(
        Packet::new_checked(&long[..]).unwrap_err(),
        WireError::BadLength
    );
    // Parse re-checks the length even on an unchecked packet.
    assert_eq!(
        FrameRepr::parse(&Packet::new_unchecked(&FRAME[..10])),
        Err(WireError::Truncated)
    );
}

#[test]
fn too_many_detections() {
    let mut body = vec![1, 0, 0, 9];
    body.extend([0u8; 9 * 8]);
    let raw = with_crc(&body);
    assert_eq!(
        Packet::new_checked(&raw[..]).unwrap_err(),
        WireError::TooManyDetections
    );
    // On the stream, a full 9-detection frame is longer than any valid
    // frame and is dropped as overlong; a short one claiming 9 is
    // classified by its count.
    let mut decoder = FrameDecoder::new();
    assert_eq!(decoder.feed(&stuffed(&raw)).count(), 0);
    assert_eq!(decoder.stats().bad_frames.overlong, 1);
    assert_eq!(decoder.feed(&stuffed(&with_crc(&[1, 0, 0, 9]))).count(), 0);
    // Too many detections is a bad body.
    assert_eq!(decoder.stats().bad_frames.bad_body, 1);
    assert_eq!(decoder.stats().bad_frames.total(), 2);
}

#[test]
fn bad_crc_version_and_range() {
    let mut bad_crc = FRAME;
    bad_crc[5] ^= 0x01;
    let packet = Packet::new_checked(&bad_crc[..]).unwrap();
    assert!(!packet.verify_crc());
    assert_eq!(FrameRepr::parse(&packet), Err(WireError::BadCrc));

    let mut body = FRAME[..20].to_vec();
    body[0] = 2;
    let raw = with_crc(&body);
    assert_eq!(
        FrameRepr::parse(&Packet::new_checked(&raw[..]).unwrap()),
        Err(WireError::BadVersion)
    );

    // cx = 32001 centipixels, valid CRC.
    let mut body = FRAME[..20].to_vec();
    body[6..8].copy_from_slice(&32_001u16.to_le_bytes());
    let raw = with_crc(&body);
    assert_eq!(
        FrameRepr::parse(&Packet::new_checked(&raw[..]).unwrap()),
        Err(WireError::ValueOutOfRange)
    );
    assert_eq!(
        TagDetection::new(1, 0, 24_001, 0),
        Err(WireError::ValueOutOfRange)
    );
}

#[test]
fn garbage_then_good_frame() {
    let mut stream = vec![0x13, 0x37, 0xFF, 0x42, 0x00];
    stream.extend(FRAME_COBS);
    stream.push(0);
    let mut decoder = FrameDecoder::new();
    let frames: Vec<_> = decoder.feed(&stream).collect();
    assert_eq!(frames, vec![fixture_repr()]);
    let stats = decoder.stats();
    assert_eq!(stats.frames_ok, 1);
    assert_eq!(stats.bad_frames.total(), 1);
}

#[test]
fn mid_frame_start_resynchronises() {
    // Receiver powered up halfway through a frame.
    let mut stream = FRAME_COBS[9..].to_vec();
    stream.push(0);
    stream.extend(FRAME_COBS);
    stream.push(0);
    let mut decoder = FrameDecoder::new();
    assert_eq!(decoder.feed(&stream).count(), 1);
    assert_eq!(decoder.stats().bad_frames.total(), 1);
}

#[test]
fn truncated_and_corrupt_frames_are_counted_by_kind() {
    let mut stream = stuffed(&FRAME[..14]); // Truncated
    stream.extend(stuffed(&{
        let mut f = FRAME;
        f[21] ^= 0xFF;
        f
    })); // BadCrc
    stream.extend([0x09, 0x01, 0x00]); // BadCobs: code runs past the end
    stream.extend([0x00, 0x00]); // empty frames: ignored
    let mut decoder = FrameDecoder::new();
    assert_eq!(decoder.feed(&stream).count(), 0);
    let s = decoder.stats().bad_frames;
    // A truncated frame counts as too short.
    assert_eq!((s.too_short, s.bad_crc, s.bad_cobs), (1, 1, 1));
    assert_eq!(s.total(), 3);
}

#[test]
fn overlong_input_is_dropped_and_counted() {
    let mut stream = vec![0x55u8; 1000];
    stream.push(0);
    stream.extend(FRAME_COBS);
    stream.push(0);
    let mut decoder = FrameDecoder::new();
    assert_eq!(
        decoder.feed(&stream).collect::<Vec<_>>(),
        vec![fixture_repr()]
    );
    assert_eq!(decoder.stats().bad_frames.overlong, 1);
    assert_eq!(decoder.stats().bad_frames.total(), 1);
}

#[test]
fn frames_split_across_feeds() {
    let mut stream = FRAME_COBS.to_vec();
    stream.push(0);
    stream.extend(FRAME_COBS);
    stream.push(0);
    for split in 0..=stream.len() {
        let mut decoder = FrameDecoder::new();
        let mut got: Vec<_> = decoder.feed(&stream[..split]).collect();
        got.extend(decoder.feed(&stream[split..]));
        assert_eq!(got.len(), 2, "split at {split}");
    }
    // Byte at a time.
    let mut decoder = FrameDecoder::new();
    let n = stream.iter().filter_map(|&b| decoder.push(b)).count();
    assert_eq!(n, 2);
}

/// The OpenMV script must agree with this crate on the link's constants.
#[test]
fn openmv_script_matches_link_constants() {
    let script = include_str!("../../drivers/camera/openmv_tags.py");
    for needle in [
        "VERSION = 1",
        "MAX_DETECTIONS = 8",
        "UART(3, 115200",
        "sensor.QVGA",
        "sensor.GRAYSCALE",
        "image.TAG36H11",
        "FOCAL_PX = 92.4",
        "0x1021",
        "0xFFFF",
        "struct.pack(\"<BHB\"",
        "struct.pack(\"<HHHH\"",
        "struct.pack(\"<H\"",
        "b\"\\x00\"",
    ] {
        assert!(script.contains(needle), "openmv_tags.py lacks {needle}");
    }
}
