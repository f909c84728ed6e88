//! Arbitrary bytes into the telemetry decoder: it must never panic, every frame it ends is
//! counted once, and whatever decodes re-encodes to a frame that decodes to the same
//! message. Run with `cargo +nightly fuzz run telemetry` from `wire/`.
//! `tests/telemetry.rs` checks the first two under `cargo test` (proptest).
#![no_main]

use libfuzzer_sys::fuzz_target;
use wire::telemetry::{encode, StreamDecoder, MAX_FRAME_LEN};

fuzz_target!(|data: &[u8]| {
    let mut decoder = StreamDecoder::new();
    let mut ended = 0u32;
    for result in decoder.feed(data) {
        ended += 1;
        if let Ok(message) = result {
            let mut frame = [0u8; MAX_FRAME_LEN];
            let n = encode(&message, &mut frame).expect("a decoded message re-encodes");
            let mut again = StreamDecoder::new();
            let back: Vec<_> = again.feed(&frame[..n]).collect();
            assert_eq!(back, vec![Ok(message)]);
        }
    }
    let stats = decoder.stats();
    assert_eq!(ended, stats.frames_ok + stats.bad_frames.total());
});
