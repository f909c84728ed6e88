//! The pose filter in plain `f64`, written from its model rather than from the integer
//! code: millimetres, radians, dimensionless scales, radians per second, and plain 6 x 6
//! matrices.
//!
//! States, in the covariance's order: x, y (mm), heading (rad, clockwise from +y), the
//! gyro's scale correction, the gyro's bias (rad/s) and the flow sensor's scale correction.
//! The motion model is dead reckoning with the calibration applied: a tick's flow counts
//! times `um_per_count (1 + flow scale)`, turned by the heading half way through the tick,
//! and a turn of `(rate - bias) (1 + gyro scale) dt`. Predict is `F P F^T + Q` with `F` that
//! model's Jacobian and `Q` diagonal (the noise model of [`EstimatorConfig`]). A sighting is
//! a range and a bearing to a tag at a listed place, gated by the joint chi-square statistic
//! and applied as two scalar updates, range first, each linearised once at the pose the
//! picture was taken from.

// Matrix arithmetic reads best with its indices.
#![allow(clippy::needless_range_loop)]

use super::{heading_of, nose, right, wrap, CENTRE_PX, FOCAL_PX};
use slam_core::estimator::config::STALE_PERIOD_US;
use slam_core::history::HISTORY_LEN;
use slam_core::{EstimatorConfig, OdometryConfig, SensorFrame, TagDetections, TagMap};

/// Number of states.
pub const N: usize = 6;
/// A 6 x 6 matrix, rows in state order.
pub type Matrix = [[f64; N]; N];
/// A state vector or a correction to one.
pub type Vector = [f64; N];

pub const X: usize = 0;
pub const Y: usize = 1;
pub const HEADING: usize = 2;
pub const GYRO_SCALE: usize = 3;
pub const GYRO_BIAS: usize = 4;
pub const FLOW_SCALE: usize = 5;

/// The integer filter's unit of each state, in the reference's units: position 1/16 mm,
/// heading 2^-16 rad, both scales 2^-16, gyro bias 2^-16 rad/s.
pub fn unit(i: usize) -> f64 {
    if i <= Y {
        1.0 / 16.0
    } else {
        1.0 / 65_536.0
    }
}

/// The smallest variance of each state, as a standard deviation squared: position 1/8 mm,
/// heading 2^-14 rad, the calibration one unit (2^-16). No variance may reach zero: a filter
/// sure of anything stops listening.
pub fn floor() -> Vector {
    let pos = (1.0f64 / 8.0).powi(2);
    let cal = (1.0f64 / 65_536.0).powi(2);
    [pos, pos, (1.0f64 / 16_384.0).powi(2), cal, cal, cal]
}

/// The largest variance of each state, as a standard deviation squared: position 10 m,
/// heading 1 rad, gyro scale 10 %, gyro bias 5 deg/s, flow scale 30 %.
pub fn ceiling() -> Vector {
    [
        10_000f64.powi(2),
        10_000f64.powi(2),
        1.0,
        0.1f64.powi(2),
        5f64.to_radians().powi(2),
        0.3f64.powi(2),
    ]
}

/// The learned calibration's limits (gyro scale, gyro bias, flow scale): beyond them a sensor
/// is broken, not miscalibrated.
pub fn calibration_limit() -> [f64; 3] {
    [0.1, 5f64.to_radians(), 0.3]
}

/// Closest a tag is taken to be in the bearing's Jacobian and the range's noise, mm.
pub const MIN_JACOBIAN_RANGE_MM: f64 = 50.0;

fn mdeg(v: u32) -> f64 {
    (v as f64 / 1000.0).to_radians()
}

fn ppm(v: u32) -> f64 {
    v as f64 / 1e6
}

/// The covariance the filter starts with.
pub fn initial(c: &EstimatorConfig) -> Matrix {
    let pos = (c.initial_position_mm as f64).powi(2);
    let mut p = diagonal([
        pos,
        pos,
        mdeg(c.initial_heading_mdeg).powi(2),
        ppm(c.initial_gyro_scale_ppm).powi(2),
        mdeg(c.initial_gyro_bias_mdps).powi(2),
        ppm(c.initial_flow_scale_ppm).powi(2),
    ]);
    bound(&mut p);
    p
}

pub fn diagonal(v: Vector) -> Matrix {
    let mut m = [[0.0; N]; N];
    for i in 0..N {
        m[i][i] = v[i];
    }
    m
}

/// One tick's motion as the filter's model sees it.
#[derive(Clone, Copy, Debug, Default)]
pub struct TickMotion {
    /// The displacement over the tick in the map frame, mm (calibration applied).
    pub dx: f64,
    pub dy: f64,
    /// The turn over the tick, rad (calibration applied).
    pub turn: f64,
    /// The turn's rate before the scale, bias removed, rad/s: the turn's derivative by the
    /// gyro's scale is this times `dt`.
    pub rate: f64,
    /// The heading half way through the turn, rad: the way the nose pointed.
    pub mid: f64,
    /// The tick's length, s.
    pub dt: f64,
    /// The displacement before the flow scale: its derivative by the flow scale, mm.
    pub nominal_dx: f64,
    pub nominal_dy: f64,
    /// The gyro's scale factor applied, `1 + scale`: the turn's derivative by the bias is
    /// `-factor dt`.
    pub gyro_factor: f64,
    /// Whether each reading was there.
    pub flow: bool,
    pub gyro: bool,
}

/// `F P F^T + Q` for one tick.
///
/// The Jacobian of `x' = x + f sin(h + t/2) + r cos(h + t/2)` (and `y'` alike) by the heading
/// is `(dy, -dx)`; by the flow scale, the displacement before the scale; the turn's by the
/// gyro's scale is the unscaled turn, by its bias `-(1 + scale) dt`. The turn's own effect
/// on the chord's direction through the calibration is second order and left out.
///
/// The noise: per axis, the flow's own noise, a share of the distance and a length per
/// radian turned (a stale flow reading instead costs its own larger figure, in proportion
/// to the frame's time, along the nose, and across it only the flow's own noise); on the
/// heading, the gyro's noise and a share of the angle turned (or the stale figure,
/// likewise); a random walk on each calibration state.
pub fn predict(p: &mut Matrix, c: &EstimatorConfig, m: &TickMotion) {
    let mut f = diagonal([1.0; N]);
    f[X][HEADING] = m.dy;
    f[Y][HEADING] = -m.dx;
    if m.flow {
        f[X][FLOW_SCALE] = m.nominal_dx;
        f[Y][FLOW_SCALE] = m.nominal_dy;
    }
    if m.gyro {
        f[HEADING][GYRO_SCALE] = m.rate * m.dt;
        f[HEADING][GYRO_BIAS] = -m.gyro_factor * m.dt;
    }
    *p = mul(&mul(&f, p), &transpose(&f));
    let distance = m.dx.hypot(m.dy);
    let turn = m.turn.abs();
    // A stale input's deviation grows with the time unseen.
    let stale = m.dt * 1e6 / f64::from(STALE_PERIOD_US);
    let own = (c.position_noise_um as f64 / 1000.0).powi(2);
    let (position, across_position) = if m.flow {
        let read = own
            + (distance * ppm(c.position_noise_ppm)).powi(2)
            + (c.position_noise_um_per_rad as f64 / 1000.0 * turn).powi(2);
        (read, read)
    } else {
        let along = (c.stale_flow_mm as f64 * stale).powi(2);
        (along, own.min(along))
    };
    let heading = if m.gyro {
        mdeg(c.heading_noise_mdeg).powi(2) + (turn * ppm(c.heading_noise_ppm)).powi(2)
    } else {
        (mdeg(c.stale_gyro_mdeg) * stale).powi(2)
    };
    // `across I + (position - across) u u'`, the nose `u = (sin, cos)` of the mid heading.
    let (sin, cos) = m.mid.sin_cos();
    let extra = position - across_position;
    let q = [
        across_position + extra * sin * sin,
        across_position + extra * cos * cos,
        heading,
        ppm(c.gyro_scale_walk_ppm).powi(2),
        (c.gyro_bias_walk_udps as f64 / 1e6).to_radians().powi(2),
        ppm(c.flow_scale_walk_ppm).powi(2),
    ];
    for i in 0..N {
        p[i][i] += q[i];
    }
    p[X][Y] += extra * sin * cos;
    p[Y][X] += extra * sin * cos;
    bound(p);
}

/// A pose in millimetres and radians.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct FPose {
    pub x: f64,
    pub y: f64,
    pub heading: f64,
}

/// One tag reading: the range read, mm, and the picture column, px.
#[derive(Clone, Copy, Debug)]
pub struct Reading {
    pub range_mm: f64,
    pub cx_px: f64,
}

/// Why the reference refused a sighting.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Refusal {
    UnknownId,
    Behind,
    TooFar,
    TooOld,
    Gate,
}

/// What a taken sighting did.
#[derive(Clone, Copy, Debug)]
pub struct Update {
    /// The correction to the state at the picture's moment.
    pub correction: Vector,
    /// The joint chi-square statistic the gate tested.
    pub chi2: f64,
}

/// The joint chi-square statistic of a sighting from `then`, and the reasons before the
/// gate: `Err` for a refusal other than the gate.
pub fn chi2(
    p: &Matrix,
    c: &EstimatorConfig,
    then: &FPose,
    tag: (f64, f64),
    reading: &Reading,
) -> Result<f64, Refusal> {
    let s = Sighting::new(p, c, then, tag, reading)?;
    Ok(s.chi2())
}

/// A sighting's linearisation.
struct Sighting {
    nu: [f64; 2],
    h: [Vector; 2],
    r: [f64; 2],
    s: [[f64; 2]; 2],
}

impl Sighting {
    fn new(
        p: &Matrix,
        c: &EstimatorConfig,
        then: &FPose,
        tag: (f64, f64),
        reading: &Reading,
    ) -> Result<Sighting, Refusal> {
        if reading.range_mm > c.max_range_mm as f64 {
            return Err(Refusal::TooFar);
        }
        let (dx, dy) = (tag.0 - then.x, tag.1 - then.y);
        let range = dx.hypot(dy);
        let direction = heading_of(dx, dy);
        let predicted = wrap(direction - then.heading);
        if predicted.abs() > mdeg(c.half_view_mdeg) {
            return Err(Refusal::Behind);
        }
        let seen = ((reading.cx_px - CENTRE_PX) / FOCAL_PX).atan();
        let nu = [reading.range_mm - range, wrap(seen - predicted)];
        // d range / d(x, y) is minus the unit vector to the tag; d bearing / d(x, y) is the
        // unit vector across the line of sight over the range, d bearing / d heading is -1.
        let (sin, cos) = (direction.sin(), direction.cos());
        let rj = range.max(MIN_JACOBIAN_RANGE_MM);
        let mut h = [[0.0; N]; 2];
        h[0][X] = -sin;
        h[0][Y] = -cos;
        h[1][X] = -cos / rj;
        h[1][Y] = sin / rj;
        h[1][HEADING] = -1.0;
        let r = [
            (c.range_noise_mm as f64 + rj * c.range_noise_permille as f64 / 1000.0).powi(2),
            (mdeg(c.bearing_noise_mdeg) * seen.cos().powi(2)).powi(2),
        ];
        let mut s = [[0.0; 2]; 2];
        for a in 0..2 {
            for b in 0..2 {
                s[a][b] = quadratic(&h[a], p, &h[b]) + if a == b { r[a] } else { 0.0 };
            }
        }
        Ok(Sighting { nu, h, r, s })
    }

    /// `nu^T S^-1 nu`.
    fn chi2(&self) -> f64 {
        let [[a, b], [_, d]] = self.s;
        let det = a * d - b * b;
        let [u, v] = self.nu;
        (d * u * u - 2.0 * b * u * v + a * v * v) / det
    }
}

/// One sighting: the gate, then range and bearing as two scalar updates of `p`. Returns the
/// state's correction, or why the sighting was refused (and then `p` is unchanged).
pub fn sight(
    p: &mut Matrix,
    c: &EstimatorConfig,
    then: &FPose,
    tag: (f64, f64),
    reading: &Reading,
) -> Result<Update, Refusal> {
    let s = Sighting::new(p, c, then, tag, reading)?;
    let chi2 = s.chi2();
    if chi2 > c.gate_chi2_q8 as f64 / 256.0 {
        return Err(Refusal::Gate);
    }
    let mut correction = [0.0; N];
    for k in 0..2 {
        // The innovation left once the earlier updates are applied (linear: the same
        // linearisation point throughout).
        let nu = s.nu[k] - dot(&s.h[k], &correction);
        let a = mul_vec(p, &s.h[k]);
        let sk = dot(&s.h[k], &a) + s.r[k];
        for i in 0..N {
            correction[i] += a[i] / sk * nu;
            for j in 0..N {
                p[i][j] -= a[i] * a[j] / sk;
            }
        }
    }
    bound(p);
    Ok(Update { correction, chi2 })
}

/// The same sighting as one joint update, `K = P H^T S^-1` with the 2 x 2 `S` inverted:
/// the textbook form, against which the sequential one is checked. No gate, no bounds.
pub fn joint_update(
    p: &Matrix,
    c: &EstimatorConfig,
    then: &FPose,
    tag: (f64, f64),
    reading: &Reading,
) -> Result<(Vector, Matrix), Refusal> {
    let s = Sighting::new(p, c, then, tag, reading)?;
    let [[a, b], [_, d]] = s.s;
    let det = a * d - b * b;
    let inverse = [[d / det, -b / det], [-b / det, a / det]];
    // P H^T, one column per measurement.
    let ph = [mul_vec(p, &s.h[0]), mul_vec(p, &s.h[1])];
    let mut gain = [[0.0; 2]; N];
    for i in 0..N {
        for k in 0..2 {
            gain[i][k] = (0..2).map(|m| ph[m][i] * inverse[m][k]).sum();
        }
    }
    let mut correction = [0.0; N];
    let mut q = *p;
    for i in 0..N {
        correction[i] = gain[i][0] * s.nu[0] + gain[i][1] * s.nu[1];
        for j in 0..N {
            q[i][j] -= gain[i][0] * ph[0][j] + gain[i][1] * ph[1][j];
        }
    }
    Ok((correction, q))
}

/// Keeps a covariance within its floor and ceiling: a variance past its ceiling scales its
/// row and column to it (a congruence), one under its floor is raised to it, and each
/// correlation is kept at or below 0.999.
pub fn bound(p: &mut Matrix) {
    let (lo, hi) = (floor(), ceiling());
    for i in 0..N {
        if p[i][i] > hi[i] {
            let c = (hi[i] / p[i][i]).sqrt();
            for j in 0..N {
                if j != i {
                    p[i][j] *= c;
                    p[j][i] *= c;
                }
            }
            p[i][i] = hi[i];
        }
        p[i][i] = p[i][i].max(lo[i]);
    }
    for i in 0..N {
        for j in i + 1..N {
            let limit = 0.999 * (p[i][i] * p[j][j]).sqrt();
            let v = p[i][j].clamp(-limit, limit);
            p[i][j] = v;
            p[j][i] = v;
        }
    }
}

pub fn mul(a: &Matrix, b: &Matrix) -> Matrix {
    let mut m = [[0.0; N]; N];
    for i in 0..N {
        for j in 0..N {
            m[i][j] = (0..N).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    m
}

pub fn transpose(a: &Matrix) -> Matrix {
    let mut m = [[0.0; N]; N];
    for i in 0..N {
        for j in 0..N {
            m[i][j] = a[j][i];
        }
    }
    m
}

pub fn mul_vec(a: &Matrix, v: &Vector) -> Vector {
    let mut out = [0.0; N];
    for i in 0..N {
        out[i] = dot(&a[i], v);
    }
    out
}

pub fn dot(a: &Vector, b: &Vector) -> f64 {
    a.iter().zip(b).map(|(a, b)| a * b).sum()
}

fn quadratic(a: &Vector, p: &Matrix, b: &Vector) -> f64 {
    dot(a, &mul_vec(p, b))
}

/// The Cholesky factor of `p` scaled to unit diagonal (a congruence, so it exists exactly
/// when `p` is positive definite); `None` if a pivot is not positive.
pub fn cholesky_of_correlation(p: &Matrix) -> Option<Matrix> {
    let mut c = [[0.0; N]; N];
    for i in 0..N {
        if p[i][i].is_nan() || p[i][i] <= 0.0 {
            return None;
        }
        for j in 0..N {
            c[i][j] = p[i][j] / (p[i][i] * p[j][j]).sqrt();
        }
    }
    let mut l = [[0.0; N]; N];
    for j in 0..N {
        let d = c[j][j] - (0..j).map(|k| l[j][k] * l[j][k]).sum::<f64>();
        if d.is_nan() || d <= 0.0 {
            return None;
        }
        l[j][j] = d.sqrt();
        for i in j + 1..N {
            l[i][j] = (c[i][j] - (0..j).map(|k| l[i][k] * l[j][k]).sum::<f64>()) / l[j][j];
        }
    }
    Some(l)
}

/// The integer filter's covariance in the reference's units.
pub fn from_integer(rows: &[[i32; N]; N]) -> Matrix {
    let mut m = [[0.0; N]; N];
    for i in 0..N {
        for j in 0..N {
            m[i][j] = rows[i][j] as f64 * unit(i) * unit(j);
        }
    }
    m
}

/// The largest difference between two covariances, each entry's as a share of the scale
/// `sqrt(want_ii want_jj)` it lives on, after `absolute` integer units per state are allowed
/// for (`|got - want| - absolute_i absolute_j`, floored at zero). Returns the worst share and
/// where it was.
pub fn worst_difference(got: &Matrix, want: &Matrix, absolute: &Vector) -> (f64, usize, usize) {
    worst_difference_on(got, want, want, absolute)
}

/// [`worst_difference`] with each entry's scale taken from `scale` (for an update, the
/// covariance before it: its rounding is a share of what it started from).
pub fn worst_difference_on(
    got: &Matrix,
    want: &Matrix,
    scale: &Matrix,
    absolute: &Vector,
) -> (f64, usize, usize) {
    let mut worst = (0.0, 0, 0);
    for i in 0..N {
        for j in 0..N {
            let allowed = absolute[i] * absolute[j];
            let diff = ((got[i][j] - want[i][j]).abs() - allowed).max(0.0);
            let scale = (scale[i][i] * scale[j][j]).sqrt();
            let share = diff / scale;
            if share > worst.0 {
                worst = (share, i, j);
            }
        }
    }
    worst
}

// ---------------------------------------------------------------------------------------
// The whole filter: pose, calibration, covariance and history, tick by tick
// ---------------------------------------------------------------------------------------

/// Sightings taken and refused, by cause (as `slam_core::TagCounters`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Counts {
    pub used: u32,
    pub unknown_id: u32,
    pub behind: u32,
    pub too_far: u32,
    pub too_old: u32,
    pub gate: u32,
}

/// The filter as `Slam::step` runs it, in `f64`.
#[derive(Clone, Debug)]
pub struct RefFilter {
    pub config: EstimatorConfig,
    pub odometry: OdometryConfig,
    pub tags: TagMap,
    pub pose: FPose,
    /// Gyro scale, gyro bias (rad/s), flow scale.
    pub calibration: [f64; 3],
    pub p: Matrix,
    pub counts: Counts,
    /// The last ticks' poses, newest last, each with the time since the one before, us.
    history: Vec<(FPose, u32)>,
    /// The last picture with sightings in it: one given again is skipped, as the core
    /// skips it (`slam_core::camera_check`).
    last_picture: Option<TagDetections>,
}

impl RefFilter {
    pub fn new(
        config: EstimatorConfig,
        odometry: OdometryConfig,
        tags: TagMap,
        start: FPose,
    ) -> RefFilter {
        RefFilter {
            config,
            odometry,
            tags,
            pose: start,
            calibration: [0.0; 3],
            p: initial(&config),
            counts: Counts::default(),
            history: vec![(start, 0)],
            last_picture: None,
        }
    }

    /// The tick's motion from its readings, with the calibration applied.
    pub fn motion(&self, frame: &SensorFrame) -> TickMotion {
        let [gs, gb, fs] = self.calibration;
        let dt = frame.dt_us as f64 / 1e6;
        let gyro_factor = 1.0 + self.odometry.gyro_scale_ppm as f64 / 1e6 + gs;
        let rate = frame
            .gyro
            .map_or(0.0, |g| (g.rate_mdps as f64 / 1000.0).to_radians() - gb);
        let turn = rate * gyro_factor * dt;
        let um_per_count = self.odometry.flow_um_per_count_q16 as f64 / 65_536.0;
        let (f, r) = frame.flow.map_or((0.0, 0.0), |f| {
            (
                f.forward_counts as f64 * um_per_count / 1000.0,
                f.right_counts as f64 * um_per_count / 1000.0,
            )
        });
        let mid = self.pose.heading + turn / 2.0;
        let (n, s) = (nose(mid), right(mid));
        let nominal_dx = f * n.0 + r * s.0;
        let nominal_dy = f * n.1 + r * s.1;
        TickMotion {
            dx: nominal_dx * (1.0 + fs),
            dy: nominal_dy * (1.0 + fs),
            turn,
            rate,
            mid,
            dt,
            nominal_dx,
            nominal_dy,
            gyro_factor,
            flow: frame.flow.is_some(),
            gyro: frame.gyro.is_some(),
        }
    }

    /// One tick: predict from the odometry, then every tag in the picture.
    pub fn step(&mut self, frame: &SensorFrame) {
        let m = self.motion(frame);
        self.pose = FPose {
            x: self.pose.x + m.dx,
            y: self.pose.y + m.dy,
            heading: self.pose.heading + m.turn,
        };
        self.history.push((self.pose, frame.dt_us));
        if self.history.len() > HISTORY_LEN {
            self.history.remove(0);
        }
        predict(&mut self.p, &self.config, &m);
        if !frame.tags.is_empty() {
            if self.last_picture.as_ref() == Some(&frame.tags) {
                return;
            }
            self.last_picture = Some(frame.tags.clone());
        }
        for d in frame.tags.iter() {
            let outcome = self.sight_one(d.id, d.cx_centipx, d.distance_mm, frame.tags_age_us);
            let c = &mut self.counts;
            *match outcome {
                Ok(()) => &mut c.used,
                Err(Refusal::UnknownId) => &mut c.unknown_id,
                Err(Refusal::Behind) => &mut c.behind,
                Err(Refusal::TooFar) => &mut c.too_far,
                Err(Refusal::TooOld) => &mut c.too_old,
                Err(Refusal::Gate) => &mut c.gate,
            } += 1;
        }
    }

    fn sight_one(&mut self, id: u16, cx: i32, range_mm: u32, age_us: u32) -> Result<(), Refusal> {
        let tag = self.tags.get(id).ok_or(Refusal::UnknownId)?;
        let tag = (tag.x_mm as f64, tag.y_mm as f64);
        if range_mm > self.config.max_range_mm {
            return Err(Refusal::TooFar);
        }
        let then = self.at(age_us).ok_or(Refusal::TooOld)?;
        let reading = Reading {
            range_mm: range_mm as f64,
            cx_px: cx as f64 / 100.0,
        };
        let u = sight(&mut self.p, &self.config, &then, tag, &reading)?;
        let d = u.correction;
        let limit = calibration_limit();
        for k in 0..3 {
            self.calibration[k] =
                (self.calibration[k] + d[GYRO_SCALE + k]).clamp(-limit[k], limit[k]);
        }
        let corrected = FPose {
            x: then.x + d[X],
            y: then.y + d[Y],
            heading: then.heading + d[HEADING],
        };
        // Every remembered pose, and the pose now, moves as the picture's pose did.
        for (pose, _) in self.history.iter_mut() {
            *pose = carry(&then, &corrected, pose);
        }
        self.pose = self.history.last().map_or(self.pose, |e| e.0);
        Ok(())
    }

    /// The pose `age_us` before now, linear between remembered ticks; `None` beyond them.
    pub fn at(&self, age_us: u32) -> Option<FPose> {
        let mut age = 0u64;
        let mut newer: Option<(u64, FPose)> = None;
        for &(pose, dt) in self.history.iter().rev() {
            if age >= age_us as u64 {
                return Some(match newer {
                    Some((newer_age, n)) if age > age_us as u64 => {
                        let f = (age - age_us as u64) as f64 / (age - newer_age) as f64;
                        FPose {
                            x: pose.x + f * (n.x - pose.x),
                            y: pose.y + f * (n.y - pose.y),
                            heading: pose.heading + f * wrap(n.heading - pose.heading),
                        }
                    }
                    _ => pose,
                });
            }
            newer = Some((age, pose));
            age += dt as u64;
        }
        None
    }
}

/// `pose` carried by the rigid motion that takes `from` onto `to` (turning clockwise, as
/// headings do).
pub fn carry(from: &FPose, to: &FPose, pose: &FPose) -> FPose {
    let t = to.heading - from.heading;
    let (dx, dy) = (pose.x - from.x, pose.y - from.y);
    FPose {
        x: to.x + dx * t.cos() + dy * t.sin(),
        y: to.y + dy * t.cos() - dx * t.sin(),
        heading: pose.heading + t,
    }
}
