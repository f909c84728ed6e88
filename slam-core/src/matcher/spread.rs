//! Spreading beam ends' scores over the translations: each end adds the bilinear
//! interpolation of its block at every translation, in cells squared (`cell^2` per point
//! of class score).
//!
//! Between two cell centres along x the interpolation is linear, and so is it between
//! two along y: the translations fall in at most three runs along each axis, and in each
//! rectangle of runs an end adds `first + k rise` at the `k`-th translation of its first
//! row, `first_by_row` more first and `rise_by_row` more rise each row after. So a
//! translation costs an add, and the multiplies are spent once a rectangle.
//!
//! Those four numbers are linear in the block's scores, so ends whose runs follow the
//! same patterns along both axes (`runs`) are summed before they are spread: with the
//! seed's window an axis has five patterns, so a heading's eighty ends fall in at most 25
//! pairs of them, and the translations are visited once a pair rather than once an end.
//! All in integers and exact, so neither the order nor the summing changes the result.

use super::footprint::{Footprint, Window, FOOTPRINT};
use super::runs::{RunTable, Runs, PATTERNS};

/// Rectangles of runs along each axis.
const RUNS: usize = FOOTPRINT - 1;

/// What an end, or a sum of ends, adds over one rectangle of translations.
#[derive(Clone, Copy, Default, Debug)]
struct Rectangle {
    first: i32,
    rise: i32,
    first_by_row: i32,
    rise_by_row: i32,
}

impl Rectangle {
    fn add(&mut self, other: &Rectangle) {
        self.first += other.first;
        self.rise += other.rise;
        self.first_by_row += other.first_by_row;
        self.rise_by_row += other.rise_by_row;
    }
}

/// Ends summed by the patterns of their runs, a heading at a time.
#[derive(Clone, Debug)]
pub(super) struct Patterns {
    /// Which of `sums` hold ends this heading, a bit each.
    used: u64,
    /// For each pair of patterns (x's times [`PATTERNS`] plus y's), each rectangle's sum,
    /// `[y run][x run]`.
    sums: [[[Rectangle; RUNS]; RUNS]; PATTERNS * PATTERNS],
}

/// A pair of patterns' bit in `used`: x's times this plus y's, so that the spread takes
/// the pair back with a shift and a mask (the M0+ has no divide).
const STRIDE: usize = 8;

const _: () = assert!(PATTERNS <= STRIDE && STRIDE * STRIDE <= u64::BITS as usize);

impl Patterns {
    /// Nothing summed.
    pub const EMPTY: Patterns = Patterns {
        used: 0,
        sums: [[[Rectangle {
            first: 0,
            rise: 0,
            first_by_row: 0,
            rise_by_row: 0,
        }; RUNS]; RUNS]; PATTERNS * PATTERNS],
    };

    /// Forgets every sum.
    pub fn clear(&mut self) {
        self.used = 0;
    }

    /// Adds end `f` to `scores`: into its patterns' sums if its runs are numbered along
    /// both axes, straight into `scores` if not.
    #[inline(never)]
    pub fn add<const SIDE: usize>(
        &mut self,
        scores: &mut [[i32; SIDE]; SIDE],
        f: &Footprint,
        w: &Window,
    ) {
        let along_x = w.runs.runs(i32::from(f.within_x));
        let along_y = w.runs.runs(i32::from(f.within_y));
        let (Some(px), Some(py)) = (along_x.pattern, along_y.pattern) else {
            for_each_rectangle(f, &along_x, &along_y, w, |r, c, sum| {
                add_rectangle(scores, run_of(&along_y, r), run_of(&along_x, c), sum);
            });
            return;
        };
        let Some(sums) = self.sums.get_mut(px * PATTERNS + py) else {
            return;
        };
        let bit = 1u64 << (px * STRIDE + py);
        if self.used & bit == 0 {
            *sums = [[Rectangle::default(); RUNS]; RUNS];
            self.used |= bit;
        }
        for_each_rectangle(f, &along_x, &along_y, w, |r, c, sum| {
            if let Some(slot) = sums.get_mut(r).and_then(|row| row.get_mut(c)) {
                slot.add(sum);
            }
        });
    }

    /// Adds every pattern's sums to `scores` and forgets them.
    #[inline(never)]
    pub fn spread<const SIDE: usize>(&mut self, scores: &mut [[i32; SIDE]; SIDE], runs: &RunTable) {
        let mut used = self.used;
        self.used = 0;
        while used != 0 {
            let index = used.trailing_zeros() as usize;
            used &= used - 1;
            let (px, py) = (index / STRIDE, index % STRIDE);
            let Some(sums) = self.sums.get(px * PATTERNS + py) else {
                continue;
            };
            let (columns, rows) = (runs.counts(px), runs.counts(py));
            let mut top = 0;
            for (&height, row_sums) in rows.iter().zip(sums) {
                let mut left = 0;
                for (&width, sum) in columns.iter().zip(row_sums) {
                    if height > 0 && width > 0 {
                        add_rectangle(scores, (top, height), (left, width), sum);
                    }
                    left += width;
                }
                top += height;
            }
        }
    }
}

/// Run `i` along an axis: where it starts and how many translations it holds.
fn run_of(runs: &Runs, i: usize) -> (usize, usize) {
    let start = runs.count.iter().take(i).sum();
    (start, runs.count.get(i).copied().unwrap_or(0))
}

/// What end `f` adds over each non-empty rectangle of runs, given to `visit` with the
/// rectangle's y run and x run.
#[inline(always)]
fn for_each_rectangle(
    f: &Footprint,
    along_x: &Runs,
    along_y: &Runs,
    w: &Window,
    mut visit: impl FnMut(usize, usize, &Rectangle),
) {
    let (cell, step) = (w.cell, w.step);
    for (r, (&height, &py)) in along_y.count.iter().zip(&along_y.past).enumerate() {
        let (Some(lo), Some(hi)) = (f.scores.get(r), f.scores.get(r + 1)) else {
            break;
        };
        if height == 0 {
            continue;
        }
        // The block interpolated along y at this run's first row, a value a column, and
        // how much each column rises from one block row to the next.
        let up: [i32; FOOTPRINT] = core::array::from_fn(|c| hi[c] - lo[c]);
        let column: [i32; FOOTPRINT] = core::array::from_fn(|c| lo[c] * cell + up[c] * py);
        for (c, (&width, &px)) in along_x.count.iter().zip(&along_x.past).enumerate() {
            let c = c.min(FOOTPRINT - 2);
            if width > 0 {
                let rise = column[c + 1] - column[c];
                let rise_by_row = (up[c + 1] - up[c]) * step;
                let sum = Rectangle {
                    first: column[c] * cell + rise * px,
                    rise: rise * step,
                    first_by_row: up[c] * step * cell + rise_by_row * px,
                    rise_by_row: rise_by_row * step,
                };
                visit(r, c, &sum);
            }
        }
    }
}

/// Adds `sum` over the rectangle of translation rows `(top, height)` and columns
/// `(left, width)`. Its numbers taken out first, so that the M0+ keeps them in registers.
#[inline(always)]
fn add_rectangle<const SIDE: usize>(
    scores: &mut [[i32; SIDE]; SIDE],
    (top, height): (usize, usize),
    (left, width): (usize, usize),
    sum: &Rectangle,
) {
    let Rectangle {
        mut first,
        mut rise,
        first_by_row,
        rise_by_row,
    } = *sum;
    let Some(rows) = scores.get_mut(top..top + height) else {
        return;
    };
    for row in rows.iter_mut() {
        let Some(span) = row.get_mut(left..left + width) else {
            return;
        };
        let mut v = first;
        for s in span.iter_mut() {
            *s += v;
            v += rise;
        }
        first += first_by_row;
        rise += rise_by_row;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lcg::Lcg;

    const SIDE: usize = 7;

    /// The bilinear interpolation of `f`'s block at every translation, one by one.
    fn interpolated(f: &Footprint, w: &Window) -> [[i32; SIDE]; SIDE] {
        let at = |within: i32, k: usize| {
            let p = within + k as i32 * w.step;
            ((p / w.cell) as usize, p % w.cell)
        };
        core::array::from_fn(|j| {
            core::array::from_fn(|i| {
                let (y, x) = (i32::from(f.within_y), i32::from(f.within_x));
                let ((r, py), (c, px)) = (at(y, j), at(x, i));
                let s = |r: usize, c: usize| f.scores[r][c];
                s(r, c) * (w.cell - px) * (w.cell - py)
                    + s(r, c + 1) * px * (w.cell - py)
                    + s(r + 1, c) * (w.cell - px) * py
                    + s(r + 1, c + 1) * px * py
            })
        })
    }

    #[test]
    fn summed_or_one_by_one_the_ends_add_their_interpolations() {
        let Some(w) = Window::new(SIDE, 10, 50) else {
            panic!("the seed's window refused");
        };
        let one_by_one = Window {
            runs: w.runs.unnumbered(),
            ..w
        };
        let mut rng = Lcg::new(0x005E_ED0F_C0DE);
        for _ in 0..50 {
            let (mut summed, mut single, mut want) =
                ([[0; SIDE]; SIDE], [[0; SIDE]; SIDE], [[0; SIDE]; SIDE]);
            let (mut patterns, mut unused) = (Patterns::EMPTY, Patterns::EMPTY);
            for _ in 0..80 {
                let mut f = Footprint::EMPTY;
                for row in f.scores.iter_mut() {
                    for s in row.iter_mut() {
                        *s = [4, -2, 0][(rng.next_u64() >> 33) as usize % 3];
                    }
                }
                f.within_x = ((rng.next_u64() >> 33) % 50) as u16;
                f.within_y = ((rng.next_u64() >> 33) % 50) as u16;
                patterns.add(&mut summed, &f, &w);
                unused.add(&mut single, &f, &one_by_one);
                for (row, add) in want.iter_mut().zip(interpolated(&f, &w)) {
                    for (s, a) in row.iter_mut().zip(add) {
                        *s += a;
                    }
                }
            }
            patterns.spread(&mut summed, &w.runs);
            assert_eq!(unused.used, 0, "unnumbered runs are never summed");
            assert_eq!(summed, want);
            assert_eq!(single, want);
        }
    }
}
