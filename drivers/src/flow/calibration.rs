//! Counts to micrometres, in Q16 fixed point (no floats in the read path).

/// Scale from flow counts to ground displacement.
///
/// The PMW3901 sees a 42 degree field of view over 35 pixels, and one
/// count is one pixel of image motion. At height `h` mm above the floor the
/// view is `2 h tan(21 deg)` mm wide, so one count is
/// `2 h tan(21 deg) / 35` mm, i.e. `21.935 h` micrometres. This holds for
/// pure translation over a flat floor; BugBot's flow sensor sits at the
/// turning centre, so yaw does not add flow. The datasheet's working range
/// starts at 80 mm; check the scale on the bench (push the robot 1 m and
/// compare) and use [`FlowCalibration::from_um_per_count_q16`] if it
/// differs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FlowCalibration {
    um_per_count_q16: u32,
}

impl FlowCalibration {
    /// Micrometres per count per millimetre of height, Q16:
    /// `2 tan(21 deg) * 1000 / 35 * 65536 = 1_437_537.9`.
    pub const UM_PER_COUNT_PER_MM_HEIGHT_Q16: u32 = 1_437_538;

    /// Scale for a sensor `height_mm` above the floor (lens to floor).
    /// Saturates above about 2.9 m.
    pub const fn from_height_mm(height_mm: u16) -> Self {
        let q16 = height_mm as u64 * Self::UM_PER_COUNT_PER_MM_HEIGHT_Q16 as u64;
        let q16 = if q16 > u32::MAX as u64 {
            u32::MAX
        } else {
            q16 as u32
        };
        FlowCalibration {
            um_per_count_q16: q16,
        }
    }

    /// Scale from a measured value: micrometres per count, Q16.
    pub const fn from_um_per_count_q16(um_per_count_q16: u32) -> Self {
        FlowCalibration { um_per_count_q16 }
    }

    /// Micrometres per count, Q16.
    pub const fn um_per_count_q16(self) -> u32 {
        self.um_per_count_q16
    }

    /// Displacement for `counts`, micrometres, rounded to nearest.
    pub const fn counts_to_um(self, counts: i16) -> i32 {
        let product = counts as i64 * self.um_per_count_q16 as i64;
        let um = (product + (1 << 15)) >> 16;
        if um > i32::MAX as i64 {
            i32::MAX
        } else if um < i32::MIN as i64 {
            i32::MIN
        } else {
            um as i32
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constant_matches_geometry() {
        let exact = 2.0 * (21.0f64).to_radians().tan() * 1000.0 / 35.0 * 65536.0;
        assert!((exact - f64::from(FlowCalibration::UM_PER_COUNT_PER_MM_HEIGHT_Q16)).abs() < 1.0);
    }

    #[test]
    fn hundred_mm_height() {
        // 100 mm up: 2193.51 um per count, rounded to nearest.
        let cal = FlowCalibration::from_height_mm(100);
        assert_eq!(cal.counts_to_um(1), 2194);
        assert_eq!(cal.counts_to_um(-1), -2194);
        assert_eq!(cal.counts_to_um(10), 21935);
        assert_eq!(cal.counts_to_um(0), 0);
    }

    #[test]
    fn extremes_do_not_overflow() {
        let cal = FlowCalibration::from_height_mm(u16::MAX);
        assert_eq!(cal.um_per_count_q16(), u32::MAX);
        assert!(cal.counts_to_um(i16::MAX) > 2_000_000_000);
        assert_eq!(cal.counts_to_um(i16::MIN), -2_147_483_647);
    }
}
