//! The walls ahead after each step: the flow sensor's scale from a drive at a wall, and
//! the gyro's turn held to the wall's.

use super::{Localiser, Slam, StepReport};

use crate::angle::Angle;
use crate::frame::SensorFrame;
use crate::plausible::Trust;
use crate::pose::{Pose, RigidMotion};
use crate::wall_rate::{fit_wall, WallFit, WallRate};
use crate::wall_turn::{self, WallTurn};

impl<const W: usize, const H: usize> Slam<W, H> {
    /// The walls ahead measure the flow sensor's scale ([`crate::wall_rate`]) and hold the
    /// gyro's turn to their own ([`crate::wall_turn`]) from the tick `step` took `frame`
    /// in, with the drive under way in `walls` and the wall held in `turn` (the caller's,
    /// as the frame is: kept out of the core's own state, whose layout the step's worst
    /// case feels); returns `report` (the step's, or what [`Slam::finish_match`] returned
    /// from it) with the pose, the filter's belief and the trust after it. Called after
    /// every step (after [`Slam::finish_match`] by a caller that defers matching): off
    /// the step, and out of line, so that the caller's loop (the firmware's task, the
    /// step inlined in it) keeps its code.
    #[inline(never)]
    pub fn measure_walls(
        &mut self,
        walls: &mut WallRate,
        turn: &mut WallTurn,
        frame: &SensorFrame,
        report: StepReport,
    ) -> StepReport {
        // The frame's wall, fitted at most once for both.
        let fitted = core::cell::OnceCell::new();
        let angles = self.config.depth.beam_angles;
        let wall =
            || *fitted.get_or_init(|| frame.depth.as_ref().and_then(|s| fit_wall(s, &angles)));
        let turned = self.wall_turn_tick(turn, frame, report.trust, &wall);
        if !self.wall_tick(walls, frame, report.trust, &wall) && !turned {
            return report;
        }
        StepReport {
            trust: self.plausibility.trust(),
            ..self.with_belief(report)
        }
    }

    /// The gyro's turn over this tick, whose inputs `step` trusted as `trust`, held to the
    /// walls' ([`crate::wall_turn`]): checked when no turn was commanded of late and the
    /// gyro and the depth sensor are trusted. A gyro the walls part from is doubted, and
    /// the heading turned back by as much as it turned past them, the filter's heading
    /// taken as set from outside ([`Estimator::heading_set_by_walls`]); while the robot
    /// is then held, the wall's tilt averaged turns it back again, more exactly
    /// ([`Estimator::heading_pinned_by_walls`]). Only with the filter. Returns whether
    /// the heading was turned.
    ///
    /// [`Estimator::heading_set_by_walls`]: crate::estimator::Estimator::heading_set_by_walls
    /// [`Estimator::heading_pinned_by_walls`]: crate::estimator::Estimator::heading_pinned_by_walls
    #[inline(never)]
    fn wall_turn_tick(
        &mut self,
        turn: &mut WallTurn,
        frame: &SensorFrame,
        trust: Trust,
        wall: &impl Fn() -> Option<WallFit>,
    ) -> bool {
        if self.config.localiser != Localiser::Filter {
            return false;
        }
        if turn.holding() {
            let wall = if trust.depth.is_none() { wall() } else { None };
            let doubted = trust.gyro == Some(crate::Doubt::UnseenTurn);
            if let Some(further) = turn.held(wall, doubted) {
                self.turn_back(further);
                self.estimator.heading_pinned_by_walls();
                return true;
            }
            if turn.holding() {
                return false;
            }
        }
        let checked = trust.gyro.is_none()
            && trust.depth.is_none()
            && self.plausibility.turning_of_late() == Some(false);
        let gyro = frame.gyro.filter(|_| checked).map(|g| {
            let g = self.estimator.correct_gyro(g);
            wall_turn::gyro_turn_ndeg(g.rate_mdps, frame.dt_us)
        });
        let wall = if gyro.is_some() { wall() } else { None };
        let Some(excess) = turn.observe(wall, gyro) else {
            return false;
        };
        self.plausibility.doubt_gyro(crate::Doubt::UnseenTurn);
        self.turn_back(excess);
        self.estimator.heading_set_by_walls();
        true
    }

    /// Turns the heading, and the past with it, back anticlockwise by `turn`: the gyro's
    /// turn past the walls. The caller tells the filter how sure of the heading to be.
    fn turn_back(&mut self, turn: Angle) {
        let then = self.pose;
        let corrected = Pose {
            heading: then.heading - turn,
            ..then
        };
        self.carry_past(&RigidMotion::carrying(&then, &corrected));
    }

    /// The drive at a wall takes this tick, whose inputs `step` trusted as `trust`: a
    /// tick that drove straight on a trusted gyro and flow, with a trusted scan of a wall
    /// ahead, adds to it; any other ends it, and a drive long enough is a measurement of
    /// the flow sensor's scale for the filter, which moves the pose at most a match's
    /// step. Only with matching on. Returns whether the filter took a measurement.
    #[inline(never)]
    fn wall_tick(
        &mut self,
        walls: &mut WallRate,
        frame: &SensorFrame,
        trust: Trust,
        wall: &impl Fn() -> Option<WallFit>,
    ) -> bool {
        if self.config.matching.is_none() || self.config.localiser != Localiser::Filter {
            return false;
        }
        let Some(measured) = walls.observe(
            frame,
            self.config.odometry.flow_um_per_count_q16,
            wall,
            &trust,
        ) else {
            return false;
        };
        let then = self.pose;
        let counters = &mut walls.counters;
        let Some(outcome) = self.estimator.apply_flow_scale(&then, &measured) else {
            counters.known += 1;
            return false;
        };
        match outcome {
            Ok(corrected) => {
                counters.taken += 1;
                self.carry_past(&RigidMotion::carrying(&then, &corrected));
            }
            Err(_) => counters.refused += 1,
        }
        self.estimator.settle();
        outcome.is_ok()
    }
}
