//! The live page: a small web page of its own that draws the map, the paths, the tags
//! and the figures while a run streams, in any browser, with nothing installed.
//!
//! [`PageServer::bind`] serves on localhost, from one thread of its own:
//!
//! | request | answer |
//! |---|---|
//! | `GET /` | the page (`index.html`, `page.css`, `page.js`, compiled in with `include_str!`: no build step, nothing fetched from elsewhere) |
//! | `GET /state.json` | the latest state: the map (one character a cell, classified by the `Hello`'s thresholds as the PNG map is), the estimated and true paths, the walls and tags, the figures, and where the page puts the map ([`MapLayout`]) |
//! | anything else | 404 |
//!
//! The page polls `/state.json` a few times a second (`POLL_MS` in `page.js`) rather
//! than hold a Server-Sent Events stream open: each poll asks for the state as it is
//! now, so the latest state wins by construction, nothing queues for a slow browser, no
//! connection outlives its answer, and the server needs no thread per browser. The cost,
//! the whole state each poll (one byte a cell), is small on localhost. The feeding side ([`PageServer::push`], [`PageServer::truth`]) only
//! updates that state under a lock the server holds while it serializes (never while it
//! writes to the network), and the state is fixed in size: the latest map, paths of at
//! most [`MAX_PATH_POINTS`] points.

mod http;
mod layout;
mod path;
mod state;

pub use http::{Route, IO_TIMEOUT, MAX_REQUEST_BYTES};
pub use layout::{MapLayout, MAP_LEFT_PX, MAP_MAX_PX, MAP_TOP_PX, MAX_CELL_PX};
pub use path::{DecimatedPath, PathPoint, MAX_PATH_POINTS};
pub use state::PageState;

use crate::record::WorldOutline;
use crate::truth::TruthSample;
use std::fmt;
use std::io;
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;
use wire::telemetry::Message;

/// Why the page could not be served.
#[derive(Debug)]
pub enum PageError {
    /// Another program listens on the port.
    InUse {
        /// The address asked for.
        addr: SocketAddr,
    },
    /// The page serves the run to this machine only: the address must be a loopback one.
    NotLoopback {
        /// The address asked for.
        addr: SocketAddr,
    },
    /// Binding failed for another reason.
    Bind {
        /// The address asked for.
        addr: SocketAddr,
        /// What the system said.
        source: io::Error,
    },
    /// The server's thread could not be started.
    Thread(io::Error),
}

impl fmt::Display for PageError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PageError::InUse { addr } => write!(
                f,
                "cannot serve the page on {addr}: port {} is already in use",
                addr.port()
            ),
            PageError::NotLoopback { addr } => write!(
                f,
                "cannot serve the page on {addr}: only a loopback address (127.0.0.1) is allowed"
            ),
            PageError::Bind { addr, source } => {
                write!(f, "cannot serve the page on {addr}: {source}")
            }
            PageError::Thread(e) => write!(f, "cannot start the page's server thread: {e}"),
        }
    }
}

impl std::error::Error for PageError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            PageError::Bind { source, .. } => Some(source),
            PageError::Thread(e) => Some(e),
            _ => None,
        }
    }
}

/// The live page's server: feed it the run's messages, point a browser at
/// `http://127.0.0.1:PORT/`. Dropping it stops the server.
pub struct PageServer {
    state: Arc<Mutex<PageState>>,
    addr: SocketAddr,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl PageServer {
    /// Serves the page on `addr`, a loopback address; port 0 picks a free port
    /// ([`PageServer::port`] says which).
    pub fn bind(addr: SocketAddr) -> Result<PageServer, PageError> {
        if !addr.ip().is_loopback() {
            return Err(PageError::NotLoopback { addr });
        }
        let listener = TcpListener::bind(addr).map_err(|source| match source.kind() {
            io::ErrorKind::AddrInUse => PageError::InUse { addr },
            _ => PageError::Bind { addr, source },
        })?;
        let local = listener
            .local_addr()
            .map_err(|source| PageError::Bind { addr, source })?;
        let state = Arc::new(Mutex::new(PageState::new()));
        let stop = Arc::new(AtomicBool::new(false));
        let thread = std::thread::Builder::new()
            .name(format!("page-server-{}", local.port()))
            .spawn({
                let (state, stop) = (Arc::clone(&state), Arc::clone(&stop));
                move || http::serve(listener, state, stop)
            })
            .map_err(PageError::Thread)?;
        Ok(PageServer {
            state,
            addr: local,
            stop,
            thread: Some(thread),
        })
    }

    /// The port it serves on.
    pub fn port(&self) -> u16 {
        self.addr.port()
    }

    /// The page's address, `http://127.0.0.1:PORT/`.
    pub fn url(&self) -> String {
        format!("http://{}/", self.addr)
    }

    /// Takes one decoded telemetry message. Never waits on a browser.
    pub fn push(&mut self, message: &Message) {
        self.with_state(|s| s.push(message));
    }

    /// Takes a true pose, when the source is a simulation: the page draws the true path
    /// and the estimate's error.
    pub fn truth(&mut self, sample: &TruthSample) {
        self.with_state(|s| s.truth(sample));
    }

    /// The world's walls and tags, when known, drawn under the paths.
    pub fn world(&mut self, outline: &WorldOutline) {
        self.with_state(|s| s.world(outline));
    }

    /// What `GET /state.json` answers now.
    pub fn state_json(&self) -> String {
        self.state
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .to_json()
    }

    fn with_state(&mut self, f: impl FnOnce(&mut PageState)) {
        // A panic on the server thread cannot leave the state half-written in a way
        // that matters to the page: carry on with it.
        f(&mut self.state.lock().unwrap_or_else(|e| e.into_inner()));
    }
}

/// Stops the server: the connection in hand, if any, is finished first (a few seconds at
/// most, see [`IO_TIMEOUT`]).
impl Drop for PageServer {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Release);
        // The thread waits in `accept`: a connection wakes it to see the flag. If none
        // can be made the thread is left to end with the process rather than joined.
        let woken = TcpStream::connect_timeout(&self.addr, Duration::from_secs(1)).is_ok();
        if let (true, Some(thread)) = (woken, self.thread.take()) {
            let _ = thread.join();
        }
    }
}

/// The page as one of a live session's sinks: every message and true pose, as they play.
impl crate::live::LiveSink for PageServer {
    fn message(&mut self, message: &Message) {
        self.push(message);
    }

    fn truth(&mut self, sample: &TruthSample) {
        PageServer::truth(self, sample);
    }
}
