//! What BugBot's bytes are on its serial links: the framing every link shares, the tag
//! camera's frames and the telemetry stream.
//!
//! Kept apart from `slam-core`, the way smoltcp keeps `wire/` apart from its stack: the
//! core decides what to do, this crate says how it looks on a wire. It depends on the core
//! (a [`telemetry::Tick`] is built from a step's report), never the other way round.
//!
//! | module | what |
//! | --- | --- |
//! | [`framing`] | COBS stuffing, CRC-16, the frame collector, the decoders' statistics |
//! | [`camera_link`] | the OpenMV co-processor's tag frames: `Packet`, `FrameRepr`, decoder |
//! | [`telemetry`] | the robot's telemetry: messages, the stream encoder, the decoder |
//!
//! `no_std`, no allocator, no floating point; nothing here panics on any input. Enable
//! the `defmt` feature for `defmt::Format` on every public type.
#![cfg_attr(not(any(test, feature = "std")), no_std)]
#![deny(unsafe_code)]
#![warn(missing_docs)]

pub mod camera_link;
pub mod framing;
pub mod telemetry;
