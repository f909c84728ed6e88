//! A fixed pseudo-random sequence for the unit tests (Knuth's MMIX linear congruential
//! generator): the same numbers every run, with no dependency.

/// The generator's state.
pub(crate) struct Lcg(u64);

impl Lcg {
    /// A sequence starting after `seed`.
    pub(crate) fn new(seed: u64) -> Lcg {
        Lcg(seed)
    }

    /// The next state, all 64 bits.
    pub(crate) fn next_u64(&mut self) -> u64 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        self.0
    }

    /// A number in `-span..=span`, from the state's high bits (the low ones cycle fast).
    pub(crate) fn within(&mut self, span: i64) -> i64 {
        ((self.next_u64() >> 33) as i64).rem_euclid(2 * span + 1) - span
    }
}
