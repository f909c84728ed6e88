//! The true world: segments a beam can hit and tags a camera can read.

use crate::scenario::{Scenario, Tag};

/// A 2-D point or vector in millimetres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Vec2 {
    /// x, millimetres.
    pub x: f64,
    /// y, millimetres.
    pub y: f64,
}

impl Vec2 {
    /// The point `(x, y)`.
    pub const fn new(x: f64, y: f64) -> Vec2 {
        Vec2 { x, y }
    }

    /// The unit vector of a heading (degrees clockwise from +y).
    pub fn heading(deg: f64) -> Vec2 {
        let r = deg.to_radians();
        Vec2::new(r.sin(), r.cos())
    }

    fn sub(self, o: Vec2) -> Vec2 {
        Vec2::new(self.x - o.x, self.y - o.y)
    }

    fn cross(self, o: Vec2) -> f64 {
        self.x * o.y - self.y * o.x
    }

    /// Length.
    pub fn norm(self) -> f64 {
        self.x.hypot(self.y)
    }
}

/// A solid segment: a wall, a box edge or a tag card.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Wall {
    /// One end.
    pub a: Vec2,
    /// The other end.
    pub b: Vec2,
    /// The tag whose card this is, if it is one.
    pub tag: Option<u16>,
}

/// A tag as the camera model needs it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TagSite {
    /// Its id.
    pub id: u16,
    /// Its centre.
    pub centre: Vec2,
    /// Unit vector its printed face points along.
    pub normal: Vec2,
}

/// Everything solid in the world.
#[derive(Clone, Debug)]
pub struct World {
    walls: Vec<Wall>,
    tags: Vec<TagSite>,
    wall_tolerance_mm: f64,
    /// Where the robot starts: the floor is what it can reach from there.
    start: Vec2,
}

impl World {
    /// The world of a (validated) scenario: its walls plus a card for each tag.
    pub fn new(scenario: &Scenario) -> World {
        let mut walls: Vec<Wall> = scenario
            .world
            .walls
            .iter()
            .map(|w| Wall {
                a: Vec2::new(w[0][0], w[0][1]),
                b: Vec2::new(w[1][0], w[1][1]),
                tag: None,
            })
            .collect();
        let tags: Vec<TagSite> = scenario.world.tags.iter().map(tag_site).collect();
        for (t, spec) in tags.iter().zip(&scenario.world.tags) {
            // The card lies across the face normal.
            let along = Vec2::new(t.normal.y, -t.normal.x);
            let h = spec.width_mm / 2.0;
            walls.push(Wall {
                a: Vec2::new(t.centre.x - along.x * h, t.centre.y - along.y * h),
                b: Vec2::new(t.centre.x + along.x * h, t.centre.y + along.y * h),
                tag: Some(t.id),
            });
        }
        World {
            walls,
            tags,
            wall_tolerance_mm: scenario.world.wall_tolerance_mm,
            start: Vec2::new(scenario.start.x_mm, scenario.start.y_mm),
        }
    }

    /// Every solid segment, tag cards included.
    pub fn walls(&self) -> &[Wall] {
        &self.walls
    }

    /// The tags.
    pub fn tags(&self) -> &[TagSite] {
        &self.tags
    }

    /// Distance along a ray from `origin` in unit direction `dir` to the first thing it hits.
    pub fn ray(&self, origin: Vec2, dir: Vec2) -> Option<f64> {
        self.ray_hit(origin, dir).map(|(d, _)| d)
    }

    /// Like [`World::ray`], with the index of the segment hit.
    pub fn ray_hit(&self, origin: Vec2, dir: Vec2) -> Option<(f64, usize)> {
        self.walls
            .iter()
            .enumerate()
            .filter_map(|(i, w)| Some((ray_segment(origin, dir, w.a, w.b)?, i)))
            .fold(None, |best, hit| match best {
                Some(b) if b.0 <= hit.0 => Some(b),
                _ => Some(hit),
            })
    }

    /// Whether the straight line from `from` to tag `id`'s centre crosses nothing but that
    /// tag's own card.
    pub fn line_of_sight(&self, from: Vec2, to: Vec2, id: u16) -> bool {
        let d = to.sub(from);
        let len = d.norm();
        if len <= 0.0 {
            return true;
        }
        let dir = Vec2::new(d.x / len, d.y / len);
        !self
            .walls
            .iter()
            .filter(|w| w.tag != Some(id))
            .filter_map(|w| ray_segment(from, dir, w.a, w.b))
            .any(|t| t < len - 1.0)
    }

    /// Where the robot starts.
    pub fn start(&self) -> Vec2 {
        self.start
    }

    /// How far `p` is from the nearest solid segment, tag cards included, millimetres
    /// (infinite in a world with none).
    pub fn clearance(&self, p: Vec2) -> f64 {
        self.walls
            .iter()
            .map(|w| point_segment_distance(p, w.a, w.b))
            .fold(f64::INFINITY, f64::min)
    }

    /// Whether a point lies on something real: within the wall tolerance of a segment, or
    /// on a tag card's square (the seed's rule: 9 cm either way of a tag's centre).
    pub fn is_real(&self, p: Vec2) -> bool {
        self.walls
            .iter()
            .filter(|w| w.tag.is_none())
            .any(|w| point_segment_distance(p, w.a, w.b) < self.wall_tolerance_mm)
            || self
                .tags
                .iter()
                .any(|t| (p.x - t.centre.x).abs() < 90.0 && (p.y - t.centre.y).abs() < 90.0)
    }
}

fn tag_site(t: &Tag) -> TagSite {
    TagSite {
        id: t.id,
        centre: Vec2::new(t.x_mm, t.y_mm),
        normal: Vec2::heading(t.facing_deg),
    }
}

/// Distance along the ray `origin + t * dir` (t >= 0) to the segment `a`-`b`, if it meets it.
pub fn ray_segment(origin: Vec2, dir: Vec2, a: Vec2, b: Vec2) -> Option<f64> {
    let seg = b.sub(a);
    let denom = dir.cross(seg);
    if denom.abs() < 1e-12 {
        return None; // parallel
    }
    let ao = a.sub(origin);
    let t = ao.cross(seg) / denom;
    let u = ao.cross(dir) / denom;
    (t >= 0.0 && (0.0..=1.0).contains(&u)).then_some(t)
}

/// Shortest distance from `p` to the segment `a`-`b`.
pub fn point_segment_distance(p: Vec2, a: Vec2, b: Vec2) -> f64 {
    let ab = b.sub(a);
    let len2 = ab.x * ab.x + ab.y * ab.y;
    let t = if len2 > 0.0 {
        (((p.x - a.x) * ab.x + (p.y - a.y) * ab.y) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    Vec2::new(a.x + ab.x * t, a.y + ab.y * t).sub(p).norm()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ray_hits_nearest_segment() {
        let o = Vec2::new(700.0, 500.0);
        let d = ray_segment(
            o,
            Vec2::heading(0.0),
            Vec2::new(0.0, 2000.0),
            Vec2::new(2000.0, 2000.0),
        );
        assert!((d.unwrap() - 1500.0).abs() < 1e-9);
        assert!(ray_segment(
            o,
            Vec2::heading(180.0),
            Vec2::new(0.0, 2000.0),
            Vec2::new(2000.0, 2000.0)
        )
        .is_none());
        assert!(ray_segment(
            o,
            Vec2::heading(90.0),
            Vec2::new(0.0, 2000.0),
            Vec2::new(2000.0, 2000.0)
        )
        .is_none());
    }

    #[test]
    fn distance_to_segment() {
        let (a, b) = (Vec2::new(0.0, 0.0), Vec2::new(100.0, 0.0));
        assert_eq!(point_segment_distance(Vec2::new(50.0, 30.0), a, b), 30.0);
        assert_eq!(point_segment_distance(Vec2::new(130.0, 40.0), a, b), 50.0);
    }
}
