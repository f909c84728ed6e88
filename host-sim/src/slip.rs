//! Wheel slip: how the robot's true motion differs from what its motors are asked for.
//!
//! The model and its options are [`crate::scenario::Slip`]'s: spells of lost speed at
//! random moments, and a slide of the robot's centre while it turns. Without slip
//! (`WheelSlip::new(None)`) the true motion is the command, bit for bit, and nothing is
//! drawn.

use crate::robot::Command;
use crate::scenario::Slip;
use crate::world::Vec2;
use rand::Rng;
use rand_chacha::ChaCha8Rng;

/// How the robot really moved in one sub-step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Motion {
    /// Forward speed over the floor, millimetres per second.
    pub speed_mm_s: f64,
    /// Turn rate, degrees per second, positive clockwise.
    pub turn_dps: f64,
    /// Slide of the centre over the floor in this sub-step, in the world's millimetres
    /// (on top of the forward motion).
    pub slide_mm: Vec2,
}

/// The slip of one robot's wheels.
pub struct WheelSlip {
    slip: Option<Slip>,
    /// Seconds left of the spell of lost speed under way (0: none).
    spell_left_s: f64,
    /// The sign of the turn under way (0: not turning), to tell when a new turn starts.
    turn_sign: f64,
    /// This turn's slide per degree turned, world millimetres.
    slide_per_deg: Vec2,
}

impl WheelSlip {
    /// Wheels that slip as `slip` says (not at all when `None`).
    pub fn new(slip: Option<Slip>) -> WheelSlip {
        WheelSlip {
            slip,
            spell_left_s: 0.0,
            turn_sign: 0.0,
            slide_per_deg: Vec2::new(0.0, 0.0),
        }
    }

    /// Whether a spell of lost speed is under way.
    pub fn in_spell(&self) -> bool {
        self.spell_left_s > 0.0
    }

    /// The true motion for `dt_s` seconds under `command`, drawing from `rng` (a stream
    /// of the slip's own, so that slip shifts no sensor's noise).
    pub fn step(&mut self, command: Command, dt_s: f64, rng: &mut ChaCha8Rng) -> Motion {
        let mut motion = Motion {
            speed_mm_s: command.speed_mm_s,
            turn_dps: command.turn_dps,
            slide_mm: Vec2::new(0.0, 0.0),
        };
        let Some(slip) = &self.slip else {
            return motion;
        };

        if self.spell_left_s > 0.0 {
            self.spell_left_s -= dt_s;
        } else if slip.spells_per_min > 0.0 {
            let chance = (slip.spells_per_min / 60.0 * dt_s).clamp(0.0, 1.0);
            if rng.gen_bool(chance) {
                self.spell_left_s = slip.spell_s;
            }
        }
        if self.spell_left_s > 0.0 {
            let keep = 1.0 - slip.speed_loss;
            motion.speed_mm_s *= keep;
            motion.turn_dps *= keep;
        }

        if slip.skid_mm_per_turn > 0.0 {
            let sign = if command.turn_dps == 0.0 {
                0.0
            } else {
                command.turn_dps.signum()
            };
            if sign != 0.0 && sign != self.turn_sign {
                // A new turn: its slide has a direction and a size of its own.
                let direction = Vec2::heading(rng.gen_range(0.0..360.0));
                let per_turn = rng.gen_range(0.0..=2.0 * slip.skid_mm_per_turn);
                let per_deg = per_turn / 360.0;
                self.slide_per_deg = Vec2::new(direction.x * per_deg, direction.y * per_deg);
            }
            self.turn_sign = sign;
            let turned_deg = (motion.turn_dps * dt_s).abs();
            motion.slide_mm = Vec2::new(
                self.slide_per_deg.x * turned_deg,
                self.slide_per_deg.y * turned_deg,
            );
        }
        motion
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    const DT_S: f64 = 0.005;
    const SPIN: Command = Command {
        speed_mm_s: 0.0,
        turn_dps: 31.5,
    };
    const DRIVE: Command = Command {
        speed_mm_s: 86.0,
        turn_dps: 0.0,
    };

    fn slip(spells_per_min: f64, speed_loss: f64, skid_mm_per_turn: f64) -> WheelSlip {
        WheelSlip::new(Some(Slip {
            spells_per_min,
            spell_s: 0.5,
            speed_loss,
            skid_mm_per_turn,
        }))
    }

    fn rng() -> ChaCha8Rng {
        ChaCha8Rng::seed_from_u64(7)
    }

    fn add(a: Vec2, b: Vec2) -> Vec2 {
        Vec2::new(a.x + b.x, a.y + b.y)
    }

    #[test]
    fn without_slip_the_motion_is_the_command_and_nothing_is_drawn() {
        for mut wheels in [WheelSlip::new(None), slip(0.0, 0.3, 0.0)] {
            let mut r = rng();
            for command in [SPIN, DRIVE, Command::default()] {
                let m = wheels.step(command, DT_S, &mut r);
                assert_eq!(
                    (m.speed_mm_s, m.turn_dps),
                    (command.speed_mm_s, command.turn_dps)
                );
                assert_eq!(m.slide_mm, Vec2::new(0.0, 0.0));
            }
            assert_eq!(r.gen::<u64>(), rng().gen::<u64>());
        }
    }

    #[test]
    fn spells_lose_speed_for_their_length() {
        // 30 spells a minute, each half a second: about a quarter of the time in a spell.
        let (mut wheels, mut r) = (slip(30.0, 0.4, 0.0), rng());
        let steps = 60 * 200;
        let (mut slowed, mut travelled_mm) = (0, 0.0);
        for _ in 0..steps {
            let m = wheels.step(DRIVE, DT_S, &mut r);
            travelled_mm += m.speed_mm_s * DT_S;
            if wheels.in_spell() {
                slowed += 1;
                assert!((m.speed_mm_s - 86.0 * 0.6).abs() < 1e-9);
            } else {
                assert_eq!(m.speed_mm_s, 86.0);
            }
        }
        let share = f64::from(slowed) / f64::from(steps);
        assert!((0.15..0.35).contains(&share), "{share}");
        let commanded_mm = 86.0 * 60.0;
        let expected_mm = commanded_mm * (1.0 - 0.4 * share);
        assert!((travelled_mm - expected_mm).abs() < 1e-6, "{travelled_mm}");
    }

    #[test]
    fn a_turn_slides_the_centre_one_drawn_way() {
        let (mut wheels, mut r) = (slip(0.0, 0.0, 10.0), rng());
        assert_eq!(
            wheels.step(DRIVE, DT_S, &mut r).slide_mm,
            Vec2::new(0.0, 0.0),
            "no slide driving straight"
        );
        let mut turn = |command: Command| {
            let steps = (360.0 / 31.5 / DT_S) as usize;
            let slides: Vec<Vec2> = (0..steps)
                .map(|_| wheels.step(command, DT_S, &mut r).slide_mm)
                .collect();
            // One direction and one size for the whole turn.
            assert!(slides.iter().all(|s| *s == slides[0]), "{:?}", slides[0]);
            slides.into_iter().fold(Vec2::new(0.0, 0.0), add)
        };
        let clockwise = turn(SPIN);
        let back = turn(Command {
            turn_dps: -31.5,
            ..SPIN
        });
        for slide in [clockwise, back] {
            // Between none and twice the average of 10 mm a turn.
            assert!(slide.norm() > 0.0 && slide.norm() <= 20.0, "{slide:?}");
        }
        assert_ne!(clockwise, back, "a new turn draws anew");
    }
}
