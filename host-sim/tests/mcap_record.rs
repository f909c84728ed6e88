//! `host-sim run --mcap`: the Foxglove channels recorded to MCAP, read back with the
//! `mcap` crate and held against the telemetry stream of the same run.

#[allow(dead_code)] // not every helper is used here
mod common;

use common::{host_sim, scratch_dir, seed_path};
use foxglove::messages::Grid;
use foxglove::Decode;
use host_sim::live::grid::{probability, CELL_BYTES, PROBABILITY_FIELD};
use host_sim::record::CellBelief;
use host_sim::telemetry::decode_bytes;
use std::collections::BTreeMap;
use std::path::PathBuf;
use wire::telemetry::{Hello, Message, StreamDecoder};

/// The prefix of this file's scratch directories.
const SCRATCH: &str = "host-sim-mcap-";

fn read(path: &PathBuf) -> Vec<u8> {
    match std::fs::read(path) {
        Ok(b) => b,
        Err(e) => panic!("cannot read {}: {e}", path.display()),
    }
}

/// What the telemetry stream held: messages by kind, the last `Hello` and the final cell
/// bytes, placed chunk by chunk as a viewer places them.
struct Stream {
    counts: BTreeMap<&'static str, usize>,
    hello: Hello,
    cells: Vec<i8>,
}

fn stream(bytes: &[u8]) -> Stream {
    let mut decoder = StreamDecoder::default();
    let mut counts = BTreeMap::new();
    let mut hello = None;
    let mut cells = Vec::new();
    for m in decoder.feed(bytes).flatten() {
        let kind = match &m {
            Message::Hello(h) => {
                if hello.is_none() {
                    cells = vec![0i8; usize::from(h.width) * usize::from(h.height)];
                }
                hello = Some(*h);
                "hello"
            }
            Message::Tick(_) => "tick",
            Message::MapRows(r) => {
                let width = hello.map_or(0, |h| usize::from(h.width));
                let start = usize::from(r.first_row) * width + usize::from(r.first_column);
                cells[start..start + r.cells.len()].copy_from_slice(&r.cells);
                "map_rows"
            }
            Message::Health(_) => "health",
            Message::Filter(_) => "filter",
            Message::Inputs(_) => "inputs",
        };
        *counts.entry(kind).or_insert(0) += 1;
    }
    Stream {
        counts,
        hello: hello.expect("the stream has a Hello"),
        cells,
    }
}

#[test]
fn the_mcap_holds_every_channel_and_ends_with_the_streams_map() {
    let dir = scratch_dir(SCRATCH);
    let (mcap_path, telemetry_path) = (dir.path().join("seed.mcap"), dir.path().join("seed.bin"));
    let out = host_sim(&[
        "run",
        seed_path().to_str().unwrap_or_default(),
        "--pose",
        "slam",
        "--json",
        "--mcap",
        mcap_path.to_str().unwrap_or_default(),
        "--telemetry",
        telemetry_path.to_str().unwrap_or_default(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let figures: serde_json::Value = serde_json::from_slice(&out.stdout).expect("figures");
    let ticks = figures["ticks"].as_u64().expect("ticks") as usize;

    let telemetry = read(&telemetry_path);
    let s = stream(&telemetry);
    assert_eq!(s.counts["tick"], ticks);

    let bytes = read(&mcap_path);
    let mut counts: BTreeMap<String, usize> = BTreeMap::new();
    let mut schemas: BTreeMap<String, (String, String, String)> = BTreeMap::new();
    let mut last_grid = None;
    let mut last_pose_time = 0;
    for m in mcap::MessageStream::new(&bytes).expect("an MCAP file") {
        let m = m.expect("a good record");
        let topic = m.channel.topic.clone();
        let schema = m
            .channel
            .schema
            .as_ref()
            .expect("every channel has a schema");
        schemas.insert(
            topic.clone(),
            (
                schema.name.clone(),
                schema.encoding.clone(),
                m.channel.message_encoding.clone(),
            ),
        );
        *counts.entry(topic.clone()).or_insert(0) += 1;
        match topic.as_str() {
            "/map" => last_grid = Some(m.data.into_owned()),
            "/pose" => {
                assert!(m.log_time >= last_pose_time, "poses in time order");
                last_pose_time = m.log_time;
            }
            "/health" | "/filter" => {
                let v: serde_json::Value = serde_json::from_slice(&m.data).expect("JSON");
                assert!(v["tick"].as_u64().is_some(), "{topic}: {v}");
            }
            _ => {}
        }
    }

    let proto = |name: &str| {
        (
            name.to_string(),
            "protobuf".to_string(),
            "protobuf".to_string(),
        )
    };
    let json = |name: &str| {
        (
            name.to_string(),
            "jsonschema".to_string(),
            "json".to_string(),
        )
    };
    let expected: BTreeMap<String, _> = [
        ("/map", proto("foxglove.Grid")),
        ("/tf", proto("foxglove.FrameTransforms")),
        ("/pose", proto("foxglove.PoseInFrame")),
        ("/pose/covariance", proto("foxglove.Odometry")),
        ("/pose/ellipse", proto("foxglove.SceneUpdate")),
        ("/path/estimated", proto("foxglove.PosesInFrame")),
        ("/path/true", proto("foxglove.PosesInFrame")),
        ("/tags", proto("foxglove.SceneUpdate")),
        ("/tags/sightings", proto("foxglove.SceneUpdate")),
        ("/health", json("bugbot.Health")),
        ("/filter", json("bugbot.Filter")),
        ("/log", proto("foxglove.Log")),
    ]
    .into_iter()
    .map(|(t, s)| (t.to_string(), s))
    .collect();
    assert_eq!(schemas, expected);

    // One pose and one transform a tick, a covariance a filter state, the sightings of
    // every tick's inputs, a health per Health; the map, paths and tags on the first
    // tick, every 10th, and once more at the end.
    let slow = ticks.div_ceil(10) + 1;
    let want: BTreeMap<String, usize> = [
        ("/map", slow),
        ("/tf", ticks),
        ("/pose", ticks),
        ("/pose/covariance", s.counts["filter"]),
        ("/pose/ellipse", s.counts["filter"]),
        ("/path/estimated", slow),
        ("/path/true", slow),
        ("/tags", slow),
        ("/tags/sightings", s.counts["inputs"]),
        ("/health", s.counts["health"]),
        ("/filter", s.counts["filter"]),
        ("/log", 2),
    ]
    .into_iter()
    .map(|(t, n)| (t.to_string(), n))
    .collect();
    assert_eq!(counts, want);
    assert_eq!(s.counts["filter"], ticks);

    // The last grid is the stream's final map, cell for cell.
    let grid = Grid::decode(last_grid.expect("a grid").as_slice()).expect("a foxglove.Grid");
    let (w, h) = (usize::from(s.hello.width), usize::from(s.hello.height));
    assert_eq!(grid.column_count as usize, w);
    assert_eq!(grid.row_stride as usize, w * CELL_BYTES);
    assert_eq!(grid.fields.len(), 1);
    assert_eq!(grid.fields[0].name, PROBABILITY_FIELD);
    assert_eq!(grid.data.len(), w * h * CELL_BYTES);
    let p: Vec<f32> = grid
        .data
        .chunks_exact(CELL_BYTES)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect();
    // A cell byte is its log odds in sixteenths: its probability is the logistic of that.
    for (i, (&p, &cell)) in p.iter().zip(&s.cells).enumerate() {
        let want = 1.0 / (1.0 + (-f64::from(cell) / 16.0).exp());
        assert!(
            (f64::from(p) - want).abs() < 1e-6,
            "cell {i}: {p} for byte {cell}"
        );
        assert_eq!(p, probability(cell));
    }
    // ... and read back by the robot's thresholds it is the map `view` draws.
    let scale = s.hello.scale();
    let beliefs: Vec<CellBelief> = p
        .iter()
        .map(|&p| {
            let cell = (16.0 * (f64::from(p) / (1.0 - f64::from(p))).ln()).round() as i8;
            scale.belief(cell).into()
        })
        .collect();
    assert_eq!(beliefs, decode_bytes(&telemetry).recorder.beliefs());
    // `view` of the same stream records the same final map.
    let viewed = dir.path().join("viewed.mcap");
    let out = host_sim(&[
        "view",
        telemetry_path.to_str().unwrap_or_default(),
        "--mcap",
        viewed.to_str().unwrap_or_default(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let viewed = read(&viewed);
    let viewed_grid = mcap::MessageStream::new(&viewed)
        .expect("an MCAP file")
        .filter_map(|m| m.ok().filter(|m| m.channel.topic == "/map"))
        .last()
        .map(|m| Grid::decode(m.data.as_ref()).expect("a foxglove.Grid"))
        .expect("a grid");
    assert_eq!(viewed_grid.data, grid.data);
    let occupied = beliefs
        .iter()
        .filter(|&&b| b == CellBelief::Occupied)
        .count();
    let free = beliefs.iter().filter(|&&b| b == CellBelief::Free).count();
    assert_eq!(figures["occupied"].as_u64(), Some(occupied as u64));
    assert_eq!(figures["free"].as_u64(), Some(free as u64));
    assert!(occupied > 100, "a map with walls: {occupied}");
}
