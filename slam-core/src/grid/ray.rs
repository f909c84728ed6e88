//! Writing a depth beam into the grid: free along it, occupied where it stopped.
//!
//! A beam from inside the grid whose ends are in it takes a specialised loop (`short_ray`
//! and `free_walk`); anything else takes the general walk (`mark_free`).
//!
//! The beam code works on a [`BeamWriter`], the grid's cells as a slice with their width,
//! not on `GridMap<W, H>`: code generic over the grid's size is built in the crate that
//! names the size (the firmware, under its own `opt-level`), while this is built once,
//! here, under the core's.

use super::divider::CellDivider;
use super::map::{Evidence, GridGeometry, GridMap, LogOdds};
use super::walk::{CellWalk, Walk, WalkInt, SHORT_WALK_MM};

impl<const W: usize, const H: usize> GridMap<W, H> {
    /// The grid as its beams write it: cells, width and rules, without the size in the
    /// type. For writing a scan's beams one after another.
    pub fn beams(&mut self) -> BeamWriter<'_> {
        let walks_fit = self.columns as usize <= W && self.rows as usize <= H;
        BeamWriter {
            walks_fit,
            geometry: self.geometry,
            evidence: self.evidence,
            divider: &self.divider,
            after_miss: &self.after_miss,
            columns: self.columns,
            rows: self.rows,
            width: W,
            cells: self.cells.as_flattened_mut(),
        }
    }

    /// Writes one beam: see [`BeamWriter::insert_beam`].
    pub fn insert_beam(
        &mut self,
        from: (i32, i32),
        free_end: (i32, i32),
        to: (i32, i32),
        hit: bool,
    ) -> u32 {
        self.beams().insert_beam(from, free_end, to, hit)
    }

    /// Where beams from `from` (map millimetres) start, worked out once for a scan's beams.
    pub fn beam_origin(&self, from: (i32, i32)) -> BeamOrigin {
        beam_origin(
            &self.geometry,
            &self.divider,
            (self.columns, self.rows),
            from,
        )
    }

    /// Writes one beam from `start`: see [`BeamWriter::insert_ray`].
    pub fn insert_ray(
        &mut self,
        start: &BeamOrigin,
        free: (i32, i32),
        to: (i32, i32),
        hit: bool,
    ) -> u32 {
        self.beams().insert_ray(start, free, to, hit)
    }
}

/// A grid's cells as a flat slice, `width` cells a row, with what its beams need to write
/// them ([`GridMap::beams`]).
pub struct BeamWriter<'a> {
    geometry: GridGeometry,
    evidence: Evidence,
    divider: &'a CellDivider,
    after_miss: &'a [LogOdds; 256],
    /// Columns and rows in use ([`GridMap::limit_to`]).
    columns: u32,
    rows: u32,
    /// Cells in a row of `cells`.
    width: usize,
    cells: &'a mut [LogOdds],
    /// Every cell in use is in `cells`: `columns <= width` and `rows` rows of `width`
    /// cells fit it. `short_ray`'s unchecked walk relies on it.
    walks_fit: bool,
}

/// [`GridMap::beam_origin`] for a grid of `extent` columns and rows in use.
fn beam_origin(
    g: &GridGeometry,
    divider: &CellDivider,
    extent: (u32, u32),
    from: (i32, i32),
) -> BeamOrigin {
    let cell = (|| {
        let (x, y) = (
            from.0.checked_sub(g.origin_x_mm)?,
            from.1.checked_sub(g.origin_y_mm)?,
        );
        let (column, row) = (divider.fast_floor(x)?, divider.fast_floor(y)?);
        let inside = (column as u32) < extent.0 && (row as u32) < extent.1;
        if !inside || !(1..SHORT_WALK_MM as i32).contains(&g.cell_mm) {
            return None;
        }
        let (left, down) = (x - column * g.cell_mm, y - row * g.cell_mm);
        Some(OriginCell {
            cell_mm: g.cell_mm,
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

impl BeamWriter<'_> {
    /// Whether `(column, row)` is a cell in use, as [`GridMap::inside`].
    #[inline(always)]
    fn inside(&self, column: i32, row: i32) -> bool {
        (column as u32) < self.columns && (row as u32) < self.rows
    }

    /// Adds `amount` to a cell, as [`GridMap::add`].
    #[inline]
    fn add(&mut self, column: i32, row: i32, amount: LogOdds) -> bool {
        if !self.inside(column, row) {
            return false;
        }
        let at = row as usize * self.width + column as usize;
        let Some(cell) = self.cells.get_mut(at) else {
            return false;
        };
        let clamp = i32::from(self.evidence.clamp);
        *cell = (i32::from(*cell) + i32::from(amount))
            .max(-clamp)
            .min(clamp) as LogOdds;
        true
    }

    /// Where beams from `from` start, as [`GridMap::beam_origin`].
    pub fn beam_origin(&self, from: (i32, i32)) -> BeamOrigin {
        beam_origin(
            &self.geometry,
            self.divider,
            (self.columns, self.rows),
            from,
        )
    }
    /// Marks the cells of `walk` free but for `spared`; returns how many were inside the
    /// grid.
    ///
    /// Any walk: beams take [`BeamWriter::short_ray`] first, which leaves here only what its
    /// loop does not cover. When both end cells are in the grid, so is every cell between
    /// (the walk never leaves their bounding box), and the loop steps a flat index instead
    /// of checking each cell's column and row. Never inlined: inside a large caller (the
    /// step, the firmware's task) its loop state does not fit the Cortex-M0+'s registers
    /// and goes through the stack at every cell.
    #[inline(never)]
    fn mark_free<T: WalkInt>(&mut self, walk: Walk<T>, spared: Option<(i32, i32)>) -> u32 {
        let miss = i32::from(self.evidence.miss);
        let clamp = i32::from(self.evidence.clamp);
        let index = |(column, row): (i32, i32)| {
            self.inside(column, row)
                .then(|| row as usize * self.width + column as usize)
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
        let row_step = walk.step_row as isize * self.width as isize;
        let cells = &mut *self.cells;
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

    /// Writes a beam from `o`'s cell whose free cells end `free` millimetres away and
    /// which stopped `to` away, the common case by [`free_walk`]; `None` (having written
    /// nothing) when it needs the general walk instead: an end outside the grid or more
    /// than 2^15 mm from its corner, a free end on a cell corner, or a hit cell on the
    /// walk before its end.
    ///
    /// The walk crosses exactly the first `columns + rows` boundaries of its line in the
    /// order of `Walk::advance`'s difference rule; `advance` also counts boundaries per axis
    /// only to end a segment that stops exactly on a cell corner in its own cell, which is
    /// left to `mark_free`, and so is a spared cell anywhere but the end (a beam's hit cell
    /// is further along the same ray, so it is on the walk only as its end cell).
    #[inline(always)]
    fn short_ray(
        &mut self,
        o: &OriginCell,
        free: (i32, i32),
        to: (i32, i32),
        hit: bool,
    ) -> Option<u32> {
        let cell = self.geometry.cell_mm;
        // `o` was worked out for this cell size, and its cell is in use here.
        if o.cell_mm != cell || !self.inside(o.column, o.row) || !self.walks_fit {
            return None;
        }
        // A wrapped sum lands within 2^15 of the corner only when the true sum does, so
        // `free` and `to` are the ends' true offsets from the start (under 2^15 each way).
        let end = (o.x.wrapping_add(free.0), o.y.wrapping_add(free.1));
        let divider = self.divider;
        let cell_of = |p: (i32, i32)| Some((divider.fast_floor(p.0)?, divider.fast_floor(p.1)?));
        let (column, row) = cell_of(end).filter(|&(c, r)| self.inside(c, r))?;
        if column * cell == end.0 && row * cell == end.1 {
            return None;
        }
        let spared = if hit {
            Some(cell_of((o.x.wrapping_add(to.0), o.y.wrapping_add(to.1)))?)
        } else {
            None
        };
        let spare_end = spared == Some((column, row));
        let between = |v: i32, a: i32, b: i32| a.min(b) <= v && v <= a.max(b);
        if !spare_end
            && spared.is_some_and(|(c, r)| between(c, o.column, column) && between(r, o.row, row))
        {
            return None;
        }
        // Off the walk (or spared on it), the hit cell is written first.
        let mut written = 0;
        if let Some((c, r)) = spared {
            written = u32::from(self.add(c, r, self.evidence.hit));
        }
        let (dx, dy) = free;
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
        let count = 1 + columns + rows - u32::from(spare_end);
        let width = self.width;
        let at = o.row as usize * width + o.column as usize;
        let end_at = row as usize * width + column as usize;
        let row_step = if dy > 0 {
            width as isize
        } else {
            -(width as isize)
        };
        let ends = (at, end_at);
        // SAFETY: the walk stays in the rectangle its end cells span (above), and both are
        // in use, so every cell of it is in `cells` (`walks_fit`).
        #[allow(unsafe_code)]
        unsafe {
            if dx > 0 {
                free_walk::<true>(self.cells, self.after_miss, ends, &steps, row_step, count)
            } else {
                free_walk::<false>(self.cells, self.after_miss, ends, &steps, row_step, count)
            }
        };
        Some(written + count)
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

    /// [`BeamWriter::insert_beam`] for a beam from `start`: its free cells end `free`
    /// millimetres away (`dx`, `dy`), and it stopped `to` away.
    ///
    /// Never inlined, with `short_ray` (and its walk) inlined into it: a beam's set-up then
    /// has a frame of its own, not the caller's crowded one, where its values would go
    /// through the stack on the Cortex-M0+.
    #[inline(never)]
    pub fn insert_ray(
        &mut self,
        start: &BeamOrigin,
        free: (i32, i32),
        to: (i32, i32),
        hit: bool,
    ) -> u32 {
        let short = start
            .cell
            .as_ref()
            .and_then(|o| self.short_ray(o, free, to, hit));
        match short {
            Some(written) => written,
            None => self.insert_beam_any_along(start.map_mm, free, to, hit),
        }
    }

    /// [`BeamWriter::insert_beam_any`] with the ends given from `from`.
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

    /// [`BeamWriter::insert_beam`] the general way, for any segment in or out of the grid.
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
        let mut written = match CellWalk::with_divider(&self.geometry, self.divider, from, free_end)
        {
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
    /// The cell size it was worked out for.
    cell_mm: i32,
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

/// Frees `count` cells from flat index `ends.0`, a step to the right (`RIGHT`) or left
/// along a row or `row_step` cells along a column as `steps` decides, towards the cell at
/// `ends.1`.
///
/// No check per cell: the M0+ would spend as long on it as on the cell. Each loop runs
/// one axis's steps with only that axis's values live, so that all of them stay in the
/// seven registers the M0+ has for them. Inlined into `short_ray`, the end of the
/// beam's set-up, where the set-up's own values are no longer live: a call would cost
/// its arguments' trip through the stack and a frame of its own.
///
/// # Safety
///
/// Every cell the walk visits is in `cells`: the caller has proved that it stays in the
/// rectangle its end cells span, rows of `row_step.unsigned_abs()` cells, and that the
/// rectangle is in `cells`. Test builds check each cell against that rectangle.
#[inline(always)]
#[allow(unsafe_code)]
unsafe fn free_walk<const RIGHT: bool>(
    cells: &mut [LogOdds],
    after_miss: &[LogOdds; 256],
    ends: (usize, usize),
    steps: &Steps,
    row_step: isize,
    count: u32,
) {
    if count == 0 {
        return;
    }
    let (delta_column, delta_row) = (steps.delta_column, steps.delta_row);
    let mut diff = steps.diff;
    let mut left = count;
    let base = cells.as_mut_ptr();
    let mut cell = base.wrapping_add(ends.0);
    let free = |cell: *mut LogOdds| {
        if cfg!(any(test, debug_assertions)) {
            let at = (cell as usize).wrapping_sub(base as usize);
            let width = row_step.unsigned_abs();
            let (column, row) = (at % width, at / width);
            let spans = |v: usize, a: usize, b: usize| a.min(b) <= v && v <= a.max(b);
            assert!(
                spans(column, ends.0 % width, ends.1 % width)
                    && spans(row, ends.0 / width, ends.1 / width)
                    && at < cells.len(),
                "cell {at} outside the walk from {} to {}",
                ends.0,
                ends.1
            );
        }
        // SAFETY: `cell` is in `cells` (this function's contract), which is borrowed
        // mutably here.
        unsafe {
            *cell = after_miss[*cell as u8 as usize];
        }
    };
    // The count is tested before the difference moves, so that the sign test reads the
    // flags of its update. One step past the last cell is never taken.
    loop {
        while diff < 0 {
            free(cell);
            left -= 1;
            if left == 0 {
                return;
            }
            cell = if RIGHT {
                cell.wrapping_add(1)
            } else {
                cell.wrapping_sub(1)
            };
            diff = diff.wrapping_add(delta_column);
        }
        loop {
            free(cell);
            left -= 1;
            if left == 0 {
                return;
            }
            cell = cell.wrapping_offset(row_step);
            diff = diff.wrapping_sub(delta_row);
            if diff < 0 {
                break;
            }
        }
    }
}

/// A 32-bit walk's difference rule, as [`free_walk`] takes it.
#[derive(Clone, Copy)]
struct Steps {
    diff: i32,
    delta_column: i32,
    delta_row: i32,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::TEST_GEOMETRY as GEO;
    use crate::grid::{Evidence, GridMap};

    /// Evidence other than the seed's, whose third miss in a cell reaches the floor.
    const OTHER: Evidence = Evidence {
        hit: 50,
        miss: -45,
        clamp: 100,
        free_below: 10,
        occupied_above: 10,
    };

    /// Writes one beam three times into a fresh grid by `insert_beam` and into another
    /// by the plain iterator, cell by cell, and checks counts and cells agree.
    fn assert_beam_as_plain(from: (i32, i32), free_end: (i32, i32), to: (i32, i32), hit: bool) {
        assert_beam_as_plain_with(Evidence::SEED, from, free_end, to, hit);
    }

    /// [`assert_beam_as_plain`] with `evidence`.
    fn assert_beam_as_plain_with(
        evidence: Evidence,
        from: (i32, i32),
        free_end: (i32, i32),
        to: (i32, i32),
        hit: bool,
    ) {
        let mut fast: GridMap<46, 46> = GridMap::new(GEO, evidence);
        let mut plain: GridMap<46, 46> = GridMap::new(GEO, evidence);
        for _ in 0..3 {
            let n = fast.insert_beam(from, free_end, to, hit);
            let hit_cell = GEO.cell_of(to.0, to.1);
            let mut m = 0;
            for (c, r) in CellWalk::new(&GEO, from, free_end) {
                if !(hit && (c, r) == hit_cell) && plain.add(c, r, evidence.miss) {
                    m += 1;
                }
            }
            if hit && plain.add(hit_cell.0, hit_cell.1, evidence.hit) {
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
        // cell), in or partly out of the grid, from a fixed pseudo-random sequence, with the
        // seed's evidence and with other evidence.
        for evidence in [Evidence::SEED, OTHER] {
            let mut rng = crate::lcg::Lcg::new(0x9e37_79b9_7f4a_7c15_u64);
            let mut next = |span: i32| rng.within(i64::from(span)) as i32;
            for _ in 0..3_000 {
                let from = (next(1_400) + 850, next(1_400) + 850);
                let to = (from.0 + next(2_500), from.1 + next(2_500));
                // A hit cell anywhere near the end, on the walk or off it.
                let free_end = (to.0 - next(60), to.1 - next(60));
                assert_beam_as_plain_with(evidence, from, free_end, to, next(1) >= 0);
                // As a beam casts it: the free end a cell short along the same ray.
                let (dx, dy) = (to.0 - from.0, to.1 - from.1);
                let length = (((dx as i64).pow(2) + (dy as i64).pow(2)) as f64)
                    .sqrt()
                    .max(1.0);
                let short = |d: i32| d - (d as f64 * 50.0 / length) as i32;
                let free_end = (from.0 + short(dx), from.1 + short(dy));
                assert_beam_as_plain_with(evidence, from, free_end, to, next(1) >= 0);
            }
        }
    }

    #[test]
    fn the_fast_walk_takes_any_evidence() {
        // A short beam from inside the grid, off every corner, with evidence other than the
        // seed's: the specialised loop writes it (not the general walk), down to the floor.
        let mut g: GridMap<46, 46> = GridMap::new(GEO, OTHER);
        let origin = g.beam_origin((712, 533));
        let o = origin.cell.expect("the sensor's cell is in the grid");
        let end = (o.x + 310, o.y + 170);
        let end_cell = (end.0 / GEO.cell_mm, end.1 / GEO.cell_mm);
        for pass in 1..=3 {
            let written = g.beams().short_ray(&o, (310, 170), (310, 170), false);
            assert_eq!(written, Some(1 + 6 + 4), "pass {pass}");
            let floor = (pass * OTHER.miss as i32).max(-(OTHER.clamp as i32));
            assert_eq!(g.log_odds(end_cell.0, end_cell.1), Some(floor as LogOdds));
            assert_eq!(g.log_odds(o.column, o.row), Some(floor as LogOdds));
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
    fn walks_to_the_grids_edges_stay_in_its_cells() {
        // A grid exactly its size (the last cell is the slice's last byte): beams from
        // cells near every side to every edge cell, most of them taking the unchecked walk
        // (whose test build checks each cell against the rectangle it was proved to stay
        // in), write what the plain walk writes.
        const W: usize = 20;
        const H: usize = 12;
        let cell = GEO.cell_mm;
        let mm = |c: i32, r: i32, x: i32, y: i32| {
            (
                GEO.origin_x_mm + c * cell + x,
                GEO.origin_y_mm + r * cell + y,
            )
        };
        let edges = (0..W as i32)
            .flat_map(|c| [(c, 0), (c, H as i32 - 1)])
            .chain((0..H as i32).flat_map(|r| [(0, r), (W as i32 - 1, r)]));
        let froms = [(0, 0), (19, 11), (3, 10), (18, 1), (9, 6)];
        for (c0, r0) in froms {
            let mut fast: GridMap<W, H> = GridMap::new(GEO, Evidence::SEED);
            let mut plain: GridMap<W, H> = GridMap::new(GEO, Evidence::SEED);
            for (i, (c, r)) in edges.clone().enumerate() {
                let i = i as i32;
                let from = mm(c0, r0, 7 + i % 37, 43 - i % 29);
                let to = mm(c, r, 1 + (i * 7) % 48, 48 - (i * 11) % 47);
                let hit = i % 3 != 0;
                let n = fast.insert_beam(from, to, to, hit);
                let hit_cell = GEO.cell_of(to.0, to.1);
                let mut m = 0;
                for (c, r) in CellWalk::new(&GEO, from, to) {
                    if !(hit && (c, r) == hit_cell) && plain.add(c, r, Evidence::SEED.miss) {
                        m += 1;
                    }
                }
                if hit && plain.add(hit_cell.0, hit_cell.1, Evidence::SEED.hit) {
                    m += 1;
                }
                assert_eq!(n, m, "{from:?} -> {to:?}");
            }
            assert_eq!(fast.rows(), plain.rows(), "from cell ({c0}, {r0})");
        }
    }

    #[test]
    fn beam_marks_free_then_hit_and_clips() {
        let mut g: GridMap<46, 46> = GridMap::new(GEO, Evidence::SEED);
        // From (700, 500) straight up to the far wall at 2000 mm.
        let n = g.insert_beam((700, 500), (700, 1950), (700, 2000), true);
        let (c, r) = GEO.cell_of(700, 2000);
        assert_eq!(g.log_odds(c, r), Some(Evidence::SEED.hit));
        assert_eq!(g.log_odds(c, r - 1), Some(Evidence::SEED.miss));
        assert_eq!(n, 31);
        // A beam leaving the grid entirely is clipped, not a panic.
        let n = g.insert_beam((700, 500), (700, 90_000), (700, 100_000), true);
        assert!(n > 0 && n < 60);
    }

    #[test]
    fn a_grid_limited_to_a_world_maps_as_one_built_that_size() {
        // The simulator's large grid limited to 20 x 12 against a 20 x 12 grid: beams from
        // inside, many leaving it (fast walks and general ones), write the same cells and
        // count the same; nothing beyond the limit is ever written.
        let mut large: GridMap<46, 46> = GridMap::new(GEO, Evidence::SEED);
        large.limit_to(20, 12);
        let mut exact: GridMap<20, 12> = GridMap::new(GEO, Evidence::SEED);
        let mut rng = crate::lcg::Lcg::new(7);
        let mut next = |span: i32| rng.within(i64::from(span)) as i32;
        for _ in 0..2_000 {
            let from = (next(450) + 500, next(250) + 350);
            let to = (from.0 + next(1_600), from.1 + next(1_600));
            let free_end = (to.0 - next(40), to.1 - next(40));
            let hit = next(1) >= 0;
            assert_eq!(
                large.insert_beam(from, free_end, to, hit),
                exact.insert_beam(from, free_end, to, hit),
                "{from:?} -> {to:?}"
            );
        }
        for (r, row) in large.rows().iter().enumerate() {
            for (c, &cell) in row.iter().enumerate() {
                let want = exact.rows().get(r).and_then(|row| row.get(c)).copied();
                assert_eq!(cell, want.unwrap_or(0), "({c}, {r})");
            }
        }
        assert_eq!(large.counts(), exact.counts());
        assert_eq!(large.log_odds(20, 0), None);
    }
}
