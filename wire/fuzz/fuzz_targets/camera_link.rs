//! Arbitrary bytes into the camera link: the packet parser and the stream
//! decoder must never panic, and whatever parses must re-emit to the same
//! bytes. Run with `cargo +nightly fuzz run camera_link` from `wire/`.
//! `tests/camera_link_props.rs` checks the same properties under `cargo test`.
#![no_main]

use wire::camera_link::{FrameDecoder, FrameRepr, Packet, MAX_FRAME_LEN};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(packet) = Packet::new_checked(data) {
        if let Ok(repr) = FrameRepr::parse(&packet) {
            let mut out = [0u8; MAX_FRAME_LEN];
            let len = repr.buffer_len();
            repr.emit(&mut Packet::new_unchecked(&mut out[..len]));
            assert_eq!(&out[..len], data);
        }
    }

    let mut decoder = FrameDecoder::new();
    let frames = decoder.feed(data).count() as u32;
    let delimiters = data.iter().filter(|&&b| b == 0).count() as u32;
    let stats = decoder.stats();
    assert_eq!(frames, stats.frames_ok);
    assert!(stats.frames_ok + stats.bad_frames.total() <= delimiters);
});
