//! The live page's server over plain HTTP: what it serves and refuses, the state it
//! gives for a whole recorded run, and that a browser that stalls holds up neither the
//! feeding side nor, for long, other browsers. (The page in a real browser:
//! `page_browser.rs`.)

#[allow(dead_code)] // the stream tests' helpers; this file uses `hello`
mod common;
#[allow(dead_code)] // the browser half of the support is page_browser.rs's
mod page_support;

use host_sim::page::{MapLayout, PageError, PageServer, MAX_PATH_POINTS};
use host_sim::record::CellBelief;
use page_support::{play, record_seed_run};
use serde_json::Value;
use slam_core::{Counters, FixOutcome, Localiser};
use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::time::{Duration, Instant};
use wire::telemetry::{CellChunk, MapRows, Message, Tick};

fn loopback() -> SocketAddr {
    "127.0.0.1:0".parse().expect("address")
}

/// Sends `request` raw and reads the whole answer (the server closes after it):
/// status, head and body.
fn raw(port: u16, request: &[u8]) -> (u16, String, String) {
    let mut s = TcpStream::connect(("127.0.0.1", port)).expect("connect");
    s.set_read_timeout(Some(Duration::from_secs(20)))
        .expect("timeout");
    s.write_all(request).expect("send");
    let mut answer = Vec::new();
    s.read_to_end(&mut answer).expect("answer");
    let text = String::from_utf8_lossy(&answer).to_string();
    let (head, body) = text.split_once("\r\n\r\n").unwrap_or((&text, ""));
    let status = head
        .split(' ')
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(0);
    (status, head.to_string(), body.to_string())
}

fn get(port: u16, target: &str) -> (u16, String, String) {
    raw(
        port,
        format!("GET {target} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n\r\n").as_bytes(),
    )
}

fn state(port: u16) -> Value {
    let (status, head, body) = get(port, "/state.json");
    assert_eq!(status, 200, "{head}");
    assert!(head.contains("application/json"), "{head}");
    serde_json::from_str(&body).expect("state is JSON")
}

#[test]
fn it_serves_its_own_page_and_nothing_else() {
    let server = PageServer::bind(loopback()).expect("bind");
    let port = server.port();
    assert_ne!(port, 0);
    assert_eq!(server.url(), format!("http://127.0.0.1:{port}/"));

    let (status, head, page) = get(port, "/");
    assert_eq!(status, 200, "{head}");
    assert!(head.contains("text/html"), "{head}");
    assert!(
        head.contains("Content-Security-Policy: default-src 'self'"),
        "{head}"
    );
    assert!(page.contains("<canvas id=\"map\""), "{page}");
    for (target, kind) in [("/page.js", "text/javascript"), ("/page.css", "text/css")] {
        let (status, head, body) = get(port, target);
        assert_eq!(status, 200, "{target}: {head}");
        assert!(head.contains(kind), "{head}");
        assert!(!body.is_empty());
        // Nothing is fetched from elsewhere: no absolute address in any file.
        for text in [&page, &body] {
            assert!(
                !text.contains("http://") && !text.contains("https://"),
                "{target}"
            );
        }
    }
    // The page's own references are all to the server's own files.
    for reference in page.split(['"', '\'']).filter(|s| s.starts_with('/')) {
        assert_eq!(get(port, reference).0, 200, "{reference}");
    }

    for target in [
        "/favicon.ico",
        "/../Cargo.toml",
        "/src/page/page.js",
        "/page.js/../../../Cargo.toml",
        "/%2e%2e/%2e%2e/etc/passwd",
        "/state.json/x",
    ] {
        let (status, _, body) = get(port, target);
        assert_eq!((status, body.as_str()), (404, "not found\n"), "{target}");
    }
    let post = b"POST / HTTP/1.1\r\nHost: x\r\nContent-Length: 2\r\n\r\nhi";
    assert_eq!(raw(port, post).0, 404);
    assert_eq!(raw(port, b"HEAD / HTTP/1.1\r\n\r\n").0, 404);
    assert_eq!(raw(port, b"\x00\x01 not http at all\r\n\r\n").0, 400);
    // A request head past the bound is refused, not buffered.
    let long = format!("GET / HTTP/1.1\r\nX: {}\r\n\r\n", "a".repeat(20_000));
    assert_eq!(raw(port, long.as_bytes()).0, 400);
    // Still serving after all that.
    assert_eq!(get(port, "/").0, 200);
}

#[test]
fn a_port_in_use_or_not_on_loopback_is_an_error_naming_it() {
    let first = PageServer::bind(loopback()).expect("bind");
    let port = first.port();
    let taken: SocketAddr = format!("127.0.0.1:{port}").parse().expect("address");
    match PageServer::bind(taken) {
        Err(e @ PageError::InUse { .. }) => {
            assert!(e.to_string().contains(&format!("port {port}")), "{e}");
        }
        Err(e) => panic!("not InUse: {e}"),
        Ok(_) => panic!("bound a port in use"),
    }
    match PageServer::bind("0.0.0.0:0".parse().expect("address")) {
        Err(e @ PageError::NotLoopback { .. }) => {
            assert!(e.to_string().contains("0.0.0.0"), "{e}")
        }
        Err(e) => panic!("not NotLoopback: {e}"),
        Ok(_) => panic!("served beyond this machine"),
    }
    // Dropping the server frees its port.
    drop(first);
    let again = PageServer::bind(taken).expect("the port is free again");
    assert_eq!(again.port(), port);
}

#[test]
fn the_state_after_a_recorded_run_is_its_map_paths_and_figures() {
    let run = record_seed_run("state");
    let mut server = PageServer::bind(loopback()).expect("bind");
    server.world(&run.output.record.world);
    play(&mut server, &run.messages, &run.truth(), Duration::ZERO);
    let s = state(server.port());

    let map = &run.output.record.map;
    let layout = MapLayout::for_grid(map.width as u16, map.height as u16);
    assert_eq!(s["layout"]["cell_px"], layout.cell_px);
    assert_eq!(s["layout"]["left_px"], layout.left_px);
    assert_eq!(s["layout"]["top_px"], layout.top_px);
    assert_eq!(s["grid"]["width"], map.width);
    // The page's map is `host-sim run`'s, cell for cell.
    let cells = s["map"].as_str().expect("map");
    let want: String = map
        .cells
        .iter()
        .map(|c| match c {
            CellBelief::Unknown => '0',
            CellBelief::Free => '1',
            CellBelief::Occupied => '2',
        })
        .collect();
    assert_eq!(cells, want);

    let ticks = run.output.record.ticks.len();
    let f = &s["figures"];
    assert_eq!(f["tick"], run.final_tick());
    assert_eq!(s["estimate"].as_array().map(Vec::len), Some(ticks));
    assert_eq!(s["truth"].as_array().map(Vec::len), Some(ticks));
    assert_eq!(s["tags"].as_array().map(Vec::len), Some(2));
    assert!(f["error_cm"].as_f64().is_some_and(|e| e < 1.0), "{f}");
    assert_eq!(f["localiser"], "slam");
    assert!(
        f["filter"]["belief"]["tags"]["used"].as_u64() > Some(100),
        "{f}"
    );
    assert!(
        f["stale"]["depth"].is_u64() && f["stale"]["flow"].is_u64(),
        "{f}"
    );
    assert_eq!(f["link"]["hellos_refused"], 0);
    assert_eq!(f["link"]["map_rows_refused"], 0);
    assert!(f["known_pct"].as_f64().is_some_and(|k| k > 50.0), "{f}");
    // What the server says over HTTP is what it holds.
    let held: Value = serde_json::from_str(&server.state_json()).expect("JSON");
    assert_eq!(held, s);
}

fn tick(n: u32) -> Message {
    Message::Tick(Tick {
        tick: n,
        time_ms: n * 100,
        x_um: (n % 2000) as i32 * 1000,
        y_um: 500_000,
        heading_bits: 0,
        fix: FixOutcome::NotAttempted,
        stale: 0,
        cells_written: 0,
        doubts: 0,
        counters: Counters {
            ticks: n,
            ..Counters::default()
        },
    })
}

#[test]
fn a_stalled_browser_holds_up_neither_push_nor_for_long_other_browsers() {
    let mut server = PageServer::bind(loopback()).expect("bind");
    let port = server.port();
    server.push(&Message::Hello(common::hello(206, 206)));
    // One browser sends half a request and stops; another asks for the state and never
    // reads it.
    let mut half = TcpStream::connect(("127.0.0.1", port)).expect("connect");
    half.write_all(b"GET /state.js").expect("send");
    let mut deaf = TcpStream::connect(("127.0.0.1", port)).expect("connect");
    deaf.write_all(b"GET /state.json HTTP/1.1\r\n\r\n")
        .expect("send");

    // An hour of ticks at 10 Hz goes in without waiting on either.
    let started = Instant::now();
    let n = 36_000;
    for i in 1..=n {
        server.push(&tick(i));
    }
    let pushing = started.elapsed();
    assert!(pushing < Duration::from_secs(2), "push took {pushing:?}");

    // A third browser is answered once the stalled ones time out, with the latest state
    // and a path kept to its bound.
    let started = Instant::now();
    let s = state(port);
    assert!(
        started.elapsed() < Duration::from_secs(15),
        "{:?}",
        started.elapsed()
    );
    assert_eq!(s["figures"]["tick"], n);
    let points = s["estimate"].as_array().map_or(0, Vec::len);
    assert!(
        (MAX_PATH_POINTS / 2..=MAX_PATH_POINTS + 1).contains(&points),
        "{points} points"
    );
    assert_eq!(s["figures"]["link"]["messages"], u64::from(n) + 1);
    drop((half, deaf));
}

#[test]
fn impossible_grids_and_rows_are_refused_and_counted() {
    let mut server = PageServer::bind(loopback()).expect("bind");
    // Rows before any Hello: nothing to put them in.
    let rows = |first_row, first_column, n: usize| {
        let mut cells = CellChunk::new();
        for _ in 0..n {
            let _ = cells.push(-100);
        }
        Message::MapRows(MapRows {
            first_row,
            first_column,
            cells,
        })
    };
    server.push(&rows(0, 0, 10));
    // A hostile grid: 65535 x 65535 would be 4 GB of cells.
    server.push(&Message::Hello(common::hello(u16::MAX, u16::MAX)));
    let s: Value = serde_json::from_str(&server.state_json()).expect("JSON");
    assert!(s["layout"].is_null() && s["grid"].is_null(), "{s}");
    assert_eq!(s["map"], "");
    assert_eq!(s["figures"]["link"]["hellos_refused"], 1);
    assert_eq!(s["figures"]["link"]["map_rows_refused"], 1);

    let mut hello = common::hello(46, 46);
    hello.localiser = Localiser::DeadReckoning;
    server.push(&Message::Hello(hello));
    server.push(&rows(45, 40, 10)); // runs past the last cell
    server.push(&rows(0, 46, 1)); // a column past the row's end
    server.push(&rows(1, 0, 3)); // fine: three free cells
    let s: Value = serde_json::from_str(&server.state_json()).expect("JSON");
    assert_eq!(s["figures"]["link"]["map_rows_refused"], 3);
    assert_eq!(s["figures"]["free"], 3);
    assert_eq!(s["figures"]["localiser"], "dead-reckoning");
    let map = s["map"].as_str().expect("map");
    assert_eq!(map.len(), 46 * 46);
    assert_eq!(&map[46..50], "1110");
}

#[test]
fn the_error_is_given_only_when_the_truth_is_the_latest_ticks() {
    use host_sim::truth::TruthSample;
    let mut server = PageServer::bind(loopback()).expect("bind");
    server.push(&Message::Hello(common::hello(46, 46)));
    server.push(&tick(7)); // at 0.7 s, x 7 mm, y 500 mm
    let error = |server: &PageServer| {
        let s: Value = serde_json::from_str(&server.state_json()).expect("JSON");
        s["figures"]["error_cm"].as_f64()
    };
    assert_eq!(error(&server), None, "no truth yet");
    let at = |t_s, x_mm| TruthSample {
        t_s,
        x_mm,
        y_mm: 500.0,
        heading_deg: 0.0,
    };
    server.truth(&at(0.7, 37.0));
    assert_eq!(error(&server), Some(3.0));
    // A truth of another moment says nothing about this tick's error.
    server.truth(&at(5.0, 7.0));
    assert_eq!(error(&server), None);
    let s: Value = serde_json::from_str(&server.state_json()).expect("JSON");
    assert_eq!(s["truth"].as_array().map(Vec::len), Some(2));
    assert_eq!(s["true_pose"]["x_mm"], 7.0);
}
