//! The window's translations along one axis, cut where they cross a cell centre's line.
//! Between two lines the interpolation is linear, so each run of translations between the
//! same two lines is an add a translation (see `spread`).
//!
//! How the runs fall depends only on how far past a line the first translation lands, so
//! for cells of up to [`TABLED`] millimetres it is looked up, and each way they can fall
//! (a pattern) is numbered: ends whose runs follow the same patterns along both axes are
//! summed before they are spread.

use super::divide::Divider;
use super::footprint::FOOTPRINT;

/// Cells up to this size, in millimetres, have their runs in a table.
const TABLED: usize = 128;

/// Most patterns an axis may have for its ends to be summed, beyond which every end is
/// spread on its own (slower, the same sums). Steps that divide the cell fall in at most
/// `cell / step` patterns (1 cm steps on 5 cm cells: five); others in more. Each pair
/// of patterns holds a 144-byte sum, so the matcher's RAM grows with the square of this.
pub(super) const PATTERNS: usize = 6;

/// Runs along one axis: how many translations each, how far past its cell centre's line
/// the first of each lands, in millimetres, and the pattern of the counts if numbered.
pub(super) struct Runs {
    pub count: [usize; FOOTPRINT - 1],
    pub past: [i32; FOOTPRINT - 1],
    pub pattern: Option<usize>,
}

/// The runs of a window of `side` translations `step` millimetres apart on `cell`
/// millimetre cells, wherever in a cell it starts (for a window `Window::new` accepts: at
/// most three runs).
#[derive(Clone, Copy, Debug)]
pub(super) struct RunTable {
    side: usize,
    step: i32,
    cell: i32,
    per_step: Divider,
    /// For each millimetre past a line at which the first translation can land, the
    /// pattern its runs follow.
    pattern_of: [u8; TABLED],
    /// Each pattern: how many translations land short of the next line and of the one
    /// after.
    patterns: [[u8; 2]; PATTERNS],
    /// Whether the table is in use: cells up to [`TABLED`] with at most [`PATTERNS`]
    /// patterns.
    tabled: bool,
}

impl RunTable {
    /// The table for `side` translations; `None` unless `step` is positive and `side`
    /// fits a byte.
    pub fn new(side: usize, step: i32, cell: i32) -> Option<RunTable> {
        if side > usize::from(u8::MAX) {
            return None;
        }
        let mut table = RunTable {
            side,
            step,
            cell,
            per_step: Divider::new(step)?,
            pattern_of: [0; TABLED],
            patterns: [[0; 2]; PATTERNS],
            tabled: false,
        };
        let Some(cells) = usize::try_from(cell).ok().filter(|&c| c <= TABLED) else {
            return Some(table);
        };
        let mut found = 0;
        for within in 0..cells {
            let (one, two) = table.counted(within as i32);
            let counts = [one as u8, two as u8];
            let known = table.patterns.iter().take(found).position(|&p| p == counts);
            let pattern = match known {
                Some(p) => p,
                None if found < PATTERNS => {
                    table.patterns[found] = counts;
                    found += 1;
                    found - 1
                }
                None => return Some(table),
            };
            table.pattern_of[within] = pattern as u8;
        }
        table.tabled = true;
        Some(table)
    }

    /// The runs of a window whose first translation lands `within` millimetres past a
    /// cell centre's line (`0..cell`).
    #[inline(always)]
    pub fn runs(&self, within: i32) -> Runs {
        let tabled = self
            .pattern_of
            .get(within as usize)
            .filter(|_| self.tabled)
            .and_then(|&p| Some((usize::from(p), *self.patterns.get(usize::from(p))?)));
        let (pattern, (one, two)) = match tabled {
            Some((p, [one, two])) => (Some(p), (usize::from(one), usize::from(two))),
            None => (None, self.counted(within)),
        };
        let at = |n: usize, lines: i32| within + n as i32 * self.step - lines * self.cell;
        Runs {
            count: [one, two - one, self.side - two],
            past: [within, at(one, 1), at(two, 2)],
            pattern,
        }
    }

    /// The same table, its patterns unnumbered: every end spread on its own.
    #[cfg(test)]
    pub fn unnumbered(self) -> RunTable {
        RunTable {
            tabled: false,
            ..self
        }
    }

    /// The run lengths of pattern `p`.
    pub fn counts(&self, p: usize) -> [usize; FOOTPRINT - 1] {
        let [one, two] = self.patterns.get(p).copied().unwrap_or_default();
        let (one, two) = (usize::from(one), usize::from(two));
        [one, two - one, self.side - two]
    }

    /// How many translations land short of the next line, and of the one after.
    fn counted(&self, within: i32) -> (usize, usize) {
        let short_of = |edge: i32| -> usize {
            if edge <= within {
                return 0;
            }
            let (q, _) = self.per_step.div_rem(edge - within - 1);
            usize::try_from(q + 1).map_or(self.side, |n| n.min(self.side))
        };
        (short_of(self.cell), short_of(2 * self.cell))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The runs by stepping through the translations one by one.
    fn stepped(side: usize, step: i32, cell: i32, within: i32) -> ([usize; 3], [i32; 3]) {
        let (mut count, mut past) = ([0; 3], [0; 3]);
        let (mut p, mut run) = (within, 0);
        past[0] = p;
        for _ in 0..side {
            if p >= cell {
                p -= cell;
                run += 1;
                past[run] = p;
            }
            count[run] += 1;
            p += step;
        }
        (count, past)
    }

    #[test]
    fn runs_are_those_stepped_through_tabled_or_not() {
        // Tabled (six patterns at most); a step that does not divide the cell, seven
        // patterns; a cell too large for the table.
        for (side, step, cell, tabled) in [
            (7, 10, 50, true),
            (7, 10, 60, true),
            (7, 1, 3, true),
            (5, 25, 50, true),
            (7, 7, 30, false),
            (7, 60, 200, false),
        ] {
            let Some(table) = RunTable::new(side, step, cell) else {
                panic!("{side} x {step} on {cell} refused");
            };
            for within in 0..cell {
                let runs = table.runs(within);
                let (count, past) = stepped(side, step, cell, within);
                let case = format!("{side} x {step} on {cell} from {within}");
                assert_eq!(runs.count, count, "{case}");
                for ((&n, &got), &want) in count.iter().zip(&runs.past).zip(&past) {
                    if n > 0 {
                        assert_eq!(got, want, "{case}");
                    }
                }
                assert_eq!(runs.pattern.is_some(), tabled, "{case}");
                if let Some(p) = runs.pattern {
                    assert_eq!(table.counts(p), count, "{case}");
                }
            }
        }
        assert!(RunTable::new(7, 0, 50).is_none());
    }
}
