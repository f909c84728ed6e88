//! `--live`: a client speaking Foxglove's WebSocket protocol connects, subscribes to the
//! map and receives it while a simulated run plays.
//!
//! The SDK names the protocol `foxglove.sdk.v1` in the handshake: the same protocol as
//! `foxglove.websocket.v1` (its messages and opcodes) under the name the Foxglove app now
//! offers; a client offering only the old name is refused.

use foxglove::messages::Grid;
use foxglove::Decode;
use host_sim::live::grid::CELL_BYTES;
use std::io::{BufRead, BufReader};
use std::net::TcpStream;
use std::process::{Child, Command, Stdio};
use std::time::Duration;
use tungstenite::client::IntoClientRequest;
use tungstenite::http::HeaderValue;
use tungstenite::Message;

/// The subprotocol the client offers.
const SUBPROTOCOL: &str = "foxglove.sdk.v1";

/// Kills the child if the test fails before it ends.
struct Running(Child);

impl Drop for Running {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Starts `host-sim ARGS` and reads the WebSocket's port from the line it prints.
fn start(args: &[&str]) -> (Running, u16) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("host-sim starts");
    let stderr = child.stderr.take().expect("stderr");
    let running = Running(child);
    let mut lines = BufReader::new(stderr).lines();
    let marker = "ws://127.0.0.1:";
    for line in lines.by_ref() {
        let line = line.expect("stderr is text");
        if let Some(at) = line.find(marker) {
            let digits: String = line[at + marker.len()..]
                .chars()
                .take_while(char::is_ascii_digit)
                .collect();
            let port = digits.parse().expect("a port number");
            // Keep draining stderr so the child never blocks on it.
            std::thread::spawn(move || lines.for_each(drop));
            return (running, port);
        }
    }
    panic!("host-sim ended without printing its WebSocket port");
}

#[test]
fn a_client_subscribes_to_the_map_and_receives_it() {
    let seed = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/seed-mat.toml");
    let (mut running, port) = start(&[
        "run",
        seed.to_str().unwrap_or_default(),
        "--pose",
        "slam",
        "--live",
        "--port",
        "0",
        "--speed",
        "10",
        "--foxglove-port",
        "0",
    ]);
    assert_ne!(port, 0);
    let stream = TcpStream::connect(("127.0.0.1", port)).expect("the server accepts");
    stream
        .set_read_timeout(Some(Duration::from_secs(30)))
        .expect("a timeout");
    let mut request = format!("ws://127.0.0.1:{port}/")
        .into_client_request()
        .expect("a request");
    request.headers_mut().insert(
        "Sec-WebSocket-Protocol",
        HeaderValue::from_static(SUBPROTOCOL),
    );
    let (mut socket, response) = tungstenite::client(request, stream).expect("a handshake");
    assert_eq!(
        response
            .headers()
            .get("Sec-WebSocket-Protocol")
            .and_then(|v| v.to_str().ok()),
        Some(SUBPROTOCOL)
    );

    let subscription: u32 = 7;
    let mut subscribed = false;
    let grid = loop {
        match socket
            .read()
            .expect("the server keeps talking until the map comes")
        {
            Message::Text(text) => {
                let v: serde_json::Value = serde_json::from_str(&text).expect("JSON");
                if v["op"] == "advertise" && !subscribed {
                    let channels = v["channels"].as_array().expect("channels");
                    let map = channels
                        .iter()
                        .find(|c| c["topic"] == "/map")
                        .expect("/map is advertised");
                    assert_eq!(map["schemaName"], "foxglove.Grid");
                    assert_eq!(map["encoding"], "protobuf");
                    let subscribe = serde_json::json!({
                        "op": "subscribe",
                        "subscriptions": [{"id": subscription, "channelId": map["id"]}],
                    });
                    socket
                        .send(Message::text(subscribe.to_string()))
                        .expect("subscribe");
                    subscribed = true;
                }
            }
            // messageData: opcode 1, subscription id (u32), log time (u64), payload.
            Message::Binary(data) if data.first() == Some(&1) && data.len() > 13 => {
                let id = u32::from_le_bytes([data[1], data[2], data[3], data[4]]);
                assert_eq!(id, subscription);
                break Grid::decode(&data[13..]).expect("a foxglove.Grid");
            }
            _ => {}
        }
    };
    // The seed mat's grid: 46 x 46 cells of 5 cm, a probability each.
    assert_eq!(grid.column_count, 46);
    assert_eq!(grid.data.len(), 46 * 46 * CELL_BYTES);
    assert_eq!(grid.frame_id, "map");
    let _ = socket.close(None);
    drop(socket);
    let status = running.0.wait().expect("host-sim ends");
    assert!(status.success(), "{status}");
}
