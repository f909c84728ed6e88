//! Headless Chromium driven over the DevTools protocol: launch it, open a page, run
//! JavaScript in it and take screenshots. Debian's `chromium`, installed by
//! `scripts/install-browser.sh`; `BUGBOT_CHROMIUM` names another binary.

use serde_json::{json, Value};
use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};
use tempfile::TempDir;
use tungstenite::{Message as WsMessage, WebSocket};

/// The page's viewport, CSS pixels at one device pixel each: the page's map (at most
/// 640 px from 88 px down) and its panel fit.
pub const WINDOW: (u32, u32) = (1000, 800);
/// How long the browser may take to start or to answer a call.
const PATIENCE: Duration = Duration::from_secs(30);

/// The binary to run.
pub fn program() -> String {
    std::env::var("BUGBOT_CHROMIUM").unwrap_or_else(|_| "/usr/bin/chromium".to_string())
}

/// A running headless Chromium, killed (and its profile removed) on drop.
pub struct Chromium {
    child: Child,
    profile: TempDir,
    /// `127.0.0.1:PORT` of its DevTools endpoint.
    devtools: String,
}

impl Chromium {
    /// Starts the browser with a fresh profile; an error says why it could not.
    pub fn launch() -> Result<Chromium, String> {
        // A profile of its own: two browsers on one profile refuse to start.
        let profile = TempDir::with_prefix("host-sim-page-chromium-")
            .map_err(|e| format!("profile dir: {e}"))?;
        let program = program();
        let mut child = Command::new(&program)
            .args([
                "--headless",
                "--no-sandbox",
                "--disable-gpu",
                "--disable-quic",
                "--no-first-run",
                "--disable-background-networking",
                "--disable-component-update",
                "--disable-sync",
                "--hide-scrollbars",
                "--force-device-scale-factor=1",
                "--remote-debugging-address=127.0.0.1",
                "--remote-debugging-port=0",
            ])
            .arg(format!("--user-data-dir={}", profile.path().display()))
            .arg(format!("--window-size={},{}", WINDOW.0, WINDOW.1))
            .arg("about:blank")
            // Its own temporary files (the profile's lock socket) in the profile too, to go
            // with it: a killed browser leaves them behind.
            .env("TMPDIR", profile.path())
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .map_err(|e| {
                format!("cannot start {program}: {e} (scripts/install-browser.sh installs it)")
            })?;
        // Its stderr names the DevTools endpoint; the thread keeps draining it after.
        let (tx, rx) = mpsc::channel();
        if let Some(stderr) = child.stderr.take() {
            std::thread::spawn(move || {
                for line in BufReader::new(stderr).lines().map_while(Result::ok) {
                    if let Some(rest) = line.split("DevTools listening on ws://").nth(1) {
                        let host = rest.split('/').next().unwrap_or_default().to_string();
                        let _ = tx.send(host);
                    }
                }
            });
        }
        let devtools = match rx.recv_timeout(PATIENCE) {
            Ok(host) => host,
            Err(_) => {
                let _ = child.kill();
                let status = child.wait().map(|s| s.to_string()).unwrap_or_default();
                return Err(format!(
                    "{program} did not open its DevTools endpoint within {PATIENCE:?} ({status})"
                ));
            }
        };
        Ok(Chromium {
            child,
            profile,
            devtools,
        })
    }

    /// Opens `url` in a new tab (`PUT /json/new`) and returns a session on it.
    pub fn open(&self, url: &str) -> Result<Page, String> {
        let body = self.http("PUT", &format!("/json/new?{url}"))?;
        let v: Value = serde_json::from_str(&body).map_err(|e| format!("/json/new: {e}"))?;
        let ws_url = v["webSocketDebuggerUrl"]
            .as_str()
            .ok_or_else(|| format!("/json/new gave no webSocketDebuggerUrl: {body}"))?;
        let stream = TcpStream::connect(&self.devtools)
            .map_err(|e| format!("connecting to {}: {e}", self.devtools))?;
        stream
            .set_read_timeout(Some(PATIENCE))
            .map_err(|e| e.to_string())?;
        let (ws, _) = tungstenite::client(ws_url, stream)
            .map_err(|e| format!("DevTools handshake with {ws_url}: {e}"))?;
        let mut page = Page { ws, next_id: 1 };
        // The window's size less whatever the browser keeps for itself: fix the viewport.
        page.call(
            "Emulation.setDeviceMetricsOverride",
            json!({ "width": WINDOW.0, "height": WINDOW.1, "deviceScaleFactor": 1, "mobile": false }),
        )?;
        Ok(page)
    }

    /// The body of an HTTP request to the DevTools endpoint.
    fn http(&self, method: &str, path: &str) -> Result<String, String> {
        let mut s = TcpStream::connect(&self.devtools).map_err(|e| e.to_string())?;
        s.set_read_timeout(Some(PATIENCE))
            .map_err(|e| e.to_string())?;
        write!(
            s,
            "{method} {path} HTTP/1.1\r\nHost: {}\r\nConnection: close\r\n\r\n",
            self.devtools
        )
        .map_err(|e| e.to_string())?;
        // It keeps the connection open: read the head, then Content-Length bytes.
        let mut bytes = Vec::new();
        let mut chunk = [0u8; 4096];
        loop {
            let text = String::from_utf8_lossy(&bytes).to_string();
            if let Some((head, body)) = text.split_once("\r\n\r\n") {
                let length = head
                    .lines()
                    .filter_map(|l| l.split_once(':'))
                    .find(|(k, _)| k.eq_ignore_ascii_case("content-length"))
                    .and_then(|(_, v)| v.trim().parse::<usize>().ok());
                if length.is_none_or(|n| body.len() >= n) {
                    return Ok(body.to_string());
                }
            }
            let n = s
                .read(&mut chunk)
                .map_err(|e| format!("{method} {path}: {e}"))?;
            if n == 0 {
                return Err(format!("{method} {path}: closed before the answer"));
            }
            bytes.extend_from_slice(&chunk[..n]);
        }
    }
}

impl Drop for Chromium {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
        // Its helper processes notice and exit a moment later, and may write to the
        // profile until then: the `TempDir`'s own single try may come too soon.
        let profile = self.profile.path();
        for _ in 0..20 {
            if std::fs::remove_dir_all(profile).is_ok() || !profile.exists() {
                break;
            }
            std::thread::sleep(Duration::from_millis(100));
        }
    }
}

/// A DevTools session on one target.
pub struct Page {
    ws: WebSocket<TcpStream>,
    next_id: u64,
}

impl Page {
    /// Calls `method` and returns its result, skipping the events that come between.
    pub fn call(&mut self, method: &str, params: Value) -> Result<Value, String> {
        let id = self.next_id;
        self.next_id += 1;
        let request = json!({ "id": id, "method": method, "params": params }).to_string();
        self.ws
            .send(WsMessage::text(request))
            .map_err(|e| format!("{method}: {e}"))?;
        let deadline = Instant::now() + PATIENCE;
        while Instant::now() < deadline {
            let message = self.ws.read().map_err(|e| format!("{method}: {e}"))?;
            let WsMessage::Text(text) = message else {
                continue;
            };
            let v: Value = serde_json::from_str(text.as_str())
                .map_err(|e| format!("{method}: not JSON: {e}"))?;
            if v["id"].as_u64() != Some(id) {
                continue;
            }
            if !v["error"].is_null() {
                return Err(format!("{method}: {}", v["error"]));
            }
            return Ok(v["result"].clone());
        }
        Err(format!("{method}: no answer within {PATIENCE:?}"))
    }

    /// The value of a JavaScript expression (a promise is awaited).
    pub fn eval(&mut self, expression: &str) -> Result<Value, String> {
        let r = self.call(
            "Runtime.evaluate",
            json!({ "expression": expression, "returnByValue": true, "awaitPromise": true }),
        )?;
        if !r["exceptionDetails"].is_null() {
            return Err(format!("{expression}: {}", r["exceptionDetails"]));
        }
        Ok(r["result"]["value"].clone())
    }

    /// Waits until the page has painted what it last drew (two animation frames).
    pub fn settle(&mut self) -> Result<(), String> {
        self.eval(
            "new Promise(r => requestAnimationFrame(() => requestAnimationFrame(() => r(true))))",
        )
        .map(|_| ())
    }

    /// A PNG screenshot of the window.
    pub fn screenshot(&mut self) -> Result<Vec<u8>, String> {
        let r = self.call("Page.captureScreenshot", json!({ "format": "png" }))?;
        let data = r["data"].as_str().ok_or("captureScreenshot gave no data")?;
        data_encoding::BASE64
            .decode(data.as_bytes())
            .map_err(|e| format!("screenshot base64: {e}"))
    }
}
