//! A plain `f64` reference of the maths in `slam-core`, written from the spec, not from the
//! fixed-point code: no binary angles, no Q16, no Q8, no integer cell walk.
//!
//! Shared by the property tests with `mod reference;`. Every test file uses a different
//! part of it, hence the `dead_code` allowance.
#![allow(dead_code)]

use std::f64::consts::PI;

use slam_core::grid::LOG_ODDS_ONE;
use slam_core::Evidence;

pub mod filter;

/// A fixed pseudo-random sequence (Knuth's MMIX linear congruential generator) for sweeps
/// too large for proptest: the same numbers every run.
pub struct Lcg(pub u64);

impl Lcg {
    /// The next state, all 64 bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        self.0
    }
}

// ---------------------------------------------------------------------------------------
// Angles and the heading convention
// ---------------------------------------------------------------------------------------

/// Radians in one binary-angle unit (`2^32` per turn).
pub const RAD_PER_BIT: f64 = 2.0 * PI / 4_294_967_296.0;

/// A raw binary angle (`2^32` per turn) as radians in `[0, 2 pi)`.
pub fn bits_to_rad(bits: u32) -> f64 {
    bits as f64 * RAD_PER_BIT
}

/// `a` wrapped into `(-pi, pi]`.
pub fn wrap(a: f64) -> f64 {
    let mut r = a.rem_euclid(2.0 * PI);
    if r > PI {
        r -= 2.0 * PI;
    }
    r
}

/// The shortest signed turn from `b` to `a`, in radians.
pub fn angle_diff(a: f64, b: f64) -> f64 {
    wrap(a - b)
}

/// Facing `h` (clockwise from +y), the nose points along `(sin h, cos h)`.
pub fn nose(h: f64) -> (f64, f64) {
    (h.sin(), h.cos())
}

/// Facing `h`, the right-hand side points along `(cos h, -sin h)`.
pub fn right(h: f64) -> (f64, f64) {
    (h.cos(), -h.sin())
}

/// The heading of direction `(x, y)`: measured from +y, clockwise towards +x.
pub fn heading_of(x: f64, y: f64) -> f64 {
    x.atan2(y)
}

// ---------------------------------------------------------------------------------------
// Log-odds occupancy, with the core's evidence
// ---------------------------------------------------------------------------------------

/// The core's cell units in a log-odds unit.
const ONE: f64 = LOG_ODDS_ONE as f64;
/// Added where a beam stops.
///
/// The seed states +0.85, -0.4, +-8 and +-1; the core's one-byte cell keeps the seed's
/// beliefs with its own integers (`evidence_beliefs.rs` holds that), so the reference takes
/// those, exactly: it checks which cells a beam updates and the clamp, not a rounding.
pub const HIT: f64 = Evidence::SEED.hit as f64 / ONE;
/// Added where a beam passes.
pub const MISS: f64 = Evidence::SEED.miss as f64 / ONE;
/// Cells saturate at `+-CLAMP`.
pub const CLAMP: f64 = Evidence::SEED.clamp as f64 / ONE;
/// Free below `-FREE_BELOW`.
pub const FREE_BELOW: f64 = Evidence::SEED.free_below as f64 / ONE;
/// Occupied above `OCCUPIED_ABOVE`.
pub const OCCUPIED_ABOVE: f64 = Evidence::SEED.occupied_above as f64 / ONE;

/// What a cell is believed to be.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Class {
    Free,
    Occupied,
    Unknown,
}

/// The classification of a log odds.
pub fn classify(l: f64) -> Class {
    if l < -FREE_BELOW {
        Class::Free
    } else if l > OCCUPIED_ABOVE {
        Class::Occupied
    } else {
        Class::Unknown
    }
}

/// The update of one cell.
pub fn update(l: f64, amount: f64) -> f64 {
    (l + amount).clamp(-CLAMP, CLAMP)
}

/// Where the grid lies, in millimetres.
#[derive(Clone, Copy, Debug)]
pub struct Geometry {
    pub cell: f64,
    pub origin_x: f64,
    pub origin_y: f64,
}

impl Geometry {
    /// The seed mat's grid: 5 cm cells, lower-left corner at (-150, -150) mm.
    pub const SEED: Geometry = Geometry {
        cell: 50.0,
        origin_x: -150.0,
        origin_y: -150.0,
    };

    /// The (half-open) cell holding a point.
    pub fn cell_of(&self, x: f64, y: f64) -> (i32, i32) {
        (
            ((x - self.origin_x) / self.cell).floor() as i32,
            ((y - self.origin_y) / self.cell).floor() as i32,
        )
    }

    /// The closed square of a cell, grown by `margin` on every side (shrunk if negative):
    /// `(x0, y0, x1, y1)`.
    pub fn square(&self, (c, r): (i32, i32), margin: f64) -> (f64, f64, f64, f64) {
        let x0 = self.origin_x + c as f64 * self.cell;
        let y0 = self.origin_y + r as f64 * self.cell;
        (
            x0 - margin,
            y0 - margin,
            x0 + self.cell + margin,
            y0 + self.cell + margin,
        )
    }

    /// The centre of a cell.
    pub fn centre(&self, (c, r): (i32, i32)) -> (f64, f64) {
        (
            self.origin_x + (c as f64 + 0.5) * self.cell,
            self.origin_y + (r as f64 + 0.5) * self.cell,
        )
    }
}

/// Whether the segment `a`-`b` meets the closed box `(x0, y0, x1, y1)` (slab clipping).
pub fn segment_meets_box(a: (f64, f64), b: (f64, f64), bx: (f64, f64, f64, f64)) -> bool {
    let (x0, y0, x1, y1) = bx;
    if x0 > x1 || y0 > y1 {
        return false;
    }
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for (p, d, lo, hi) in [(a.0, b.0 - a.0, x0, x1), (a.1, b.1 - a.1, y0, y1)] {
        if d == 0.0 {
            if p < lo || p > hi {
                return false;
            }
        } else {
            let (mut ta, mut tb) = ((lo - p) / d, (hi - p) / d);
            if ta > tb {
                core::mem::swap(&mut ta, &mut tb);
            }
            t0 = t0.max(ta);
            t1 = t1.min(tb);
            if t0 > t1 {
                return false;
            }
        }
    }
    true
}

/// The cells the segment `a`-`b` crosses, in order, by plain geometry: the cell of `a`, then
/// the cell holding the middle of each stretch between consecutive grid-line crossings, then
/// the cell of `b` (consecutive repeats merged).
///
/// Where the segment passes exactly through a grid corner this steps diagonally (the two
/// cells beside the corner are only touched, not crossed); where it runs exactly along a
/// grid line the half-open rule picks the cell above or to the right.
pub fn crossed_cells(g: &Geometry, a: (f64, f64), b: (f64, f64)) -> Vec<(i32, i32)> {
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let mut ts = vec![0.0, 1.0];
    for (p, d, origin) in [(a.0, dx, g.origin_x), (a.1, dy, g.origin_y)] {
        if d == 0.0 {
            continue;
        }
        let (lo, hi) = if d > 0.0 { (p, p + d) } else { (p + d, p) };
        let mut k = ((lo - origin) / g.cell).ceil();
        while origin + k * g.cell <= hi {
            let t = (origin + k * g.cell - p) / d;
            if t > 0.0 && t < 1.0 {
                ts.push(t);
            }
            k += 1.0;
        }
    }
    ts.sort_by(|x, y| x.partial_cmp(y).unwrap());
    ts.dedup();
    let at = |t: f64| (a.0 + t * dx, a.1 + t * dy);
    let mut out = vec![g.cell_of(a.0, a.1)];
    for w in ts.windows(2) {
        let (x, y) = at((w[0] + w[1]) / 2.0);
        out.push(g.cell_of(x, y));
    }
    out.push(g.cell_of(b.0, b.1));
    out.dedup();
    out
}

/// A log-odds grid in `f64` that knows how unsure it is.
///
/// Each cell keeps an interval `[lo, hi]` of the log odds it could have, because a beam that
/// passes within `eps` millimetres of a cell's edge may or may not update it in a fixed-point
/// implementation whose beam end points are rounded by up to `eps`: such a cell gets an
/// *optional* update (the interval widens to cover both outcomes). Updates a beam makes for
/// certain move both ends. `updates` counts every beam that could have changed the cell.
#[derive(Clone, Debug)]
pub struct RefGrid {
    pub geometry: Geometry,
    pub width: usize,
    pub height: usize,
    pub lo: Vec<f64>,
    pub hi: Vec<f64>,
    pub updates: Vec<u32>,
}

/// The possible effects of one beam on one cell.
#[derive(Clone, Copy, Default, Debug)]
struct Options {
    none: bool,
    miss: bool,
    hit: bool,
}

impl RefGrid {
    pub fn new(geometry: Geometry, width: usize, height: usize) -> RefGrid {
        RefGrid {
            geometry,
            width,
            height,
            lo: vec![0.0; width * height],
            hi: vec![0.0; width * height],
            updates: vec![0; width * height],
        }
    }

    fn index(&self, (c, r): (i32, i32)) -> Option<usize> {
        (c >= 0 && r >= 0 && (c as usize) < self.width && (r as usize) < self.height)
            .then(|| r as usize * self.width + c as usize)
    }

    /// `[lo, hi]` and the number of updates of a cell inside the grid.
    pub fn cell(&self, cell: (i32, i32)) -> (f64, f64, u32) {
        let i = self.index(cell).expect("inside");
        (self.lo[i], self.hi[i], self.updates[i])
    }

    /// One beam from `sensor` along heading `angle` (radians, clockwise from +y) that
    /// returned `range` millimetres, for a sensor whose limit is `max_range`:
    ///
    /// * the beam's end is `min(range, max_range)` along it, and it is a hit if
    ///   `range < max_range`;
    /// * every cell the segment from the sensor to a point one cell short of the end crosses
    ///   is passed (`MISS`), except the hit cell;
    /// * the cell holding the end gets `HIT` if it is a hit.
    ///
    /// Cells within `eps` mm (per axis) of deciding otherwise get optional updates.
    pub fn insert_beam(
        &mut self,
        sensor: (f64, f64),
        angle: f64,
        range: f64,
        max_range: f64,
        eps: f64,
    ) {
        let g = self.geometry;
        let end = range.min(max_range);
        let hit = range < max_range;
        let (nx, ny) = nose(angle);
        let at = |d: f64| (sensor.0 + d * nx, sensor.1 + d * ny);
        let free_end = at((end - g.cell).max(0.0));
        let stop = at(end);
        // The hit cell: certain if the stop point is more than eps inside it.
        let certain_hit = g.cell_of(stop.0, stop.1);
        let (sx0, sy0, sx1, sy1) = g.square(certain_hit, -eps);
        let hit_is_certain = stop.0 >= sx0 && stop.0 <= sx1 && stop.1 >= sy0 && stop.1 <= sy1;
        for r in 0..self.height as i32 {
            for c in 0..self.width as i32 {
                let cell = (c, r);
                let certain_free = segment_meets_box(sensor, free_end, g.square(cell, -eps));
                let maybe_free = segment_meets_box(sensor, free_end, g.square(cell, eps));
                let maybe_hit = hit
                    && if hit_is_certain {
                        cell == certain_hit
                    } else {
                        let (x0, y0, x1, y1) = g.square(cell, eps);
                        stop.0 >= x0 && stop.0 <= x1 && stop.1 >= y0 && stop.1 <= y1
                    };
                let certain_hit_here = hit && hit_is_certain && cell == certain_hit;
                let free = Options {
                    none: !certain_free,
                    miss: maybe_free,
                    hit: false,
                };
                let options = if certain_hit_here {
                    Options {
                        hit: true,
                        ..Options::default()
                    }
                } else if maybe_hit {
                    Options { hit: true, ..free }
                } else {
                    free
                };
                self.apply(cell, options);
            }
        }
    }

    fn apply(&mut self, cell: (i32, i32), o: Options) {
        let Some(i) = self.index(cell) else { return };
        let amounts = [(o.none, 0.0), (o.miss, MISS), (o.hit, HIT)];
        let (lo, hi) = (self.lo[i], self.hi[i]);
        let mut new_lo = f64::INFINITY;
        let mut new_hi = f64::NEG_INFINITY;
        for (possible, amount) in amounts {
            if possible {
                new_lo = new_lo.min(update(lo, amount));
                new_hi = new_hi.max(update(hi, amount));
            }
        }
        if o.miss || o.hit {
            self.updates[i] += 1;
        }
        self.lo[i] = new_lo;
        self.hi[i] = new_hi;
    }
}

// ---------------------------------------------------------------------------------------
// Odometry
// ---------------------------------------------------------------------------------------

/// A pose in micrometres and radians (heading not wrapped).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RefPose {
    pub x_um: f64,
    pub y_um: f64,
    pub heading: f64,
}

/// The turn a yaw rate (millidegrees per second, clockwise positive) makes in `dt_us`.
pub fn turn(rate_mdps: f64, dt_us: f64) -> f64 {
    (rate_mdps / 1000.0 * dt_us / 1e6).to_radians()
}

/// One tick of dead reckoning: the flow displacement (counts x `um_per_count`, forward and
/// right in the robot frame) is rotated by the heading half way through the tick's turn.
pub fn odometry_tick(
    pose: RefPose,
    flow: Option<(i32, i32)>,
    gyro_mdps: Option<i32>,
    dt_us: u32,
    um_per_count: f64,
) -> RefPose {
    let dh = gyro_mdps.map_or(0.0, |g| turn(g as f64, dt_us as f64));
    let (f, r) = flow.map_or((0.0, 0.0), |(f, r)| {
        (f as f64 * um_per_count, r as f64 * um_per_count)
    });
    let mid = pose.heading + dh / 2.0;
    let (nx, ny) = nose(mid);
    let (rx, ry) = right(mid);
    RefPose {
        x_um: pose.x_um + f * nx + r * rx,
        y_um: pose.y_um + f * ny + r * ry,
        heading: pose.heading + dh,
    }
}

// ---------------------------------------------------------------------------------------
// The two-tag fix
// ---------------------------------------------------------------------------------------

/// The seed camera: 320 px wide, optical centre at 160 px, focal length 92.4 px.
pub const CENTRE_PX: f64 = 160.0;
pub const FOCAL_PX: f64 = 92.4;

/// Bearing of a picture column from the nose, positive to the right.
pub fn bearing(cx_px: f64) -> f64 {
    ((cx_px - CENTRE_PX) / FOCAL_PX).atan()
}

/// The picture column at which a bearing appears.
pub fn column_of(bearing: f64) -> f64 {
    CENTRE_PX + FOCAL_PX * bearing.tan()
}

/// A detection in the reference's units: column in pixels, distance in millimetres.
#[derive(Clone, Copy, Debug)]
pub struct Seen {
    pub cx_px: f64,
    pub distance_mm: f64,
}

/// What a perfect camera at `(x, y)` mm facing `heading` sees of a tag at `tag` (mm).
pub fn see(x: f64, y: f64, heading: f64, tag: (f64, f64)) -> Seen {
    let (dx, dy) = (tag.0 - x, tag.1 - y);
    let b = wrap(heading_of(dx, dy) - heading);
    Seen {
        cx_px: column_of(b),
        distance_mm: dx.hypot(dy),
    }
}

/// A fix in millimetres and radians.
#[derive(Clone, Copy, Debug)]
pub struct Fix {
    pub x_mm: f64,
    pub y_mm: f64,
    pub heading: f64,
}

/// The pose two detections of tags at known places imply.
///
/// Each tag lies at `d (sin b, cos b)` in the robot frame `(right, forward)`; the heading is
/// the direction of the true baseline (tag a to tag b) minus the direction of the seen one;
/// each tag then gives `tag - d (sin, cos)(heading + b)` and the fix is their mean.
pub fn two_tag_fix(a: Seen, tag_a: (f64, f64), b: Seen, tag_b: (f64, f64)) -> Fix {
    let (ba, bb) = (bearing(a.cx_px), bearing(b.cx_px));
    let pa = (a.distance_mm * ba.sin(), a.distance_mm * ba.cos());
    let pb = (b.distance_mm * bb.sin(), b.distance_mm * bb.cos());
    let seen = heading_of(pb.0 - pa.0, pb.1 - pa.1);
    let truth = heading_of(tag_b.0 - tag_a.0, tag_b.1 - tag_a.1);
    let heading = wrap(truth - seen);
    let from = |s: Seen, t: (f64, f64), b: f64| {
        let (nx, ny) = nose(heading + b);
        (t.0 - s.distance_mm * nx, t.1 - s.distance_mm * ny)
    };
    let (x1, y1) = from(a, tag_a, ba);
    let (x2, y2) = from(b, tag_b, bb);
    Fix {
        x_mm: (x1 + x2) / 2.0,
        y_mm: (y1 + y2) / 2.0,
        heading,
    }
}

// ---------------------------------------------------------------------------------------
// The seed mat
// ---------------------------------------------------------------------------------------

/// The mat's walls: the square from (0, 0) to (2000, 2000) mm.
pub const MAT_MM: f64 = 2000.0;

/// Distance from `(x, y)` inside the mat along heading `angle` to the first wall.
pub fn ray_to_walls(x: f64, y: f64, angle: f64) -> f64 {
    let (dx, dy) = nose(angle);
    let mut best = f64::INFINITY;
    for (p, d) in [(x, dx), (y, dy)] {
        if d > 1e-12 {
            best = best.min((MAT_MM - p) / d);
        } else if d < -1e-12 {
            best = best.min(-p / d);
        }
    }
    best
}

/// Distance from `(x, y)` to the nearest of the mat's four wall segments.
pub fn distance_to_walls(x: f64, y: f64) -> f64 {
    let seg = |ax: f64, ay: f64, bx: f64, by: f64| {
        let (vx, vy) = (bx - ax, by - ay);
        let t = (((x - ax) * vx + (y - ay) * vy) / (vx * vx + vy * vy)).clamp(0.0, 1.0);
        (x - ax - t * vx).hypot(y - ay - t * vy)
    };
    let m = MAT_MM;
    seg(0.0, 0.0, m, 0.0)
        .min(seg(m, 0.0, m, m))
        .min(seg(m, m, 0.0, m))
        .min(seg(0.0, m, 0.0, 0.0))
}

/// The seed depth fan: centres of 8 equal zones across 45 degrees, left to right.
pub fn fan_angles() -> [f64; 8] {
    let mut out = [0.0; 8];
    for (i, a) in out.iter_mut().enumerate() {
        *a = (-22.5 + 45.0 * (2.0 * i as f64 + 1.0) / 16.0).to_radians();
    }
    out
}

/// The depth sensor's eight ranges from `pose` inside the mat, millimetres, rounded, with
/// no noise and every beam returning.
pub fn mat_scan(pose: &RefPose) -> [Option<u16>; 8] {
    let mut ranges_mm = [None; 8];
    for (r, beam) in ranges_mm.iter_mut().zip(fan_angles()) {
        let d = ray_to_walls(pose.x_um / 1000.0, pose.y_um / 1000.0, pose.heading + beam);
        *r = Some(d.round().min(u16::MAX as f64) as u16);
    }
    ranges_mm
}
