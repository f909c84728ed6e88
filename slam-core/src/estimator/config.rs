//! What the filter is told about its sensors: their noise, the uncertainty it starts
//! with, and how much disagreement it believes.

/// The time the stale noises ([`EstimatorConfig::stale_flow_mm`],
/// [`EstimatorConfig::stale_gyro_mdeg`]) are given for, microseconds: a tick of the 10 Hz
/// loop.
pub const STALE_PERIOD_US: u32 = 100_000;

/// The filter's noise model and gate, in the units of datasheets.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct EstimatorConfig {
    /// Standard deviation of the start position along each axis, millimetres: how well the
    /// robot is set on the start it is given.
    pub initial_position_mm: u32,
    /// Standard deviation of the start heading, millidegrees.
    pub initial_heading_mdeg: u32,
    /// Standard deviation of the gyro's scale error before any is learned, ppm.
    pub initial_gyro_scale_ppm: u32,
    /// Standard deviation of the gyro's remaining bias at start, millidegrees per second.
    pub initial_gyro_bias_mdps: u32,
    /// Standard deviation of the flow sensor's scale error before any is learned, ppm.
    pub initial_flow_scale_ppm: u32,
    /// Position noise per tick along each axis, micrometres (the flow sensor's own noise,
    /// which piles up even when turning on the spot).
    pub position_noise_um: u32,
    /// Position noise per tick as a share of the distance driven that tick, ppm: for an
    /// odometry whose scale error is not a state (the flow scale is one, with its walk).
    pub position_noise_ppm: u32,
    /// Position noise per tick per radian turned that tick, micrometres (a flow sensor
    /// off the turning axis, wheel scrub).
    pub position_noise_um_per_rad: u32,
    /// Heading noise per tick, millidegrees (the gyro's own noise).
    pub heading_noise_mdeg: u32,
    /// Heading noise per tick as a share of the angle turned that tick, ppm: for a gyro
    /// whose scale error is not a state (the gyro scale is one, with its walk).
    pub heading_noise_ppm: u32,
    /// Random walk of the gyro's bias per tick, micro-degrees per second.
    pub gyro_bias_walk_udps: u32,
    /// Random walk of the gyro's scale per tick, ppm.
    pub gyro_scale_walk_ppm: u32,
    /// Random walk of the flow sensor's scale per tick, ppm.
    pub flow_scale_walk_ppm: u32,
    /// Position noise of a [`STALE_PERIOD_US`] with no flow reading, millimetres along
    /// the robot's nose (across it, a reading's own): how far the robot may have gone
    /// unseen. A longer frame without one (the time a watchdog reset left unseen) costs
    /// it in proportion.
    pub stale_flow_mm: u32,
    /// Heading noise of a [`STALE_PERIOD_US`] with no gyro reading, millidegrees, in
    /// proportion over a longer frame likewise.
    pub stale_gyro_mdeg: u32,
    /// The camera's range noise: a constant part, millimetres...
    pub range_noise_mm: u32,
    /// ... and a part proportional to the range, per mille.
    pub range_noise_permille: u32,
    /// The camera's bearing noise at the picture's centre, millidegrees. A tag is found to
    /// a share of a pixel anywhere in the picture, and the column is `focal tan(bearing)`,
    /// so off the centre a pixel spans less angle: the filter scales this by cos^2 of the
    /// bearing seen.
    pub bearing_noise_mdeg: u32,
    /// Tags read further than this, millimetres, are refused.
    pub max_range_mm: u32,
    /// A tag whose listed place is further off the nose than this from the believed pose,
    /// millidegrees, cannot be in the picture: refused.
    pub half_view_mdeg: u32,
    /// The gate: a sighting whose squared Mahalanobis distance (chi-square, 2 degrees of
    /// freedom) exceeds this, in Q8, is refused. 13.8 (3533) refuses one honest sighting
    /// in a thousand.
    pub gate_chi2_q8: u32,
}

impl EstimatorConfig {
    /// BugBot's sensors as the seed describes them, each figure the sensor's own:
    /// - a PMW3901 with 0.5 counts of noise per 100 Hz reading, ten a tick, at 100 um a
    ///   count less the -4 % it reads short (104 um once learned): 165 um a tick;
    /// - a gyro with 0.1 deg/s of noise per 200 Hz sample, twenty a tick (2 mdeg a tick), up
    ///   to 1 % scale error, and a bias that wanders with temperature (0.005 deg/s per
    ///   kelvin, a board warming 2 K in its first minute: 0.002 deg/s per root second,
    ///   632 udps a tick);
    /// - a flow scale known to 5 %; both scales are states, so no share of the distance
    ///   or the turn is added as noise;
    /// - a camera reading tags to 1.5 m with 2 mm of range noise at any range, and a column
    ///   to 0.15 px of a 92.4 px focal length: 93 mdeg at the picture's centre;
    /// - a start set to a millimetre, and known to half a degree.
    pub const SEED: EstimatorConfig = EstimatorConfig {
        initial_position_mm: 1,
        initial_heading_mdeg: 500,
        initial_gyro_scale_ppm: 10_000,
        initial_gyro_bias_mdps: 100,
        initial_flow_scale_ppm: 50_000,
        position_noise_um: 165,
        position_noise_ppm: 0,
        position_noise_um_per_rad: 500,
        heading_noise_mdeg: 2,
        heading_noise_ppm: 0,
        gyro_bias_walk_udps: 632,
        gyro_scale_walk_ppm: 10,
        flow_scale_walk_ppm: 10,
        stale_flow_mm: 10,
        stale_gyro_mdeg: 3_000,
        range_noise_mm: 2,
        range_noise_permille: 0,
        bearing_noise_mdeg: 93,
        max_range_mm: 1500,
        half_view_mdeg: 70_000,
        gate_chi2_q8: 3533,
    };
}
