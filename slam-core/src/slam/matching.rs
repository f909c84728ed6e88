//! The step's match against the map: started by the step, searched in pieces by the
//! caller if it defers it, and applied through the pose history.

use super::{Slam, StepReport};

use crate::estimator::Estimator;
use crate::pose::RigidMotion;

impl<const W: usize, const H: usize> Slam<W, H> {
    /// Leaves each step's match to the caller ([`Slam::search_match`], then
    /// [`Slam::finish_match`]), so that it can yield to other work between pieces; the
    /// result is the same, bit for bit, as a step that matches itself.
    pub fn defer_matching(&mut self, defer: bool) {
        self.defer_matching = defer;
    }

    /// Does up to `pieces` more pieces of the match the last step started: its start,
    /// each piece of its search ([`Matcher::search`]), then the surface's moments. `true`
    /// when nothing is left but to apply it ([`Slam::finish_match`]).
    ///
    /// [`Matcher::search`]: crate::matcher::Matcher::search
    pub fn search_match(&mut self, pieces: usize) -> bool {
        for _ in 0..pieces {
            if core::mem::take(&mut self.match_due) {
                self.start_match();
                continue;
            }
            if self.matched.is_some() || !self.matcher.in_progress() {
                return true;
            }
            if self.matcher.searched() {
                self.matched = Some(self.matcher.finish());
                continue;
            }
            let view = self.map.view();
            if let Err(why) = self.matcher.search(&view, 1) {
                self.estimator.settle();
                self.match_counters.count(Err(why));
                return true;
            }
        }
        !self.match_due && (self.matched.is_some() || !self.matcher.in_progress())
    }

    /// Finishes the match the last step started, if any (searching what is left), and
    /// returns `report` with the pose and the filter's belief after it. Applies the
    /// corrections the step left recorded to the remembered poses; a caller that defers
    /// matching calls it after every step.
    pub fn finish_match(&mut self, report: StepReport) -> StepReport {
        let pending = self.match_pending();
        if pending {
            self.complete_match();
        }
        // Here, off the step, rather than by the next correction in it.
        self.history.settle();
        self.sweep.settle();
        if !pending {
            return report;
        }
        self.with_belief(report)
    }

    /// `report` with the pose and the filter's belief now. Out of line: one read-out of
    /// the belief off the step for every caller, and the step's own left as it is.
    #[inline(never)]
    pub(super) fn with_belief(&self, report: StepReport) -> StepReport {
        StepReport {
            pose: self.pose,
            estimate: self.filter().map(Estimator::estimate),
            ..report
        }
    }

    /// Whether a match is due, in progress or found and not yet applied.
    #[inline]
    pub(super) fn match_pending(&self) -> bool {
        self.match_due || self.matcher.in_progress() || self.matched.is_some()
    }

    /// Starts matching the sweep; a sweep refused at once is counted.
    fn start_match(&mut self) {
        self.sweep.settle();
        if let Err(why) = self
            .matcher
            .start(&self.sweep, &self.config.depth.beam_angles)
        {
            self.estimator.settle();
            self.match_counters.count(Err(why));
        }
    }

    /// Searches what is left of the match in progress, if any, and applies it through the
    /// pose history.
    pub(super) fn complete_match(&mut self) {
        if !self.search_match(usize::MAX) {
            return;
        }
        let (Some(matching), Some(matched)) = (self.config.matching, self.matched.take()) else {
            return;
        };
        let outcome = matched.and_then(|m| {
            self.last_match = Some(m);
            let corrected =
                self.estimator
                    .apply_match(&m, &matching.noise, &self.map_uncertainty)?;
            Ok(RigidMotion::carrying(&m.prediction, &corrected))
        });
        if let Ok(motion) = &outcome {
            self.carry_past(motion);
        }
        self.estimator.settle();
        self.match_counters.count(outcome.map(|_| ()));
    }
}
