//! Files from outside, read whole only up to a bound: a file far longer than any the tool
//! writes (or a device that never ends, like `/dev/zero`) is refused after that many bytes
//! instead of filling the memory.

use std::io::Read as _;
use std::path::Path;

/// Longest truth file or recorded stream, bytes: an hour of the emulator's truth is a few
/// megabytes, a robot sending its inputs fills this in about five hours.
pub const MAX_RECORDING_BYTES: u64 = 64 << 20;

/// The whole of `path` if it holds at most `max` bytes, `None` if it holds more (read no
/// further than one byte past the bound).
pub fn read(path: &Path, max: u64) -> std::io::Result<Option<Vec<u8>>> {
    let mut bytes = Vec::new();
    std::fs::File::open(path)?
        .take(max.saturating_add(1))
        .read_to_end(&mut bytes)?;
    Ok((bytes.len() as u64 <= max).then_some(bytes))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_file_within_the_bound_is_read_whole_and_one_past_it_refused() {
        let file = tempfile::NamedTempFile::with_prefix("bounded-").expect("temp file");
        let path = file.path();
        let _ = std::fs::write(path, b"12345");
        assert_eq!(read(path, 5).ok().flatten().as_deref(), Some(&b"12345"[..]));
        assert_eq!(read(path, 4).ok().map(|b| b.is_none()), Some(true));
    }

    #[test]
    fn an_endless_device_is_refused() {
        assert_eq!(
            read(Path::new("/dev/zero"), 1 << 16)
                .ok()
                .map(|b| b.is_none()),
            Some(true)
        );
    }
}
