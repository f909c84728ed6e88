//! The MCAP file `--mcap` records the channels into, for opening in Foxglove later.

use super::LiveError;
use ::foxglove::{Context, McapWriteOptions, McapWriter, McapWriterHandle};
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// An MCAP file being written with every channel of a context.
pub struct McapFile {
    handle: McapWriterHandle<BufWriter<File>>,
    path: PathBuf,
}

impl McapFile {
    /// Creates (or replaces) `path` and records every message logged in `ctx` from now on.
    /// Uncompressed: the compressors the SDK offers are C libraries.
    pub fn create(ctx: &Arc<Context>, path: &Path) -> Result<McapFile, LiveError> {
        let error = |reason: String| LiveError::Mcap {
            path: path.display().to_string(),
            reason,
        };
        let file = File::create(path).map_err(|e| error(e.to_string()))?;
        let options = McapWriteOptions::new().compression(None);
        let handle = McapWriter::with_options(options)
            .context(ctx)
            .create(BufWriter::new(file))
            .map_err(|e| error(e.to_string()))?;
        Ok(McapFile {
            handle,
            path: path.to_path_buf(),
        })
    }

    /// Writes the summary and the index and closes the file.
    pub fn close(self) -> Result<(), LiveError> {
        let path = self.path;
        let error = |reason: String| LiveError::Mcap {
            path: path.display().to_string(),
            reason,
        };
        let mut writer = self.handle.close().map_err(|e| error(e.to_string()))?;
        std::io::Write::flush(&mut writer).map_err(|e| error(e.to_string()))
    }
}
