//! Wall-clock time of each stage of a long command, for CI's log.

use std::time::Instant;

/// Runs `f` and prints `stage NAME: N s` when it returns, whether it failed or not.
pub fn timed<R>(name: &str, f: impl FnOnce() -> R) -> R {
    let started = Instant::now();
    let result = f();
    println!("stage {name}: {} s", started.elapsed().as_secs());
    result
}
