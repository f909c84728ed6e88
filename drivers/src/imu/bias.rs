//! Gyro bias estimation at rest, integers only.

/// Gyro Z bias in raw counts, subtracted from every sample.
///
/// Built by [`BiasCalibrator`] (or [`GyroBias::ZERO`] / a stored value via
/// [`GyroBias::from_counts`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct GyroBias {
    counts: i16,
}

impl GyroBias {
    /// No correction.
    pub const ZERO: GyroBias = GyroBias { counts: 0 };

    /// A bias from a previous calibration, raw counts at the configured
    /// full scale.
    pub const fn from_counts(counts: i16) -> Self {
        GyroBias { counts }
    }

    /// The bias, raw counts.
    pub const fn counts(self) -> i16 {
        self.counts
    }
}

/// What the calibrator says after a sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum CalibrationStatus {
    /// Not enough samples yet.
    NeedMore {
        /// Samples so far.
        have: u32,
        /// Samples required.
        need: u32,
    },
    /// Enough samples, but their variance says the robot was moving (or
    /// vibrating): [`BiasCalibrator::reset`] and try again at rest.
    TooNoisy {
        /// Population variance, counts squared (saturated).
        variance_counts2: u32,
    },
    /// Bias accepted.
    Done(GyroBias),
}

/// Running mean and variance of gyro samples at rest.
///
/// Keeps exact integer sums (`sum`, `sum of squares`), so the mean and
/// variance carry no rounding drift however many samples come in.
/// Sizing: the ICM-42688-P's noise is 0.0028 dps/sqrt(Hz); at 200 Hz ODR that
/// is under one count rms at +-1000 dps, so a limit of 25 counts squared
/// (5 counts, 0.15 dps rms) rejects a robot that is being moved while
/// passing a still one. One second of samples (200) is plenty.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BiasCalibrator {
    min_samples: u32,
    max_variance_counts2: u32,
    count: u32,
    sum: i64,
    sum_sq: u64,
}

impl BiasCalibrator {
    /// Accept the mean once at least `min_samples` (at least 1) are in and
    /// the variance is at most `max_variance_counts2`.
    pub const fn new(min_samples: u32, max_variance_counts2: u32) -> Self {
        BiasCalibrator {
            min_samples: if min_samples == 0 { 1 } else { min_samples },
            max_variance_counts2,
            count: 0,
            sum: 0,
            sum_sq: 0,
        }
    }

    /// Forget all samples.
    pub fn reset(&mut self) {
        self.count = 0;
        self.sum = 0;
        self.sum_sq = 0;
    }

    /// Add one raw gyro Z sample and report the status. Samples past
    /// `u32::MAX` are ignored.
    pub fn push(&mut self, raw: i16) -> CalibrationStatus {
        if let Some(count) = self.count.checked_add(1) {
            self.count = count;
            self.sum += i64::from(raw);
            self.sum_sq += u64::from(raw.unsigned_abs()) * u64::from(raw.unsigned_abs());
        }
        self.status()
    }

    /// Samples so far.
    pub const fn samples(&self) -> u32 {
        self.count
    }

    /// Mean so far, counts, rounded to nearest; `None` before any sample.
    pub fn mean(&self) -> Option<i16> {
        if self.count == 0 {
            return None;
        }
        let n = i64::from(self.count);
        let half = if self.sum >= 0 { n / 2 } else { -(n / 2) };
        // The mean of i16 samples is within i16.
        i16::try_from((self.sum + half) / n).ok()
    }

    /// Population variance so far, counts squared, rounded down and
    /// saturated; `None` before any sample.
    pub fn variance_counts2(&self) -> Option<u32> {
        if self.count == 0 {
            return None;
        }
        let n = i128::from(self.count);
        let spread = n * i128::from(self.sum_sq) - i128::from(self.sum) * i128::from(self.sum);
        let variance = spread.max(0) / (n * n);
        Some(u32::try_from(variance).unwrap_or(u32::MAX))
    }

    /// Status without adding a sample.
    pub fn status(&self) -> CalibrationStatus {
        match (self.mean(), self.variance_counts2()) {
            (Some(mean), Some(variance)) if self.count >= self.min_samples => {
                if variance > self.max_variance_counts2 {
                    CalibrationStatus::TooNoisy {
                        variance_counts2: variance,
                    }
                } else {
                    CalibrationStatus::Done(GyroBias { counts: mean })
                }
            }
            _ => CalibrationStatus::NeedMore {
                have: self.count,
                need: self.min_samples,
            },
        }
    }
}
