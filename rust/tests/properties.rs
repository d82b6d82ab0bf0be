//! Property tests over random inputs, valid and invalid: trajectory segment lists,
//! filter configurations, noise strategies, sensor models, recorded data.
//!
//! The contract checked everywhere: an input either runs and every number it returns
//! is finite, or it is refused with an `Err`. Nothing panics (proptest turns a panic
//! into a failure), and nothing hands back NaN or ±inf inside an `Ok`. Inputs that the
//! validation rules of the library clearly forbid (non-finite values, non-positive
//! durations or steps, negative variances, ...) must give `Err`; modest, clearly valid
//! inputs must give `Ok`.
//!
//! Inputs are built as a valid value plus a few "corruptions", each replacing one
//! field with a wild value (zero, negative, NaN, ±inf, huge, tiny), so that both the
//! accepting and the refusing paths are exercised in every property.
//!
//! Gaps these properties found: finite but absurd magnitudes (tuning or sensor values
//! ≥ 1e100, an initial velocity ≥ 1e6 m/s, heights or yaw rates ≥ 1e100) were accepted
//! and overflowed to NaN/inf inside an `Ok`. They are fixed (a prediction that is not
//! finite is an error, a trajectory that overflows is refused, σ of a NaN variance is
//! NaN, the IMU variance schedule is validated), and the `pinned_*` tests at the end
//! keep each case. The main properties still leave those regions out (see `HUGE`,
//! `ABSURD_DATA`), where an `Err` is the only answer and says little.
//!
//! Cases are few (64 per property; `PROPTEST_CASES` raises it) and the simulated runs
//! short, so the file runs in well under a second once built. Failure persistence is
//! off: found failures are pinned as explicit tests instead of files written next to
//! this one.

use nalgebra::Vector3;
use pronet::ekf::calibration::CalibrationConfig;
use pronet::ekf::{
    filter_recorded, Aiding, Ekf, FilterConfig, FilterOutput, Formulation, RecordedData,
};
use pronet::mechanization::NavState;
use pronet::montecarlo::{run_monte_carlo, McOptions, RunSummary, Scenario};
use pronet::noise::StrategySpec;
use pronet::sensors::{SensorConfig, SensorSim, VarianceSchedule};
use pronet::trajectory::{paper_origin, Segment, TrajectorySpec, Truth, MAX_SPEED};
use proptest::prelude::*;
use proptest::sample::Index;
use std::sync::{Arc, OnceLock};

/// 64 cases per property, unless `PROPTEST_CASES` asks for more (longer bug hunts).
fn config() -> ProptestConfig {
    // A fixed seed: CI runs the same cases every time (no flaky failures); set
    // PROPTEST_RNG_SEED or raise PROPTEST_CASES to explore more.
    let seed = std::env::var("PROPTEST_RNG_SEED")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(0x5eed);
    let mut c = ProptestConfig {
        failure_persistence: None,
        rng_seed: proptest::test_runner::RngSeed::Fixed(seed),
        ..ProptestConfig::default()
    };
    if std::env::var_os("PROPTEST_CASES").is_none() {
        c.cases = 64;
    }
    c
}

/// Values that stress validation: zero, negatives, non-finite, huge, tiny.
const WILD: [f64; 15] = [
    0.0,
    -0.0,
    -1.0,
    -1e-9,
    f64::NAN,
    f64::INFINITY,
    f64::NEG_INFINITY,
    1e300,
    -1e300,
    f64::MAX,
    1e10,
    1e6,
    1e-300,
    f64::MIN_POSITIVE,
    5e-324,
];

fn wild() -> impl Strategy<Value = f64> {
    prop::sample::select(WILD.to_vec())
}

/// No corruption two times in three, else 1..=`n` of them (so that most cases of a
/// property with several corruptible parts still reach the code under test).
fn rarely<T: std::fmt::Debug + Clone + 'static>(
    item: impl Strategy<Value = T> + 'static,
    n: usize,
) -> BoxedStrategy<Vec<T>> {
    prop_oneof![
        2 => Just(Vec::new()),
        1 => prop::collection::vec(item, 1..=n),
    ]
    .boxed()
}

/// Corruptions of a list: (which item, which field, the value).
fn corruptions(fields: usize, n: usize) -> BoxedStrategy<Vec<(Index, usize, f64)>> {
    rarely((any::<Index>(), 0..fields, wild()), n)
}

fn all_finite<'a>(values: impl IntoIterator<Item = &'a f64>) -> bool {
    values.into_iter().all(|v| v.is_finite())
}

fn nav_finite(s: &NavState) -> bool {
    all_finite(s.lla.iter()) && all_finite(s.vel.iter()) && all_finite(s.dcm.iter())
}

// =======================================================================================
// Trajectories.

fn valid_segment() -> impl Strategy<Value = Segment> {
    (0.05..30.0f64, -0.2..0.2f64, -0.5..0.5f64, -0.01..0.01f64)
        .prop_map(|(d, a, y, p)| Segment::new(d, a, y, p))
}

fn set_segment_field(s: &mut Segment, field: usize, v: f64) {
    match field {
        // A huge duration is pushed past the sample limit (always refused): one that is
        // merely large (1e6 s at dt = 0.1 s, 1e7 samples) is valid, only slow and big.
        0 if v.is_finite() && v > 1e3 => s.duration = 1e12,
        0 => s.duration = v,
        1 => s.accel = v,
        2 => s.yaw_rate = v,
        _ => s.pitch_rate = v,
    }
}

/// A trajectory spec and whether a wild value was put into it.
fn trajectory_spec() -> impl Strategy<Value = (TrajectorySpec, bool)> {
    (
        prop::collection::vec(valid_segment(), 0..6),
        corruptions(4, 2),
        prop::sample::select(vec![0.01, 0.02, 0.05, 0.1, 0.25]),
        0.0..3.0f64,
        prop_oneof![3 => Just(paper_origin()[0]), 1 => -1.6..1.6f64],
        (-3.2..3.2f64, -0.5..0.5f64, -3.2..3.2f64),
        // Corruptions of the scalars: 0 dt, 1 speed0, 2..5 lla0, 5..8 rpy0.
        rarely((0..8usize, wild()), 1),
    )
        .prop_map(
            |(mut segments, seg_bad, dt, speed0, lat, rpy, scalar_bad)| {
                let corrupted =
                    (!seg_bad.is_empty() && !segments.is_empty()) || !scalar_bad.is_empty();
                if !segments.is_empty() {
                    for (i, field, v) in &seg_bad {
                        let i = i.index(segments.len());
                        set_segment_field(&mut segments[i], *field, *v);
                    }
                }
                let mut spec = TrajectorySpec {
                    name: "prop".into(),
                    lla0: Vector3::new(lat, paper_origin()[1], paper_origin()[2]),
                    speed0,
                    rpy0: Vector3::new(rpy.0, rpy.1, rpy.2),
                    segments,
                    dt,
                };
                for (field, v) in scalar_bad {
                    match field {
                        0 => spec.dt = v,
                        1 => spec.speed0 = v,
                        2..=4 => spec.lla0[field - 2] = v,
                        _ => spec.rpy0[field - 5] = v,
                    }
                }
                (spec, corrupted)
            },
        )
}

/// The documented rules a spec must meet (see `TrajectorySpec::validate`), computed
/// independently: `Some(reason)` if it must be refused.
fn must_refuse(spec: &TrajectorySpec) -> Option<&'static str> {
    let scalars = [
        spec.dt,
        spec.speed0,
        spec.lla0[0],
        spec.lla0[1],
        spec.lla0[2],
    ];
    if !all_finite(scalars.iter().chain(spec.rpy0.iter())) {
        return Some("non-finite scalar");
    }
    if spec.dt <= 0.0 {
        return Some("dt <= 0");
    }
    if spec.lla0[0].abs() > 89f64.to_radians() {
        return Some("latitude beyond 89°");
    }
    if spec.segments.is_empty() {
        return Some("no segments");
    }
    for s in &spec.segments {
        if !all_finite(&[s.duration, s.accel, s.yaw_rate, s.pitch_rate]) {
            return Some("non-finite segment value");
        }
        if s.duration <= 0.0 {
            return Some("duration <= 0");
        }
    }
    None
}

/// Whether a spec is modest enough that it must be accepted: no wild values, speed and
/// pitch within the documented limits with margin, at least one sample.
fn must_accept(spec: &TrajectorySpec, corrupted: bool) -> bool {
    if corrupted || must_refuse(spec).is_some() {
        return false;
    }
    let top_speed = spec.speed0.abs()
        + spec
            .segments
            .iter()
            .map(|s| (s.accel * s.duration).abs())
            .sum::<f64>();
    let mut pitch = spec.rpy0[1];
    let mut max_pitch = pitch.abs();
    for s in &spec.segments {
        pitch += s.pitch_rate * s.duration;
        max_pitch = max_pitch.max(pitch.abs());
    }
    top_speed < 0.99 * MAX_SPEED
        && max_pitch < 79f64.to_radians()
        && spec.duration() >= 1.01 * spec.dt
}

/// Everything a generated truth must satisfy.
fn check_truth(spec: &TrajectorySpec, truth: &Truth) -> Result<(), TestCaseError> {
    let n = truth.len();
    prop_assert!(n >= 1, "an Ok truth has at least one IMU sample");
    prop_assert_eq!(n, (spec.duration() / spec.dt + 1e-9).floor() as usize);
    prop_assert_eq!(truth.time.len(), n + 1);
    prop_assert_eq!(truth.states.len(), n + 1);
    prop_assert_eq!(truth.rpy.len(), n + 1);
    prop_assert!(all_finite(&truth.time), "non-finite time");
    prop_assert!(
        truth.time.windows(2).all(|w| w[1] > w[0]),
        "time not increasing"
    );
    for (k, s) in truth.states.iter().enumerate() {
        prop_assert!(
            nav_finite(s),
            "non-finite truth state {} of {}: {:?}",
            k,
            n,
            s
        );
        prop_assert!(
            s.vel.norm() <= MAX_SPEED * (1.0 + 1e-9),
            "speed {} m/s at epoch {} beyond the {} m/s limit",
            s.vel.norm(),
            k,
            MAX_SPEED
        );
    }
    for (k, r) in truth.rpy.iter().enumerate() {
        prop_assert!(all_finite(r.iter()), "non-finite rpy at {}: {:?}", k, r);
    }
    for (k, m) in truth.imu.iter().enumerate() {
        prop_assert!(all_finite(m), "non-finite ideal IMU sample {}: {:?}", k, m);
    }
    Ok(())
}

proptest! {
    #![proptest_config(config())]

    /// A random segment list either generates a finite truth of the documented length
    /// or is refused; clearly invalid lists are refused, modest valid ones accepted.
    #[test]
    fn trajectory_generates_finite_truth_or_err((spec, corrupted) in trajectory_spec()) {
        // Known: a huge finite initial height overflows gravity, a huge finite yaw rate
        // overflows the yaw angle (both pinned below).
        let huge = |v: f64| v.is_finite() && v.abs() >= HUGE;
        prop_assume!(!huge(spec.lla0[2]));
        prop_assume!(!spec.segments.iter().any(|s| huge(s.yaw_rate)));
        let result = spec.generate();
        if let Some(reason) = must_refuse(&spec) {
            prop_assert!(result.is_err(), "{} must be refused: {:?}", reason, spec);
        }
        if must_accept(&spec, corrupted) {
            prop_assert!(result.is_ok(), "valid spec refused: {:?} {:?}", result.as_ref().err(), spec);
        }
        match result {
            Ok(truth) => check_truth(&spec, &truth)?,
            Err(e) => prop_assert!(
                matches!(e, pronet::Error::InvalidArgument { .. }),
                "a spec is refused as an invalid argument, not {:?}",
                e
            ),
        }
    }
}

// =======================================================================================
// Filter configurations and noise strategies.

/// A filter configuration with up to two wild fields.
fn filter_config() -> impl Strategy<Value = FilterConfig> {
    (
        prop::collection::vec(-6.0..1.0f64, 15),
        prop_oneof![Just(0.0), -14.0..-2.0f64],
        prop_oneof![Just(0.0), -16.0..-4.0f64],
        prop::collection::vec(-6.0..0.0f64, 3),
        prop::collection::vec(-2.0..2.0f64, 3),
        any::<bool>(),
        prop_oneof![4 => Just(0.05), 1 => -3.0..0.0f64],
        // The DVL calibration states: off, or with 1σ and a scale walk of 10^e.
        prop_oneof![3 => Just(None), 1 => prop::collection::vec(-5.0..-1.0f64, 5).prop_map(Some)],
        // Corruptions: 0..15 p0_sigma, 15 accel psd, 16 gyro psd, 17..20 dvl variance,
        // 20..23 lever arm, 23 imu_dt, 24 innovation gate, 25..30 the calibration's
        // scale σ, misalignment σ (3) and scale walk (where the states are on), 30 the
        // covariance step.
        rarely((0..31usize, wild()), 2),
        // The formulation: both are held to every property.
        any::<bool>(),
        // The covariance step: every sample, or intervals of 0.1 s.
        prop_oneof![2 => Just(0.0), 1 => Just(0.1)],
    )
        .prop_map(
            |(p0, psd_a, psd_g, r, arm, body, dt, cal, bad, invariant, step)| {
                let pow = |e: f64| if e == 0.0 { 0.0 } else { 10f64.powf(e) };
                let mut c = FilterConfig {
                    p0_sigma: std::array::from_fn(|i| 10f64.powf(p0[i])),
                    accel_bias_psd: pow(psd_a),
                    gyro_bias_psd: pow(psd_g),
                    dvl_variance: std::array::from_fn(|i| 10f64.powf(r[i])),
                    lever_arm: Vector3::new(arm[0], arm[1], arm[2]),
                    aiding: if body { Aiding::Body } else { Aiding::Nav },
                    imu_dt: if dt == 0.05 { dt } else { 10f64.powf(dt) },
                    innovation_gate: None,
                    dvl_calibration: cal.map(|e| CalibrationConfig {
                        scale_sigma: 10f64.powf(e[0]),
                        misalignment_sigma: [10f64.powf(e[1]), 10f64.powf(e[2]), 10f64.powf(e[3])],
                        scale_psd: 10f64.powf(e[4]),
                        misalignment_psd: 0.0,
                    }),
                    formulation: if invariant {
                        Formulation::Invariant
                    } else {
                        Formulation::Classic
                    },
                    covariance_step: step,
                };
                for (field, v) in bad {
                    match (field, c.dvl_calibration.as_mut()) {
                        (0..=14, _) => c.p0_sigma[field] = v,
                        (15, _) => c.accel_bias_psd = v,
                        (16, _) => c.gyro_bias_psd = v,
                        (17..=19, _) => c.dvl_variance[field - 17] = v,
                        (20..=22, _) => c.lever_arm[field - 20] = v,
                        (23, _) => c.imu_dt = v,
                        (24, _) => c.innovation_gate = Some(v),
                        (25, Some(k)) => k.scale_sigma = v,
                        (26..=28, Some(k)) => k.misalignment_sigma[field - 26] = v,
                        (29, Some(k)) => k.scale_psd = v,
                        (30, _) => c.covariance_step = v,
                        _ => {}
                    }
                }
                c
            },
        )
}

/// The documented validity of a filter configuration (see `docs/filter.md` and
/// `FilterConfig::validate`), computed independently.
fn config_is_valid(c: &FilterConfig) -> bool {
    let nonneg = |v: f64| v.is_finite() && v >= 0.0;
    c.p0_sigma.iter().all(|v| nonneg(*v))
        && nonneg(c.accel_bias_psd)
        && nonneg(c.gyro_bias_psd)
        && c.dvl_variance.iter().all(|v| v.is_finite() && *v > 0.0)
        && all_finite(c.lever_arm.iter())
        && c.imu_dt.is_finite()
        && c.imu_dt > 0.0
        && c.innovation_gate.is_none_or(|g| g.is_finite() && g > 0.0)
        && nonneg(c.covariance_step)
        && c.dvl_calibration.is_none_or(|k| {
            c.aiding == Aiding::Body
                && nonneg(k.scale_sigma)
                && k.misalignment_sigma.iter().all(|v| nonneg(*v))
                && nonneg(k.scale_psd)
                && nonneg(k.misalignment_psd)
        })
}

/// The scalar metrics of a run summary: SRMSE, SMAE, final and max horizontal error,
/// mean NIS.
fn summary_metrics(s: &RunSummary) -> [f64; 5] {
    [
        s.srmse,
        s.smae,
        s.final_horizontal_error,
        s.max_horizontal_error,
        s.mean_nis,
    ]
}

fn q_row() -> impl Strategy<Value = [f64; 6]> {
    (
        prop::collection::vec(-12.0..3.0f64, 6),
        rarely((0..6usize, wild()), 1),
    )
        .prop_map(|(e, bad)| {
            let mut q: [f64; 6] = std::array::from_fn(|i| 10f64.powf(e[i]));
            for (i, v) in bad {
                q[i] = v;
            }
            q
        })
}

fn strategy_spec() -> impl Strategy<Value = StrategySpec> {
    prop_oneof![
        q_row().prop_map(|q| StrategySpec::Constant { q }),
        (0..5usize, q_row()).prop_map(|(window, prior_q)| StrategySpec::Mehra { window, prior_q }),
        q_row().prop_map(|prior_q| StrategySpec::External { prior_q }),
        (0..5usize, q_row())
            .prop_map(|(window, prior_q)| StrategySpec::Adaptive { window, prior_q }),
    ]
}

fn strategy_is_valid(s: &StrategySpec) -> bool {
    let ok = |q: &[f64; 6]| q.iter().all(|v| v.is_finite() && *v >= 0.0);
    match s {
        StrategySpec::Constant { q } => ok(q),
        StrategySpec::Mehra { window, prior_q } | StrategySpec::Adaptive { window, prior_q } => {
            *window > 0 && ok(prior_q)
        }
        StrategySpec::External { prior_q } => ok(prior_q),
        StrategySpec::Oracle => true,
    }
}

/// Recorded arrays of a short simulated run (20 s at 20 Hz, DVL at 1 Hz): the paper's
/// sensors along a straight leg, a turn and a speed-up.
struct Recording {
    truth: Truth,
    imu: Vec<[f64; 6]>,
    imu_time: Vec<f64>,
    dvl: Vec<[f64; 3]>,
    dvl_time: Vec<f64>,
}

fn recording() -> &'static Recording {
    static CELL: OnceLock<Recording> = OnceLock::new();
    CELL.get_or_init(|| {
        let spec = TrajectorySpec {
            name: "recording".into(),
            lla0: paper_origin(),
            speed0: 1.0,
            rpy0: Vector3::zeros(),
            segments: vec![
                Segment::new(8.0, 0.0, 0.0, 0.0),
                Segment::new(6.0, 0.0, 10f64.to_radians(), 0.0),
                Segment::new(6.0, 0.05, 0.0, 0.0),
            ],
            dt: 0.05,
        };
        let truth = spec.generate().unwrap();
        let sensors = SensorConfig::paper();
        let mut sim = SensorSim::new(&sensors, 11, 0);
        let mut imu = Vec::new();
        let mut dvl = Vec::new();
        let mut dvl_time = Vec::new();
        for k in 0..truth.len() {
            imu.push(sim.imu(&sensors.imu, &truth.imu[k], truth.time[k], truth.dt));
            if (k + 1) % 20 == 0 {
                let g = &truth.imu[k];
                let z = sim.dvl(
                    &sensors.dvl,
                    &truth.states[k + 1],
                    &Vector3::new(g[3], g[4], g[5]),
                );
                dvl.push([z[0], z[1], z[2]]);
                dvl_time.push(truth.time[k + 1]);
            }
        }
        let imu_time = truth.time[1..].to_vec();
        Recording {
            truth,
            imu,
            imu_time,
            dvl,
            dvl_time,
        }
    })
}

/// Which DVL rows a case uses.
#[derive(Clone, Copy, Debug)]
enum DvlRows {
    All,
    None,
    FirstFive,
}

/// One corruption of the recorded data: 0 an IMU value, 1 a DVL value, 2 a DVL time,
/// 3 t0, 4 the initial bias, 5 the initial velocity.
type DataCorruption = (usize, Index, usize, f64);

fn check_output(out: &FilterOutput, n_imu: usize, n_dvl: usize) -> Result<(), TestCaseError> {
    prop_assert_eq!(out.time.len(), n_imu + 1);
    prop_assert_eq!(out.nav.len(), n_imu + 1);
    prop_assert_eq!(out.sigma.len(), n_imu + 1);
    prop_assert_eq!(out.updates.len(), n_dvl);
    prop_assert!(all_finite(&out.time));
    for (k, s) in out.nav.iter().enumerate() {
        prop_assert!(nav_finite(s), "non-finite state at epoch {}: {:?}", k, s);
    }
    for (k, b) in out.bias.iter().enumerate() {
        prop_assert!(all_finite(b), "non-finite bias at epoch {}: {:?}", k, b);
    }
    for (k, s) in out.sigma.iter().enumerate() {
        prop_assert!(all_finite(s), "non-finite sigma at epoch {}: {:?}", k, s);
    }
    prop_assert!(
        all_finite(out.final_covariance.iter()),
        "non-finite final covariance: diag {:?}",
        out.final_covariance.diagonal().as_slice()
    );
    // σ is √diag P: a NaN variance must not come out as σ = 0.
    let last = out.sigma.last().unwrap();
    for (i, s) in last.iter().enumerate() {
        let var = out.final_covariance[(i, i)];
        prop_assert!(
            (s * s - var.max(0.0)).abs() <= 1e-9 * var.abs().max(1e-300),
            "sigma[{}] = {} but P[{},{}] = {}",
            i,
            s,
            i,
            i,
            var
        );
    }
    for (j, u) in out.updates.iter().enumerate() {
        prop_assert_eq!(u.is_some(), out.dvl_epoch[j].is_some());
        if let Some(u) = u {
            prop_assert!(
                u.nis.is_finite()
                    && all_finite(u.innovation.iter())
                    && all_finite(u.s.iter())
                    && all_finite(u.gain.iter()),
                "non-finite update {}: {:?}",
                j,
                u
            );
        }
    }
    for (j, q) in out.adaptive_q.iter().enumerate() {
        if let Some(q) = q {
            prop_assert!(all_finite(q.iter()), "non-finite adaptive Q at row {}", j);
        }
    }
    Ok(())
}

/// Finite tuning values so large that P overflows (σ² or q·Δt sums beyond f64): the
/// library accepts them (they are finite and ≥ 0) and does not notice the overflow. See
/// the pinned tests at the end of this file; the main properties leave them out.
const HUGE: f64 = 1e100;

/// Data values (IMU samples, DVL rows and times, t0, initial velocity and bias) of this
/// size are physically absurd; with no DVL update after them they overflow the state
/// unnoticed, like [`HUGE`] tuning values. Left out of the main property.
const ABSURD_DATA: f64 = 1e6;

fn huge_tuning(cfg: &FilterConfig, spec: &StrategySpec) -> bool {
    let q = match spec {
        StrategySpec::Constant { q } => q,
        StrategySpec::Mehra { prior_q, .. }
        | StrategySpec::Adaptive { prior_q, .. }
        | StrategySpec::External { prior_q } => prior_q,
        StrategySpec::Oracle => &[0.0; 6],
    };
    let calibration: Vec<f64> = cfg
        .dvl_calibration
        .iter()
        .flat_map(|k| {
            [k.scale_sigma, k.scale_psd, k.misalignment_psd]
                .into_iter()
                .chain(k.misalignment_sigma)
        })
        .collect();
    let huge = cfg
        .p0_sigma
        .iter()
        .chain(q)
        .chain([&cfg.accel_bias_psd, &cfg.gyro_bias_psd, &cfg.imu_dt])
        .chain(&calibration)
        .any(|v| v.is_finite() && v.abs() >= HUGE);
    huge
}

/// One case of the filter-pass property (known overflow cases are left out).
fn filter_case(
    cfg: &FilterConfig,
    spec: &StrategySpec,
    rows: DvlRows,
    bad: &[DataCorruption],
) -> Result<(), TestCaseError> {
    let rec = recording();
    let valid_cfg = config_is_valid(cfg);
    prop_assert_eq!(
        cfg.validate().is_ok(),
        valid_cfg,
        "validate() disagrees: {:?}",
        cfg
    );
    let truth0 = rec.truth.states[0];
    prop_assert_eq!(
        Ekf::new(cfg, truth0, Vector3::zeros(), Vector3::zeros()).is_ok(),
        valid_cfg
    );
    // Strategies come validated, as every public entry point does (Python, Monte Carlo).
    if !strategy_is_valid(spec) {
        prop_assert!(
            spec.validate().is_err(),
            "invalid strategy accepted: {:?}",
            spec
        );
        return Ok(());
    }
    prop_assert!(
        spec.validate().is_ok(),
        "valid strategy refused: {:?}",
        spec
    );
    let huge_data = bad
        .iter()
        .any(|c| c.3.is_finite() && c.3.abs() >= ABSURD_DATA);
    if valid_cfg && (huge_tuning(cfg, spec) || huge_data) {
        return Ok(());
    }

    let mut imu = rec.imu.clone();
    let (mut dvl, mut dvl_time) = match rows {
        DvlRows::All => (rec.dvl.clone(), rec.dvl_time.clone()),
        DvlRows::None => (Vec::new(), Vec::new()),
        DvlRows::FirstFive => (rec.dvl[..5].to_vec(), rec.dvl_time[..5].to_vec()),
    };
    let mut t0 = 0.0;
    let mut bias0 = [0.0; 6];
    let mut init = truth0;
    let mut bad_data = false;
    for &(what, row, col, v) in bad {
        match what {
            0 => {
                let i = row.index(imu.len());
                imu[i][col] = v;
            }
            1 if !dvl.is_empty() => {
                let i = row.index(dvl.len());
                dvl[i][col % 3] = v;
            }
            2 if !dvl.is_empty() => {
                let i = row.index(dvl.len());
                dvl_time[i] = v;
            }
            3 => t0 = v,
            4 => bias0[col] = v,
            5 => init.vel[col % 3] = v,
            _ => continue,
        }
        bad_data |= !v.is_finite();
    }
    let data = RecordedData {
        imu: &imu,
        imu_time: &rec.imu_time,
        dvl: &dvl,
        dvl_time: &dvl_time,
        t0,
        q_time: &[],
        q_values: &[],
        covariance_time: &[],
        ..RecordedData::default()
    };
    let mut strategy = spec.build(cfg.bias_psd());
    let result = filter_recorded(&data, init, bias0, cfg, strategy.as_mut());
    if valid_cfg && bad.is_empty() {
        // Valid inputs: the pass may only fail numerically.
        prop_assert!(
            !matches!(result, Err(pronet::Error::InvalidArgument { .. })),
            "valid inputs refused: {:?}",
            result.as_ref().err()
        );
    }
    if !valid_cfg || bad_data {
        prop_assert!(
            matches!(result, Err(pronet::Error::InvalidArgument { .. })),
            "invalid config or non-finite data not refused as an invalid argument: {:?}, {:?}",
            cfg,
            bad
        );
    }
    if let Ok(out) = &result {
        check_output(out, imu.len(), dvl.len())?;
    }
    Ok(())
}

fn dvl_rows() -> impl Strategy<Value = DvlRows> {
    prop_oneof![
        4 => Just(DvlRows::All),
        1 => Just(DvlRows::None),
        1 => Just(DvlRows::FirstFive),
    ]
}

fn data_corruptions() -> BoxedStrategy<Vec<DataCorruption>> {
    rarely((0..6usize, any::<Index>(), 0..6usize, wild()), 1)
}

proptest! {
    #![proptest_config(config())]

    /// Random filter configs (P0 σ, bias PSDs, DVL variances, lever arm, imu_dt),
    /// strategies and recorded-data corruptions through `filter_recorded`.
    #[test]
    fn filter_pass_is_finite_or_err(
        cfg in filter_config(),
        spec in strategy_spec(),
        rows in dvl_rows(),
        bad in data_corruptions(),
    ) {
        filter_case(&cfg, &spec, rows, &bad)?;
    }
}

// =======================================================================================
// Monte Carlo: random short trajectories, sensors, filter configs and strategies.

/// Sensors with up to two wild fields: 0..6 IMU variance, 6..12 bias, 12..18 bias PSD,
/// 18..21 DVL variance, 21 DVL period, 22..25 lever arm. The IMU variance goes through
/// the checked `VarianceSchedule::new` (as the Python layer does); when it refuses, the
/// case carries `None` (the schedule's validation is checked by the property).
fn sensor_config() -> impl Strategy<Value = (Option<SensorConfig>, [f64; 6])> {
    (
        prop::sample::select(vec![1.0, 1.0, 0.5, 2.0, 100.0, 0.015]),
        rarely((0..25usize, wild()), 2),
    )
        .prop_map(|(period, bad)| {
            let mut s = SensorConfig::paper();
            s.dvl.period = period;
            let mut q = [1e-4, 1e-4, 1e-4, 1e-6, 1e-6, 1e-6];
            for (field, v) in bad {
                match field {
                    0..=5 => q[field] = v,
                    6..=11 => s.imu.bias[field - 6] = v,
                    12..=17 => s.imu.bias_rw_psd[field - 12] = v,
                    18..=20 => s.dvl.variance[field - 18] = v,
                    21 => s.dvl.period = v,
                    _ => s.dvl.lever_arm[field - 22] = v,
                }
            }
            match VarianceSchedule::new(vec![0.0], vec![q]) {
                Ok(schedule) => {
                    s.imu.variance = schedule;
                    (Some(s), q)
                }
                Err(_) => (None, q),
            }
        })
}

fn sensors_are_valid(s: &SensorConfig) -> bool {
    let nonneg = |v: &f64| v.is_finite() && *v >= 0.0;
    all_finite(&s.imu.bias)
        && s.imu.bias_rw_psd.iter().all(nonneg)
        && s.dvl.variance.iter().all(nonneg)
        && s.dvl.period.is_finite()
        && s.dvl.period > 0.0
        && s.dvl
            .lever_arm
            .iter()
            .all(|v| v.abs() <= pronet::sensors::MAX_LEVER_ARM)
}

fn short_trajectory() -> impl Strategy<Value = TrajectorySpec> {
    (
        prop::collection::vec(
            (0.5..8.0f64, -0.1..0.1f64, -0.6..0.6f64, -0.02..0.02f64)
                .prop_map(|(d, a, y, p)| Segment::new(d, a, y, p)),
            1..4,
        ),
        prop::sample::select(vec![0.02, 0.05, 0.1]),
        0.0..2.5f64,
    )
        .prop_map(|(segments, dt, speed0)| TrajectorySpec {
            name: "mc".into(),
            lla0: paper_origin(),
            speed0,
            rpy0: Vector3::zeros(),
            segments,
            dt,
        })
}

/// Sensor values of overflow size (the simulated IMU and DVL overflow the same way).
fn huge_sensors(s: &SensorConfig) -> bool {
    s.imu.variance.values()[0]
        .iter()
        .chain(&s.imu.bias)
        .chain(&s.imu.bias_rw_psd)
        .chain(&s.dvl.variance)
        .chain(s.dvl.lever_arm.iter())
        .any(|v| v.is_finite() && v.abs() >= HUGE)
}

/// One case of the Monte Carlo property (known overflow cases are left out).
fn mc_case(
    traj: &TrajectorySpec,
    sensors: Option<SensorConfig>,
    imu_q: [f64; 6],
    cfg: &FilterConfig,
    spec: &StrategySpec,
    initial_error: bool,
    record_every: usize,
) -> Result<(), TestCaseError> {
    let q_valid = imu_q.iter().all(|v| v.is_finite() && *v >= 0.0);
    prop_assert_eq!(sensors.is_some(), q_valid, "IMU variance {:?}", imu_q);
    let Some(sensors) = sensors else {
        return Ok(());
    };
    let truth = match traj.generate() {
        Ok(t) => t,
        // Validation of trajectories is the first property's business.
        Err(_) => return Ok(()),
    };
    // The DVL period must be a whole number of IMU steps (a period so long that the
    // ratio overflows, 1.8e308 s, counts as whole: it means no DVL epoch at all).
    let ratio = sensors.dvl.period / truth.dt;
    let off = (ratio - ratio.round()).abs();
    let period_fits = ratio.round() >= 1.0 && (off <= 1e-6 * ratio || !ratio.is_finite());
    // An external strategy's q comes from outside: a Monte Carlo refuses it.
    let settings_valid = config_is_valid(cfg)
        && strategy_is_valid(spec)
        && !matches!(spec, StrategySpec::External { .. })
        && sensors_are_valid(&sensors)
        && period_fits;
    // An initial error drawn from an absurd P0 σ is absurd data.
    let absurd_start = initial_error
        && cfg
            .p0_sigma
            .iter()
            .any(|v| v.is_finite() && *v >= ABSURD_DATA);
    if settings_valid && (huge_tuning(cfg, spec) || huge_sensors(&sensors) || absurd_start) {
        return Ok(());
    }
    let scenario = Arc::new(Scenario {
        truth: Arc::new(truth),
        sensors: sensors.clone(),
        sample_initial_error: initial_error,
    });
    let opts = McOptions {
        n_runs: 2,
        seed: 5,
        record_every,
        first_run: 0,
        smooth: false,
    };
    let result = run_monte_carlo(&scenario, cfg, spec, &opts);
    if settings_valid {
        prop_assert!(result.is_ok(), "valid settings refused: {:?}", result.err());
    } else {
        prop_assert!(
            matches!(result, Err(pronet::Error::InvalidArgument { .. })),
            "invalid settings not refused as an invalid argument: {:?}",
            result.as_ref().err()
        );
    }
    let Ok(mc) = result else {
        return Ok(());
    };
    prop_assert_eq!(mc.runs.len(), 2);
    prop_assert!(all_finite(&mc.dvl_time) && all_finite(&mc.record_time));
    for (i, run) in mc.runs.iter().enumerate() {
        let s = &run.summary;
        let metrics = summary_metrics(s);
        match &s.failure {
            Some(msg) => {
                prop_assert!(!msg.is_empty());
                prop_assert!(
                    metrics.iter().all(|m| m.is_nan()),
                    "failed run {} has metrics {:?}",
                    i,
                    metrics
                );
            }
            None => {
                // Mean NIS is NaN, by design, when no update was applied (none made,
                // or the gate rejected every one).
                let none_applied = s.rejected_updates == run.nis.len();
                let checked = if none_applied {
                    &metrics[..4]
                } else {
                    &metrics[..]
                };
                prop_assert!(
                    all_finite(checked),
                    "run {}: metrics {:?} with no failure reported",
                    i,
                    metrics
                );
                prop_assert!(all_finite(&run.nis), "run {}: NIS {:?}", i, run.nis);
                if let Some(h) = &run.history {
                    for (k, (e, sg)) in h.error.iter().zip(&h.sigma).enumerate() {
                        prop_assert!(all_finite(e), "run {} epoch {}: error {:?}", i, k, e);
                        prop_assert!(all_finite(sg), "run {} epoch {}: sigma {:?}", i, k, sg);
                    }
                }
            }
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(config())]

    /// A Monte Carlo over a random short trajectory with random sensors, filter config
    /// and strategy: invalid settings are refused; otherwise every run either reports
    /// a numerical failure (and NaN metrics, as documented) or finite results.
    #[test]
    fn monte_carlo_is_finite_reports_failure_or_err(
        traj in short_trajectory(),
        (sensors, imu_q) in sensor_config(),
        cfg in filter_config(),
        spec in strategy_spec(),
        initial_error in any::<bool>(),
        record_every in prop::sample::select(vec![0usize, 1, 7]),
    ) {
        mc_case(&traj, sensors, imu_q, &cfg, &spec, initial_error, record_every)?;
    }
}

// =======================================================================================
// Pinned failures: inputs the library accepts and then answers with NaN or ±inf inside
// an `Ok` (found by the properties above, then reduced by hand). Each test states the
// contract, so it fails today; they are ignored to keep the suite green until fixed.
// Root causes: nothing checks that the state and P stay finite after propagation (only
// `Ekf::update` checks, so an overflow after the last update, or in a run with no DVL
// update, goes unnoticed); `Ekf::sigma` turns a NaN variance into σ = 0; and some
// finite-but-absurd inputs are not bounded by validation.

/// Every number of a filter pass is finite.
fn output_is_finite(out: &FilterOutput) -> bool {
    out.nav.iter().all(nav_finite)
        && out.sigma.iter().all(all_finite)
        && out.bias.iter().all(all_finite)
        && all_finite(out.final_covariance.iter())
}

/// `filter_recorded` over the 20 s recording without DVL rows, from the true start.
fn pass_without_dvl(
    cfg: &FilterConfig,
    spec: &StrategySpec,
    t0: f64,
    bias0: [f64; 6],
    vel0: Option<Vector3<f64>>,
) -> pronet::Result<FilterOutput> {
    let rec = recording();
    let data = RecordedData {
        imu: &rec.imu,
        imu_time: &rec.imu_time,
        dvl: &[],
        dvl_time: &[],
        t0,
        q_time: &[],
        q_values: &[],
        covariance_time: &[],
        ..RecordedData::default()
    };
    let mut init = rec.truth.states[0];
    if let Some(v) = vel0 {
        init.vel = v;
    }
    let mut strategy = spec.build(cfg.bias_psd());
    filter_recorded(&data, init, bias0, cfg, strategy.as_mut())
}

fn tuned_config() -> FilterConfig {
    FilterConfig {
        imu_dt: 0.05,
        ..FilterConfig::default()
    }
}

const TRUE_Q: StrategySpec = StrategySpec::Constant {
    q: [1e-4, 1e-4, 1e-4, 1e-6, 1e-6, 1e-6],
};

fn assert_err_or_finite(result: pronet::Result<FilterOutput>) {
    if let Ok(out) = result {
        let k = out
            .nav
            .iter()
            .zip(&out.sigma)
            .position(|(n, s)| !nav_finite(n) || !all_finite(s));
        assert!(
            output_is_finite(&out),
            "Ok with non-finite output: first bad epoch {k:?}; final P diagonal {:?}",
            out.final_covariance.diagonal().as_slice()
        );
    }
}

/// Before the fix: `Ok`, and the truth is NaN from t = 1.01 s (yaw = yaw_rate·t overflows to inf
/// once t > 1 s; sin(inf) = NaN), the ideal IMU too.
#[test]
fn pinned_huge_yaw_rate_generates_nan_truth() {
    let spec = TrajectorySpec {
        name: "yaw".into(),
        lla0: paper_origin(),
        speed0: 1.0,
        rpy0: Vector3::zeros(),
        segments: vec![Segment::new(2.0, 0.0, f64::MAX, 0.0)],
        dt: 0.01,
    };
    if let Ok(truth) = spec.generate() {
        check_truth(&spec, &truth).unwrap();
    }
}

/// Before the fix: `Ok`, with ideal IMU sample 0 = [inf, NaN, −inf, …] (gravity's h² term
/// overflows; h = 1e154 does the same, h = 1e20 is still finite).
#[test]
fn pinned_huge_initial_height_generates_non_finite_imu() {
    let spec = TrajectorySpec {
        name: "height".into(),
        lla0: Vector3::new(paper_origin()[0], paper_origin()[1], 1e300),
        speed0: 1.0,
        rpy0: Vector3::zeros(),
        segments: vec![Segment::new(1.0, 0.0, 0.0, 0.0)],
        dt: 0.01,
    };
    if let Ok(truth) = spec.generate() {
        check_truth(&spec, &truth).unwrap();
    }
}

/// `sigma()` is documented as √diag P; a NaN variance must not come out as σ = 0
/// ("perfectly known"). Before the fix: `NaN.max(0.0) = 0.0`, so σ = 0.
#[test]
fn pinned_nan_variance_is_reported_as_zero_sigma() {
    let cfg = tuned_config();
    let mut ekf = Ekf::new(
        &cfg,
        recording().truth.states[0],
        Vector3::zeros(),
        Vector3::zeros(),
    )
    .unwrap();
    ekf.p[(0, 0)] = f64::NAN;
    let sigma = ekf.sigma()[0];
    assert!(sigma.is_nan(), "sigma of a NaN variance is {sigma}");
}

/// Before the fix: `validate()` accepts p0_sigma[0] = 1e300 (finite, ≥ 0), P0[0,0] = inf, and the
/// pass returns `Ok`: σ_N = inf at t0, then 0.0 (NaN masked), 36 non-finite entries in
/// the final P.
#[test]
fn pinned_huge_p0_sigma_overflows_p() {
    let mut cfg = tuned_config();
    cfg.p0_sigma[0] = 1e300;
    assert_err_or_finite(pass_without_dvl(&cfg, &TRUE_Q, 0.0, [0.0; 6], None));
}

/// Before the fix: `Ok`; Q_d overflows, the final P has 72 non-finite entries, and the final σ
/// of position and velocity is reported as 0.0.
#[test]
fn pinned_huge_q_overflows_p() {
    let spec = StrategySpec::Constant {
        q: [1e-4, 1e-4, 1e-4, f64::MAX, 1e-6, 1e-6],
    };
    assert!(spec.validate().is_ok());
    assert_err_or_finite(pass_without_dvl(
        &tuned_config(),
        &spec,
        0.0,
        [0.0; 6],
        None,
    ));
}

/// Before the fix: `Ok`; the first step is 1e300 s long and the state after it is NaN.
#[test]
fn pinned_huge_first_time_step() {
    assert_err_or_finite(pass_without_dvl(
        &tuned_config(),
        &TRUE_Q,
        -1e300,
        [0.0; 6],
        None,
    ));
}

/// Before the fix: `Ok`; the velocity is −5e298 m/s after one step, the height −inf after two.
#[test]
fn pinned_huge_initial_bias() {
    let bias0 = [1e300, 0.0, 0.0, 0.0, 0.0, 0.0];
    assert_err_or_finite(pass_without_dvl(&tuned_config(), &TRUE_Q, 0.0, bias0, None));
}

/// Before the fix: `Ok`; from epoch 165 (t = 8.25 s) the state is non-finite.
#[test]
fn pinned_absurd_initial_velocity() {
    let vel0 = Vector3::new(1e10, 0.0, 0.0);
    assert_err_or_finite(pass_without_dvl(
        &tuned_config(),
        &TRUE_Q,
        0.0,
        [0.0; 6],
        Some(vel0),
    ));
}

/// A 1.5 s Monte Carlo run (20 Hz) with the given sensors: its one summary.
fn one_short_run(sensors: SensorConfig) -> pronet::Result<pronet::montecarlo::RunSummary> {
    let spec = TrajectorySpec {
        name: "short".into(),
        lla0: paper_origin(),
        speed0: 1.0,
        rpy0: Vector3::zeros(),
        segments: vec![Segment::new(1.5, 0.0, 0.0, 0.0)],
        dt: 0.05,
    };
    let scenario = Arc::new(Scenario {
        truth: Arc::new(spec.generate().unwrap()),
        sensors,
        sample_initial_error: false,
    });
    let opts = McOptions {
        n_runs: 1,
        seed: 1,
        record_every: 0,
        first_run: 0,
        smooth: false,
    };
    run_monte_carlo(&scenario, &tuned_config(), &TRUE_Q, &opts).map(|r| r.runs[0].summary.clone())
}

fn assert_err_failure_or_finite(result: pronet::Result<pronet::montecarlo::RunSummary>) {
    if let Ok(s) = result {
        let metrics = summary_metrics(&s);
        assert!(
            s.failure.is_some() || all_finite(&metrics),
            "NaN metrics without a reported failure: {s:?}"
        );
    }
}

/// Before the fix: `Ok` with srmse = smae = final error = NaN, `failure: None` (no DVL epoch in
/// the 1.5 s run to notice). With a 1 s DVL period the failure is reported.
#[test]
fn pinned_monte_carlo_huge_imu_variance_without_dvl_epoch() {
    let mut sensors = SensorConfig::paper();
    sensors.imu.variance =
        VarianceSchedule::new(vec![0.0], vec![[1e300, 1e-4, 1e-4, 1e-6, 1e-6, 1e-6]]).unwrap();
    sensors.dvl.period = 2.0;
    assert_err_failure_or_finite(one_short_run(sensors));
}

/// Before the fix: the t = 1 s update accepts a 1e150 m/s reading (NIS 1.2e301) and feeds it
/// back; the metrics are NaN with `failure: None`.
#[test]
fn pinned_monte_carlo_huge_dvl_variance() {
    let mut sensors = SensorConfig::paper();
    sensors.dvl.variance = [1e300, 0.01, 0.01];
    assert_err_failure_or_finite(one_short_run(sensors));
}

/// `VarianceSchedule::constant` does not check its values (`new` does) and
/// `SensorConfig::validate` does not look at the schedule, so a negative variance
/// reaches the simulator: √(−1) = NaN IMU samples. Before the fix: `Ok` with NaN metrics and
/// `failure: None` when no DVL epoch falls in the run.
#[test]
fn pinned_unchecked_constant_variance_schedule() {
    let mut sensors = SensorConfig::paper();
    sensors.imu.variance = VarianceSchedule::constant([-1.0, 1e-4, 1e-4, 1e-6, 1e-6, 1e-6]);
    sensors.dvl.period = 2.0;
    assert!(
        sensors.validate().is_err(),
        "a negative IMU variance passes SensorConfig::validate"
    );
    assert_err_failure_or_finite(one_short_run(sensors));
}
