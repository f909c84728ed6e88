//! The log-odds occupancy grid: fixed point, saturating, sized at compile time.

use crate::pose::div_floor;

/// Log odds in Q8 fixed point: 256 is a log-odds of 1.0.
pub type LogOdds = i16;

/// One log-odds unit (1.0) in [`LogOdds`].
pub const LOG_ODDS_ONE: LogOdds = 256;

/// How much one beam says about a cell, and when a cell counts as known.
///
/// The defaults are the seed's: +0.85 where a beam stops, -0.4 where it passes,
/// clamped to +-8, free below -1 and occupied above +1.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Evidence {
    /// Added to the cell where a beam stops (positive).
    pub hit: LogOdds,
    /// Added to each cell a beam passes through (negative).
    pub miss: LogOdds,
    /// Cells saturate at `+-clamp`.
    pub clamp: LogOdds,
    /// A cell below `-free_below` is free; above `occupied_above` it is occupied.
    pub free_below: LogOdds,
    /// See `free_below`.
    pub occupied_above: LogOdds,
}

impl Evidence {
    /// The seed's evidence in Q8: +0.85 -> 218, -0.4 -> -102, +-8 -> +-2048, +-1 -> +-256.
    pub const SEED: Evidence = Evidence {
        hit: 218,
        miss: -102,
        clamp: 8 * LOG_ODDS_ONE,
        free_below: LOG_ODDS_ONE,
        occupied_above: LOG_ODDS_ONE,
    };
}

impl Default for Evidence {
    fn default() -> Self {
        Evidence::SEED
    }
}

/// What the map believes about a cell.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Occupancy {
    /// No opinion yet, or not enough evidence either way.
    Unknown,
    /// Beams have passed through it.
    Free,
    /// Beams have stopped in it.
    Occupied,
}

/// Where the grid lies in the map frame.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct GridGeometry {
    /// Side of one square cell, in millimetres (> 0).
    pub cell_mm: i32,
    /// Map-frame x of the grid's lower-left corner, in millimetres.
    pub origin_x_mm: i32,
    /// Map-frame y of the grid's lower-left corner, in millimetres.
    pub origin_y_mm: i32,
}

impl GridGeometry {
    /// The cell `(column, row)` holding map point `(x_mm, y_mm)`; may lie outside the grid.
    pub fn cell_of(&self, x_mm: i32, y_mm: i32) -> (i32, i32) {
        (
            (x_mm - self.origin_x_mm).div_euclid(self.cell_mm),
            (y_mm - self.origin_y_mm).div_euclid(self.cell_mm),
        )
    }

    /// Map-frame centre of cell `(column, row)`, in millimetres (rounded down to whole mm).
    pub fn centre_of(&self, column: i32, row: i32) -> (i32, i32) {
        (
            self.origin_x_mm + column * self.cell_mm + self.cell_mm / 2,
            self.origin_y_mm + row * self.cell_mm + self.cell_mm / 2,
        )
    }
}

/// Counts of the grid's cells by what the map believes.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct OccupancyCounts {
    /// Cells believed free.
    pub free: u32,
    /// Cells believed occupied.
    pub occupied: u32,
    /// Cells with no firm belief.
    pub unknown: u32,
}

/// A `W` x `H` log-odds grid; row 0 is the lowest y, column 0 the lowest x.
///
/// The seed's mat is `GridMap<46, 46>` (5 cm cells, 15 cm margin, 4.2 KB); a 10 m room at
/// 5 cm is `GridMap<206, 206>` (83 KB). Sized by const generics so there is no allocator.
#[derive(Clone, PartialEq, Eq, Debug)]
pub struct GridMap<const W: usize, const H: usize> {
    geometry: GridGeometry,
    evidence: Evidence,
    /// Divides by the cell size without dividing, for every beam's cells.
    divider: CellDivider,
    cells: [[LogOdds; W]; H],
}

impl<const W: usize, const H: usize> GridMap<W, H> {
    /// Columns in the grid.
    pub const WIDTH: usize = W;
    /// Rows in the grid.
    pub const HEIGHT: usize = H;

    /// An empty (all unknown) grid.
    pub const fn new(geometry: GridGeometry, evidence: Evidence) -> Self {
        GridMap {
            geometry,
            evidence,
            divider: CellDivider::new(geometry.cell_mm as i64),
            cells: [[0; W]; H],
        }
    }

    /// Forgets everything: every cell back to unknown.
    pub fn clear(&mut self) {
        for row in self.cells.iter_mut() {
            row.fill(0);
        }
    }

    /// Where the grid lies.
    pub fn geometry(&self) -> &GridGeometry {
        &self.geometry
    }

    /// The evidence rules in use.
    pub fn evidence(&self) -> &Evidence {
        &self.evidence
    }

    /// The log odds of a cell, or `None` outside the grid.
    pub fn log_odds(&self, column: i32, row: i32) -> Option<LogOdds> {
        let row = self.cells.get(usize::try_from(row).ok()?)?;
        row.get(usize::try_from(column).ok()?).copied()
    }

    /// What the map believes about a cell; outside the grid is unknown.
    pub fn occupancy(&self, column: i32, row: i32) -> Occupancy {
        self.log_odds(column, row)
            .map_or(Occupancy::Unknown, |l| self.classify(l))
    }

    fn classify(&self, l: LogOdds) -> Occupancy {
        if l < -self.evidence.free_below {
            Occupancy::Free
        } else if l > self.evidence.occupied_above {
            Occupancy::Occupied
        } else {
            Occupancy::Unknown
        }
    }

    /// Every row of raw log odds, lowest y first: for telemetry and pictures.
    pub fn rows(&self) -> &[[LogOdds; W]; H] {
        &self.cells
    }

    /// Counts cells by belief.
    pub fn counts(&self) -> OccupancyCounts {
        let mut counts = OccupancyCounts::default();
        for &l in self.cells.iter().flatten() {
            match self.classify(l) {
                Occupancy::Free => counts.free += 1,
                Occupancy::Occupied => counts.occupied += 1,
                Occupancy::Unknown => counts.unknown += 1,
            }
        }
        counts
    }

    /// Adds `amount` to a cell, saturating at the clamp; cells outside the grid are ignored.
    /// Returns whether the cell was inside.
    #[inline]
    pub fn add(&mut self, column: i32, row: i32, amount: LogOdds) -> bool {
        // One unsigned comparison per axis rejects negatives too; the sum in 32 bits cannot
        // overflow, and the clamp (at most `i16::MAX`) brings it back into a cell.
        let (Ok(column), Ok(row)) = (usize::try_from(column), usize::try_from(row)) else {
            return false;
        };
        let Some(cell) = self.cells.get_mut(row).and_then(|r| r.get_mut(column)) else {
            return false;
        };
        let clamp = i32::from(self.evidence.clamp);
        *cell = (i32::from(*cell) + i32::from(amount))
            .max(-clamp)
            .min(clamp) as LogOdds;
        true
    }

    /// Marks the cells of `walk` free but for `spared`; returns how many were inside the
    /// grid.
    ///
    /// Any walk: beams take [`GridMap::free_ray`] first, which leaves here only what its
    /// loop does not cover. When both end cells are in the grid, so is every cell between
    /// (the walk never leaves their bounding box), and the loop steps a flat index instead
    /// of checking each cell's column and row. Never inlined: inlined into the step (and
    /// the firmware's task) its state was spilled to the stack on the Cortex-M0+, at about
    /// 90 cycles a cell.
    #[inline(never)]
    fn mark_free<T: WalkInt>(&mut self, walk: Walk<T>, spared: Option<(i32, i32)>) -> u32 {
        let miss = i32::from(self.evidence.miss);
        let clamp = i32::from(self.evidence.clamp);
        let index = |(column, row): (i32, i32)| {
            let inside = (column as u32) < W as u32 && (row as u32) < H as u32;
            inside.then(|| row as usize * W + column as usize)
        };
        let ends = (index((walk.column, walk.row)), index(walk.end()));
        let (Some(mut at), Some(_), true) = (ends.0, ends.1, miss <= 0) else {
            // An end outside the grid (or evidence that adds where beams pass): cell by
            // cell, skipping those outside.
            let mut written = 0;
            for cell in walk {
                if Some(cell) != spared && self.add(cell.0, cell.1, self.evidence.miss) {
                    written += 1;
                }
            }
            return written;
        };
        // Every cell visited is written but the spared one: counted once, not per cell.
        // Once met, `spared` becomes `SEEN`, which no index reaches (fewer registers than
        // a flag: the M0+ has eight).
        const SEEN: usize = usize::MAX - 1;
        let visited = 1 + walk.columns_left + walk.rows_left;
        let mut spared = spared.and_then(index).unwrap_or(usize::MAX);
        let column_step = walk.step_column as isize;
        let row_step = walk.step_row as isize * W as isize;
        let cells = self.cells.as_flattened_mut();
        let mut free = |at: usize| {
            if at == spared {
                spared = SEEN;
            } else if let Some(cell) = cells.get_mut(at) {
                // Cells never exceed the clamp, so a negative miss needs only the floor.
                *cell = (i32::from(*cell) + miss).max(-clamp) as LogOdds;
            }
        };
        // `Walk::advance`'s rule in two phases, each with fewer live values than the M0+
        // has registers for: while both axes have boundaries left the difference decides;
        // then the rest is a straight run along the one axis left. The test
        // `beams_write_exactly_the_cells_their_walk_visits` holds it to the iterator.
        let (mut diff, mut columns, mut rows) = (walk.diff, walk.columns_left, walk.rows_left);
        free(at);
        while columns > 0 && rows > 0 {
            if diff < T::ZERO {
                columns -= 1;
                diff = diff + walk.delta_column;
                at = at.wrapping_add_signed(column_step);
            } else {
                rows -= 1;
                diff = diff - walk.delta_row;
                at = at.wrapping_add_signed(row_step);
            }
            free(at);
        }
        let (run, step) = if columns > 0 {
            (columns, column_step)
        } else {
            (rows, row_step)
        };
        for _ in 0..run {
            at = at.wrapping_add_signed(step);
            free(at);
        }
        visited - u32::from(spared == SEEN)
    }

    /// Frees a beam's walk from `o`'s cell to `end` (millimetres from the grid's
    /// corner, in the grid, less than [`SHORT_WALK_MM`] from the start along each axis),
    /// sparing `spared`; `None` when the walk needs [`GridMap::mark_free`] instead.
    ///
    /// The common case in one loop with one counter, specialised by direction, which the
    /// Cortex-M0+ runs from its registers. The walk crosses exactly the first
    /// `columns + rows` boundaries of its line in the order of `Walk::advance`'s
    /// difference rule; `advance` also counts boundaries per axis only to end a segment
    /// that stops exactly on a cell corner in its own cell. Such a walk, a spared cell
    /// anywhere but the end (a beam's hit cell is further along the same ray, so it is on
    /// the walk only as its end cell), or evidence that adds where beams pass, is left to
    /// `mark_free`.
    #[inline(always)]
    fn free_ray(
        &mut self,
        o: &OriginCell,
        end: (i32, i32),
        cell_of_end: (i32, i32),
        spared: Option<(i32, i32)>,
    ) -> Option<u32> {
        let cell = self.geometry.cell_mm;
        let (column, row) = cell_of_end;
        let (dx, dy) = (end.0 - o.x, end.1 - o.y);
        let spare_end = spared == Some(cell_of_end);
        let between = |v: i32, a: i32, b: i32| a.min(b) <= v && v <= a.max(b);
        let spared_on_the_way = !spare_end
            && spared.is_some_and(|(c, r)| between(c, o.column, column) && between(r, o.row, row));
        let on_corner = column * cell == end.0 && row * cell == end.1;
        if on_corner || spared_on_the_way || self.evidence.miss > 0 {
            return None;
        }
        let (columns, rows) = (column.abs_diff(o.column), row.abs_diff(o.row));
        let (adx, ady) = (dx.abs(), dy.abs());
        // Along one axis only, the difference must always pick that axis.
        let steps = match (columns, rows) {
            (_, 0) => Steps {
                diff: -1,
                delta_column: 0,
                delta_row: 0,
            },
            (0, _) => Steps {
                diff: 0,
                delta_column: 0,
                delta_row: 0,
            },
            _ => Steps {
                diff: (if dx > 0 { o.right } else { o.left }) * ady
                    - (if dy > 0 { o.up } else { o.down }) * adx,
                delta_column: cell * ady,
                delta_row: cell * adx,
            },
        };
        let at = o.row as usize * W + o.column as usize;
        let count = 1 + columns + rows - u32::from(spare_end);
        let direction = (dx > 0, dy > 0);
        let (miss, floor) = (self.evidence.miss, -self.evidence.clamp);
        if (miss, floor) == (Evidence::SEED.miss, -Evidence::SEED.clamp) {
            self.free_walk_in_direction(direction, at, steps, count, SeedMiss);
        } else {
            let miss = AnyMiss {
                miss: i32::from(miss),
                floor: i32::from(floor),
            };
            self.free_walk_in_direction(direction, at, steps, count, miss);
        }
        Some(count)
    }

    /// [`GridMap::free_walk`] for the walk's direction: right, up.
    #[inline(always)]
    fn free_walk_in_direction<M: Miss>(
        &mut self,
        direction: (bool, bool),
        at: usize,
        steps: Steps,
        count: u32,
        miss: M,
    ) {
        match direction {
            (true, true) => self.free_walk::<true, true, M>(at, steps, count, miss),
            (true, false) => self.free_walk::<true, false, M>(at, steps, count, miss),
            (false, true) => self.free_walk::<false, true, M>(at, steps, count, miss),
            (false, false) => self.free_walk::<false, false, M>(at, steps, count, miss),
        }
    }

    /// Frees `count` cells from flat index `at`, stepping right (`RIGHT`) or left and up
    /// (`UP`) or down as `steps` decides. Never inlined: alone, its state nearly fits the
    /// M0+'s registers. Each step is looked up by the difference's sign bit, which the M0+
    /// does in fewer cycles than the compare-and-select the compiler makes of an `if`.
    #[inline(never)]
    fn free_walk<const RIGHT: bool, const UP: bool, M: Miss>(
        &mut self,
        mut at: usize,
        steps: Steps,
        count: u32,
        miss: M,
    ) {
        let column_step: isize = if RIGHT { 1 } else { -1 };
        let row_step: isize = if UP { W as isize } else { -(W as isize) };
        let cells = self.cells.as_flattened_mut();
        let Steps {
            mut diff,
            delta_column,
            delta_row,
        } = steps;
        let by_sign = [
            (delta_row.wrapping_neg(), row_step),
            (delta_column, column_step),
        ];
        for _ in 0..count {
            if let Some(cell) = cells.get_mut(at) {
                *cell = miss.apply(*cell);
            }
            // One step past the last cell is computed and never used.
            let (d, step) = by_sign[(diff as u32 >> 31) as usize];
            diff = diff.wrapping_add(d);
            at = at.wrapping_add_signed(step);
        }
    }

    /// Writes one beam: free along it, occupied where it stopped.
    ///
    /// `from` is the sensor's position and `to` where the beam stopped, both map millimetres.
    /// Cells from the sensor's cell to the cell of `free_end` are marked free once each
    /// (integer grid traversal: every cell the segment crosses, none twice); the cell of `to`
    /// is marked occupied when `hit` is set and is never also marked free. Cells outside
    /// the grid are skipped. Returns the number of cells written.
    pub fn insert_beam(
        &mut self,
        from: (i32, i32),
        free_end: (i32, i32),
        to: (i32, i32),
        hit: bool,
    ) -> u32 {
        let start = self.beam_origin(from);
        let along = |p: (i32, i32)| Some((p.0.checked_sub(from.0)?, p.1.checked_sub(from.1)?));
        match (along(free_end), along(to)) {
            (Some(free), Some(stop)) => self.insert_ray(&start, free, stop, hit),
            _ => self.insert_beam_any(from, free_end, to, hit),
        }
    }

    /// Where beams from `from` (map millimetres) start, worked out once for a scan's beams.
    pub fn beam_origin(&self, from: (i32, i32)) -> BeamOrigin {
        let g = &self.geometry;
        let divider = &self.divider;
        let cell = (|| {
            let (x, y) = (
                from.0.checked_sub(g.origin_x_mm)?,
                from.1.checked_sub(g.origin_y_mm)?,
            );
            let (column, row) = (divider.fast_floor(x)?, divider.fast_floor(y)?);
            let inside = (column as u32) < W as u32 && (row as u32) < H as u32;
            if !inside || g.cell_mm >= SHORT_WALK_MM as i32 {
                return None;
            }
            let (left, down) = (x - column * g.cell_mm, y - row * g.cell_mm);
            Some(OriginCell {
                x,
                y,
                column,
                row,
                right: g.cell_mm - left,
                left,
                up: g.cell_mm - down,
                down,
            })
        })();
        BeamOrigin { map_mm: from, cell }
    }

    /// [`GridMap::insert_beam`] for a beam from `start`: its free cells end `free`
    /// millimetres away (`dx`, `dy`), and it stopped `to` away.
    ///
    /// Never inlined, with `free_ray` inlined into it: a beam's set-up then has
    /// a frame of its own, not the caller's crowded one (inlined into the firmware's SLAM
    /// task it went through the stack: about 90 M0+ cycles more a beam).
    #[inline(never)]
    pub fn insert_ray(
        &mut self,
        start: &BeamOrigin,
        free: (i32, i32),
        to: (i32, i32),
        hit: bool,
    ) -> u32 {
        let short = |d: (i32, i32)| {
            let limit = SHORT_WALK_MM as u32;
            d.0.unsigned_abs() < limit && d.1.unsigned_abs() < limit
        };
        let Some(o) = start.cell.as_ref().filter(|_| short(free) && short(to)) else {
            return self.insert_beam_any_along(start.map_mm, free, to, hit);
        };
        // Both under 2^15 from the grid's corner: the sums cannot overflow.
        let end = (o.x + free.0, o.y + free.1);
        let stop = (o.x + to.0, o.y + to.1);
        let divider = &self.divider;
        let cell_of = |p: (i32, i32)| Some((divider.fast_floor(p.0)?, divider.fast_floor(p.1)?));
        let inside = |(c, r): (i32, i32)| (c as u32) < W as u32 && (r as u32) < H as u32;
        let (Some(end_cell), Some(hit_cell)) = (cell_of(end).filter(|&c| inside(c)), cell_of(stop))
        else {
            return self.insert_beam_any_along(start.map_mm, free, to, hit);
        };
        let spared = hit.then_some(hit_cell);
        let Some(mut written) = self.free_ray(o, end, end_cell, spared) else {
            return self.insert_beam_any_along(start.map_mm, free, to, hit);
        };
        if hit && self.add(hit_cell.0, hit_cell.1, self.evidence.hit) {
            written += 1;
        }
        written
    }

    /// [`GridMap::insert_beam_any`] with the ends given from `from`.
    #[cold]
    #[inline(never)]
    fn insert_beam_any_along(
        &mut self,
        from: (i32, i32),
        free: (i32, i32),
        to: (i32, i32),
        hit: bool,
    ) -> u32 {
        let at = |d: (i32, i32)| (from.0.wrapping_add(d.0), from.1.wrapping_add(d.1));
        self.insert_beam_any(from, at(free), at(to), hit)
    }

    /// [`GridMap::insert_beam`] the general way, for any segment in or out of the grid.
    /// Kept out of line (and cold), so the beams' own path stays small enough for the
    /// Cortex-M0+'s registers.
    #[cold]
    #[inline(never)]
    fn insert_beam_any(
        &mut self,
        from: (i32, i32),
        free_end: (i32, i32),
        to: (i32, i32),
        hit: bool,
    ) -> u32 {
        let hit_cell = self.divider.cell_of(&self.geometry, to);
        let spared = hit.then_some(hit_cell);
        let mut written =
            match CellWalk::with_divider(&self.geometry, &self.divider, from, free_end) {
                CellWalk::Short(walk) => self.mark_free(walk, spared),
                CellWalk::Long(walk) => self.mark_free(walk, spared),
            };
        if hit && self.add(hit_cell.0, hit_cell.1, self.evidence.hit) {
            written += 1;
        }
        written
    }
}

/// Where a scan's beams start, worked out once for all of them: the sensor's cell and its
/// distances to that cell's sides.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub struct BeamOrigin {
    /// The sensor's position, map millimetres.
    map_mm: (i32, i32),
    /// The sensor's cell, when it is in the grid and its beams can take the short way.
    cell: Option<OriginCell>,
}

/// The cell a beam starts in, and where in it.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
struct OriginCell {
    /// Millimetres from the grid's corner.
    x: i32,
    y: i32,
    column: i32,
    row: i32,
    /// Millimetres to the cell's sides: towards +x, -x, +y and -y.
    right: i32,
    left: i32,
    up: i32,
    down: i32,
}

/// Floor division by the cell size by a multiply and a shift: the Cortex-M0+ has no
/// divide instruction, and a beam needs six divisions (about 140 cycles each in software).
///
/// For `0 <= a < 2^15` (a point up to 32 m from the grid's corner), `floor(a / cell)` is
/// `(a * m) >> s` with `s = 15 + ceil(log2(cell))` and `m = ceil(2^s / cell)`: then
/// `m <= 2^16`, so `a * m` fits 32 bits, and the rounding error `m * cell - 2^s` is below
/// `cell <= 2^(s - 15)`, which keeps the quotient exact over that range (Granlund and
/// Montgomery). Anything else, and cells of 2^16 mm or more, divide.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub struct CellDivider {
    /// The cell size, millimetres (at least 1).
    cell: i64,
    /// `m`, or 0 when the cell is too large for the shortcut.
    multiplier: u32,
    /// `s`.
    shift: u32,
}

impl CellDivider {
    /// Offsets from `0` up to (not including) this take the multiply.
    const LIMIT: i64 = 1 << 15;

    const fn new(cell: i64) -> CellDivider {
        let cell = if cell < 1 { 1 } else { cell };
        if cell >= 1 << 16 {
            return CellDivider {
                cell,
                multiplier: 0,
                shift: 0,
            };
        }
        // ceil(log2(cell)), for cell >= 1.
        let log2 = 64 - (cell - 1).leading_zeros();
        let shift = 15 + log2;
        let multiplier = (1u64 << shift).div_ceil(cell as u64);
        CellDivider {
            cell,
            multiplier: multiplier as u32,
            shift,
        }
    }

    /// `floor(a / cell)`.
    #[inline]
    fn floor(&self, a: i64) -> i64 {
        if (0..Self::LIMIT).contains(&a) && self.multiplier != 0 {
            ((a as u32 * self.multiplier) >> self.shift) as i64
        } else {
            div_floor(a, self.cell)
        }
    }

    /// `floor(a / cell)` for `0 <= a < LIMIT` by the multiply; `None` otherwise.
    #[inline]
    fn fast_floor(&self, a: i32) -> Option<i32> {
        // One unsigned comparison takes in `0 <= a < LIMIT`.
        ((a as u32) < Self::LIMIT as u32 && self.multiplier != 0)
            .then(|| ((a as u32 * self.multiplier) >> self.shift) as i32)
    }

    /// `floor(a / cell)` in 32 bits.
    #[inline]
    fn floor_i32(&self, a: i32) -> i32 {
        self.fast_floor(a)
            .unwrap_or_else(|| self.floor(i64::from(a)) as i32)
    }

    /// The cell holding map point `p`, as [`GridGeometry::cell_of`].
    #[inline]
    fn cell_of(&self, geometry: &GridGeometry, p: (i32, i32)) -> (i32, i32) {
        let axis = |v: i32, origin: i32| match v.checked_sub(origin) {
            Some(offset) => self.floor_i32(offset),
            None => self.floor(i64::from(v) - i64::from(origin)) as i32,
        };
        (
            axis(p.0, geometry.origin_x_mm),
            axis(p.1, geometry.origin_y_mm),
        )
    }
}

/// The cells a segment crosses, in order, each once (Amanatides and Woo, in integers).
///
/// Works in whole millimetres relative to the grid. A segment up to [`SHORT_WALK_MM`] along
/// each axis (every beam the robot casts) walks in 32-bit arithmetic, which the Cortex-M0+
/// does in single instructions; longer ones walk the same way in 64 bits, where every
/// product stays far inside `i64`.
pub enum CellWalk {
    /// Both axes and the cell size under [`SHORT_WALK_MM`].
    Short(Walk<i32>),
    /// Anything longer.
    Long(Walk<i64>),
}

/// Longest extent along either axis (and largest cell) walked in 32 bits: the walk's
/// numbers stay below `cell * extent` (see [`Walk`]), under `2^28` here.
pub const SHORT_WALK_MM: i64 = 1 << 14;

impl CellWalk {
    /// The walk from `from` to `to` (map millimetres) over `geometry`'s cells.
    pub fn new(geometry: &GridGeometry, from: (i32, i32), to: (i32, i32)) -> CellWalk {
        CellWalk::with_divider(
            geometry,
            &CellDivider::new(geometry.cell_mm as i64),
            from,
            to,
        )
    }

    /// [`CellWalk::new`] with the cell size's divider already made.
    fn with_divider(
        geometry: &GridGeometry,
        divider: &CellDivider,
        from: (i32, i32),
        to: (i32, i32),
    ) -> CellWalk {
        // A beam: everything in 32 bits from the start (64-bit arithmetic is several
        // instructions per operation on the M0+).
        let (ox, oy) = (geometry.origin_x_mm, geometry.origin_y_mm);
        let short = |v: i32| i64::from(v).abs() < SHORT_WALK_MM;
        if let (Some(fx), Some(fy), Some(tx), Some(ty)) = (
            from.0.checked_sub(ox),
            from.1.checked_sub(oy),
            to.0.checked_sub(ox),
            to.1.checked_sub(oy),
        ) {
            if let (Some(dx), Some(dy)) = (tx.checked_sub(fx), ty.checked_sub(fy)) {
                if short(dx) && short(dy) && divider.cell < SHORT_WALK_MM {
                    return CellWalk::Short(Walk::new(divider, (fx, fy), (tx, ty)));
                }
            }
        }
        let (ox, oy) = (i64::from(ox), i64::from(oy));
        let start = (i64::from(from.0) - ox, i64::from(from.1) - oy);
        let end = (i64::from(to.0) - ox, i64::from(to.1) - oy);
        CellWalk::Long(Walk::new(divider, start, end))
    }
}

impl Iterator for CellWalk {
    type Item = (i32, i32);

    #[inline]
    fn next(&mut self) -> Option<(i32, i32)> {
        match self {
            CellWalk::Short(w) => w.next(),
            CellWalk::Long(w) => w.next(),
        }
    }
}

/// The integers a [`Walk`] compares boundary distances in.
pub trait WalkInt:
    Copy
    + Ord
    + core::ops::Add<Output = Self>
    + core::ops::Sub<Output = Self>
    + core::ops::Mul<Output = Self>
{
    /// Zero.
    const ZERO: Self;
    /// One.
    const ONE: Self;
    /// `v` in this width; only called with values that fit.
    fn narrow(v: i64) -> Self;
    /// `floor(self / cell)`.
    fn cells(self, divider: &CellDivider) -> Self;
    /// A cell index as the grid's `i32` (cells past `i32` wrap, as they always have: no
    /// grid is that large).
    fn index(self) -> i32;
    /// `|self|`, as a count of cell boundaries.
    fn count(self) -> u32;
}

impl WalkInt for i32 {
    const ZERO: i32 = 0;
    const ONE: i32 = 1;
    #[inline]
    fn narrow(v: i64) -> i32 {
        v as i32
    }
    #[inline]
    fn cells(self, divider: &CellDivider) -> i32 {
        divider.floor_i32(self)
    }
    #[inline]
    fn index(self) -> i32 {
        self
    }
    #[inline]
    fn count(self) -> u32 {
        self.unsigned_abs()
    }
}

impl WalkInt for i64 {
    const ZERO: i64 = 0;
    const ONE: i64 = 1;
    #[inline]
    fn narrow(v: i64) -> i64 {
        v
    }
    #[inline]
    fn cells(self, divider: &CellDivider) -> i64 {
        divider.floor(self)
    }
    #[inline]
    fn index(self) -> i32 {
        self as i32
    }
    #[inline]
    fn count(self) -> u32 {
        self.unsigned_abs() as u32
    }
}

/// One walk's state, its boundary distances in `T`.
///
/// The next vertical boundary is `next_column` along the segment and the next horizontal
/// one `next_row` (each scaled by the other axis's extent, so they compare in integers).
/// Only their order matters, so the walk keeps their difference: it stays between
/// `-delta_row` and `delta_column` (each step moves it towards the other side), which
/// bounds it by `cell * max(|dx|, |dy|)`: under `2^28` for a short walk, under `2^50`
/// for any segment between `i32` points over cells under 65 m. Nothing can overflow.
pub struct Walk<T> {
    column: i32,
    row: i32,
    step_column: i32,
    step_row: i32,
    /// `next_column - next_row`: a column boundary comes first when negative.
    diff: T,
    /// How far apart column boundaries are (`cell * |dy|`).
    delta_column: T,
    /// How far apart row boundaries are (`cell * |dx|`).
    delta_row: T,
    /// Column boundaries still to cross before the end cell.
    columns_left: u32,
    /// Row boundaries still to cross before the end cell.
    rows_left: u32,
    started: bool,
}

impl<T: WalkInt> Walk<T> {
    /// The walk from `start` to `end`, millimetres from the grid's corner. The cell size
    /// and the extent along each axis must fit `T`'s products (see [`SHORT_WALK_MM`]).
    fn new(divider: &CellDivider, start: (T, T), end: (T, T)) -> Walk<T> {
        let cell = T::narrow(divider.cell);
        let (fx, fy) = start;
        let (c0, r0) = (fx.cells(divider), fy.cells(divider));
        let (c1, r1) = (end.0.cells(divider), end.1.cells(divider));
        let (dx, dy) = (end.0 - fx, end.1 - fy);
        // Distance from the start to the first boundary crossed along each axis (at most
        // one cell).
        let to_column_edge = if dx > T::ZERO {
            (c0 + T::ONE) * cell - fx
        } else {
            fx - c0 * cell
        };
        let to_row_edge = if dy > T::ZERO {
            (r0 + T::ONE) * cell - fy
        } else {
            fy - r0 * cell
        };
        let abs = |v: T| if v < T::ZERO { T::ZERO - v } else { v };
        let (adx, ady) = (abs(dx), abs(dy));
        Walk {
            column: c0.index(),
            row: r0.index(),
            step_column: if dx > T::ZERO { 1 } else { -1 },
            step_row: if dy > T::ZERO { 1 } else { -1 },
            // With no move along an axis there are no boundaries left on it to cross, and
            // the difference is never consulted.
            diff: if dx == T::ZERO || dy == T::ZERO {
                T::ZERO
            } else {
                to_column_edge * ady - to_row_edge * adx
            },
            delta_column: cell * ady,
            delta_row: cell * adx,
            columns_left: (c1 - c0).count(),
            rows_left: (r1 - r0).count(),
            started: false,
        }
    }
}

/// What a beam passing through does to a cell, for [`GridMap::free_walk`].
///
/// Cells never exceed the clamp, so a negative miss needs only the floor.
trait Miss: Copy {
    /// The cell after one more beam passed through it.
    fn apply(self, cell: LogOdds) -> LogOdds;
}

/// The seed's evidence, as constants: the Cortex-M0+ then keeps them in its instructions,
/// not in two of its eight registers.
#[derive(Clone, Copy)]
struct SeedMiss;

impl Miss for SeedMiss {
    #[inline(always)]
    fn apply(self, cell: LogOdds) -> LogOdds {
        const MISS: i32 = Evidence::SEED.miss as i32;
        const FLOOR: i32 = -(Evidence::SEED.clamp as i32);
        (i32::from(cell) + MISS).max(FLOOR) as LogOdds
    }
}

/// Any other evidence with a negative miss.
#[derive(Clone, Copy)]
struct AnyMiss {
    miss: i32,
    floor: i32,
}

impl Miss for AnyMiss {
    #[inline(always)]
    fn apply(self, cell: LogOdds) -> LogOdds {
        (i32::from(cell) + self.miss).max(self.floor) as LogOdds
    }
}

/// A 32-bit walk's difference rule, as [`GridMap::free_walk`] takes it.
#[derive(Clone, Copy)]
struct Steps {
    diff: i32,
    delta_column: i32,
    delta_row: i32,
}

/// The axis a walk's step moved along.
enum Axis {
    Column,
    Row,
}

impl<T: WalkInt> Walk<T> {
    /// The cell the walk ends in.
    fn end(&self) -> (i32, i32) {
        (
            self.column + self.step_column * self.columns_left as i32,
            self.row + self.step_row * self.rows_left as i32,
        )
    }

    /// Crosses the next boundary: the axis it moved along, or `None` in the end cell.
    #[inline(always)]
    fn advance(&mut self) -> Option<Axis> {
        // Cross whichever boundary comes first along the segment; once one axis has
        // reached the end cell's line only the other may move, so a segment that ends
        // exactly on a corner still ends in its own cell.
        if self.columns_left > 0 && (self.rows_left == 0 || self.diff < T::ZERO) {
            self.columns_left -= 1;
            self.column += self.step_column;
            self.diff = self.diff + self.delta_column;
            Some(Axis::Column)
        } else if self.rows_left > 0 {
            self.rows_left -= 1;
            self.row += self.step_row;
            self.diff = self.diff - self.delta_row;
            Some(Axis::Row)
        } else {
            None
        }
    }
}

impl<T: WalkInt> Iterator for Walk<T> {
    type Item = (i32, i32);

    #[inline]
    fn next(&mut self) -> Option<(i32, i32)> {
        if !self.started {
            self.started = true;
            return Some((self.column, self.row));
        }
        self.advance().map(|_| (self.column, self.row))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const GEO: GridGeometry = GridGeometry {
        cell_mm: 50,
        origin_x_mm: -150,
        origin_y_mm: -150,
    };

    fn walk(from: (i32, i32), to: (i32, i32)) -> std::vec::Vec<(i32, i32)> {
        CellWalk::new(&GEO, from, to).collect()
    }

    #[test]
    fn walk_visits_each_cell_once_and_ends_at_target() {
        let cells = walk((700, 500), (1234, 1987));
        let end = GEO.cell_of(1234, 1987);
        assert_eq!(cells.first(), Some(&GEO.cell_of(700, 500)));
        assert_eq!(cells.last(), Some(&end));
        for pair in cells.windows(2) {
            let d = (pair[1].0 - pair[0].0).abs() + (pair[1].1 - pair[0].1).abs();
            assert_eq!(d, 1, "4-connected steps only: {pair:?}");
        }
        let mut sorted = cells.clone();
        sorted.sort();
        sorted.dedup();
        assert_eq!(sorted.len(), cells.len());
    }

    #[test]
    fn cell_divider_is_exact() {
        // Every offset the shortcut takes, for every cell size up to 200 mm, and a spread
        // of larger ones up to the shortcut's end; then across the fallback's edges.
        let sizes = (1..=200).chain([255, 256, 257, 1000, 4095, 4096, 12_345, 65_535]);
        for cell in sizes {
            let d = CellDivider::new(cell);
            let step = if cell <= 200 { 1 } else { 7 };
            for a in (0..CellDivider::LIMIT).step_by(step) {
                assert_eq!(d.floor(a), a.div_euclid(cell), "{a} / {cell}");
            }
            for a in [
                -1,
                -cell,
                -cell - 1,
                CellDivider::LIMIT,
                1 << 40,
                -(1 << 40),
            ] {
                assert_eq!(d.floor(a), a.div_euclid(cell), "{a} / {cell}");
            }
            for a in [0, 1, -1, 49, 50, -50, 32_767, 32_768, i32::MAX, i32::MIN] {
                let expect = i64::from(a).div_euclid(cell) as i32;
                assert_eq!(d.floor_i32(a), expect, "{a} / {cell} in 32 bits");
            }
        }
        for cell in [0, -5, 1 << 16, 1 << 20] {
            let d = CellDivider::new(cell);
            assert_eq!(d.floor(12_345), 12_345i64.div_euclid(cell.max(1)));
        }
    }

    #[test]
    fn short_walks_in_32_bits_equal_the_64_bit_walk() {
        // A fixed pseudo-random sequence (LCG) of segments up to the 32-bit limit.
        let mut rng = crate::lcg::Lcg::new(0x2545_f491_4f6c_dd1d_u64);
        let mut next = |span: i64| rng.within(span);
        let limit = SHORT_WALK_MM - 1;
        for _ in 0..20_000 {
            let cell = 1 + next(200).abs();
            let start = (next(30_000), next(30_000));
            let end = (start.0 + next(limit), start.1 + next(limit));
            let divider = CellDivider::new(cell);
            let wide: std::vec::Vec<_> = Walk::<i64>::new(&divider, start, end).collect();
            let (start32, end32) = (
                (start.0 as i32, start.1 as i32),
                (end.0 as i32, end.1 as i32),
            );
            let narrow: std::vec::Vec<_> = Walk::<i32>::new(&divider, start32, end32).collect();
            assert_eq!(narrow, wide, "cell {cell} from {start:?} to {end:?}");
        }
        // And the dispatch: a beam takes the 32-bit walk, a segment past the limit does not.
        assert!(matches!(
            CellWalk::new(&GEO, (0, 0), (4000, -3000)),
            CellWalk::Short(_)
        ));
        assert!(matches!(
            CellWalk::new(&GEO, (0, 0), (20_000, 0)),
            CellWalk::Long(_)
        ));
    }

    /// Writes one beam three times into a fresh grid by `insert_beam` and into another
    /// by the plain iterator, cell by cell, and checks counts and cells agree.
    fn assert_beam_as_plain(from: (i32, i32), free_end: (i32, i32), to: (i32, i32), hit: bool) {
        let mut fast: GridMap<46, 46> = GridMap::new(GEO, Evidence::SEED);
        let mut plain: GridMap<46, 46> = GridMap::new(GEO, Evidence::SEED);
        for _ in 0..3 {
            let n = fast.insert_beam(from, free_end, to, hit);
            let hit_cell = GEO.cell_of(to.0, to.1);
            let mut m = 0;
            for (c, r) in CellWalk::new(&GEO, from, free_end) {
                if !(hit && (c, r) == hit_cell) && plain.add(c, r, Evidence::SEED.miss) {
                    m += 1;
                }
            }
            if hit && plain.add(hit_cell.0, hit_cell.1, Evidence::SEED.hit) {
                m += 1;
            }
            assert_eq!(n, m, "{from:?} -> {free_end:?} / {to:?}");
        }
        assert_eq!(
            fast.rows(),
            plain.rows(),
            "{from:?} -> {free_end:?} / {to:?}"
        );
    }

    #[test]
    fn beams_write_exactly_the_cells_their_walk_visits() {
        // The specialised loops against the plain one: every walk cell free (bar the hit
        // cell), in or partly out of the grid, from a fixed pseudo-random sequence.
        let mut rng = crate::lcg::Lcg::new(0x9e37_79b9_7f4a_7c15_u64);
        let mut next = |span: i32| rng.within(i64::from(span)) as i32;
        for _ in 0..3_000 {
            let from = (next(1_400) + 850, next(1_400) + 850);
            let to = (from.0 + next(2_500), from.1 + next(2_500));
            // A hit cell anywhere near the end, on the walk or off it.
            let free_end = (to.0 - next(60), to.1 - next(60));
            assert_beam_as_plain(from, free_end, to, next(1) >= 0);
            // As a beam casts it: the free end a cell short along the same ray.
            let (dx, dy) = (to.0 - from.0, to.1 - from.1);
            let length = (((dx as i64).pow(2) + (dy as i64).pow(2)) as f64)
                .sqrt()
                .max(1.0);
            let short = |d: i32| d - (d as f64 * 50.0 / length) as i32;
            let free_end = (from.0 + short(dx), from.1 + short(dy));
            assert_beam_as_plain(from, free_end, to, next(1) >= 0);
        }
    }

    #[test]
    fn walks_ending_on_a_cell_corner_end_in_their_own_cell() {
        // Every direction into and along corners (multiples of 50 mm from the grid's
        // corner), where only counting boundaries per axis tells the last step.
        for from in [(712, 533), (700, 500), (688, 450), (650, 517)] {
            for x in (400..=1000).step_by(50) {
                for y in (200..=800).step_by(50) {
                    for hit in [false, true] {
                        assert_beam_as_plain(from, (x, y), (x, y), hit);
                        assert_beam_as_plain(from, (x, y), (2 * x - from.0, 2 * y - from.1), hit);
                    }
                }
            }
            // From a corner or a side at exactly 45 degrees, where two boundaries meet
            // before the first of the other axis.
            for d in 1..400 {
                for (sx, sy) in [(1, 1), (1, -1), (-1, 1), (-1, -1)] {
                    let to = (from.0 + sx * d, from.1 + sy * d);
                    assert_beam_as_plain(from, to, to, false);
                    let to = (from.0 + sx * d, from.1 + sy * (d + 1));
                    assert_beam_as_plain(from, to, to, true);
                }
            }
        }
    }

    #[test]
    fn walk_axis_aligned_and_single_cell() {
        assert_eq!(walk((10, 10), (20, 30)), [(3, 3)]);
        assert_eq!(walk((10, 10), (160, 10)), [(3, 3), (4, 3), (5, 3), (6, 3)]);
        assert_eq!(walk((10, 10), (10, -90)), [(3, 3), (3, 2), (3, 1)]);
    }

    #[test]
    fn cells_saturate_and_classify() {
        let mut g: GridMap<4, 4> = GridMap::new(GEO, Evidence::SEED);
        for _ in 0..100 {
            g.add(1, 1, Evidence::SEED.hit);
            g.add(2, 2, Evidence::SEED.miss);
        }
        assert_eq!(g.log_odds(1, 1), Some(2048));
        assert_eq!(g.log_odds(2, 2), Some(-2048));
        assert_eq!(g.occupancy(1, 1), Occupancy::Occupied);
        assert_eq!(g.occupancy(2, 2), Occupancy::Free);
        assert_eq!(g.occupancy(0, 0), Occupancy::Unknown);
        assert!(!g.add(-1, 0, 5));
        assert!(!g.add(0, 4, 5));
        assert_eq!(
            g.counts(),
            OccupancyCounts {
                free: 1,
                occupied: 1,
                unknown: 14
            }
        );
    }

    #[test]
    fn beam_marks_free_then_hit_and_clips() {
        let mut g: GridMap<46, 46> = GridMap::new(GEO, Evidence::SEED);
        // From (700, 500) straight up to the far wall at 2000 mm.
        let n = g.insert_beam((700, 500), (700, 1950), (700, 2000), true);
        let (c, r) = GEO.cell_of(700, 2000);
        assert_eq!(g.log_odds(c, r), Some(218));
        assert_eq!(g.log_odds(c, r - 1), Some(-102));
        assert_eq!(n, 31);
        // A beam leaving the grid entirely is clipped, not a panic.
        let n = g.insert_beam((700, 500), (700, 90_000), (700, 100_000), true);
        assert!(n > 0 && n < 60);
    }
}
