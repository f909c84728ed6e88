//! Each input's trust, from its verdicts, and how long a reading has repeated.

use super::Doubt;

/// One input's trust: doubted from a bad reading until enough good ones in a row.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default)]
pub(super) struct Watch {
    pub(super) doubt: Option<Doubt>,
    pub(super) good_in_a_row: u8,
}

impl Watch {
    #[inline(never)]
    pub(super) fn judge(&mut self, verdict: Result<(), Doubt>, trust_after: u8) {
        match verdict {
            Err(doubt) => {
                self.doubt = self.doubt.or(Some(doubt));
                self.good_in_a_row = 0;
            }
            Ok(()) if self.doubt.is_some() => {
                self.good_in_a_row = self.good_in_a_row.saturating_add(1);
                if self.good_in_a_row >= trust_after {
                    *self = Watch::default();
                }
            }
            Ok(()) => {}
        }
    }
}

/// How many ticks running a reading has been equal to the one before.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default)]
pub(super) struct Repeats<T> {
    pub(super) last: Option<T>,
    repeats: u8,
}

impl<T: PartialEq + Copy> Repeats<T> {
    /// Takes a reading; returns the reading before it and how many repeats end here.
    #[inline(never)]
    pub(super) fn push(&mut self, reading: T) -> (Option<T>, u8) {
        let before = self.last.replace(reading);
        self.repeats = if before == Some(reading) {
            self.repeats.saturating_add(1)
        } else {
            0
        };
        (before, self.repeats)
    }

    /// Takes a reading; returns how many repeats end here ([`Repeats::push`] without
    /// handing back the reading before).
    #[inline(never)]
    pub(super) fn count(&mut self, reading: T) -> u8 {
        self.repeats = if self.last == Some(reading) {
            self.repeats.saturating_add(1)
        } else {
            0
        };
        self.last = Some(reading);
        self.repeats
    }
}
