//! The core is not tied to the seed's mat: a 10 m room with an inner wall, a box and three
//! tags maps into the 206 x 206 grid (5 cm cells), through the same `step`.

use host_sim::{run, PoseMode, Scenario};
use std::path::PathBuf;

fn room() -> Scenario {
    let path =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../host-sim/scenarios/room-10m.toml");
    match Scenario::load(&path) {
        Ok(s) => s,
        Err(e) => panic!("the shipped room scenario must load: {e}"),
    }
}

#[test]
fn a_ten_metre_room_maps_with_the_true_pose() {
    let out = match run(&room(), PoseMode::Truth, 1) {
        Ok(o) => o,
        Err(e) => panic!("{e}"),
    };
    let f = &out.figures;
    assert_eq!((out.record.map.width, out.record.map.height), (206, 206));
    assert_eq!(f.out_of_place, 0, "{f:?}");
    assert!(
        f.occupied > 20,
        "the box and the inner wall are seen: {f:?}"
    );
    // The box's near face (y = 3000 mm, x 6500..7100) is mapped where it stands.
    let m = &out.record.map;
    let cell = |x: f64, y: f64| {
        let c = ((x - m.origin_x_mm) / m.cell_mm).floor() as usize;
        let r = ((y - m.origin_y_mm) / m.cell_mm).floor() as usize;
        m.cells[r * m.width + c]
    };
    let box_face_seen = (0..12).any(|i| {
        let x = 6525.0 + 50.0 * i as f64;
        [2975.0, 3025.0]
            .iter()
            .any(|&y| cell(x, y) == host_sim::record::CellBelief::Occupied)
    });
    assert!(box_face_seen, "no occupied cell on the box's face");
}

#[test]
fn tags_in_a_large_room_fix_the_pose() {
    let out = match run(&room(), PoseMode::Tags, 1) {
        Ok(o) => o,
        Err(e) => panic!("{e}"),
    };
    assert!(out.figures.fixes > 20, "{:?}", out.figures);
    let dr = match run(&room(), PoseMode::DeadReckoning, 1) {
        Ok(o) => o,
        Err(e) => panic!("{e}"),
    };
    assert_eq!(dr.figures.fixes, 0);
}
