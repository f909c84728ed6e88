//! RAM that a watchdog reset leaves alone: the live SLAM state (map, pose, covariance,
//! learned calibration, pose history, counters) and the route's progress, so that after
//! a watchdog reset the robot carries on where it was instead of at the start with an
//! empty map.
//!
//! # Where
//!
//! A watchdog reset restarts the processors and peripherals but leaves SRAM as it was
//! (RP2040 datasheet, 4.7 "Watchdog" and 2.13 "Power-On State Machine": the watchdog
//! restarts the PSM stages it is told to, and none of them clears SRAM); cortex-m-rt's
//! start-up fills `.data` and zeroes `.bss` and nothing else. The block lives in its own
//! `.retained` section (`memory.x`), below `.data` and `.bss` and out of the top 8 KB of
//! SRAM, which the boot ROM uses at every boot (2.8.1: boot stage 2 is copied to
//! 0x20041f00, and its stack is above it).
//!
//! # Trusted only when whole
//!
//! The state is the live one, not a copy, so saving costs no copying: the tick marks the
//! block open before `step` changes it, and closes it after with a checksum over all of
//! it (and the route's progress of that moment). At start-up it is taken up only if the
//! watchdog timed out, the block was closed, its checksum holds, it was written by this
//! very image (a hash of the flash: another build may lay the state out differently) for
//! this world ([`world::WORLD_ID`]), and the resumes before it did not keep failing. A
//! reset in the middle of a tick leaves the block open: the robot starts fresh, since a
//! step cut short leaves half a map update and maybe the cause of the hang.
#![allow(unsafe_code)]

use core::cell::UnsafeCell;
use core::mem::{offset_of, size_of, MaybeUninit};
use core::sync::atomic::{compiler_fence, Ordering};

use portable_atomic::AtomicBool;
use wire::telemetry::{Boot, ResetCause};

use crate::world::{self, WorldSlam};

/// First word of a block some run of this firmware wrote.
const MAGIC: u32 = 0xB06B_0751;
/// [`Block::closed`] when the state is whole; anything else means a tick was cut short.
const CLOSED: u32 = 0xC105_ED00;
/// Resumes in a row, each reset again before [`PROVEN_TICKS`], after which the state is
/// suspected of causing the resets and dropped.
const MAX_UNPROVEN_RESUMES: u32 = 2;
/// Ticks a resumed run must complete before its state is trusted again.
const PROVEN_TICKS: u32 = 50;

/// Why the saved state was not taken up.
#[derive(Clone, Copy, PartialEq, Eq, defmt::Format)]
pub enum Fresh {
    /// Not a watchdog timeout: power-on, the RUN pin, a debugger or a deliberate reboot.
    NotAWatchdogReset,
    /// Nothing this firmware wrote (no magic).
    Empty,
    /// Written by another firmware image.
    OtherImage,
    /// Written by this firmware's code for another world.
    OtherWorld,
    /// The reset came in the middle of a tick.
    CutShort,
    /// The checksum does not hold: something else wrote into it.
    Corrupt,
    /// The state was resumed and the watchdog fired again soon after, more than once.
    KeepsFailing,
}

/// Where the route was at the last closed tick: the leg, and how far into it (a turn's
/// millidegrees turned or a drive's milliseconds driven), packed as `leg << 24 | done`.
#[derive(Clone, Copy, PartialEq, Eq, Default, defmt::Format)]
pub struct RoutePoint(pub u32);

impl RoutePoint {
    /// `done` (saturated to 24 bits) into leg `leg` (saturated to 8 bits).
    pub fn new(leg: usize, done: u32) -> RoutePoint {
        let leg = u32::try_from(leg).unwrap_or(u32::MAX).min(0xFF);
        RoutePoint(leg << 24 | done.min(0xFF_FFFF))
    }

    /// The leg's index in the route.
    pub fn leg(self) -> usize {
        (self.0 >> 24) as usize
    }

    /// How far into the leg: millidegrees turned or milliseconds driven.
    pub fn done(self) -> u32 {
        self.0 & 0xFF_FFFF
    }
}

// A route longer than a `RoutePoint` can count would resume at the wrong leg.
const _: () = assert!(world::ROUTE.len() < 0xFF);

/// The retained block: a header, the route's progress and the SLAM state.
#[repr(C)]
struct Block {
    magic: u32,
    /// Hash of the firmware image that wrote it.
    image: u32,
    /// [`world::WORLD_ID`] of the firmware that wrote it.
    world: u32,
    /// [`CLOSED`] between ticks.
    closed: u32,
    /// Over everything from [`Block::resumes`] on, at the last close.
    checksum: u32,
    /// Resumes since the last fresh start.
    resumes: u32,
    /// Resumes in a row that were reset again before [`PROVEN_TICKS`].
    unproven: u32,
    /// Where the map's cells lie in the block, in bytes from its start, and how many
    /// there are: for a debugger (and the emulator's checks) to read the map. A cell is
    /// one byte of log odds (the emulator's `retained.mjs` reads it so).
    map_at: u32,
    map_cells: u32,
    /// Where the route was at the last close.
    route: u32,
    /// The run's time at the last close, milliseconds since it started fresh.
    run_ms: u32,
    slam: MaybeUninit<WorldSlam>,
}

/// The first word the checksum covers, and how many.
const SUMMED_FROM: usize = offset_of!(Block, resumes);
const SUMMED_WORDS: usize = (size_of::<Block>() - SUMMED_FROM) / 4;
const _: () = assert!(size_of::<slam_core::LogOdds>() == 1);
const _: () = assert!(SUMMED_FROM.is_multiple_of(4) && size_of::<Block>().is_multiple_of(4));

/// The block, in the section start-up leaves alone.
struct Retained(UnsafeCell<MaybeUninit<Block>>);

// SAFETY: only reached through the one `&'static mut` that `open` hands out once.
unsafe impl Sync for Retained {}

#[link_section = ".retained.bugbot"]
static RETAINED: Retained = Retained(UnsafeCell::new(MaybeUninit::uninit()));

/// Set by the first [`open`]: the block has one owner.
static OPENED: AtomicBool = AtomicBool::new(false);

/// The retained state, owned by the SLAM loop: the core to step, and the open/close
/// around each tick that makes it safe to resume.
pub struct Saved {
    /// The block, reached only through this pointer: its header as words, the state as
    /// a `WorldSlam` once it is whole.
    block: *mut Block,
    /// Ticks closed since start-up.
    closes: u32,
}

/// How the run started, and where the route resumes.
pub struct Start {
    /// For the telemetry's `Hello`.
    pub boot: Boot,
    /// Why the saved state was dropped, if it was.
    pub fresh: Option<Fresh>,
    /// Where the route resumes (the start when fresh).
    pub route: RoutePoint,
    /// The run's time at the last close before the reset, milliseconds (0 when fresh).
    pub run_ms: u32,
}

/// A header word of the block at `block`.
macro_rules! word {
    ($block:expr, $field:ident) => {
        // SAFETY: an aligned word inside the block, which `Saved` or `open` owns; any
        // value is a valid `u32`.
        unsafe { core::ptr::addr_of_mut!((*$block).$field) }
    };
}

/// Reads a header word.
fn get(p: *mut u32) -> u32 {
    // SAFETY: `p` comes from `word!`.
    unsafe { p.read_volatile() }
}

/// Writes a header word.
fn set(p: *mut u32, value: u32) {
    // SAFETY: `p` comes from `word!`.
    unsafe { p.write_volatile(value) }
}

/// Takes up the retained state after a reset caused by `cause`, or starts it afresh with
/// `fresh` (which builds a new core at the world's start where it is given it, in the
/// block itself). Call once; a second call panics.
pub fn open(
    cause: ResetCause,
    fresh: impl FnOnce(&mut MaybeUninit<WorldSlam>),
) -> (Saved, Start) {
    if OPENED.swap(true, portable_atomic::Ordering::AcqRel) {
        defmt::panic!("retained: opened twice");
    }
    // Reached only here, once (`OPENED`), and then only through `Saved`.
    let block = RETAINED.0.get().cast::<Block>();
    let verdict = judge(block, cause, image_hash);
    let (route, run_ms) = match verdict {
        Ok(()) => {
            set(
                word!(block, resumes),
                get(word!(block, resumes)).saturating_add(1),
            );
            set(
                word!(block, unproven),
                get(word!(block, unproven)).saturating_add(1),
            );
            (
                RoutePoint(get(word!(block, route))),
                get(word!(block, run_ms)),
            )
        }
        Err(_) => {
            // SAFETY: the state's own field of the block, reached only here and, once
            // written, through `Saved`; any bytes are a valid `MaybeUninit`.
            fresh(unsafe { &mut *core::ptr::addr_of_mut!((*block).slam) });
            set(word!(block, magic), MAGIC);
            set(word!(block, image), image_hash());
            set(word!(block, world), world::WORLD_ID);
            set(word!(block, resumes), 0);
            set(word!(block, unproven), 0);
            (RoutePoint::default(), 0)
        }
    };
    let boot = Boot {
        cause,
        resumed: verdict.is_ok(),
        resumes: u16::try_from(get(word!(block, resumes))).unwrap_or(u16::MAX),
    };
    let mut saved = Saved { block, closes: 0 };
    let map = saved.slam().map().rows().as_ptr() as usize;
    set(word!(block, map_at), (map - block as usize) as u32);
    set(
        word!(block, map_cells),
        (world::GRID_COLUMNS * world::GRID_ROWS) as u32,
    );
    saved.close(route, run_ms);
    (
        saved,
        Start {
            boot,
            fresh: verdict.err(),
            route,
            run_ms,
        },
    )
}

/// Whether the block may be taken up; `image` hashes this firmware's image.
fn judge(block: *mut Block, cause: ResetCause, image: fn() -> u32) -> Result<(), Fresh> {
    if cause != ResetCause::Watchdog {
        return Err(Fresh::NotAWatchdogReset);
    }
    if get(word!(block, magic)) != MAGIC {
        return Err(Fresh::Empty);
    }
    if get(word!(block, image)) != image() {
        return Err(Fresh::OtherImage);
    }
    if get(word!(block, world)) != world::WORLD_ID {
        return Err(Fresh::OtherWorld);
    }
    if get(word!(block, closed)) != CLOSED {
        return Err(Fresh::CutShort);
    }
    if get(word!(block, checksum)) != checksum(block) {
        return Err(Fresh::Corrupt);
    }
    if get(word!(block, unproven)) >= MAX_UNPROVEN_RESUMES {
        return Err(Fresh::KeepsFailing);
    }
    Ok(())
}

impl Saved {
    /// The core. Only between [`Saved::open_tick`] and [`Saved::close`] may it change.
    pub fn slam(&mut self) -> &mut WorldSlam {
        // SAFETY: whole since `open` (written or checked), and reached only through this
        // `&mut self` for as long as the borrow lasts.
        unsafe { &mut *core::ptr::addr_of_mut!((*self.block).slam).cast::<WorldSlam>() }
    }

    /// Marks the state as being changed: a reset from here to [`Saved::close`] drops it.
    pub fn open_tick(&mut self) {
        set(word!(self.block, closed), 0);
        compiler_fence(Ordering::SeqCst);
    }

    /// Marks the state whole again, with the route at `route` and the run's clock at
    /// `run_ms`: what a reset from here to the next [`Saved::open_tick`] resumes from.
    pub fn close(&mut self, route: RoutePoint, run_ms: u32) {
        compiler_fence(Ordering::SeqCst);
        self.closes = self.closes.wrapping_add(1);
        if self.closes == PROVEN_TICKS {
            set(word!(self.block, unproven), 0);
        }
        set(word!(self.block, route), route.0);
        set(word!(self.block, run_ms), run_ms);
        set(word!(self.block, checksum), checksum(self.block));
        compiler_fence(Ordering::SeqCst);
        set(word!(self.block, closed), CLOSED);
    }
}

/// Fletcher-style sum of the block's words from [`Block::resumes`] on: two running sums,
/// so that a changed, swapped or zeroed word shows.
fn checksum(block: *mut Block) -> u32 {
    // SAFETY: the words lie inside the block; padding inside the state is read as it lies
    // (it changes only when the state does, between an open and a close).
    let words = unsafe { block.cast::<u8>().add(SUMMED_FROM).cast::<u32>() };
    sum_words(words, SUMMED_WORDS)
}

/// The firmware image in flash, from its start to the end of `.data`'s initial values.
fn image_hash() -> u32 {
    extern "C" {
        static __sidata: u32;
        static __sdata: u32;
        static __edata: u32;
    }
    const FLASH_START: usize = 0x1000_0000;
    // Only the linker symbols' addresses are taken.
    let (sidata, sdata, edata) = {
        (
            core::ptr::addr_of!(__sidata) as usize,
            core::ptr::addr_of!(__sdata) as usize,
            core::ptr::addr_of!(__edata) as usize,
        )
    };
    let end = sidata + edata.saturating_sub(sdata);
    sum_words(FLASH_START as *const u32, (end - FLASH_START) / 4)
}

/// The sum of `n` words from `words`, each read as it lies in memory.
fn sum_words(words: *const u32, n: usize) -> u32 {
    let (mut a, mut b) = (1u32, 0u32);
    for i in 0..n {
        // SAFETY: the caller's `n` words are readable memory.
        let w = unsafe { words.add(i).read_volatile() };
        a = a.wrapping_add(w);
        b = b.wrapping_add(a);
    }
    a ^ b.rotate_left(16)
}
