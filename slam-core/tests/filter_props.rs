//! The fixed-point filter against its `f64` reference (`reference/filter.rs`): predict alone,
//! one sighting, and a whole run through `Slam::step`.
//!
//! The runs use [`EXACT`], the seed's noise model moved to figures the filter's units hold
//! to 0.1 %, so that what is compared is the arithmetic, not the rounding of the
//! configuration (see `seed_noise_model_is_held`, which compares that).

mod reference;
mod simulated;

use core::f64::consts::FRAC_PI_2;
use proptest::prelude::*;
use proptest::test_runner::TestCaseError;
use reference::bits_to_rad;
use reference::filter::{self as rf, FPose, Matrix, Reading, RefFilter};
use simulated::{Robot, Sensors};
use slam_core::tagfix::{CameraConfig, KnownTag};
use slam_core::OdometryConfig;
use slam_core::{
    Angle, Estimator, EstimatorConfig, FlowDelta, GyroRate, Localiser, Pose, SensorFrame, Slam,
    SlamConfig, TagDetection, TagMap, TagRefusal,
};

/// The seed's noise model with each figure moved to one the filter's units hold within
/// 0.1 %, and the parts proportional to the motion set to zero: the filter rounds each
/// standard deviation to a unit before squaring it, which for a tick's share of the motion
/// is a few units (`seed_process_noise_matches_the_reference` compares the seed's own figures).
/// Position 125 um (2 units); heading 7 mdeg (8.007 units); walks of 61 ppm (3.997 units)
/// and 7 mdps (8.007 units); the camera's range 3 mm flat (its per-mille part is kept to
/// whole millimetres) and its bearing 90 mdeg (102.94 units).
const EXACT: EstimatorConfig = EstimatorConfig {
    position_noise_um: 125,
    position_noise_ppm: 0,
    position_noise_um_per_rad: 0,
    heading_noise_mdeg: 7,
    heading_noise_ppm: 0,
    gyro_bias_walk_udps: 7_000,
    gyro_scale_walk_ppm: 61,
    flow_scale_walk_ppm: 61,
    range_noise_mm: 3,
    range_noise_permille: 0,
    bearing_noise_mdeg: 90,
    ..EstimatorConfig::SEED
};

fn config() -> ProptestConfig {
    ProptestConfig {
        failure_persistence: None,
        ..ProptestConfig::default()
    }
}

fn fpose(p: &Pose) -> FPose {
    FPose {
        x: p.x_um as f64 / 1000.0,
        y: p.y_um as f64 / 1000.0,
        heading: reference::wrap(bits_to_rad(p.heading.bits())),
    }
}

fn slam_config(estimator: EstimatorConfig, tags: &[KnownTag]) -> SlamConfig {
    SlamConfig {
        localiser: Localiser::Filter,
        estimator,
        tags: TagMap::new(tags).unwrap(),
        ..unchecked(world::shipped::seed_robot().config)
    }
}

fn covariance<const W: usize, const H: usize>(slam: &Slam<W, H>) -> Matrix {
    rf::from_integer(slam.estimator().covariance().rows())
}

/// One tick's readings: flow and gyro each present or stale, and the tick's length.
fn tick() -> impl Strategy<Value = SensorFrame> {
    (
        proptest::option::weighted(0.9, (-200i32..=200, -40i32..=40)),
        proptest::option::weighted(0.9, -90_000i32..=90_000),
        prop_oneof![3 => Just(100_000u32), 1 => 50_000u32..=150_000],
    )
        .prop_map(|(flow, gyro, dt_us)| {
            let mut frame = SensorFrame::empty(dt_us);
            frame.flow = flow.map(|(f, r)| FlowDelta {
                forward_counts: f,
                right_counts: r,
            });
            frame.gyro = gyro.map(|g| GyroRate { rate_mdps: g });
            frame
        })
}

/// Integer units allowed on every entry beyond the relative bound, per state (an entry
/// `(i, j)` is allowed `a_i a_j` in the reference's units): the rounding of one operation.
fn absolute(units: f64) -> rf::Vector {
    let mut a = [0.0; rf::N];
    for (i, a) in a.iter_mut().enumerate() {
        *a = units * rf::unit(i);
    }
    a
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 128, ..config() })]

    /// Predict alone: up to 300 ticks of random flow (forward +-200 counts, sideways +-40),
    /// gyro (+-90 deg/s), either stale one tick in ten, and tick lengths 50-150 ms, from
    /// anywhere on a 20 m square, through `Slam::step` and through the reference.
    ///
    /// Every tick, each covariance entry within 2.5 % of its scale `sqrt(P_ii P_jj)`, after
    /// allowing 4 units on each side for one operation's rounding; nearly every run stays
    /// within 1 %, a run in a few thousand reaches nearly 2 %. Why so much: the initial
    /// gyro bias's standard deviation is held to 0.35 % (114 units for 114.4), so its
    /// variance to 0.7 %, and that stays while nothing corrects it; on top, the Jacobian's
    /// displacements are rounded to 1/16 mm (0.36 % of an 8.6 mm tick) and every product to
    /// a unit, roundings without a sign that add up as a random walk.
    #[test]
    fn predict_alone_matches_the_reference(
        x_mm in -10_000i32..10_000,
        y_mm in -10_000i32..10_000,
        heading in any::<u32>(),
        ticks in proptest::collection::vec(tick(), 1..300),
    ) {
        let start = Pose { x_um: x_mm * 1000, y_um: y_mm * 1000, heading: Angle::from_bits(heading) };
        let config = slam_config(EXACT, &[]);
        let mut slam: Slam<46, 46> = Slam::new(config, start).unwrap();
        let mut reference = RefFilter::new(EXACT, OdometryConfig::NOMINAL, config.tags, fpose(&start));
        let mut worst = (0.0, 0, 0);
        for frame in &ticks {
            slam.step(frame);
            reference.step(frame);
            let w = rf::worst_difference(&covariance(&slam), &reference.p, &absolute(4.0));
            if w.0 > worst.0 {
                worst = w;
            }
        }
        prop_assert!(worst.0 <= 0.025, "entry {:?} off by {:.3} % of its scale", (worst.1, worst.2), worst.0 * 100.0);
    }
}

/// A sighting to test: the pose the picture was taken from, where the tag is listed, and
/// how far the reading is from the prediction, in standard deviations of range and bearing.
#[derive(Clone, Copy, Debug)]
struct Case {
    then: Pose,
    range_mm: f64,
    bearing: f64,
    range_sds: f64,
    bearing_sds: f64,
}

fn case() -> impl Strategy<Value = Case> {
    (
        -3_000_000i32..3_000_000,
        -3_000_000i32..3_000_000,
        any::<u32>(),
        60.0f64..1450.0,
        -65.0f64..65.0,
        -4.0f64..4.0,
        -4.0f64..4.0,
    )
        .prop_map(
            |(x_um, y_um, h, range_mm, deg, range_sds, bearing_sds)| Case {
                then: Pose {
                    x_um,
                    y_um,
                    heading: Angle::from_bits(h),
                },
                range_mm,
                bearing: deg.to_radians(),
                range_sds,
                bearing_sds,
            },
        )
}

/// The listed tag and the detection for a case, given the covariance the filter holds.
fn sighting(c: &Case, p: &Matrix, config: &EstimatorConfig) -> (KnownTag, TagDetection) {
    let then = fpose(&c.then);
    let (nx, ny) = reference::nose(then.heading + c.bearing);
    let tag = KnownTag {
        id: 11,
        x_mm: (then.x + c.range_mm * nx).round() as i32,
        y_mm: (then.y + c.range_mm * ny).round() as i32,
    };
    // Roughly the innovations' standard deviations: enough to put the readings on both
    // sides of the gate.
    let (dx, dy) = (tag.x_mm as f64 - then.x, tag.y_mm as f64 - then.y);
    let range = dx.hypot(dy);
    let bearing = reference::wrap(reference::heading_of(dx, dy) - then.heading);
    let sd_range = (p[0][0].max(p[1][1]) + (config.range_noise_mm as f64).powi(2)).sqrt();
    let sd_bearing = (p[2][2]
        + p[0][0].max(p[1][1]) / range.max(50.0).powi(2)
        + (config.bearing_noise_mdeg as f64 / 1000.0)
            .to_radians()
            .powi(2))
    .sqrt();
    // Within the picture: a column past its edge is no reading at all.
    let edge = reference::bearing(2.0 * reference::CENTRE_PX - 0.5);
    let seen = (bearing + c.bearing_sds * sd_bearing).clamp(-edge, edge);
    let detection = TagDetection {
        id: 11,
        cx_centipx: (reference::column_of(seen) * 100.0).round() as i32,
        distance_mm: (range + c.range_sds * sd_range).round().max(0.0) as u32,
    };
    (tag, detection)
}

/// A case set up for both filters: the integer filter after `ticks` from the case's pose,
/// its covariance in the reference's units, and the case's sighting as each takes it.
struct SetUp {
    estimator: Estimator,
    prior: Matrix,
    tag: KnownTag,
    detection: TagDetection,
    then: FPose,
    place: (f64, f64),
    reading: Reading,
}

fn set_up(ticks: &[SensorFrame], c: &Case) -> SetUp {
    let config = slam_config(EXACT, &[]);
    let mut slam: Slam<46, 46> = Slam::new(config, c.then).unwrap();
    for frame in ticks {
        slam.step(frame);
    }
    let prior = rf::from_integer(slam.estimator().covariance().rows());
    let (tag, detection) = sighting(c, &prior, &EXACT);
    SetUp {
        estimator: slam.estimator().clone(),
        prior,
        tag,
        detection,
        then: fpose(&c.then),
        place: (tag.x_mm as f64, tag.y_mm as f64),
        reading: Reading {
            range_mm: detection.distance_mm as f64,
            cx_px: detection.cx_centipx as f64 / 100.0,
        },
    }
}

/// The filter's predicted range is formed from the offset to the tag rounded to whole
/// position units (1/16 mm; half a unit each way, at most 0.71 of one along the line of
/// sight) and a floored square root (under one unit): within 1.71 units of the exact one,
/// so its range innovation is too. Allowed: two units, 1/8 mm.
const RANGE_QUANTUM_MM: f64 = 2.0 / 16.0;

/// How far the reference's correction moves, state by state, when the range reading moves
/// [`RANGE_QUANTUM_MM`] either way: what the filter's range quantisation may cost each
/// state. Large where a state is tied to the position along the line of sight and the
/// range is believed closely (a flow scale after a straight drive takes hundreds of ppm
/// per 1/16 mm).
fn range_sensitivity(
    prior: &Matrix,
    then: &FPose,
    place: (f64, f64),
    reading: &Reading,
    correction: &rf::Vector,
) -> rf::Vector {
    let mut worst = [0.0; rf::N];
    for delta in [-RANGE_QUANTUM_MM, RANGE_QUANTUM_MM] {
        let mut p = *prior;
        let moved = Reading {
            range_mm: reading.range_mm + delta,
            ..*reading
        };
        if let Ok(update) = rf::sight(&mut p, &EXACT, then, place, &moved) {
            for ((w, a), b) in worst.iter_mut().zip(update.correction).zip(correction) {
                *w = f64::max(*w, (a - b).abs());
            }
        }
    }
    worst
}

/// The reference's bearing innovation, radians: the seen bearing less the predicted one.
fn bearing_innovation(then: &FPose, place: (f64, f64), reading: &Reading) -> f64 {
    let predicted = reference::heading_of(place.0 - then.x, place.1 - then.y) - then.heading;
    reference::wrap(reference::bearing(reading.cx_px) - predicted)
}

/// The gate's threshold, 13.8 (`gate_chi2_q8` / 256).
fn gate(config: &EstimatorConfig) -> f64 {
    config.gate_chi2_q8 as f64 / 256.0
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 1000, ..config() })]

    /// One sighting from a random pose (anywhere on a 6 m square, any heading) of a tag
    /// 6 cm to 1.45 m away within 65 degrees of the nose, read up to 4 standard deviations
    /// off in range and in bearing, with the covariance that up to 60 random ticks of
    /// odometry leave (stale ticks among them: up to tens of millimetres and degrees).
    ///
    /// Bounds, as shares of the covariance before the update (the update's rounding scales
    /// with what it starts from, not with what it ends with):
    /// - the gate's decision agrees unless the reference's statistic is within
    ///   `2 % + 2 mm / range` of the threshold (the integer one is two Q8 quotients of
    ///   rounded innovations, and its bearing's variance comes from the Jacobian over the
    ///   range in whole millimetres, truncated, squared), or the
    ///   reference's bearing innovation is a quarter turn or more, which the integer filter
    ///   refuses by design;
    /// - a taken sighting's corrected position, heading and each calibration state within
    ///   `(1 % + 2 mm / range)` of that state's standard deviation, plus 20 um, 2e-5 rad
    ///   and 2 ppm or mdps. The 1 %: Q16 gains whose unit is a sizeable share of a small
    ///   gain (1/16 mm per radian for the position from the bearing); the `2 mm / range`:
    ///   the bearing's Jacobian divides by the range in whole millimetres, truncated, which
    ///   reaches the correction through the gain and the innovation's variance both; the
    ///   absolute parts: innovations rounded to 1/16 mm and 2^-16 rad, and a read-out
    ///   rounded to whole ppm and mdps; and what the range's quantisation moves each state
    ///   by ([`range_sensitivity`]);
    /// - each covariance entry within `(1 % + 1 mm / range)` of its scale before the
    ///   update, after 4 units.
    #[test]
    fn one_sighting_matches_the_reference(
        ticks in proptest::collection::vec(tick(), 0..60),
        c in case(),
    ) {
        let SetUp { mut estimator, prior, tag, detection, then, place, reading } = set_up(&ticks, &c);
        let mut p = prior;
        let chi2 = rf::chi2(&p, &EXACT, &then, place, &reading);
        prop_assume!(chi2.is_ok());
        let chi2 = chi2.unwrap_or_default();
        let want = rf::sight(&mut p, &EXACT, &then, place, &reading);
        let got = estimator.sight(&detection, Some(&tag), &CameraConfig::SEED, Some(c.then), None);
        match (got, want) {
            (Ok(pose), Ok(update)) => {
                let d = update.correction;
                let q = range_sensitivity(&prior, &then, place, &reading, &d);
                let got = fpose(&pose);
                let share = 0.01 + 2.0 / c.range_mm;
                let sd = |i: usize| prior[i][i].sqrt();
                let position = (got.x - then.x - d[0]).hypot(got.y - then.y - d[1]);
                let position_sd = (prior[0][0] + prior[1][1]).sqrt();
                prop_assert!(position <= 0.020 + share * position_sd + q[0].hypot(q[1]),
                    "position off by {position} mm, prior sd {position_sd} mm");
                let heading = reference::wrap(got.heading - then.heading - d[2]).abs();
                prop_assert!(heading <= 2e-5 + share * sd(2) + q[2],
                    "heading off by {heading} rad, prior sd {} rad", sd(2));
                let cal = estimator.calibration();
                let calibration = [
                    (cal.gyro_scale_ppm as f64 - d[3] * 1e6, sd(3) * 1e6, q[3] * 1e6),
                    (cal.gyro_bias_mdps as f64 - d[4].to_degrees() * 1e3, sd(4).to_degrees() * 1e3,
                        q[4].to_degrees() * 1e3),
                    (cal.flow_scale_ppm as f64 - d[5] * 1e6, sd(5) * 1e6, q[5] * 1e6),
                ];
                for (e, sd, quantum) in calibration {
                    prop_assert!(e.abs() <= 2.0 + share * sd + quantum,
                        "calibration off by {e}, prior sd {sd}, range quantum's share {quantum}");
                }
                let w = rf::worst_difference_on(
                    &rf::from_integer(estimator.covariance().rows()), &p, &prior, &absolute(4.0));
                prop_assert!(w.0 <= 0.01 + 1.0 / c.range_mm, "covariance entry {:?} off by {:.3} % of its prior scale",
                    (w.1, w.2), w.0 * 100.0);
            }
            (Err(TagRefusal::Gate), Err(rf::Refusal::Gate)) => {}
            // The integer filter refuses a bearing more than a quarter turn off outright
            // (its innovation is an arcsine); the reference takes any.
            (Err(TagRefusal::Gate), Ok(_))
                if bearing_innovation(&then, place, &reading).abs() >= 0.99 * FRAC_PI_2 => {}
            (got, _) => {
                let near_edge = (chi2 / gate(&EXACT) - 1.0).abs() < 0.02 + 2.0 / c.range_mm;
                prop_assert!(near_edge, "integer filter {got:?}, reference chi2 {chi2} (gate {})", gate(&EXACT));
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..config() })]

    /// The reference checks itself: its sequential update (range, then bearing given the
    /// range) equals the textbook joint update with the 2 x 2 innovation covariance
    /// inverted, to 1e-9 of each state's standard deviation and of each entry's scale
    /// (where no floor or ceiling engages, since the joint form has none).
    #[test]
    fn the_reference_sequential_update_is_the_joint_update(
        ticks in proptest::collection::vec(tick(), 0..60),
        c in case(),
    ) {
        let SetUp { prior, then, place, reading, .. } = set_up(&ticks, &c);
        let joint = rf::joint_update(&prior, &EXACT, &then, place, &reading);
        prop_assume!(joint.is_ok());
        let (correction, q) = joint.unwrap_or_default();
        let mut ungated = EXACT;
        ungated.gate_chi2_q8 = u32::MAX;
        let mut p = prior;
        let update = rf::sight(&mut p, &ungated, &then, place, &reading).unwrap();
        // Where a bound engaged, the two differ by design.
        let mut bounded = q;
        rf::bound(&mut bounded);
        prop_assume!(rf::worst_difference_on(&bounded, &q, &prior, &[0.0; rf::N]).0 < 1e-12);
        for i in 0..rf::N {
            let sd = prior[i][i].sqrt();
            prop_assert!((update.correction[i] - correction[i]).abs() <= 1e-9 * sd,
                "state {i}: {} against {}", update.correction[i], correction[i]);
        }
        let (share, i, j) = rf::worst_difference_on(&p, &q, &prior, &[0.0; rf::N]);
        prop_assert!(share <= 1e-9, "entry {:?} off by {share:e}", (i, j));
    }
}

fn true_places(tags: &[KnownTag]) -> Vec<(u16, f64, f64)> {
    tags.iter()
        .map(|t| (t.id, t.x_mm as f64, t.y_mm as f64))
        .collect()
}

/// How far apart a run through `Slam::step` and the same run through the reference came,
/// at worst over its ticks.
#[derive(Clone, Copy, Debug, Default)]
struct Apart {
    /// Position, mm, and heading, degrees.
    position: f64,
    heading: f64,
    /// The worst covariance entry of the pose's block and of the whole, as a share of its
    /// scale after 4 units.
    pose_block: f64,
    all: f64,
}

/// 400 ticks (40 s) of the simulated robot wandering the seed mat with the seed's sensor
/// errors (flow 4 % short, gyro 0.75 % and 20 mdps off, 0.1 deg/s of noise), both tags read
/// whenever in view from pictures up to a tick old, through `Slam::step` with `estimator`
/// and through the reference side by side: how far apart they came. Fails if they ever
/// take or refuse different sightings, or if the run is not one a filter can follow.
fn run_beside_reference(
    seed: u64,
    estimator: EstimatorConfig,
    sensors: Sensors,
) -> Result<Apart, TestCaseError> {
    let start = world::shipped::seed_robot().start;
    let config = slam_config(estimator, &world::shipped::seed_robot().tags);
    let mut slam: Slam<46, 46> = Slam::new(config, start).unwrap();
    let mut reference = RefFilter::new(
        estimator,
        OdometryConfig::NOMINAL,
        config.tags,
        fpose(&start),
    );
    let mut robot = Robot::new(
        fpose(&start),
        sensors,
        true_places(&world::shipped::seed_robot().tags),
        seed,
    );
    let mut pose_block = absolute(4.0);
    for a in pose_block.iter_mut().skip(3) {
        *a = f64::INFINITY;
    }
    let mut apart = Apart::default();
    for tick in 0..400 {
        let (speed, rate) = robot.wander();
        let age = (50_000.0 * (1.0 + robot.uniform())) as u32;
        let frame = robot.tick(speed, rate, 100_000, age);
        slam.step(&frame);
        reference.step(&frame);
        let counts = slam.tag_counters();
        // A picture that repeats one from a tick or two before (a robot all but standing,
        // its readings rounding alike) is the camera check's to refuse, and the
        // reference does not model it (`camera_check` has its own tests): such a run
        // compares nothing.
        prop_assume!(slam.counters().pictures_late == 0);
        prop_assert_eq!(
            (counts.used, counts.gate),
            (reference.counts.used, reference.counts.gate),
            "tick {}",
            tick
        );
        let (got, want) = (fpose(slam.pose()), reference.pose);
        let p = covariance(&slam);
        apart.position = apart.position.max((got.x - want.x).hypot(got.y - want.y));
        apart.heading = apart.heading.max(
            reference::wrap(got.heading - want.heading)
                .abs()
                .to_degrees(),
        );
        apart.pose_block = apart
            .pose_block
            .max(rf::worst_difference(&p, &reference.p, &pose_block).0);
        apart.all = apart
            .all
            .max(rf::worst_difference(&p, &reference.p, &absolute(4.0)).0);
    }
    // The simulation is one the filters can follow: not a comparison of two lost filters.
    let truth = (reference.pose.x - robot.truth.x).hypot(reference.pose.y - robot.truth.y);
    prop_assert!(
        truth <= 10.0,
        "the reference ended {} mm from the truth",
        truth
    );
    prop_assert!(
        reference.counts.used > 400,
        "only {} sightings taken",
        reference.counts.used
    );
    Ok(apart)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, ..config() })]

    /// A whole run ([`run_beside_reference`]) with [`EXACT`]'s noise model, the camera's
    /// range noise 3 mm as it says.
    ///
    /// Bounds, every tick:
    /// - the same sightings taken and refused;
    /// - the poses within 0.5 mm and 0.03 degrees (a few times one sighting's rounding,
    ///   which each later sighting pulls back rather than adds to; a run in many thousand
    ///   parts past 0.02 degrees);
    /// - each entry of the pose's block of the covariance within 15 % of its scale after
    ///   4 units, every entry within 25 %. Wide, because two things the single steps do
    ///   not show build up over a run: the calibration's variances, a few thousand units
    ///   once learned and observed only slowly, random-walk by each update's rounding and
    ///   feed the heading's variance through predict; and the reference takes the
    ///   calibration's derivatives exactly (the displacement before the flow scale, the
    ///   turn before the gyro's scale, `(1 + scale) dt` for the bias) where the filter takes
    ///   them at the corrected motion, a difference of the calibration's own size (4 % on
    ///   the flow scale's column) that grows the heading's variance 1.5-2.5 % apart over a
    ///   few seconds without tags.
    #[test]
    fn whole_run_matches_the_reference(seed in any::<u64>()) {
        exact_run(seed)?;
    }

    /// The same run with the seed's own noise model, the one the robot flies.
    ///
    /// The same sightings taken and refused; the poses within 0.8 mm and 0.045 degrees,
    /// wider than with [`EXACT`] since the two filters' gains now differ with their
    /// covariances, and a run now and then whose gains part more (a random seed found one
    /// at 0.031 degrees: the bounds leave the tail of many thousand runs well inside). The
    /// covariance only within 60 % of its scale: the filter holds
    /// the seed's per-tick noise to whole units of its covariance, up to a quarter off for
    /// the position and heading and more for the calibration's walks (see
    /// `seed_process_noise_matches_the_reference`), and the heading's variance, refreshed
    /// by every sighting, sits where that noise puts it.
    #[test]
    fn whole_run_with_the_seed_noise_model(seed in any::<u64>()) {
        seed_noise_model_run(seed)?;
    }
}

/// [`whole_run_matches_the_reference`]'s run and bounds for one seed.
fn exact_run(seed: u64) -> Result<(), TestCaseError> {
    let sensors = Sensors {
        range_noise_mm: 3.0,
        ..Sensors::SEED
    };
    let apart = run_beside_reference(seed, EXACT, sensors)?;
    prop_assert!(apart.position <= 0.5, "{apart:?}");
    prop_assert!(apart.heading <= 0.03, "{apart:?}");
    prop_assert!(apart.pose_block <= 0.15, "{apart:?}");
    prop_assert!(apart.all <= 0.25, "{apart:?}");
    Ok(())
}

/// [`whole_run_with_the_seed_noise_model`]'s run and bounds for one seed.
fn seed_noise_model_run(seed: u64) -> Result<(), TestCaseError> {
    let apart = run_beside_reference(seed, EstimatorConfig::SEED, Sensors::SEED)?;
    prop_assert!(apart.position <= 0.8, "{apart:?}");
    prop_assert!(apart.heading <= 0.045, "{apart:?}");
    prop_assert!(apart.all <= 0.6, "{apart:?}");
    Ok(())
}

/// Seeds that random runs of the whole-run tests found hard, every time: one whose
/// heading parted 0.022 degrees with [`EXACT`], one 0.031 degrees with the seed's noise
/// model, and one whose robot, all but standing, gave a picture that repeats one from a
/// tick before (a run that compares nothing).
#[test]
fn the_hard_seeds_of_the_whole_runs() {
    if let Err(e) = exact_run(6_027_219_747_448_503_400) {
        panic!("{e}");
    }
    if let Err(e) = seed_noise_model_run(10_453_588_633_721_808_906) {
        panic!("{e}");
    }
    assert!(matches!(
        seed_noise_model_run(5_640_388_155_920_098_204),
        Err(TestCaseError::Reject(_))
    ));
}

/// A tick to compare: its name, its flow (forward, right counts) and its gyro (mdps).
type TickReadings = (&'static str, Option<(i32, i32)>, Option<i32>);

/// The seed's own noise model: what the filter adds to the variances over 100 ticks from
/// the start, against the reference, for a robot standing, driving at the seed's 86 mm/s,
/// turning on the spot at its 31.5 deg/s, and with each reading stale. Each within 10 %
/// plus the propagation's own rounding. The per-tick noise of the seed is a few covariance
/// units or less; the filter forms it in 1/256 units and carries the fraction to the next
/// tick, so that over many ticks none of it is lost.
#[test]
fn seed_process_noise_matches_the_reference() {
    let config = EstimatorConfig::SEED;
    let cases: [TickReadings; 5] = [
        ("standing", Some((0, 0)), Some(0)),
        ("driving 86 mm/s", Some((86, 0)), Some(0)),
        ("turning 31.5 deg/s", Some((0, 0)), Some(31_500)),
        ("flow stale", None, Some(0)),
        ("gyro stale", Some((0, 0)), None),
    ];
    const TICKS: usize = 100;
    let mut off = Vec::new();
    for (name, flow, gyro) in cases {
        let start = world::shipped::seed_robot().start;
        let mut slam: Slam<46, 46> = Slam::new(slam_config(config, &[]), start).unwrap();
        let mut reference = RefFilter::new(
            config,
            OdometryConfig::NOMINAL,
            TagMap::default(),
            fpose(&start),
        );
        let before = covariance(&slam);
        reference.p = before;
        let mut frame = SensorFrame::empty(100_000);
        frame.flow = flow.map(|(f, r)| FlowDelta {
            forward_counts: f,
            right_counts: r,
        });
        frame.gyro = gyro.map(|g| GyroRate { rate_mdps: g });
        for _ in 0..TICKS {
            slam.step(&frame);
            reference.step(&frame);
        }
        let after = covariance(&slam);
        // x moves with nothing else on these ticks (its Jacobian's row is zero), the heading
        // with the gyro bias's variance (rounded once); the calibration alone.
        for (i, state, rounding) in [(0, "x", 0.5), (2, "heading", 1.0)] {
            let unit = rf::unit(i).powi(2);
            let got = (after[i][i] - before[i][i]) / unit;
            let want = (reference.p[i][i] - before[i][i]) / unit;
            if (got - want).abs() > 0.1 * want.abs() + rounding {
                off.push(format!(
                    "{name}: {state} grew {got:.2} units, want {want:.2}"
                ));
            }
        }
        for (i, state) in [(3, "gyro scale"), (4, "gyro bias"), (5, "flow scale")] {
            let unit = rf::unit(i).powi(2);
            let got = (after[i][i] - before[i][i]) / unit;
            let want = (reference.p[i][i] - before[i][i]) / unit;
            if (got - want).abs() > 0.1 * want.abs() + 1.0 {
                off.push(format!(
                    "{name}: {state} grew {got:.2} units, want {want:.2}"
                ));
            }
        }
    }
    assert!(off.is_empty(), "{}", off.join("\n"));
}

/// `config` without the plausibility checks (`slam_core::plausible`): these inputs are
/// synthetic (constant rates, repeated frames, a robot that never holds), and the checks
/// are not what this file tests.
fn unchecked(config: slam_core::SlamConfig) -> slam_core::SlamConfig {
    slam_core::SlamConfig {
        plausible: None,
        ..config
    }
}

/// A run whose camera gives one picture twice in a row (seed 1520964776337080459, tick 23:
/// the same column and distance, as rounding to whole hundredths of a pixel and whole
/// millimetres sometimes makes them): the core skips the second, and so does the
/// reference; the two stay together.
#[test]
fn a_picture_given_twice_is_skipped_by_both() {
    let seed = 1_520_964_776_337_080_459;
    let apart = run_beside_reference(seed, EstimatorConfig::SEED, Sensors::SEED).unwrap();
    assert!(apart.position <= 0.6, "{apart:?}");
}
