//! The page's HTTP server: one thread that answers one connection at a time, each
//! bounded in time and size, with the three embedded files and the latest state.
//!
//! One connection at a time keeps it bounded with no pool to size: a request is read
//! whole (at most [`MAX_REQUEST_BYTES`], within [`REQUEST_DEADLINE`]), answered and
//! closed, and a browser that stops reading is dropped after [`IO_TIMEOUT`]. The state
//! is serialized under its lock and written after the lock is let go, so the network
//! never holds up [`super::PageServer::push`].

use super::state::PageState;
use std::io::{self, Read, Write};
use std::net::{Shutdown, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// The page, its style and its script: the only files ever served.
const INDEX_HTML: &str = include_str!("index.html");
const PAGE_CSS: &str = include_str!("page.css");
const PAGE_JS: &str = include_str!("page.js");

/// The longest request read: a browser's GET with its headers is well under 2 KB.
pub const MAX_REQUEST_BYTES: usize = 8 * 1024;
/// The longest one read or write may wait for the browser.
pub const IO_TIMEOUT: Duration = Duration::from_secs(2);
/// The longest a whole request may take to arrive.
pub const REQUEST_DEADLINE: Duration = Duration::from_secs(3);
/// Headers a request may carry.
const MAX_HEADERS: usize = 48;

/// What a request asks for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Route {
    /// `GET /`: the page.
    Page,
    /// `GET /page.css`.
    Style,
    /// `GET /page.js`.
    Script,
    /// `GET /state.json`: the latest state.
    State,
    /// Anything else, any method other than GET included.
    NotFound,
}

impl Route {
    /// The route of a request line's method and target. The query, if any, is ignored.
    pub fn of(method: &str, target: &str) -> Route {
        if method != "GET" {
            return Route::NotFound;
        }
        let path = target.split_once('?').map_or(target, |(p, _)| p);
        match path {
            "/" | "/index.html" => Route::Page,
            "/page.css" => Route::Style,
            "/page.js" => Route::Script,
            "/state.json" => Route::State,
            _ => Route::NotFound,
        }
    }
}

/// Serves `listener` until `stop` is set (and a connection wakes the loop to see it).
pub fn serve(listener: TcpListener, state: Arc<Mutex<PageState>>, stop: Arc<AtomicBool>) {
    for connection in listener.incoming() {
        if stop.load(Ordering::Acquire) {
            break;
        }
        match connection {
            // A browser that goes away mid-request is its own problem, not the server's.
            Ok(stream) => {
                let _ = answer(stream, &state);
            }
            // Out of file descriptors and the like: wait a little rather than spin.
            Err(_) => std::thread::sleep(Duration::from_millis(50)),
        }
    }
}

fn answer(mut stream: TcpStream, state: &Mutex<PageState>) -> io::Result<()> {
    stream.set_read_timeout(Some(IO_TIMEOUT))?;
    stream.set_write_timeout(Some(IO_TIMEOUT))?;
    let response = match read_route(&mut stream)? {
        Some(Route::Page) => response(200, "text/html; charset=utf-8", INDEX_HTML),
        Some(Route::Style) => response(200, "text/css; charset=utf-8", PAGE_CSS),
        Some(Route::Script) => response(200, "text/javascript; charset=utf-8", PAGE_JS),
        Some(Route::State) => {
            let json = state.lock().unwrap_or_else(|e| e.into_inner()).to_json();
            response(200, "application/json", &json)
        }
        Some(Route::NotFound) => response(404, "text/plain; charset=utf-8", "not found\n"),
        None => response(400, "text/plain; charset=utf-8", "bad request\n"),
    };
    stream.write_all(&response)?;
    stream.flush()?;
    stream.shutdown(Shutdown::Write)
}

/// Reads one request's head; `None` when it is not HTTP or too long.
fn read_route(stream: &mut TcpStream) -> io::Result<Option<Route>> {
    let started = Instant::now();
    let mut buf = vec![0u8; MAX_REQUEST_BYTES];
    let mut filled = 0;
    loop {
        if started.elapsed() > REQUEST_DEADLINE {
            return Err(io::Error::new(io::ErrorKind::TimedOut, "request too slow"));
        }
        let Some(space) = buf.get_mut(filled..).filter(|s| !s.is_empty()) else {
            return Ok(None);
        };
        let n = stream.read(space)?;
        if n == 0 {
            return Err(io::Error::new(io::ErrorKind::UnexpectedEof, "closed"));
        }
        filled += n;
        let mut headers = [httparse::EMPTY_HEADER; MAX_HEADERS];
        let mut request = httparse::Request::new(&mut headers);
        match request.parse(buf.get(..filled).unwrap_or_default()) {
            Ok(httparse::Status::Complete(_)) => {
                let method = request.method.unwrap_or_default();
                let target = request.path.unwrap_or_default();
                return Ok(Some(Route::of(method, target)));
            }
            Ok(httparse::Status::Partial) => continue,
            Err(_) => return Ok(None),
        }
    }
}

/// A whole response that closes the connection. The page may load nothing from
/// elsewhere (`Content-Security-Policy`), and nothing is cached: the state changes.
fn response(status: u16, content_type: &str, body: &str) -> Vec<u8> {
    let reason = match status {
        200 => "OK",
        400 => "Bad Request",
        _ => "Not Found",
    };
    let head = format!(
        "HTTP/1.1 {status} {reason}\r\n\
         Content-Type: {content_type}\r\n\
         Content-Length: {}\r\n\
         Cache-Control: no-store\r\n\
         X-Content-Type-Options: nosniff\r\n\
         Content-Security-Policy: default-src 'self'\r\n\
         Connection: close\r\n\r\n",
        body.len()
    );
    let mut bytes = head.into_bytes();
    bytes.extend_from_slice(body.as_bytes());
    bytes
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_the_pages_files_are_routed() {
        assert_eq!(Route::of("GET", "/"), Route::Page);
        assert_eq!(Route::of("GET", "/?paths=0"), Route::Page);
        assert_eq!(Route::of("GET", "/index.html"), Route::Page);
        assert_eq!(Route::of("GET", "/page.js"), Route::Script);
        assert_eq!(Route::of("GET", "/page.css"), Route::Style);
        assert_eq!(Route::of("GET", "/state.json?t=5"), Route::State);
        for target in [
            "/favicon.ico",
            "/../Cargo.toml",
            "/page.js/",
            "//page.js",
            "/src/page/page.js",
            "/%2e%2e/etc/passwd",
            "",
            "*",
        ] {
            assert_eq!(Route::of("GET", target), Route::NotFound, "{target}");
        }
        for method in ["POST", "HEAD", "PUT", "DELETE", "get"] {
            assert_eq!(Route::of(method, "/"), Route::NotFound, "{method}");
        }
    }

    #[test]
    fn responses_say_their_length_and_close() {
        let r = String::from_utf8(response(404, "text/plain", "not found\n")).unwrap();
        assert!(r.starts_with("HTTP/1.1 404 Not Found\r\n"), "{r}");
        assert!(r.contains("Content-Length: 10\r\n"), "{r}");
        assert!(r.contains("Connection: close\r\n"), "{r}");
        assert!(r.ends_with("\r\n\r\nnot found\n"), "{r}");
    }
}
