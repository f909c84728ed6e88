//! The Foxglove WebSocket server (`foxglove.websocket.v1`) that `--live` serves on.

use super::LiveError;
use ::foxglove::{Context, FoxgloveError, WebSocketServer, WebSocketServerHandle};
use std::sync::Arc;

/// Only this machine may connect: the stream is the robot's, not the network's.
pub const HOST: &str = "127.0.0.1";

/// What the errors call this server.
const WHAT: &str = "Foxglove WebSocket";

/// A running server publishing every channel of its context.
pub struct FoxgloveServer {
    handle: WebSocketServerHandle,
}

impl FoxgloveServer {
    /// Listens on [`HOST`] at `port` (0: any free port, see [`FoxgloveServer::port`]).
    pub fn start(ctx: &Arc<Context>, port: u16) -> Result<FoxgloveServer, LiveError> {
        let handle = WebSocketServer::new()
            .name("BugBot host-sim")
            .bind(HOST, port)
            .context(ctx)
            .start_blocking()
            .map_err(|e| match e {
                FoxgloveError::Bind(io) if io.kind() == std::io::ErrorKind::AddrInUse => {
                    LiveError::PortInUse { what: WHAT, port }
                }
                other => LiveError::Server {
                    what: WHAT,
                    port,
                    reason: other.to_string(),
                },
            })?;
        Ok(FoxgloveServer { handle })
    }

    /// The port it listens on.
    pub fn port(&self) -> u16 {
        self.handle.port()
    }

    /// Closes every connection and stops listening.
    pub fn stop(self) {
        self.handle.stop().wait_blocking();
    }
}
