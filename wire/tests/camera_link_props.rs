//! The fuzz target's properties, run by `cargo test` through proptest.

use proptest::prelude::*;
use wire::camera_link::{
    encode_frame, FrameDecoder, FrameRepr, Packet, TagDetection, MAX_DETECTIONS, MAX_ENCODED_LEN,
};

fn detection() -> impl Strategy<Value = TagDetection> {
    (any::<u16>(), 0..=32_000u16, 0..=24_000u16, any::<u16>())
        .prop_map(|(id, cx, cy, d)| TagDetection::new(id, cx, cy, d).unwrap())
}

fn frame() -> impl Strategy<Value = FrameRepr> {
    (
        any::<u16>(),
        proptest::collection::vec(detection(), 0..=MAX_DETECTIONS),
    )
        .prop_map(|(counter, dets)| {
            let mut f = FrameRepr::new(counter);
            for d in dets {
                f.push(d).unwrap();
            }
            f
        })
}

proptest! {
    /// Whatever parses re-emits to the same bytes: the format has no slack.
    #[test]
    fn emit_parse_round_trips(bytes in proptest::collection::vec(any::<u8>(), 0..80)) {
        if let Ok(packet) = Packet::new_checked(&bytes[..]) {
            if let Ok(repr) = FrameRepr::parse(&packet) {
                let mut out = vec![0u8; repr.buffer_len()];
                repr.emit(&mut Packet::new_unchecked(&mut out[..]));
                prop_assert_eq!(out, bytes);
            }
        }
    }

    /// Same, from valid frames with at most one corrupted byte, so the
    /// parse-success path is exercised, and a valid frame always parses.
    #[test]
    fn emit_parse_round_trips_near_valid(
        repr in frame(),
        flip in proptest::option::of((any::<prop::sample::Index>(), 1..=255u8)),
    ) {
        let mut bytes = vec![0u8; repr.buffer_len()];
        repr.emit(&mut Packet::new_unchecked(&mut bytes[..]));
        if let Some((at, mask)) = flip {
            let i = at.index(bytes.len());
            bytes[i] ^= mask;
        }
        let parsed = Packet::new_checked(&bytes[..]).and_then(|p| FrameRepr::parse(&p));
        match parsed {
            Ok(parsed) => {
                let mut out = vec![0u8; parsed.buffer_len()];
                parsed.emit(&mut Packet::new_unchecked(&mut out[..]));
                prop_assert_eq!(out, bytes);
                if flip.is_none() {
                    prop_assert_eq!(parsed, repr);
                }
            }
            // A single corrupted byte is always caught (CRC-16 detects every
            // single-byte error), so only flipped frames may fail.
            Err(_) => prop_assert!(flip.is_some()),
        }
    }

    /// The decoder never panics, and cannot yield or reject more frames
    /// than there were delimiters.
    #[test]
    fn decoder_survives_anything(bytes in proptest::collection::vec(any::<u8>(), 0..600)) {
        let mut decoder = FrameDecoder::new();
        let frames = decoder.feed(&bytes).count() as u32;
        let delimiters = bytes.iter().filter(|&&b| b == 0).count() as u32;
        let stats = decoder.stats();
        prop_assert_eq!(frames, stats.frames_ok);
        prop_assert!(stats.frames_ok + stats.bad_frames.total() <= delimiters);
    }

    /// Any valid frame survives encoding and arrives intact after any
    /// garbage, once a delimiter has passed.
    #[test]
    fn frames_survive_garbage(
        repr in frame(),
        garbage in proptest::collection::vec(any::<u8>(), 0..200),
    ) {
        let mut stream = garbage;
        stream.push(0);
        let mut out = [0u8; MAX_ENCODED_LEN + 1];
        let n = encode_frame(&repr, &mut out).unwrap();
        stream.extend_from_slice(&out[..n]);
        let mut decoder = FrameDecoder::new();
        let frames: Vec<_> = decoder.feed(&stream).collect();
        prop_assert_eq!(frames.last(), Some(&repr));
    }
}
