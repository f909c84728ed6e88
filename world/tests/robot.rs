//! What the robot is built with from a world file: the grid's size, the route's legs and
//! the constants the firmware's build writes.

use world::robot::{grid_size, route_legs};
use world::{Leg, RobotWorld, Scenario};

fn shipped(name: &str) -> Scenario {
    let path = world::shipped::directory().join(name);
    Scenario::load(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

#[test]
fn every_shipped_world_builds_and_its_grid_holds_its_walls_with_a_margin_each_side() {
    for name in world::shipped::SHIPPED {
        let s = shipped(name);
        let robot = RobotWorld::of(&s).unwrap_or_else(|e| panic!("{name}: {e}"));
        let cell = f64::from(s.grid.cell_mm);
        for (field, p) in s.placed_points() {
            let column = (p.x - f64::from(s.grid.origin_x_mm)) / cell;
            let row = (p.y - f64::from(s.grid.origin_y_mm)) / cell;
            assert!(
                column < robot.columns as f64 && row < robot.rows as f64,
                "{name}: {field} off the {} x {} grid",
                robot.columns,
                robot.rows
            );
        }
        assert_eq!(robot.route.len(), s.route.len(), "{name}");
    }
}

#[test]
fn the_grid_takes_the_origins_margin_on_the_far_side_too() {
    // The seed's 2 m mat from -15 cm: 2.3 m, 46 cells; the 10 m room: 206; a 3 m x 2 m room: 66 x 46.
    assert_eq!(grid_size(&shipped("seed-mat.toml")), (46, 46));
    assert_eq!(grid_size(&shipped("room-10m.toml")), (206, 206));
    assert_eq!(grid_size(&shipped("two-wall-room.toml")), (66, 46));
}

#[test]
fn a_route_is_legs_the_firmware_times_or_ends_by_its_gyro() {
    let mut s = shipped("seed-mat.toml");
    s.route = Scenario::parse(
        &world::shipped::SEED_MAT_TOML.replacen(
            "[[route]]\naction = \"turn\"\ndegrees = 360\nrate_dps = 31.5\n\n[[route]]\naction = \"drive\"\nseconds = 7\nspeed_mm_s = 86\n",
            "[[route]]\naction = \"drive_distance\"\ndistance_mm = 1500\nspeed_mm_s = 100\n\n[[route]]\naction = \"wait\"\nseconds = 1.5\n",
            1,
        ),
    )
    .expect("the edited seed parses")
    .route;
    let legs = route_legs(&s).expect("fits");
    assert_eq!(
        legs[..2],
        [
            Leg::Drive {
                ms: 15_000,
                speed_mm_s: 100
            },
            Leg::Drive {
                ms: 1500,
                speed_mm_s: 0
            },
        ]
    );
    assert_eq!(
        legs[2],
        Leg::Turn {
            mdeg: 360_000,
            rate_mdps: 31_500
        }
    );
}

#[test]
fn the_firmware_constants_carry_the_worlds_numbers() {
    let robot = world::shipped::seed_robot();
    let text = world::codegen::firmware_constants(&robot, "seed-mat.toml");
    for want in [
        "pub const GRID_COLUMNS: usize = 46;",
        "pub const GRID_ROWS: usize = 46;",
        "KnownTag { id: 11, x_mm: 700, y_mm: 1950 }",
        "KnownTag { id: 12, x_mm: 1500, y_mm: 1950 }",
        "pub const START: Pose = Pose { x_um: 700000, y_um: 500000,",
        "pub const ROUTE: [Leg; 5] = [Leg::Turn { mdeg: 360000, rate_mdps: 31500 }, Leg::Drive { time: Duration::from_millis(7000), speed_mm_s: 86 },",
        "pub const WHEEL_FULL_SPEED_MM_S: i64 = 300;",
    ] {
        assert!(text.contains(want), "missing {want:?} in:\n{text}");
    }
}

#[test]
fn a_world_the_firmware_cannot_drive_is_refused_with_its_field() {
    let text = world::shipped::SEED_MAT_TOML
        .replace("max_wheel_speed_mm_s = 300", "max_wheel_speed_mm_s = 0.2");
    let s = Scenario::parse(&text).expect("valid for the simulator");
    let e = RobotWorld::of(&s).expect_err("no drive");
    assert!(e.to_string().contains("robot.max_wheel_speed_mm_s"), "{e}");
}
