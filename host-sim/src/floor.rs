//! The world's floor on the grid: the cells a "known %" is a share of.
//!
//! A grid is laid over more than the world (a margin, or a built-in size far larger than a
//! small room), so a share of the whole grid says little: a 3 m x 2 m room on the 206 x 206
//! grid could never be more than a few percent known. The floor is the cells the robot
//! could see: those whose centres it can reach from its start without crossing a wall,
//! and the wall cells that border them. Box interiors and the outside of the room are not
//! floor. A world whose walls do not close (the fill reaches the grid's edge) has no
//! inside, and then the whole grid is its floor.

use std::collections::VecDeque;

use slam_core::GridGeometry;

use crate::world::{ray_segment, Vec2, World};

/// For each cell of a `width` x `height` grid laid on the world by `g`, row-major from the
/// lowest row: whether it is floor. Every cell is floor when the world's start lies off
/// the grid or its walls do not close around it.
pub fn floor_mask(world: &World, g: &GridGeometry, width: usize, height: usize) -> Vec<bool> {
    floor_from(world, world.start(), g, width, height)
}

fn floor_from(
    world: &World,
    start: Vec2,
    g: &GridGeometry,
    width: usize,
    height: usize,
) -> Vec<bool> {
    let all = vec![true; width * height];
    let cell = f64::from(g.cell_mm);
    let (ox, oy) = (f64::from(g.origin_x_mm), f64::from(g.origin_y_mm));
    let col = ((start.x - ox) / cell).floor();
    let row = ((start.y - oy) / cell).floor();
    if !(cell > 0.0 && (0.0..width as f64).contains(&col) && (0.0..height as f64).contains(&row)) {
        return all;
    }
    let centre =
        |c: usize, r: usize| Vec2::new(ox + (c as f64 + 0.5) * cell, oy + (r as f64 + 0.5) * cell);
    // A step of one cell from a centre is open unless a wall (or tag card) crosses it.
    let open = |from: Vec2, dir: Vec2| {
        !world
            .walls()
            .iter()
            .filter_map(|w| ray_segment(from, dir, w.a, w.b))
            .any(|t| t <= cell)
    };
    let mut floor = vec![false; width * height];
    let first = row as usize * width + col as usize;
    floor[first] = true;
    let mut queue = VecDeque::from([first]);
    while let Some(i) = queue.pop_front() {
        let (c, r) = (i % width, i / width);
        if c == 0 || r == 0 || c + 1 == width || r + 1 == height {
            // Out to the grid's edge: the walls leave the start open.
            return all;
        }
        let from = centre(c, r);
        for (dir, next) in [
            (Vec2::new(1.0, 0.0), i + 1),
            (Vec2::new(-1.0, 0.0), i - 1),
            (Vec2::new(0.0, 1.0), i + width),
            (Vec2::new(0.0, -1.0), i - width),
        ] {
            if !floor[next] && open(from, dir) {
                floor[next] = true;
                queue.push_back(next);
            }
        }
    }
    // The walls round the floor: real cells next to it (diagonals too, for corners).
    let inside = floor.clone();
    for r in 0..height {
        for c in 0..width {
            let i = r * width + c;
            if inside[i] || !world.is_real(centre(c, r)) {
                continue;
            }
            let near = (r.saturating_sub(1)..=(r + 1).min(height - 1)).any(|rr| {
                (c.saturating_sub(1)..=(c + 1).min(width - 1)).any(|cc| inside[rr * width + cc])
            });
            floor[i] = near;
        }
    }
    floor
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::Scenario;

    const GEO: GridGeometry = GridGeometry {
        cell_mm: 50,
        origin_x_mm: -150,
        origin_y_mm: -150,
    };

    fn world(path: &str) -> World {
        World::new(&Scenario::load(std::path::Path::new(path)).expect("scenario"))
    }

    fn cell_at(x: f64, y: f64, width: usize) -> usize {
        let c = ((x + 150.0) / 50.0) as usize;
        let r = ((y + 150.0) / 50.0) as usize;
        r * width + c
    }

    #[test]
    fn the_mat_is_its_floor_and_the_margin_is_not() {
        let floor = floor_mask(&world("scenarios/seed-mat.toml"), &GEO, 46, 46);
        // 40 x 40 cells of mat, plus the ring of wall cells just outside it.
        assert_eq!(floor.iter().filter(|&&f| f).count(), 42 * 42);
        assert!(floor[cell_at(1000.0, 1000.0, 46)]);
        assert!(floor[cell_at(10.0, 1000.0, 46)], "the wall's own cell");
        assert!(!floor[cell_at(-120.0, 1000.0, 46)], "the margin");
    }

    #[test]
    fn a_box_interior_is_not_floor() {
        let floor = floor_mask(&world("scenarios/two-wall-room.toml"), &GEO, 206, 206);
        assert!(floor[cell_at(300.0, 300.0, 206)]);
        assert!(!floor[cell_at(1500.0, 1000.0, 206)], "inside the box");
        assert!(!floor[cell_at(5000.0, 5000.0, 206)], "outside the room");
    }

    #[test]
    fn an_open_world_or_a_start_off_the_grid_is_all_floor() {
        let w = world("scenarios/seed-mat.toml");
        let off = floor_from(&w, Vec2::new(-1e6, 0.0), &GEO, 46, 46);
        assert!(off.iter().all(|&f| f));
        // Outside the mat's walls, the fill reaches the grid's edge.
        let open = floor_from(&w, Vec2::new(-100.0, 1000.0), &GEO, 46, 46);
        assert!(open.iter().all(|&f| f));
    }
}
