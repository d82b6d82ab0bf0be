//! Pinned failures: inputs the library once accepted and then answered with NaN or ±inf
//! inside an `Ok` (found by the properties in the sibling modules, then reduced by
//! hand). Each test states the contract; all of them hold since the fixes (a prediction
//! that is not finite is an error, a trajectory that overflows is refused, σ of a NaN
//! variance is NaN, the IMU variance schedule is validated). The root causes were: nothing
//! checked that the state and P stay finite after propagation (only the DVL update did,
//! so an overflow after the last update, or in a run with no DVL update, went
//! unnoticed); `Ekf::sigma` turned a NaN variance into σ = 0; and some finite-but-absurd
//! inputs were not bounded by validation.

use super::*;

/// Every number of a filter pass is finite.
fn output_is_finite(out: &FilterOutput) -> bool {
    (0..solution_epochs(out)).all(|k| solution_finite(out, k))
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
        t0,
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
        let k = (0..solution_epochs(&out))
            .position(|k| !solution_finite(&out, k) || !all_finite(&out.sigma[k]));
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
