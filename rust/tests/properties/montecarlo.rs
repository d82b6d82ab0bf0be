//! Monte Carlo: random short trajectories, sensors, filter configs and strategies.

use super::*;

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
            .all(|v| v.abs() <= pronet::ekf::MAX_LEVER_ARM)
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
